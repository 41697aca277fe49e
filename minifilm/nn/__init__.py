"""The deep-learning kit, written from scratch. Knows nothing about motion.

    functional.py  forward/backward pairs (the maths)
    params.py      Parameters: named weights as views into one flat buffer; initialisers
    layers.py      thin layer classes over functional.py
    optim.py       Adam, in place over flat buffers, skipping frozen sets
    gradcheck.py   centred-difference gradient checks for any layer or network
"""
from minifilm.nn import functional
from minifilm.nn.gradcheck import check_gradients, check_layer, numerical_gradient, rel_error
from minifilm.nn.layers import (ELU, FiLM, Conv1d, Dropout, ExpertLinear, Layer, LayerNorm, Linear,
                     MaxPool1d, ReLU, Softmax)
from minifilm.nn.optim import Adam
from minifilm.nn.params import Parameters, init_constant, init_he_normal, init_uniform_fan

__all__ = [
    "functional", "Parameters", "init_uniform_fan", "init_he_normal", "init_constant",
    "Layer", "Linear", "ExpertLinear", "Conv1d", "ELU", "ReLU", "Softmax", "LayerNorm", "FiLM",
    "Dropout", "MaxPool1d", "Adam", "rel_error", "numerical_gradient", "check_gradients",
    "check_layer",
]
