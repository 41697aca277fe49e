"""The fast convolution (minifilm/nn/fast_conv.py, what training runs) equals the plain one
(minifilm/nn/conv.py, what a reader meets first), forward and backward, in float64 and float32,
for both of its methods; and Ψ's blocks run the fast one. Same for the linear layer's weight
gradient in a workspace (minifilm/nn/fast_linear.py)."""
import numpy as np
import pytest

from minifilm.model import blocks
from minifilm.nn import conv, fast_conv
from minifilm.nn import functional as F
from minifilm.nn.fast_linear import linear_fast_backward

# (B, T, C, F, k): odd kernels 1-25, clips shorter than the kernel, a single frame, FFT lengths
# odd (T + k//2 = 45 -> 45) and even (29 -> 30, with a Nyquist frequency), one clip and many
SHAPES = [(3, 11, 4, 5, 5), (1, 8, 6, 3, 1), (2, 1, 3, 2, 7), (2, 3, 3, 2, 5), (4, 16, 7, 9, 3),
          (2, 33, 5, 4, 25), (3, 20, 6, 5, 9), (1, 40, 2, 3, 11)]
METHODS = ["im2col", "fft", "auto"]


def rel(a, b):
    """max |a - b| / max(1, max |b|)."""
    return float(np.max(np.abs(np.asarray(a, np.float64) - b)) / max(1.0, float(np.max(np.abs(b)))))


def draw(rng, B, T, C, Fo, k, dtype):
    x, W, b = rng.standard_normal((B, T, C)), rng.standard_normal((k, C, Fo)), rng.standard_normal(Fo)
    dout = rng.standard_normal((B, T, Fo))
    return [a.astype(dtype) for a in (x, W, b, dout)]


@pytest.mark.parametrize("dtype, tol", [(np.float64, 1e-12), (np.float32, 2e-6)])
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("B,T,C,Fo,k", SHAPES)
def test_fast_conv1d_equals_the_plain_one(B, T, C, Fo, k, method, dtype, tol):
    """Outputs and all three gradients, with and without dx. The float32 bound is float32
    rounding (about 1e-7 here); the float64 bound leaves room for the FFT's rounding only."""
    rng = np.random.default_rng(B * 1000 + T * 10 + k)
    x, W, b, dout = draw(rng, B, T, C, Fo, k, dtype)
    y_plain, c_plain = conv.conv1d_forward(x, W, b)
    y_fast, c_fast = fast_conv.conv1d_fast_forward(x, W, b, method=method)
    assert y_plain.dtype == y_fast.dtype == dtype
    assert rel(y_fast, y_plain) < tol
    plain = conv.conv1d_backward(dout, c_plain)
    fast = fast_conv.conv1d_fast_backward(dout, c_fast)
    for name, g_fast, g_plain in zip(("dx", "dW", "db"), fast, plain):
        assert g_fast.dtype == g_plain.dtype == dtype, name
        assert g_fast.shape == g_plain.shape, name
        assert rel(g_fast, g_plain) < tol, name
    no_dx = fast_conv.conv1d_fast_backward(dout, c_fast, need_dx=False)
    assert no_dx[0] is None and conv.conv1d_backward(dout, c_plain, need_dx=False)[0] is None
    assert rel(no_dx[1], plain[1]) < tol and rel(no_dx[2], plain[2]) < tol


def test_fast_im2col_is_the_plain_im2col_bit_for_bit():
    """The strided-view copy puts exactly the same numbers where np.pad + stacking the taps does."""
    rng = np.random.default_rng(3)
    for B, T, C, k in [(2, 7, 3, 5), (1, 3, 4, 9), (3, 12, 1, 1)]:
        x = rng.standard_normal((B, T, C))
        assert np.array_equal(fast_conv._im2col(x, k, {}), conv.im2col(x, k))


def test_the_plain_im2col_holds_the_windows():
    """Row (b, t) is x[b, t-p .. t+p] flattened tap-major, with zeros off the clip (by hand)."""
    x = np.arange(1.0, 7.0).reshape(1, 3, 2)         # frames [1, 2], [3, 4], [5, 6]
    cols = conv.im2col(x, 3)
    np.testing.assert_array_equal(cols, [[0, 0, 1, 2, 3, 4], [1, 2, 3, 4, 5, 6], [3, 4, 5, 6, 0, 0]])


def test_workspaces_change_no_result():
    """Repeated calls through one workspace (reused buffers), with changing batch and clip length,
    give what the plain pair gives."""
    rng = np.random.default_rng(5)
    W, b = rng.standard_normal((5, 3, 4)), rng.standard_normal(4)
    for method in ("im2col", "fft"):
        work = {}
        for B, T in [(2, 9), (2, 9), (3, 9), (2, 12), (2, 9)]:
            x, dout = rng.standard_normal((B, T, 3)), rng.standard_normal((B, T, 4))
            y, cache = fast_conv.conv1d_fast_forward(x, W, b, work=work, method=method)
            got = (y,) + fast_conv.conv1d_fast_backward(dout, cache)
            y0, c0 = conv.conv1d_forward(x, W, b)
            for g, r in zip(got, (y0,) + conv.conv1d_backward(dout, c0)):
                assert rel(g, r) < 1e-12


def test_psi_conv_blocks_run_the_fast_convolution(monkeypatch):
    """conv_block_forward (Ψ's layers, the main job) goes through fast_conv, with its method
    choice and the layer's workspace, and gives the plain pair's numbers."""
    rng = np.random.default_rng(7)
    x, W, b = rng.standard_normal((2, 10, 3)), rng.standard_normal((3, 3, 4)), rng.standard_normal(4)
    calls = []
    real = fast_conv.conv1d_fast_forward
    monkeypatch.setattr(blocks, "conv1d_fast_forward",
                        lambda *a, **kw: calls.append(kw.get("work")) or real(*a, **kw))
    work = {}
    h, cache = blocks.conv_block_forward(x, W, b, work)
    assert calls == [work] and "cols" in work and cache.conv[0] == "im2col"
    y, _ = conv.conv1d_forward(x, W, b)
    pooled, _ = F.max_pool1d_forward(np.maximum(y, 0))
    assert rel(h, pooled) < 1e-12


def test_linear_fast_backward_equals_the_plain_one():
    rng = np.random.default_rng(9)
    work = {}
    for dtype in (np.float64, np.float32):
        x, W, b = (rng.standard_normal(s).astype(dtype) for s in ((5, 6), (6, 4), (4,)))
        _, cache = F.linear_forward(x, W, b)
        dout = rng.standard_normal((5, 4)).astype(dtype)
        for g_fast, g_plain in zip(linear_fast_backward(dout, cache, work), F.linear_backward(dout, cache)):
            assert g_fast.dtype == dtype and np.array_equal(g_fast, g_plain)
        assert work["dW"].dtype == dtype
