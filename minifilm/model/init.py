"""Weight initialisation shared by Ω, Φ and Ψ."""
from __future__ import annotations

import numpy as np

from minifilm.nn.params import init_uniform_fan


def glorot_uniform(rng: np.random.Generator, shape, fan_in: int, fan_out: int, dtype) -> np.ndarray:
    """U(-a, a) with a = sqrt(6 / (fan_in + fan_out)) (Glorot & Bengio 2010), as the original
    code initialises its expert weights."""
    return init_uniform_fan(np.empty(shape, dtype), fan_in, fan_out, rng)


def init_dense_stack(params, sizes, rng: np.random.Generator, dtype) -> None:
    """Glorot-uniform weights ``W{l}`` and zero biases ``b{l}`` for the layers sizes[l] -> sizes[l+1]
    of a plain (Ω) or gated-expert (Φ) stack, in place; ``params`` is a Parameters."""
    for l in range(len(sizes) - 1):
        W = params.params[f"W{l}"]
        W[...] = glorot_uniform(rng, W.shape, sizes[l], sizes[l + 1], dtype)
        params.params[f"b{l}"][...] = 0.0
