"""Gradient checks: every input and every parameter of every layer, in float64, rel error < 1e-7.

The numerical side uses the fourth-order centred stencil with h = 1e-4 (truncation ~h^4, rounding
~1e-12): it is more accurate than the two-point h = 1e-6 stencil, so it makes the check stricter.
Inputs stay more than 2h away from kinks (ReLU, ELU at 0) and ties (max-pool).
"""
import math

import numpy as np
import pytest

from minifilm.nn import (ELU, FiLM, Conv1d, Dropout, ExpertLinear, LayerNorm, Linear, MaxPool1d,
                         Parameters, ReLU, Softmax, check_gradients, check_layer,
                         numerical_gradient, rel_error)
from minifilm.nn import functional as F

TOL = 1e-7
H, ORDER = 1e-4, 4
F64 = np.float64


def away_from_zero(rng, shape, gap=0.05):
    """Normal-ish numbers with |x| >= gap, so a +-2h step never crosses 0."""
    x = rng.standard_normal(shape)
    return np.sign(x) * (gap + np.abs(x))


def run_check(layer, inputs, seed=0, **kw):
    errors = check_layer(layer, inputs, np.random.default_rng(seed), h=H, order=ORDER, **kw)
    assert len(errors) == len(inputs) + len(layer.params)
    bad = {k: v for k, v in errors.items() if not v < TOL}
    assert not bad, f"{type(layer).__name__}: rel errors above {TOL}: {bad}"


# ------------------------------------------------------------------------------ the helpers
def test_rel_error_is_elementwise_max():
    a = np.array([1.0, 0.0, 2.0])
    b = np.array([1.0, 0.0, 2.2])
    assert rel_error(a, b) == pytest.approx(0.2 / 4.2)
    assert rel_error(np.zeros(3), np.full(3, 1e-12)) < 1e-3   # the 1e-8 floor
    with pytest.raises(ValueError):
        rel_error(np.zeros(2), np.zeros(3))


@pytest.mark.parametrize("order,h", [(2, 1e-6), (4, 1e-4)])
def test_numerical_gradient_of_known_function_and_restores_x(order, h):
    x = np.array([[0.3, -1.2], [2.0, 0.7]])
    before = x.copy()
    g = numerical_gradient(lambda: float(np.sum(np.sin(x) * x ** 2)), x, h=h, order=order)
    assert np.array_equal(x, before)
    exact = np.cos(x) * x ** 2 + 2 * x * np.sin(x)
    assert rel_error(g, exact) < 1e-8


def test_numerical_gradient_refuses_float32():
    x = np.ones(3, dtype=np.float32)
    with pytest.raises(TypeError, match="float64"):
        numerical_gradient(lambda: float(x.sum()), x)


def test_check_gradients_catches_a_wrong_backward():
    rng = np.random.default_rng(1)
    x, W, b = rng.standard_normal((3, 4)), rng.standard_normal((4, 2)), rng.standard_normal(2)
    r = rng.standard_normal((3, 2))
    out, cache = F.linear_forward(x, W, b)
    dx, dW, db = F.linear_backward(r, cache)
    f = lambda: float(np.sum(F.linear_forward(x, W, b)[0] * r))
    good = check_gradients(f, {"x": (x, dx), "W": (W, dW), "b": (b, db)})
    assert max(good.values()) < 1e-6                 # default two-point h = 1e-6 works too
    bad = check_gradients(f, {"W": (W, 1.01 * dW), "b": (b, 0 * db)})
    assert bad["W"] > 1e-3 and bad["b"] > 0.5


# ------------------------------------------------------------------------------ every layer
def test_linear():
    rng = np.random.default_rng(0)
    run_check(Linear(5, 3, rng, dtype=F64), (rng.standard_normal((4, 5)),))


@pytest.mark.parametrize("batch", [1, 4])   # batch 1 takes the blend-first path
def test_expert_linear(batch):
    rng = np.random.default_rng(batch)
    layer = ExpertLinear(3, 5, 4, rng, dtype=F64)
    layer.params["b"][...] = rng.standard_normal(layer.params["b"].shape)
    alpha = F.softmax_forward(rng.standard_normal((batch, 3)))[0]
    run_check(layer, (rng.standard_normal((batch, 5)), alpha))


@pytest.mark.parametrize("k", [1, 3, 5, 7])
@pytest.mark.parametrize("T", [6, 7])
def test_conv1d(k, T):
    rng = np.random.default_rng(10 * k + T)
    layer = Conv1d(3, 2, k, rng, dtype=F64)
    layer.params["b"][...] = rng.standard_normal(2)
    run_check(layer, (rng.standard_normal((2, T, 3)),))


def test_elu():
    rng = np.random.default_rng(2)
    run_check(ELU(), (away_from_zero(rng, (4, 6)),))


def test_relu():
    rng = np.random.default_rng(3)
    run_check(ReLU(), (away_from_zero(rng, (4, 6)),))


def test_softmax():
    rng = np.random.default_rng(4)
    run_check(Softmax(), (rng.standard_normal((4, 6)),))


@pytest.mark.parametrize("unbiased,eps", [(True, 1e-6), (False, 0.0)])
def test_layer_norm(unbiased, eps):
    rng = np.random.default_rng(5)
    run_check(LayerNorm(unbiased, eps), (rng.standard_normal((4, 8)),))


@pytest.mark.parametrize("per_sample", [True, False])
def test_film(per_sample):
    rng = np.random.default_rng(6)
    shape = (4, 5) if per_sample else (5,)
    run_check(FiLM(), (rng.standard_normal((4, 5)), rng.standard_normal(shape),
                       rng.standard_normal(shape)))


def test_dropout_with_fixed_mask():
    rng = np.random.default_rng(7)
    x = rng.standard_normal((4, 6))
    mask = rng.random(x.shape) >= 0.3
    run_check(Dropout(0.3), (x,), train=True, mask=mask)


@pytest.mark.parametrize("T", [6, 7])
def test_max_pool1d(T):
    rng = np.random.default_rng(8)
    x = (rng.permutation(2 * T * 3) * 0.1).reshape(2, T, 3)   # distinct, 0.1 apart: no ties
    run_check(MaxPool1d(), (x,))


def test_whole_small_network():
    """check_gradients on a composition, as a reader would check a network they built:
    ExpertLinear -> LayerNorm -> FiLM -> ELU -> Dropout -> Linear, all parameters in one buffer."""
    rng = np.random.default_rng(9)
    B, I, Hd, O, K = 3, 4, 6, 2, 3
    params = Parameters({**ExpertLinear.param_shapes(K, I, Hd, "e."), **Linear.param_shapes(Hd, O, "o.")},
                        dtype=F64)
    params.data[...] = rng.standard_normal(params.size) * 0.5
    expert = ExpertLinear(K, I, Hd, parameters=params, prefix="e.")
    norm, film, act, drop = LayerNorm(), FiLM(), ELU(), Dropout(0.2)
    out_layer = Linear(Hd, O, parameters=params, prefix="o.")
    x = rng.standard_normal((B, I))
    logits = rng.standard_normal((B, K))
    gamma, beta = rng.standard_normal((B, Hd)), rng.standard_normal((B, Hd))
    mask = rng.random((B, Hd)) >= 0.2
    r = rng.standard_normal((B, O))

    def forward():
        alpha = F.softmax_forward(logits)[0]
        h = expert.forward(x, alpha)
        h = act.forward(film.forward(norm.forward(h), gamma, beta))
        return out_layer.forward(drop.forward(h, train=True, mask=mask))

    def loss():
        return math.fsum((forward() * r).ravel().tolist())

    forward()
    sm_cache = F.softmax_forward(logits)[1]
    params.zero_grad()
    dh = act.backward(drop.backward(out_layer.backward(r)))
    dh, dgamma, dbeta = film.backward(dh)
    dx, dalpha = expert.backward(norm.backward(dh))
    dlogits = F.softmax_backward(dalpha, sm_cache)
    pairs = {"x": (x, dx), "logits": (logits, dlogits), "gamma": (gamma, dgamma),
             "beta": (beta, dbeta), "all parameters": (params.data, params.grad)}
    errors = check_gradients(loss, pairs, h=H, order=ORDER)
    assert max(errors.values()) < TOL, errors
