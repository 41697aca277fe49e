"""functional.py against independent computations written here (loops, closed forms, properties)."""

import numpy as np
import pytest

from minifilm.nn import fast_conv
from minifilm.nn import functional as F

#: conv1d's plain pair (conv.py, re-exported by functional.py) and the fast pair's two methods
CONV_FORMS = {
    "plain": (F.conv1d_forward, F.conv1d_backward),
    "fast im2col": (lambda x, W, b: fast_conv.conv1d_fast_forward(x, W, b, method="im2col"),
                    fast_conv.conv1d_fast_backward),
    "fast fft": (lambda x, W, b: fast_conv.conv1d_fast_forward(x, W, b, method="fft"),
                 fast_conv.conv1d_fast_backward),
}


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


# ------------------------------------------------------------------------------ linear / experts
def test_linear_matches_loop(rng):
    x, W, b = rng.standard_normal((3, 4)), rng.standard_normal((4, 2)), rng.standard_normal(2)
    y, _ = F.linear_forward(x, W, b)
    expect = np.array([[sum(x[n, i] * W[i, o] for i in range(4)) + b[o] for o in range(2)]
                       for n in range(3)])
    np.testing.assert_allclose(y, expect, rtol=1e-12)


def test_linear_rejects_mismatched_shapes(rng):
    with pytest.raises(ValueError, match="linear_forward"):
        F.linear_forward(rng.standard_normal((3, 4)), rng.standard_normal((5, 2)), np.zeros(2))


def test_expert_linear_with_one_expert_equals_linear(rng):
    x, W, b = rng.standard_normal((5, 4)), rng.standard_normal((1, 4, 3)), rng.standard_normal((1, 3))
    alpha = np.ones((5, 1))
    y, ce = F.expert_linear_forward(x, alpha, W, b)
    y_lin, cl = F.linear_forward(x, W[0], b[0])
    np.testing.assert_allclose(y, y_lin, rtol=1e-12)
    dout = rng.standard_normal(y.shape)
    dx, dalpha, dW, db = F.expert_linear_backward(dout, ce)
    dx_l, dW_l, db_l = F.linear_backward(dout, cl)
    np.testing.assert_allclose(dx, dx_l, rtol=1e-12)
    np.testing.assert_allclose(dW[0], dW_l, rtol=1e-12)
    np.testing.assert_allclose(db[0], db_l, rtol=1e-12)
    # with a single expert, dL/dalpha is the output's gradient dotted with y
    np.testing.assert_allclose(dalpha[:, 0], np.sum(dout * y_lin, axis=1), rtol=1e-12)


@pytest.mark.parametrize("batch", [1, 6])
def test_expert_linear_fast_form_equals_per_sample_weights(rng, batch):
    K, I, O = 4, 5, 3
    x, W, b = rng.standard_normal((batch, I)), rng.standard_normal((K, I, O)), rng.standard_normal((K, O))
    alpha = rng.random((batch, K))
    # the slow, obvious form: build each sample's blended weights
    W_per = np.einsum("bk,kio->bio", alpha, W)                   # (B, I, O)
    b_per = alpha @ b                                            # (B, O)
    expect = np.einsum("bi,bio->bo", x, W_per) + b_per
    y, cache = F.expert_linear_forward(x, alpha, W, b)
    np.testing.assert_allclose(y, expect, rtol=1e-12, atol=1e-12)
    # backward of the slow form, written out directly
    dout = rng.standard_normal((batch, O))
    dx, dalpha, dW, db = F.expert_linear_backward(dout, cache)
    np.testing.assert_allclose(dx, np.einsum("bo,bio->bi", dout, W_per), rtol=1e-11, atol=1e-12)
    dW_per = np.einsum("bi,bo->bio", x, dout)                    # dL/dW_b
    np.testing.assert_allclose(dW, np.einsum("bk,bio->kio", alpha, dW_per), rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(db, np.einsum("bk,bo->ko", alpha, dout), rtol=1e-11, atol=1e-12)
    expect_dalpha = np.einsum("bio,kio->bk", dW_per, W) + dout @ b.T
    np.testing.assert_allclose(dalpha, expect_dalpha, rtol=1e-11, atol=1e-12)
    # frozen experts (fitting a style's vector or adapter): the same dx and dalpha, no weight gradients
    dx_frozen, dalpha_frozen, dW_frozen, db_frozen = F.expert_linear_backward(dout, cache, weights=False)
    assert dW_frozen is None and db_frozen is None
    np.testing.assert_array_equal(dx_frozen, dx)          # one process, the same products: exact
    np.testing.assert_array_equal(dalpha_frozen, dalpha)


# ------------------------------------------------------------------------------ activations
def test_elu_and_relu_values():
    x = np.array([-2.0, -1e-9, 0.0, 0.5, 800.0])
    y, _ = F.elu_forward(x)
    # exp(-1e-9) - 1 = -1e-9 + 5e-19 - ... (Taylor): expm1 keeps that precision, exp(x) - 1 would not
    np.testing.assert_allclose(y, [np.exp(-2.0) - 1, -1e-9 + 5e-19, 0.0, 0.5, 800.0], rtol=1e-14)
    np.testing.assert_array_equal(F.relu_forward(x)[0], [0, 0, 0, 0.5, 800.0])


def test_softmax_rows_sum_to_one_and_match_closed_form(rng):
    x = rng.standard_normal((5, 7))
    y, _ = F.softmax_forward(x)
    np.testing.assert_allclose(y.sum(axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(y, np.exp(x) / np.exp(x).sum(axis=1, keepdims=True), rtol=1e-12)


def test_softmax_is_stable_near_1000():
    x = np.array([[1000.0, 1001.0, 999.0], [-1000.0, -1000.0, -1002.0]])
    with np.errstate(over="raise", invalid="raise"):
        y, _ = F.softmax_forward(x)
    e = np.exp(np.array([-1.0, 0.0, -2.0]))
    np.testing.assert_allclose(y[0], e / e.sum(), rtol=1e-12)
    e = np.exp(np.array([0.0, 0.0, -2.0]))
    np.testing.assert_allclose(y[1], e / e.sum(), rtol=1e-12)
    y32, _ = F.softmax_forward(x.astype(np.float32))
    assert np.all(np.isfinite(y32)) and np.allclose(y32.sum(axis=1), 1.0, atol=1e-6)


# ------------------------------------------------------------------------------ layer norm
@pytest.mark.parametrize("unbiased,eps,ddof", [(True, 1e-6, 1), (False, 0.0, 0)])
def test_layer_norm_matches_numpy_std(rng, unbiased, eps, ddof):
    x = rng.standard_normal((4, 9)) * 3 + 2
    y, _ = F.layer_norm_forward(x, unbiased=unbiased, eps=eps)
    expect = (x - x.mean(axis=1, keepdims=True)) / (np.std(x, axis=1, ddof=ddof, keepdims=True) + eps)
    np.testing.assert_allclose(y, expect, rtol=1e-12)
    # per row: mean 0; the (ddof) std is 1 up to eps
    np.testing.assert_allclose(y.mean(axis=1), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.std(y, axis=1, ddof=ddof), 1.0, rtol=1e-5)


def test_layer_norm_conventions_differ_by_the_std_ratio(rng):
    H = 8
    x = rng.standard_normal((3, H))
    y_train, _ = F.layer_norm_forward(x, unbiased=True, eps=0.0)
    y_run, _ = F.layer_norm_forward(x, unbiased=False, eps=0.0)
    np.testing.assert_allclose(y_run / y_train, np.sqrt(H / (H - 1)), rtol=1e-12)


@pytest.mark.parametrize("value", [0.0, 3.0])
def test_layer_norm_constant_row_gradient_is_the_stated_limit(value):
    """A constant row (σ = 0, training's ε = 1e-6): y = 0 and, as the docstring states,
    dx = g/s − mean(g/s) with s = ε exactly (the layer norm's row of `minifilm gradcheck` checks it
    numerically)."""
    g = np.array([[0.0, 1.0, 2.0, 3.0, 4.0], [1.5, -2.0, 0.25, 0.0, 7.0]])
    x = np.full(g.shape, value)
    y, cache = F.layer_norm_forward(x, unbiased=True, eps=1e-6)
    dx = F.layer_norm_backward(g, cache)
    assert np.all(y == 0)
    np.testing.assert_allclose(dx, (g - g.mean(axis=1, keepdims=True)) / 1e-6, rtol=1e-12)


def test_layer_norm_gradient_is_continuous_at_a_constant_row(rng):
    """The constant-row value is the limit of the general formula: rows x0 + t v (v not
    constant) approach it as t -> 0, linearly in t."""
    g = rng.standard_normal((1, 6))
    x0, v = np.zeros((1, 6)), rng.standard_normal((1, 6))
    at_zero = F.layer_norm_backward(g, F.layer_norm_forward(x0)[1])
    gaps = [np.abs(F.layer_norm_backward(g, F.layer_norm_forward(x0 + t * v)[1]) - at_zero).max() / np.abs(at_zero).max()
            for t in (1e-12, 1e-13, 1e-14)]
    assert gaps[0] < 1e-5 and gaps[1] < 1e-6 and gaps[2] < 1e-7
    assert gaps[0] / gaps[1] == pytest.approx(10, rel=0.05) and gaps[1] / gaps[2] == pytest.approx(10, rel=0.05)


# ------------------------------------------------------------------------------ FiLM / dropout
def test_film_per_sample_values(rng):
    h, g, b = (rng.standard_normal((3, 4)) for _ in range(3))
    y, cache = F.film_forward(h, g, b)
    np.testing.assert_allclose(y, g * h + b)
    dh, dg, db = F.film_backward(np.ones_like(y), cache)
    np.testing.assert_allclose(dh, g)
    np.testing.assert_allclose(dg, h)
    np.testing.assert_allclose(db, np.ones_like(b))


def test_dropout_fixed_mask_and_eval_identity(rng):
    x = rng.standard_normal((4, 5))
    mask = np.zeros((4, 5), dtype=bool)
    mask[::2] = True
    y, cache = F.dropout_forward(x, 0.25, mask=mask)
    np.testing.assert_allclose(y, np.where(mask, x / 0.75, 0.0), rtol=1e-15)
    np.testing.assert_allclose(F.dropout_backward(np.ones_like(x), cache), np.where(mask, 1 / 0.75, 0))
    y_eval, cache = F.dropout_forward(x, 0.25, train=False)
    assert y_eval is x and F.dropout_backward(x, cache) is x


def test_dropout_from_rng_keeps_about_1_minus_p_and_preserves_the_mean():
    x = np.ones((200, 500))
    y, _ = F.dropout_forward(x, 0.3, rng=np.random.default_rng(0))
    kept = np.mean(y != 0)
    assert abs(kept - 0.7) < 0.01                 # 100000 draws: std of the fraction ~0.0015
    assert abs(y.mean() - 1.0) < 0.02


def test_dropout_errors():
    x = np.ones((2, 3))
    with pytest.raises(ValueError, match="rng"):
        F.dropout_forward(x, 0.5)
    with pytest.raises(ValueError, match="mask"):
        F.dropout_forward(x, 0.5, mask=np.ones((3, 2), dtype=bool))
    with pytest.raises(ValueError, match="p must be"):
        F.dropout_forward(x, 1.0, rng=np.random.default_rng(0))


# ------------------------------------------------------------------------------ conv / pool
def conv1d_loop(x, W, b):
    """Direct definition: y[n, t, f] = b[f] + sum_j sum_c x[n, t + j - k//2, c] W[j, c, f]."""
    B, T, C = x.shape
    k, _, Fo = W.shape
    y = np.zeros((B, T, Fo))
    for n in range(B):
        for t in range(T):
            for f in range(Fo):
                acc = b[f]
                for j in range(k):
                    s = t + j - k // 2
                    if 0 <= s < T:
                        acc += sum(x[n, s, c] * W[j, c, f] for c in range(C))
                y[n, t, f] = acc
    return y


@pytest.mark.parametrize("form", list(CONV_FORMS))
@pytest.mark.parametrize("k", [1, 3, 5, 7])
@pytest.mark.parametrize("T", [4, 9, 10])   # includes T < k
def test_conv1d_matches_loop(rng, k, T, form):
    forward, backward = CONV_FORMS[form]
    x, W, b = rng.standard_normal((2, T, 3)), rng.standard_normal((k, 3, 4)), rng.standard_normal(4)
    y, cache = forward(x, W, b)
    np.testing.assert_allclose(y, conv1d_loop(x, W, b), rtol=1e-11, atol=1e-12)
    # dx by the loop definition: every output (n, t, f) sends dout * W[j, c, f] to x[n, t+j-k//2, c]
    dout = rng.standard_normal(y.shape)
    dx, dW, db = backward(dout, cache)
    dx_loop = np.zeros_like(x)
    dW_loop = np.zeros_like(W)
    for t in range(T):
        for j in range(k):
            s = t + j - k // 2
            if 0 <= s < T:
                dx_loop[:, s, :] += dout[:, t, :] @ W[j].T
                dW_loop[j] += x[:, s, :].T @ dout[:, t, :]
    np.testing.assert_allclose(dx, dx_loop, rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(dW, dW_loop, rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(db, dout.sum(axis=(0, 1)), rtol=1e-12)


@pytest.mark.parametrize("form", list(CONV_FORMS))
def test_conv1d_rejects_even_kernel(rng, form):
    with pytest.raises(ValueError, match="odd"):
        CONV_FORMS[form][0](rng.standard_normal((1, 5, 2)), rng.standard_normal((2, 2, 3)), np.zeros(3))


@pytest.mark.parametrize("T", [6, 7])
def test_max_pool1d_distinct_values(rng, T):
    x = rng.permutation(2 * T * 3).reshape(2, T, 3).astype(float)
    y, cache = F.max_pool1d_forward(x)
    assert y.shape == (2, T // 2, 3)
    for t in range(T // 2):
        np.testing.assert_array_equal(y[:, t], np.maximum(x[:, 2 * t], x[:, 2 * t + 1]))
    dx = F.max_pool1d_backward(np.ones_like(y), cache)
    # a 1 exactly where x was the larger of its pair; the dropped odd frame gets nothing
    for t in range(T // 2):
        win = x[:, 2 * t] > x[:, 2 * t + 1]
        np.testing.assert_array_equal(dx[:, 2 * t], win)
        np.testing.assert_array_equal(dx[:, 2 * t + 1], ~win)
    if T % 2:
        assert np.all(dx[:, -1] == 0)


# ------------------------------------------------------------------------------ dtypes
def _float32_cases(rng):
    f = lambda *s: rng.standard_normal(s).astype(np.float32)
    alpha = rng.random((3, 2)).astype(np.float32)
    return {
        "linear": (F.linear_forward, F.linear_backward, (f(3, 4), f(4, 2), f(2))),
        "elu": (F.elu_forward, F.elu_backward, (f(3, 4),)),
        "relu": (F.relu_forward, F.relu_backward, (f(3, 4),)),
        "softmax": (F.softmax_forward, F.softmax_backward, (f(3, 4),)),
        "layer_norm": (F.layer_norm_forward, F.layer_norm_backward, (f(3, 4),)),
        "layer_norm_runtime": (lambda x: F.layer_norm_forward(x, False, 0.0), F.layer_norm_backward, (f(3, 4),)),
        "film": (F.film_forward, F.film_backward, (f(3, 4), f(3, 4), f(3, 4))),
        "dropout": (lambda x: F.dropout_forward(x, 0.3, rng=rng), F.dropout_backward, (f(3, 4),)),
        "expert_linear": (F.expert_linear_forward, F.expert_linear_backward, (f(3, 4), alpha, f(2, 4, 5), f(2, 5))),
        "expert_linear_b1": (F.expert_linear_forward, F.expert_linear_backward, (f(1, 4), alpha[:1], f(2, 4, 5), f(2, 5))),
        "conv1d": (F.conv1d_forward, F.conv1d_backward, (f(2, 7, 3), f(3, 3, 4), f(4))),
        "conv1d_fast": (fast_conv.conv1d_fast_forward, fast_conv.conv1d_fast_backward, (f(2, 7, 3), f(3, 3, 4), f(4))),
        "conv1d_fft": (lambda x, W, b: fast_conv.conv1d_fast_forward(x, W, b, method="fft"),
                       fast_conv.conv1d_fast_backward, (f(2, 7, 3), f(3, 3, 4), f(4))),
        "max_pool1d": (F.max_pool1d_forward, F.max_pool1d_backward, (f(2, 7, 3),)),
    }


@pytest.mark.parametrize("name", list(_float32_cases(np.random.default_rng(0))))
def test_float32_in_float32_out(name):
    rng = np.random.default_rng(5)
    fwd, bwd, args = _float32_cases(rng)[name]
    out, cache = fwd(*args)
    assert out.dtype == np.float32, f"{name} forward gave {out.dtype}"
    grads = bwd(np.ones_like(out), cache)
    for g in grads if isinstance(grads, tuple) else (grads,):
        assert g.dtype == np.float32, f"{name} backward gave {g.dtype}"


# ------------------------------------------------------------------------------ bad arguments
def _pairs_with_gather(rng):
    cases = _float32_cases(rng)
    cases["gather"] = (lambda x: F.gather_forward(x, np.array([0, 2, 2, 1])), F.gather_backward,
                       (rng.standard_normal((3, 5)).astype(np.float32),))
    return cases


@pytest.mark.parametrize("name", list(_pairs_with_gather(np.random.default_rng(0))))
def test_a_dout_of_another_shape_than_the_output_is_a_named_error(name):
    """numpy would broadcast a (1, H) gradient over a (B, H) output (softmax, layer norm) or
    return a gradient of the wrong shape (FiLM's dh): every backward pass refuses it by name."""
    rng = np.random.default_rng(6)
    fwd, bwd, args = _pairs_with_gather(rng)[name]
    out, cache = fwd(*args)
    one_row = np.ones((1 if out.shape[0] != 1 else 2,) + out.shape[1:], out.dtype)
    for dout in (one_row, np.ones(out.shape + (1,), out.dtype), np.ones(out.shape[1:], out.dtype)):
        if name == "dropout" and cache is None:
            continue
        with pytest.raises(ValueError, match=r"_backward: dout is .*expected the output's shape"):
            bwd(dout, cache)
    bwd(np.ones_like(out), cache)                    # the right shape still works


def test_the_broadcasts_of_the_issue_are_refused():
    rng = np.random.default_rng(7)
    x = rng.standard_normal((4, 6))
    for fwd, bwd in ((F.softmax_forward, F.softmax_backward), (F.layer_norm_forward, F.layer_norm_backward)):
        _, cache = fwd(x)
        with pytest.raises(ValueError, match=r"dout is \(1, 6\), expected the output's shape \(4, 6\)"):
            bwd(np.ones((1, 6)), cache)
    _, cache = F.film_forward(x, np.ones(6), np.zeros(6))
    with pytest.raises(ValueError, match=r"film_backward: dout is \(1, 6\)"):
        F.film_backward(np.ones((1, 6)), cache)


def test_a_batch_of_zero_is_a_named_error():
    with pytest.raises(ValueError, match=r"gather_forward: index is empty \(a batch of 0 samples\)"):
        F.gather_forward(np.ones((3, 2)), np.array([], dtype=np.int64))
    with pytest.raises(ValueError, match=r"gather_forward: index must lie in \[0, 3\), got -1..2"):
        F.gather_forward(np.ones((3, 2)), np.array([2, -1]))
    forwards = [F.conv1d_forward] + [lambda x, W, b, m=m: fast_conv.conv1d_fast_forward(x, W, b, method=m)
                                     for m in ("auto", "im2col", "fft")]
    for forward in forwards:
        with pytest.raises(ValueError, match=r"conv1d_forward: x is \(0, 5, 3\): a batch of 0 clips"):
            forward(np.ones((0, 5, 3)), np.ones((3, 3, 2)), np.zeros(2))
        with pytest.raises(ValueError, match=r"conv1d_forward: x is \(2, 0, 3\).*clips of 0 frames"):
            forward(np.ones((2, 0, 3)), np.ones((3, 3, 2)), np.zeros(2))


@pytest.mark.parametrize("dtype", [np.int64, np.int32, np.uint8, bool])
def test_dropout_refuses_integer_arrays(dtype):
    """An integer x was scaled by int(1 / (1 - p)) = 1 for p < 0.5, silently."""
    x = np.ones((4, 5), dtype=dtype)
    with pytest.raises(TypeError, match=r"dropout_forward: x must be a floating-point array, got"):
        F.dropout_forward(x, 0.3, rng=np.random.default_rng(0))
