"""Adam: hand-computed steps, convergence on a known convex quadratic, freezing, checkpoints; every
test runs on the plain Adam (nn/optim.py) and on the chunked one training uses (nn/fast_optim.py)."""
import numpy as np
import pytest

from minifilm.nn import optim
from minifilm.nn.fast_optim import ChunkedAdam
from minifilm.nn.params import Parameters


@pytest.fixture(params=[optim.Adam, ChunkedAdam], ids=["Adam", "ChunkedAdam"])
def Adam(request):  # noqa: N802  (the class under test)
    return request.param


def one_set(values, dtype=np.float64):
    p = Parameters({"w": (len(values),)}, dtype=dtype)
    p.data[...] = values
    return p


def test_first_step_moves_each_weight_by_lr_against_its_gradient_sign(Adam):
    # at t = 1: m_hat = g, v_hat = g^2, so the step is lr * g / (|g| + eps)
    p = one_set([1.0, -2.0, 0.5])
    p.grad[...] = [2.0, -0.5, 0.0]
    Adam([p], lr=0.1).step()
    expected = np.array([1.0 - 0.1 * 2 / (2 + 1e-8), -2.0 + 0.1 * 0.5 / (0.5 + 1e-8), 0.5])
    np.testing.assert_allclose(p.data, expected, rtol=1e-14)


def test_one_step_from_a_known_state_equals_hand_computation(Adam):
    lr, b1, b2, eps = 0.01, 0.8, 0.99, 1e-3
    p = one_set([0.3, -1.0])
    opt = Adam([p], lr=lr, beta1=b1, beta2=b2, eps=eps)
    opt.load_state_dict({"steps": np.array([4]), "m.0": np.array([0.2, -0.1]),
                         "v.0": np.array([0.05, 0.02])})
    p.grad[...] = [1.0, 0.5]
    opt.step()
    # by hand, t = 5, first weight:
    # m = 0.8*0.2 + 0.2*1.0 = 0.36;  v = 0.99*0.05 + 0.01*1.0 = 0.0595
    # m_hat = 0.36 / (1 - 0.8^5) = 0.36 / 0.67232;  v_hat = 0.0595 / (1 - 0.99^5) = 0.0595 / 0.0490099501
    # second weight: m = -0.08 + 0.1 = 0.02;  v = 0.0198 + 0.0025 = 0.0223
    m_hat = np.array([0.36, 0.02]) / 0.67232
    v_hat = np.array([0.0595, 0.0223]) / 0.0490099501
    expected = np.array([0.3, -1.0]) - lr * m_hat / (np.sqrt(v_hat) + eps)
    np.testing.assert_allclose(p.data, expected, rtol=1e-12)
    np.testing.assert_allclose(opt.m[0], [0.36, 0.02], rtol=1e-12)
    np.testing.assert_allclose(opt.v[0], [0.0595, 0.0223], rtol=1e-12)
    assert opt.steps == [5]


def test_converges_to_the_minimum_of_a_convex_quadratic(Adam):
    # f(w) = 0.5 (w - c)^T A (w - c), A symmetric positive definite: the minimum is w = c
    rng = np.random.default_rng(0)
    Q = np.linalg.qr(rng.standard_normal((5, 5)))[0]
    A = Q @ np.diag([0.5, 1.0, 2.0, 5.0, 10.0]) @ Q.T
    c = np.array([1.0, -2.0, 0.5, 3.0, -1.0])
    p = one_set(np.zeros(5))
    opt = Adam([p], lr=0.05)
    for step in range(3000):
        if step in (1500, 2500):
            opt.lr *= 0.1      # Adam with a fixed lr circles the minimum at a radius ~lr
        p.zero_grad()
        p.grad += A @ (p.data - c)
        opt.step()
    np.testing.assert_allclose(p.data, c, atol=1e-3)


def test_frozen_sets_do_not_move_and_keep_no_state(Adam):
    a = one_set([1.0, 2.0])
    b = one_set([3.0, 4.0])
    b.trainable = False
    opt = Adam([a, b], lr=0.1)
    for _ in range(3):
        a.grad[...] = 1.0
        b.grad[...] = 1.0
        opt.step()
    np.testing.assert_array_equal(b.data, [3.0, 4.0])
    assert np.all(a.data < [1.0, 2.0])
    assert opt.steps == [3, 0] and not opt.m[1].any() and not opt.v[1].any()
    # unfreezing: b's first step is a first step (bias correction from t = 1)
    b.trainable = True
    opt.step()
    np.testing.assert_allclose(b.data, [3.0 - 0.1, 4.0 - 0.1], rtol=1e-7)


def test_float32_sets_stay_float32(Adam):
    p = one_set([1.0, 2.0], dtype=np.float32)
    p.grad[...] = [0.1, -0.2]
    opt = Adam([p])
    opt.step()
    assert p.data.dtype == np.float32 and opt.m[0].dtype == np.float32 and opt.v[0].dtype == np.float32


def test_updates_in_place_so_views_see_the_change(Adam):
    p = Parameters({"W": (2, 2), "b": (2,)}, dtype=np.float64)
    W_view, data = p.params["W"], p.data
    p.grad[...] = 1.0
    Adam([p], lr=0.5).step()
    assert p.data is data and np.shares_memory(W_view, p.data)
    np.testing.assert_allclose(W_view, -0.5, rtol=1e-7)


def test_state_dict_round_trip_continues_identically(Adam):
    rng = np.random.default_rng(3)
    p1, p2 = one_set(rng.standard_normal(4)), None
    opt1 = Adam([p1], lr=0.01)
    for _ in range(5):
        p1.grad[...] = rng.standard_normal(4)
        opt1.step()
    p2 = p1.astype(np.float64)
    opt2 = Adam([p2], lr=0.01)
    opt2.load_state_dict(opt1.state_dict())
    g = rng.standard_normal(4)
    p1.grad[...] = g
    p2.grad[...] = g
    opt1.step()
    opt2.step()
    np.testing.assert_array_equal(p1.data, p2.data)


def test_load_state_dict_names_what_is_wrong(Adam):
    opt = Adam([one_set([1.0, 2.0])])
    state = opt.state_dict()
    with pytest.raises(ValueError, match="m.0"):
        opt.load_state_dict({**state, "m.0": np.zeros(3)})
    with pytest.raises(KeyError, match="v.0"):
        opt.load_state_dict({k: v for k, v in state.items() if k != "v.0"})
    with pytest.raises(ValueError, match="steps"):
        opt.load_state_dict({**state, "steps": np.array([1, 2])})
