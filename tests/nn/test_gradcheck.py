"""Gradient checks: every input of every forward/backward pair and block, in float64, rel error < 1e-7.

The numerical side uses the fourth-order centred stencil with h = 1e-4 (truncation ~h^4, rounding
~1e-12): it is more accurate than the two-point h = 1e-6 stencil, so it makes the check stricter.
Inputs stay more than 2h away from kinks (ReLU, ELU at 0) and ties (max-pool).
"""
import math

import numpy as np
import pytest

from minifilm.model import blocks
from minifilm.model.dropout import Dropout
from minifilm.nn import functional as F
from minifilm.nn.gradcheck import check_gradients, check_pair, numerical_gradient, rel_error
from minifilm.nn.params import Parameters

TOL = 1e-7
H, ORDER = 1e-4, 4
F64 = np.float64


def away_from_zero(rng, shape, gap=0.05):
    """Normal-ish numbers with |x| >= gap, so a +-2h step never crosses 0."""
    x = rng.standard_normal(shape)
    return np.sign(x) * (gap + np.abs(x))


def run_check(forward, backward, inputs, names, seed=0, **kw):
    errors = check_pair(forward, backward, inputs, np.random.default_rng(seed), names=names, h=H, order=ORDER, **kw)
    assert set(errors) == set(names), errors
    bad = {k: v for k, v in errors.items() if not v < TOL}
    assert not bad, f"{forward.__name__}: rel errors above {TOL}: {bad}"


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


# ------------------------------------------------------------------------------ every pair
def test_linear():
    rng = np.random.default_rng(0)
    x, W, b = rng.standard_normal((4, 5)), rng.standard_normal((5, 3)), rng.standard_normal(3)
    run_check(F.linear_forward, F.linear_backward, (x, W, b), ("x", "W", "b"))


@pytest.mark.parametrize("batch", [1, 4])
def test_expert_linear(batch):
    rng = np.random.default_rng(batch)
    alpha = F.softmax_forward(rng.standard_normal((batch, 3)))[0]
    inputs = (rng.standard_normal((batch, 5)), alpha, rng.standard_normal((3, 5, 4)), rng.standard_normal((3, 4)))
    run_check(F.expert_linear_forward, F.expert_linear_backward, inputs, ("x", "alpha", "W", "b"))


@pytest.mark.parametrize("k", [1, 3, 5, 7])
@pytest.mark.parametrize("T", [6, 7])
def test_conv1d(k, T):
    rng = np.random.default_rng(10 * k + T)
    inputs = (rng.standard_normal((2, T, 3)), rng.standard_normal((k, 3, 2)), rng.standard_normal(2))
    run_check(F.conv1d_forward, F.conv1d_backward, inputs, ("x", "W", "b"))


def test_elu():
    rng = np.random.default_rng(2)
    run_check(F.elu_forward, F.elu_backward, (away_from_zero(rng, (4, 6)),), ("x",))


def test_relu():
    rng = np.random.default_rng(3)
    run_check(F.relu_forward, F.relu_backward, (away_from_zero(rng, (4, 6)),), ("x",))


def test_softmax():
    rng = np.random.default_rng(4)
    run_check(F.softmax_forward, F.softmax_backward, (rng.standard_normal((4, 6)),), ("x",))


@pytest.mark.parametrize("unbiased,eps", [(True, 1e-6), (False, 0.0)])
def test_layer_norm(unbiased, eps):
    rng = np.random.default_rng(5)
    run_check(F.layer_norm_forward, F.layer_norm_backward, (rng.standard_normal((4, 8)),), ("x",),
              unbiased=unbiased, eps=eps)


@pytest.mark.parametrize("per_sample", [True, False])
def test_film(per_sample):
    rng = np.random.default_rng(6)
    shape = (4, 5) if per_sample else (5,)
    inputs = (rng.standard_normal((4, 5)), rng.standard_normal(shape), rng.standard_normal(shape))
    run_check(F.film_forward, F.film_backward, inputs, ("h", "gamma", "beta"))


def test_dropout_with_fixed_mask():
    rng = np.random.default_rng(7)
    x = rng.standard_normal((4, 6))
    mask = rng.random(x.shape) >= 0.3
    run_check(F.dropout_forward, F.dropout_backward, (x,), ("x",), p=0.3, mask=mask)


@pytest.mark.parametrize("T", [6, 7])
def test_max_pool1d(T):
    rng = np.random.default_rng(8)
    x = (rng.permutation(2 * T * 3) * 0.1).reshape(2, T, 3)   # distinct, 0.1 apart: no ties
    run_check(F.max_pool1d_forward, F.max_pool1d_backward, (x,), ("x",))


def test_gather_rows():
    """y[b] = x[index[b]] with a row used twice and a row not used (shared style clips)."""
    rng = np.random.default_rng(15)
    x = rng.standard_normal((3, 4, 2))
    index = np.array([2, 0, 2, 2, 0])
    run_check(F.gather_forward, F.gather_backward, (x,), ("x",), index=index)


# ------------------------------------------------------------------------------ the model's blocks
def fixed_dropout(shape, rng, site="s", p=0.2):
    """A Dropout of a training pass whose one site has a fixed mask (so every evaluation agrees)."""
    return Dropout(p, train=True, masks={site: rng.random(shape) >= p})


def test_dense_block():
    rng = np.random.default_rng(11)
    x, W, b = rng.standard_normal((4, 5)), rng.standard_normal((5, 3)), rng.standard_normal(3)
    run_check(blocks.dense_forward, blocks.dense_backward, (x, W, b), ("x", "W", "b"),
              activation="elu", drop=fixed_dropout(x.shape, rng), site="s")


def test_expert_block():
    rng = np.random.default_rng(12)
    alpha = F.softmax_forward(rng.standard_normal((4, 3)))[0]
    inputs = (rng.standard_normal((4, 5)), alpha, rng.standard_normal((3, 5, 2)), rng.standard_normal((3, 2)))
    run_check(blocks.expert_forward, blocks.expert_backward, inputs, ("x", "alpha", "W", "b"),
              drop=fixed_dropout((4, 5), rng), site="s")


def test_film_block_eq3():
    rng = np.random.default_rng(13)
    B, I, O, K = 4, 5, 6, 3
    alpha = F.softmax_forward(rng.standard_normal((B, K)))[0]
    inputs = (rng.standard_normal((B, I)), alpha, rng.standard_normal((K, I, O)), rng.standard_normal((K, O)),
              rng.standard_normal((B, O)), rng.standard_normal((B, O)))
    run_check(blocks.film_block_forward, blocks.film_block_backward, inputs,
              ("x", "alpha", "W", "b", "gamma", "beta"), drop=fixed_dropout((B, I), rng), site="s")


def test_conv_block():
    rng = np.random.default_rng(14)
    x = (rng.permutation(2 * 8 * 3) * 0.05 - 0.6).reshape(2, 8, 3)
    inputs = (x, 0.3 * rng.standard_normal((3, 3, 4)), 0.1 * rng.standard_normal(4))
    run_check(blocks.conv_block_forward, blocks.conv_block_backward, inputs, ("x", "W", "b"))


def test_whole_small_network():
    """check_gradients on a composition, as a reader would check a network they built:
    experts -> layer norm -> FiLM -> ELU (the Eq. 3 block) -> dropout -> linear, all parameters
    in one buffer, α from a softmax of logits."""
    rng = np.random.default_rng(9)
    B, I, Hd, O, K = 3, 4, 6, 2, 3
    params = Parameters({"W0": (K, I, Hd), "b0": (K, Hd), "W1": (Hd, O), "b1": (O,)}, dtype=F64)
    params.data[...] = rng.standard_normal(params.size) * 0.5
    P, G = params.params, params.grads
    x = rng.standard_normal((B, I))
    logits = rng.standard_normal((B, K))
    gamma, beta = rng.standard_normal((B, Hd)), rng.standard_normal((B, Hd))
    drop = Dropout(0.2, train=True, masks={"in": np.ones((B, I), bool), "out": rng.random((B, Hd)) >= 0.2})
    r = rng.standard_normal((B, O))

    def forward():
        alpha, c_soft = F.softmax_forward(logits)
        h, c_film = blocks.film_block_forward(x, alpha, P["W0"], P["b0"], gamma, beta, drop, "in")
        y, c_out = blocks.dense_forward(h, P["W1"], P["b1"], None, drop, "out")
        return y, (c_soft, c_film, c_out)

    def loss():
        return math.fsum((forward()[0] * r).ravel().tolist())

    _, (c_soft, c_film, c_out) = forward()
    params.zero_grad()
    dh, G["W1"][...], G["b1"][...] = blocks.dense_backward(r, c_out)
    dx, dalpha, G["W0"][...], G["b0"][...], dgamma, dbeta = blocks.film_block_backward(dh, c_film)
    dlogits = F.softmax_backward(dalpha, c_soft)
    pairs = {"x": (x, dx), "logits": (logits, dlogits), "gamma": (gamma, dgamma),
             "beta": (beta, dbeta), "all parameters": (params.data, params.grad)}
    errors = check_gradients(loss, pairs, h=H, order=ORDER)
    assert max(errors.values()) < TOL, errors
