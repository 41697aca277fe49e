"""The gradient-check method (minifilm/nn/gradcheck.py) and every pair of the kit, in float64.

The kit's rows of ``minifilm gradcheck`` run here, one test per (row, seed): four-point centred
differences with h = 3e-4, every entry of every input, the objective normalised to 1e-4, the
elementwise relative error below 1e-7, inputs away from kinks and no stencil evaluation crossing
one (minifilm/evaluation/gradcheck_table.py explains the numbers). The first tests show the
method itself: that it is exact on known functions, that it catches a wrong backward pass, why
the objective is normalised, and that the kink guard sees a crossed kink.
"""
import math

import numpy as np
import pytest

from gradcheck_report import check
from minifilm.evaluation import gradcheck_cases as kit
from minifilm.evaluation.gradcheck_table import SEEDS, cases
from minifilm.nn import functional as F
from minifilm.nn.gradcheck import (H, LIMIT, SCALE, check_gradients, check_pair, compare_gradients,
                                   numerical_gradient, passed, rel_error, worst_error)

KIT = [c for c in cases() if c.group == "kit"]


# ------------------------------------------------------------------------------ the method
def test_rel_error_is_elementwise_max():
    a = np.array([1.0, 0.0, 2.0])
    b = np.array([1.0, 0.0, 2.2])
    assert rel_error(a, b) == pytest.approx(0.2 / 4.2)
    assert rel_error(np.zeros(3), np.full(3, 1e-12)) == pytest.approx(1e-4)   # the 1e-8 floor
    with pytest.raises(ValueError):
        rel_error(np.zeros(2), np.zeros(3))


@pytest.mark.parametrize("order,h,tol", [(2, 1e-6, 1e-8), (4, H, 1e-11)])
def test_numerical_gradient_of_known_function_and_restores_x(order, h, tol):
    x = np.array([[0.3, -1.2], [2.0, 0.7]])
    before = x.copy()
    g = numerical_gradient(lambda: float(np.sum(np.sin(x) * x ** 2)), x, h=h, order=order)
    assert np.array_equal(x, before)
    exact = np.cos(x) * x ** 2 + 2 * x * np.sin(x)
    assert rel_error(g, exact) < tol


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
    f = lambda: math.fsum((F.linear_forward(x, W, b)[0] * r).ravel().tolist())   # noqa: E731
    scale = math.fsum(np.abs(out * r).ravel().tolist())
    good = check_gradients(f, {"x": (x, dx), "W": (W, dW), "b": (b, db)}, scale=scale)
    assert max(good.values()) < 1e-9
    wrong = dW.copy()
    wrong[1, 0] *= 1 + 1e-6                          # one entry off by one part in a million
    bad = check_gradients(f, {"W": (W, wrong), "b": (b, 0 * db)}, scale=scale)
    assert 1e-7 < bad["W"] < 1e-5 and bad["b"] == 1.0


def test_check_pair_uses_the_suite_method():
    rng = np.random.default_rng(2)
    errors = check_pair(F.softmax_forward, F.softmax_backward, (rng.standard_normal((3, 5)),), rng, names=("x",))
    assert errors["x"] < LIMIT


def test_normalising_the_objective_makes_tiny_entries_meaningful():
    """An entry whose gradient is 1e-7 of the objective's scale: un-normalised, the stencil's
    rounding (~1.5 ε S / h) alone is ~1e-6 of it, and the entry fails 1e-7 although the gradient
    is exact; normalised to SCALE, the floor of rel_error turns it into an absolute check at the
    rounding level. A wrong gradient still fails either way."""
    w = np.array([1.0, 1e-7])
    x = np.array([0.7, -0.4])
    f = lambda: float(np.sum(w * np.exp(x)) + 3.0)   # noqa: E731  (the constant: S > |gradient|)
    exact = w * np.exp(x)
    raw = compare_gradients(f, {"x": (x, exact)})["x"]
    assert raw.worst == (1,) and raw.error > LIMIT
    S = float(np.sum(np.abs(w * np.exp(x))) + 3.0)
    assert check_gradients(f, {"x": (x, exact)}, scale=S)["x"] < LIMIT
    assert check_gradients(f, {"x": (x, exact * [1 + 1e-6, 1])}, scale=S)["x"] > LIMIT
    assert compare_gradients(f, {"x": (x, exact)}, scale=S)["x"].analytic[0] == pytest.approx(SCALE * exact[0] / S)


def test_the_kink_guard_sees_a_crossed_kink():
    """An ELU input 1e-4 from 0 (inside the stencil's ±2h): the guard counts the evaluations
    that switched side, and the error shows why inputs are kept away from kinks."""
    rng = np.random.default_rng(3)
    x = kit.away_from_zero(rng, (2, 3))
    x[0, 1] = 1e-4
    result = kit.pair_result(F.elu_forward, F.elu_backward, (x,), ("x",), rng, kinks=lambda c: [c[0]])
    assert result.crossings == 2 and result.margin == pytest.approx(1e-4)
    assert result.errors["x"] > 1e-6


# ------------------------------------------------------------------------------ NaN and inf fail
def _poisoned(backward, value, where=0):
    """``backward`` with one entry of its ``where``-th gradient replaced by ``value``."""
    def broken(dout, cache):
        grads = list(backward(dout, cache))
        g = np.array(grads[where], dtype=np.float64)
        g.flat[g.size // 2] = value
        grads[where] = g
        return tuple(grads)
    return broken


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("where", [0, 1, 2])
def test_a_non_finite_gradient_fails_check_pair(value, where):
    """One NaN or inf in any gradient: its array's error is inf (not NaN, which compares False
    with everything), so every way of reading the result fails, whatever the arrays' order."""
    rng = np.random.default_rng(4)
    x, W, b = rng.standard_normal((3, 4)), rng.standard_normal((4, 2)), rng.standard_normal(2)
    errors = check_pair(F.linear_forward, _poisoned(F.linear_backward, value, where), (x, W, b), rng,
                        names=("x", "W", "b"))
    assert errors[("x", "W", "b")[where]] == np.inf
    assert not passed(errors) and worst_error(errors) == np.inf
    for order in (list(errors.values()), list(errors.values())[::-1]):
        assert not max(order) < LIMIT


def test_a_non_finite_forward_output_fails_check_pair():
    rng = np.random.default_rng(5)
    x = rng.standard_normal((2, 3))
    x[1, 2] = np.inf
    errors = check_pair(F.relu_forward, F.relu_backward, (x,), rng, names=("x",))
    assert errors["x"] == np.inf and not passed(errors)


def test_worst_error_reads_nan_and_inf_as_failures_in_any_order():
    assert worst_error({"a": 1e-9, "b": np.nan}) == worst_error({"b": np.nan, "a": 1e-9}) == np.inf
    assert worst_error([np.inf, 0.0]) == np.inf and worst_error({}) == np.inf   # nothing checked
    assert worst_error({"a": 1e-9, "b": 3e-9}) == 3e-9
    assert passed({"a": 1e-9}) and not passed({"a": np.nan}) and not passed({}) and not passed({"a": 2e-7})
    assert rel_error(np.array([1.0, np.nan]), np.array([1.0, 1.0])) == np.inf
    assert rel_error(np.array([np.inf]), np.array([np.inf])) == np.inf


@pytest.mark.parametrize("h", [0, 0.0, -1e-4, np.nan, np.inf, "1e-4", None])
def test_numerical_gradient_refuses_a_step_that_is_not_finite_and_positive(h):
    x = np.ones(3)
    with pytest.raises(ValueError, match="numerical_gradient: h must be a finite step > 0"):
        numerical_gradient(lambda: float(x.sum()), x, h=h)
    with pytest.raises(ValueError, match="h must be a finite step > 0"):
        check_gradients(lambda: float(x.sum()), {"x": (x, np.ones(3))}, h=h)


@pytest.mark.parametrize("scale", [0.0, -1.0, np.nan, np.inf])
def test_check_gradients_refuses_a_scale_that_is_not_finite_and_positive(scale):
    x = np.ones(3)
    with pytest.raises(ValueError, match="scale must be a finite number > 0"):
        check_gradients(lambda: float(x.sum()), {"x": (x, np.ones(3))}, scale=scale)


# ------------------------------------------------------------------------------ every pair of the kit
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", KIT, ids=lambda c: c.name)
def test_kit_pair(case, seed):
    check(case, seed)
