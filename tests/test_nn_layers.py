"""Parameters (one flat buffer, named views) and the thin layer classes around functional.py."""
import math

import numpy as np
import pytest

from minifilm.nn import (ELU, FiLM, Conv1d, Dropout, ExpertLinear, LayerNorm, Linear, MaxPool1d,
                         Parameters, ReLU, Softmax, init_he_normal, init_uniform_fan)
from minifilm.nn import functional as F


# ------------------------------------------------------------------------------ Parameters
def test_parameters_are_views_into_one_buffer():
    p = Parameters({"W": (3, 4), "b": 4, "E": (2, 3, 4)})
    assert p.size == 12 + 4 + 24 and p.data.shape == (40,) and p.data.dtype == np.float32
    p.params["W"][1, 2] = 5.0
    assert p.data[1 * 4 + 2] == 5.0
    p.data[12:16] = [1, 2, 3, 4]
    np.testing.assert_array_equal(p.params["b"], [1, 2, 3, 4])
    p.grads["E"][...] = 7.0
    assert np.all(p.grad[16:] == 7.0) and np.all(p.grad[:16] == 0)
    p.zero_grad()
    assert not p.grad.any() and np.shares_memory(p.grads["E"], p.grad)


def test_state_dict_is_a_copy_and_round_trips():
    p = Parameters({"W": (2, 3), "b": (3,)}, dtype=np.float64)
    p.data[...] = np.arange(9.0)
    state = p.state_dict()
    state["W"][0, 0] = 100.0
    assert p.params["W"][0, 0] == 0.0
    q = Parameters({"W": (2, 3), "b": (3,)}, dtype=np.float32)
    q.load_state_dict(p.state_dict())
    np.testing.assert_array_equal(q.data, np.arange(9.0))
    assert q.data.dtype == np.float32


def test_load_state_dict_errors_name_the_culprit():
    p = Parameters({"W": (2, 3), "b": (3,)})
    with pytest.raises(KeyError, match="'b'"):
        p.load_state_dict({"W": np.zeros((2, 3))})
    with pytest.raises(ValueError, match=r"'W' has shape \(3, 2\)"):
        p.load_state_dict({"W": np.zeros((3, 2)), "b": np.zeros(3)})
    with pytest.raises(KeyError, match="unexpected"):
        p.load_state_dict({"W": np.zeros((2, 3)), "b": np.zeros(3), "c": 1}, strict=True)
    p.load_state_dict({"W": np.ones((2, 3)), "b": np.ones(3), "c": 1})   # extras are fine by default
    assert np.all(p.data == 1)


def test_astype_copies():
    p = Parameters({"W": (2, 2)})
    p.data[...] = [1, 2, 3, 4]
    p.trainable = False
    q = p.astype(np.float64)
    assert q.data.dtype == np.float64 and q.trainable is False
    q.data[0] = 9
    assert p.data[0] == 1 and q.params["W"][0, 0] == 9


def test_initialisers():
    rng = np.random.default_rng(0)
    a = np.empty((200, 300))
    init_uniform_fan(a, 200, 300, rng)
    r = math.sqrt(6 / 500)
    assert np.abs(a).max() <= r and np.abs(a).max() > 0.99 * r
    assert abs(a.mean()) < 0.01 * r
    init_he_normal(a, 200, rng)
    assert abs(a.std() - math.sqrt(2 / 200)) < 0.01 * math.sqrt(2 / 200)


# ------------------------------------------------------------------------------ layers
def test_layers_share_one_buffer_through_prefixes():
    rng = np.random.default_rng(1)
    shapes = {**ExpertLinear.param_shapes(4, 6, 5, "l0."), **Linear.param_shapes(5, 2, "l1."),
              **Conv1d.param_shapes(3, 2, 5, "c.")}
    p = Parameters(shapes)
    e = ExpertLinear(4, 6, 5, rng, parameters=p, prefix="l0.")
    lin = Linear(5, 2, rng, parameters=p, prefix="l1.")
    conv = Conv1d(3, 2, 5, rng, parameters=p, prefix="c.")
    assert e.parameters is p and lin.parameters is p and conv.parameters is p
    assert np.shares_memory(e.params["W"], p.data) and np.shares_memory(lin.grads["b"], p.grad)
    # experts are initialised like the original: uniform in +-sqrt(6 / (in + out)), biases zero
    assert np.abs(e.params["W"]).max() <= math.sqrt(6 / 11) and not e.params["b"].any()
    with pytest.raises(ValueError, match="'l1.W'"):
        Linear(5, 3, parameters=p, prefix="l1.")
    with pytest.raises(KeyError, match="'l2.W'"):
        Linear(5, 2, parameters=p, prefix="l2.")


def test_layer_forward_matches_functional_and_gradients_accumulate():
    rng = np.random.default_rng(2)
    layer = ExpertLinear(3, 4, 2, rng, dtype=np.float64)
    x, alpha = rng.standard_normal((5, 4)), rng.random((5, 3))
    y = layer.forward(x, alpha)
    y_ref, cache = F.expert_linear_forward(x, alpha, layer.params["W"], layer.params["b"])
    np.testing.assert_array_equal(y, y_ref)
    dout = rng.standard_normal(y.shape)
    _, _, dW, db = F.expert_linear_backward(dout, cache)
    layer.backward(dout)
    layer.backward(dout)
    np.testing.assert_allclose(layer.grads["W"], 2 * dW, rtol=1e-12)
    np.testing.assert_allclose(layer.grads["b"], 2 * db, rtol=1e-12)
    W_before = layer.params["W"].copy()
    layer.backward(dout)
    np.testing.assert_array_equal(layer.params["W"], W_before)   # backward never moves weights


@pytest.mark.parametrize("index", range(3))   # the layers with weights: Linear, ExpertLinear, Conv1d
def test_every_weighted_layer_accumulates_gradients(index):
    rng = np.random.default_rng(4)
    layer, inputs, kwargs = _all_layers(rng, np.float64)[index]
    out = layer.forward(*inputs, **kwargs)
    dout = rng.standard_normal(out.shape)
    layer.backward(dout)
    once = {k: g.copy() for k, g in layer.grads.items()}
    assert all(np.any(g != 0) for g in once.values())
    layer.backward(dout)
    for k, g in layer.grads.items():
        np.testing.assert_allclose(g, 2 * once[k], rtol=1e-12, err_msg=f"{type(layer).__name__} {k}")


def test_backward_before_forward_is_an_error():
    with pytest.raises(RuntimeError, match="before forward"):
        Linear(2, 2).backward(np.ones((1, 2)))


def test_dropout_layer_train_and_eval():
    drop = Dropout(0.5)
    x = np.ones((4, 6), dtype=np.float32)
    assert drop.forward(x) is x and drop.backward(x) is x
    y = drop.forward(x, train=True, rng=np.random.default_rng(0))
    assert set(np.unique(y)) <= {0.0, 2.0}
    np.testing.assert_array_equal(drop.backward(np.ones_like(x)), y)


def _all_layers(rng, dtype):
    f = lambda *s: rng.standard_normal(s).astype(dtype)
    return [
        (Linear(4, 3, rng, dtype=dtype), (f(2, 4),), {}),
        (ExpertLinear(3, 4, 5, rng, dtype=dtype), (f(2, 4), rng.random((2, 3)).astype(dtype)), {}),
        (Conv1d(3, 4, 3, rng, dtype=dtype), (f(2, 5, 3),), {}),
        (ELU(), (f(2, 4),), {}),
        (ReLU(), (f(2, 4),), {}),
        (Softmax(), (f(2, 4),), {}),
        (LayerNorm(), (f(2, 4),), {}),
        (LayerNorm(unbiased=False, eps=0.0), (f(2, 4),), {}),
        (FiLM(), (f(2, 4), f(2, 4), f(2, 4)), {}),
        (Dropout(0.3), (f(2, 4),), {"train": True, "rng": rng}),
        (MaxPool1d(), (f(2, 5, 3),), {}),
    ]


@pytest.mark.parametrize("index", range(11))
def test_every_layer_float32_in_float32_out(index):
    rng = np.random.default_rng(3)
    layer, inputs, kwargs = _all_layers(rng, np.float32)[index]
    out = layer.forward(*inputs, **kwargs)
    assert out.dtype == np.float32, type(layer).__name__
    din = layer.backward(np.ones_like(out))
    for g in (din if isinstance(din, tuple) else (din,)) + tuple(layer.grads.values()):
        assert g.dtype == np.float32, type(layer).__name__


def test_max_pool_layer_odd_length_drops_last_frame():
    x = np.arange(7.0).reshape(1, 7, 1)
    y = MaxPool1d().forward(x)
    np.testing.assert_array_equal(y[0, :, 0], [1.0, 3.0, 5.0])
