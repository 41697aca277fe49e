"""Speed work must not change results: the optimised layers and the whole style model against plain
reference formulations written here, in float64, on random inputs, to 1e-10.

The references are deliberately the slow, obvious forms: a loop over the kernel taps with
scatter-adds for the convolution (not im2col, not the FFT), per-sample blended weights for the experts (not the
(B, K*I) product), explicit per-row Jacobians for layer norm and softmax, pair-by-pair max pooling.
"""
import numpy as np
import pytest

from minifilm.nn.fast_optim import ChunkedAdam
from minifilm.nn.optim import Adam
from minifilm.nn.params import Parameters
from minifilm.nn import fast_conv
from minifilm.nn.fast_linear import linear_fast_backward
from minifilm.nn import functional as F

TOL = 1e-10


def assert_close(actual, expected, tol=TOL):
    """max |actual - expected| <= tol * max(1, max |expected|) (a norm-wise relative bound)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape, (actual.shape, expected.shape)
    scale = max(1.0, float(np.max(np.abs(expected))) if expected.size else 1.0)
    err = float(np.max(np.abs(actual - expected))) if expected.size else 0.0
    assert err <= tol * scale, f"max abs difference {err:.3e} > {tol:g} * {scale:.3g}"


@pytest.fixture
def rng():
    return np.random.default_rng(20220509)


# ============================================================================ references (float64)
def conv_ref(x, W, b):
    """'same' cross-correlation by a loop over taps: y[t] += x[t + j - k//2] W[j]."""
    k = W.shape[0]
    B, T, C = x.shape
    pad = k // 2
    xp = np.zeros((B, T + 2 * pad, C))
    xp[:, pad: pad + T] = x
    y = np.zeros((B, T, W.shape[2])) + b
    for j in range(k):
        y += np.einsum("btc,cf->btf", xp[:, j: j + T], W[j])
    return y


def conv_ref_backward(dout, x, W):
    """Scatter form: every product of the forward pass sends its gradient back where it came from."""
    k = W.shape[0]
    B, T, C = x.shape
    pad = k // 2
    xp = np.zeros((B, T + 2 * pad, C))
    xp[:, pad: pad + T] = x
    dxp = np.zeros_like(xp)
    dW = np.zeros_like(W)
    for j in range(k):
        dW[j] = np.einsum("btc,btf->cf", xp[:, j: j + T], dout)
        dxp[:, j: j + T] += np.einsum("btf,cf->btc", dout, W[j])
    return dxp[:, pad: pad + T], dW, dout.sum(axis=(0, 1))


def pool_ref(x):
    B, T, C = x.shape
    out = np.empty((B, T // 2, C))
    for t in range(T // 2):
        out[:, t] = np.maximum(x[:, 2 * t], x[:, 2 * t + 1])
    return out


def pool_ref_backward(dout, x):
    dx = np.zeros_like(x)
    for t in range(dout.shape[1]):
        first = x[:, 2 * t] >= x[:, 2 * t + 1]          # ties go to the first frame
        dx[:, 2 * t] = np.where(first, dout[:, t], 0.0)
        dx[:, 2 * t + 1] = np.where(first, 0.0, dout[:, t])
    return dx


def experts_ref(x, alpha, W, b):
    W_b = np.einsum("bk,kio->bio", alpha, W)              # each sample's blended weights
    return np.einsum("bi,bio->bo", x, W_b) + alpha @ b


def experts_ref_backward(dout, x, alpha, W, b):
    W_b = np.einsum("bk,kio->bio", alpha, W)
    dx = np.einsum("bo,bio->bi", dout, W_b)
    dW = np.einsum("bk,bi,bo->kio", alpha, x, dout)
    db = alpha.T @ dout
    dalpha = np.einsum("bi,kio,bo->bk", x, W, dout) + dout @ b.T
    return dx, dalpha, dW, db


def ln_ref(x, unbiased=True, eps=1e-6):
    n = x.shape[-1] - 1 if unbiased else x.shape[-1]
    xc = x - x.mean(axis=-1, keepdims=True)
    return xc / (np.sqrt((xc ** 2).sum(axis=-1, keepdims=True) / n) + eps)


def ln_ref_backward(dout, x, unbiased=True, eps=1e-6):
    """dx = J^T dout with each row's Jacobian written out:
    J_ij = (delta_ij - 1/H) / s - xc_i xc_j / (n sigma s^2)."""
    H = x.shape[-1]
    n = H - 1 if unbiased else H
    dx = np.empty_like(x)
    for r in range(x.shape[0]):
        xc = x[r] - x[r].mean()
        sigma = np.sqrt((xc ** 2).sum() / n)
        s = sigma + eps
        J = (np.eye(H) - 1.0 / H) / s - np.outer(xc, xc) / (n * sigma * s * s)
        dx[r] = J.T @ dout[r]
    return dx


def softmax_ref_backward(dout, y):
    return np.stack([(np.diag(yr) - np.outer(yr, yr)).T @ dr for yr, dr in zip(y, dout)])


def elu(x):
    return np.where(x > 0, x, np.exp(np.minimum(x, 0)) - 1)


def elu_slope(x):
    return np.where(x > 0, 1.0, np.exp(np.minimum(x, 0)))


# ============================================================================ layers
CONV_CASES = [(3, 11, 4, 5, 5), (2, 3, 3, 2, 5), (1, 8, 6, 3, 1), (4, 16, 7, 9, 3),
              (2, 1, 3, 2, 7),      # a single frame, kernel longer than the clip
              (2, 30, 5, 4, 25),    # the paper's kernel width; fft length 45 (odd)
              (3, 20, 6, 5, 9)]     # fft length 24 (even: a Nyquist frequency)


@pytest.mark.parametrize("method", ["im2col", "fft"])
@pytest.mark.parametrize("B,T,C,Fo,k", CONV_CASES)
def test_conv1d_equals_tap_loop(rng, method, B, T, C, Fo, k):
    x, W, b = rng.standard_normal((B, T, C)), rng.standard_normal((k, C, Fo)), rng.standard_normal(Fo)
    y, cache = fast_conv.conv1d_fast_forward(x, W, b, method=method)
    assert cache[0] == method
    assert_close(y, conv_ref(x, W, b))
    dout = rng.standard_normal(y.shape)
    dx, dW, db = fast_conv.conv1d_fast_backward(dout, cache)
    rx, rW, rb = conv_ref_backward(dout, x, W)
    assert_close(dx, rx)
    assert_close(dW, rW)
    assert_close(db, rb)
    # skipping dx changes nothing else
    none, dW2, db2 = fast_conv.conv1d_fast_backward(dout, cache, need_dx=False)
    assert none is None
    assert_close(dW2, rW)
    assert_close(db2, rb)


def test_conv1d_method_choice():
    """'auto' takes fft where it is much cheaper (the paper's Ψ and train_small's at batch 32)
    and im2col for single clips and tiny layers; an unknown method is an error."""
    choose = fast_conv._conv1d_method
    assert choose(32, 240, 300, 256, 25) == "fft" and choose(32, 120, 256, 256, 25) == "fft"
    assert choose(32, 120, 300, 32, 9) == "fft"
    assert choose(1, 120, 300, 32, 9) == "im2col" and choose(1, 240, 300, 256, 25) == "im2col"
    assert choose(32, 16, 12, 8, 5) == "im2col"
    with pytest.raises(ValueError, match="method"):
        fast_conv.conv1d_fast_forward(np.zeros((1, 4, 2)), np.zeros((3, 2, 2)), np.zeros(2), method="winograd")


@pytest.mark.parametrize("method", ["im2col", "fft"])
def test_workspaces_reuse_buffers_without_changing_results(rng, method):
    """A layer's workspace (reused im2col / spectrum and gradient buffers): successive calls with
    new data, and a change of batch size or clip length, give exactly what calls without a
    workspace give."""
    k, C, Fo = 5, 3, 4
    W, b = rng.standard_normal((k, C, Fo)), rng.standard_normal(Fo)
    work = {}
    for B, T in [(2, 9), (2, 9), (3, 9), (2, 12), (2, 9)]:
        x = rng.standard_normal((B, T, C))
        y, cache = fast_conv.conv1d_fast_forward(x, W, b, work=work, method=method)
        dout = rng.standard_normal(y.shape)
        got = fast_conv.conv1d_fast_backward(dout, cache)
        assert_close(y, conv_ref(x, W, b))
        for g, r in zip(got, conv_ref_backward(dout, x, W)):
            assert_close(g, r)
    name = "cols" if method == "im2col" else "fft.H3"
    buf = work[name]
    fast_conv.conv1d_fast_forward(rng.standard_normal((2, 9, C)), W, b, work=work, method=method)
    assert work[name] is buf                              # same shape: the buffer was reused
    Wl, bl = rng.standard_normal((6, 4)), rng.standard_normal(4)
    lwork = {}
    for _ in range(2):
        x = rng.standard_normal((5, 6))
        _, cache = F.linear_forward(x, Wl, bl)
        dout = rng.standard_normal((5, 4))
        assert_close(linear_fast_backward(dout, cache, lwork)[1], x.T @ dout)


@pytest.mark.parametrize("method", ["im2col", "fft"])
def test_conv1d_float32_agrees_with_float64_reference(rng, method):
    x, W, b = rng.standard_normal((2, 20, 6)), rng.standard_normal((5, 6, 4)), rng.standard_normal(4)
    y, _ = fast_conv.conv1d_fast_forward(x.astype(np.float32), W.astype(np.float32), b.astype(np.float32),
                            method=method)
    assert y.dtype == np.float32
    assert_close(y, conv_ref(x, W, b), tol=1e-5)


def test_conv1d_fft_float32_rounding_is_that_of_im2col(rng):
    """At train_small's sizes (clip 120 x 300, 32 filters of width 9; 4 clips) in float32, the
    FFT path's error against the float64 reference is float32 rounding, of the same size as the
    im2col product's: both about 1e-7 to 1e-6 of the largest value."""
    B, T, C, Fo, k = 4, 120, 300, 32, 9
    x = rng.standard_normal((B, T, C))
    W = rng.standard_normal((k, C, Fo)) / np.sqrt(k * C)
    b = rng.standard_normal(Fo)
    dout = rng.standard_normal((B, T, Fo))
    ref = (conv_ref(x, W, b),) + conv_ref_backward(dout, x, W)
    f32 = lambda a: a.astype(np.float32)   # noqa: E731
    errors = {}
    for method in ("im2col", "fft"):
        y, cache = fast_conv.conv1d_fast_forward(f32(x), f32(W), f32(b), method=method)
        got = (y,) + fast_conv.conv1d_fast_backward(f32(dout), cache)
        assert all(g.dtype == np.float32 for g in got)
        errors[method] = [float(np.max(np.abs(g - r)) / np.max(np.abs(r))) for g, r in zip(got, ref)]
    for e_fft, e_im2col in zip(errors["fft"], errors["im2col"]):
        assert e_fft < 2e-6 and e_fft < 5 * max(e_im2col, 1e-7), errors


@pytest.mark.parametrize("T", [8, 9])
def test_max_pool_equals_pairwise_maximum(rng, T):
    x = rng.standard_normal((3, T, 4))
    x[0, 2, :] = x[0, 3, :]                               # exact ties: gradient to the first frame
    y, cache = F.max_pool1d_forward(x)
    assert_close(y, pool_ref(x))
    dout = rng.standard_normal(y.shape)
    assert_close(F.max_pool1d_backward(dout, cache), pool_ref_backward(dout, x))


@pytest.mark.parametrize("B", [1, 2, 7])
def test_expert_linear_equals_per_sample_weights(rng, B):
    K, I, O = 4, 6, 5
    x, W, b = rng.standard_normal((B, I)), rng.standard_normal((K, I, O)), rng.standard_normal((K, O))
    alpha = rng.dirichlet(np.ones(K), size=B)
    y, cache = F.expert_linear_forward(x, alpha, W, b)
    assert_close(y, experts_ref(x, alpha, W, b))
    dout = rng.standard_normal(y.shape)
    for got, ref in zip(F.expert_linear_backward(dout, cache), experts_ref_backward(dout, x, alpha, W, b)):
        assert_close(got, ref)


@pytest.mark.parametrize("B", [1, 5])
def test_expert_linear_equals_the_plain_weight_blending_pair(rng, B):
    """The fast gated-expert pair (one (B, K*I) product) against the plain one of functional.py
    (blend the experts' weights per sample, then multiply): outputs and all four gradients."""
    x, W, b = rng.standard_normal((B, 6)), rng.standard_normal((3, 6, 4)), rng.standard_normal((3, 4))
    alpha = rng.dirichlet(np.ones(3), size=B)
    dout = rng.standard_normal((B, 4))
    fast, cache_fast = F.expert_linear_forward(x, alpha, W, b)
    plain, cache_plain = F.expert_blend_forward(x, alpha, W, b)
    assert_close(fast, plain)
    for g_fast, g_plain in zip(F.expert_linear_backward(dout, cache_fast), F.expert_blend_backward(dout, cache_plain)):
        assert_close(g_fast, g_plain)


@pytest.mark.parametrize("unbiased,eps", [(True, 1e-6), (False, 0.0)])
def test_layer_norm_equals_explicit_jacobian(rng, unbiased, eps):
    x = 3 * rng.standard_normal((5, 9)) + 1
    y, cache = F.layer_norm_forward(x, unbiased=unbiased, eps=eps)
    assert_close(y, ln_ref(x, unbiased, eps))
    dout = rng.standard_normal(x.shape)
    assert_close(F.layer_norm_backward(dout, cache), ln_ref_backward(dout, x, unbiased, eps))


class TextbookAdam:
    """Algorithm 1 of Kingma and Ba (2014), one array per parameter set, nothing in place:
    m = b1 m + (1 - b1) g, v = b2 v + (1 - b2) g^2, m_hat = m / (1 - b1^t), v_hat = v / (1 - b2^t),
    w = w - lr m_hat / (sqrt(v_hat) + eps); t counts the steps each set actually took."""

    def __init__(self, weights, lr, b1, b2, eps):
        self.w = [np.array(w, dtype=np.float64) for w in weights]
        self.m = [np.zeros_like(w) for w in self.w]
        self.v = [np.zeros_like(w) for w in self.w]
        self.t = [0] * len(self.w)
        self.lr, self.b1, self.b2, self.eps = lr, b1, b2, eps

    def step(self, grads, trainable):
        for i, (g, on) in enumerate(zip(grads, trainable)):
            if not on:
                continue
            self.t[i] += 1
            t = self.t[i]
            self.m[i] = self.b1 * self.m[i] + (1 - self.b1) * g
            self.v[i] = self.b2 * self.v[i] + (1 - self.b2) * g * g
            m_hat = self.m[i] / (1 - self.b1 ** t)
            v_hat = self.v[i] / (1 - self.b2 ** t)
            self.w[i] = self.w[i] - self.lr * m_hat / (np.sqrt(v_hat) + self.eps)


@pytest.mark.parametrize("optimiser", [Adam, ChunkedAdam])
@pytest.mark.parametrize("dtype,tol", [(np.float64, TOL), (np.float32, 2e-6)])
def test_adam_equals_the_textbook_update(rng, dtype, tol, optimiser):
    """The package's plain Adam (nn/optim.py) and the chunked in-place one (nn/fast_optim.py)
    over three sets (one of several chunks with a partial last one, one smaller than a chunk,
    one frozen for the first steps and then unfrozen, so the sets' step counts differ) against
    the textbook rule written here, over steps of changing gradients; half-way the optimiser is
    rebuilt from its state_dict. In float32 they agree to float32 rounding."""
    from minifilm.nn import fast_optim
    Adam = optimiser                                      # noqa: N806
    sizes = [2 * fast_optim.CHUNK + 123, 37, 1000]
    sets = [Parameters({"a": (n - 7,), "b": (7,)}, dtype=dtype) for n in sizes]
    for p in sets:
        p.data[...] = rng.standard_normal(p.size)
    lr, b1, b2, eps = 1e-2, 0.9, 0.999, 1e-8
    ref = TextbookAdam([p.data for p in sets], lr, b1, b2, eps)
    opt = Adam(sets, lr=lr, beta1=b1, beta2=b2, eps=eps)
    for step in range(6):
        sets[2].trainable = step >= 2
        grads = [rng.standard_normal(p.size) * 10.0 ** rng.integers(-4, 2) for p in sets]
        for p, g in zip(sets, grads):
            p.grad[...] = g
        opt.step()
        ref.step([p.grad.astype(np.float64) for p in sets], [p.trainable for p in sets])
        if step == 2:                                     # a checkpoint round trip
            state = {k: v.copy() for k, v in opt.state_dict().items()}
            opt = Adam(sets, lr=lr, beta1=b1, beta2=b2, eps=eps)
            opt.load_state_dict(state)
        assert opt.steps == ref.t
        for i, p in enumerate(sets):
            assert p.data.dtype == dtype and opt.m[i].dtype == dtype
            # the update is at most lr per step, so compare to the weights' scale
            assert_close(p.data, ref.w[i], tol=tol)
            assert_close(opt.m[i], ref.m[i], tol=tol)
            assert_close(opt.v[i], ref.v[i], tol=tol)


# ============================================================================ whole model
def model_ref_forward(model, x, p, clip):
    """Eq. (2)-(4) written plainly from the parameter arrays (eval mode: no dropout)."""
    c = model.config
    G, M, P = model.gating.params.params, model.motion.params.params, model.film.params.params
    acts = {}
    # Ω
    h0 = p @ G["W0"] + G["b0"]
    h1 = elu(h0) @ G["W1"] + G["b1"]
    logits = elu(h1) @ G["W2"] + G["b2"]
    e = np.exp(logits - logits.max(axis=1, keepdims=True))
    alpha = e / e.sum(axis=1, keepdims=True)
    acts["gating"] = (h0, h1, alpha)
    # Ψ
    u0 = conv_ref(clip, P["conv0_W"], P["conv0_b"])
    q0 = pool_ref(np.maximum(u0, 0))
    u1 = conv_ref(q0, P["conv1_W"], P["conv1_b"])
    q1 = pool_ref(np.maximum(u1, 0))
    flat = q1.reshape(q1.shape[0], -1)
    d0 = flat @ P["dense0_W"] + P["dense0_b"]
    film = np.maximum(d0, 0) @ P["dense1_W"] + P["dense1_b"]
    acts["film"] = (u0, q0, u1, q1, flat, d0)
    # Φ
    H = c.hidden
    h, layers = x, []
    for l in range(3):
        f = experts_ref(h, alpha, M[f"W{l}"], M[f"b{l}"])
        if l < 2:
            gamma, beta = film[:, 2 * l * H:(2 * l + 1) * H], film[:, (2 * l + 1) * H:(2 * l + 2) * H]
            n = ln_ref(f, c.ln_unbiased, c.ln_eps)
            layers.append((h, f, n, gamma * n + beta))
            h = elu(gamma * n + beta)
        else:
            layers.append((h,))
            h = f
    acts["motion"] = layers
    return h, film, alpha, acts


def model_ref_backward(model, dz, x, p, clip):
    """The reverse of model_ref_forward, layer by layer, with the reference backward passes."""
    c = model.config
    G, M, P = model.gating.params.params, model.motion.params.params, model.film.params.params
    _, film, alpha, acts = model_ref_forward(model, x, p, clip)
    H = c.hidden
    grads = {}
    # Φ
    dfilm = np.zeros_like(film)
    dalpha = np.zeros_like(alpha)
    dh = dz
    for l in reversed(range(3)):
        h_in = acts["motion"][l][0]
        if l < 2:
            _, f, n, pre = acts["motion"][l]
            dpre = dh * elu_slope(pre)
            gamma = film[:, 2 * l * H:(2 * l + 1) * H]
            dfilm[:, 2 * l * H:(2 * l + 1) * H] = dpre * n
            dfilm[:, (2 * l + 1) * H:(2 * l + 2) * H] = dpre
            dh = ln_ref_backward(dpre * gamma, f, c.ln_unbiased, c.ln_eps)
        dh, da, dW, db = experts_ref_backward(dh, h_in, alpha, M[f"W{l}"], M[f"b{l}"])
        grads[f"motion.W{l}"], grads[f"motion.b{l}"] = dW, db
        dalpha += da
    grads["x"] = dh
    # Ω
    h0, h1, _ = acts["gating"]
    dlog = softmax_ref_backward(dalpha, alpha)
    grads["gating.W2"], grads["gating.b2"] = elu(h1).T @ dlog, dlog.sum(0)
    dh1 = (dlog @ G["W2"].T) * elu_slope(h1)
    grads["gating.W1"], grads["gating.b1"] = elu(h0).T @ dh1, dh1.sum(0)
    dh0 = (dh1 @ G["W1"].T) * elu_slope(h0)
    grads["gating.W0"], grads["gating.b0"] = p.T @ dh0, dh0.sum(0)
    grads["p"] = dh0 @ G["W0"].T
    # Ψ
    u0, q0, u1, q1, flat, d0 = acts["film"]
    grads["film.dense1_W"], grads["film.dense1_b"] = np.maximum(d0, 0).T @ dfilm, dfilm.sum(0)
    dd0 = (dfilm @ P["dense1_W"].T) * (d0 > 0)
    grads["film.dense0_W"], grads["film.dense0_b"] = flat.T @ dd0, dd0.sum(0)
    dq1 = (dd0 @ P["dense0_W"].T).reshape(q1.shape)
    du1 = pool_ref_backward(dq1, np.maximum(u1, 0)) * (u1 > 0)
    dq0, grads["film.conv1_W"], grads["film.conv1_b"] = conv_ref_backward(du1, q0, P["conv1_W"])
    du0 = pool_ref_backward(dq0, np.maximum(u0, 0)) * (u0 > 0)
    grads["clip"], grads["film.conv0_W"], grads["film.conv0_b"] = conv_ref_backward(du0, clip, P["conv0_W"])
    return grads


def small_model(rng):
    from minifilm.model.config import ModelConfig
    from minifilm.model.style_model import StyleModel
    cfg = ModelConfig(x_dim=7, z_dim=6, phase_dim=8, n_experts=3, hidden=5, gating_hidden=4,
                      clip_frames=13, clip_channels=3, conv_filters=4, conv_kernel=5, film_dense=6)
    model = StyleModel(cfg, rng, dtype=np.float64)
    for ps in model.parameter_sets():                    # non-zero biases so every term counts
        ps.data += 0.1 * rng.standard_normal(ps.size)
    B = 4
    x = rng.standard_normal((B, cfg.x_dim))
    p = rng.standard_normal((B, cfg.phase_dim))
    clip = rng.standard_normal((B, cfg.clip_frames, cfg.clip_channels))
    return model, x, p, clip


@pytest.fixture(params=["auto", "fft"])
def conv_method(request, monkeypatch):
    """Run a test with Ψ's convolutions as chosen ('auto': im2col at these tiny sizes) or forced
    onto the FFT path."""
    if request.param == "fft":
        monkeypatch.setattr(fast_conv, "_conv1d_method", lambda *sizes: "fft")
    return request.param


def test_style_model_forward_equals_reference(rng, conv_method):
    model, x, p, clip = small_model(rng)
    z = model.forward(x, p, clip)
    z_ref, film_ref, alpha_ref, _ = model_ref_forward(model, x, p, clip)
    assert_close(z, z_ref)
    assert_close(model.film_parameters(clip), film_ref)
    assert_close(model.gating.forward(p), alpha_ref)


def test_style_model_backward_equals_reference(rng, conv_method):
    model, x, p, clip = small_model(rng)
    z = model.forward(x, p, clip)
    dz = rng.standard_normal(z.shape)
    model.zero_grad()
    got = model.backward(dz)
    ref = model_ref_backward(model, dz, x, p, clip)
    for name in ("x", "p", "clip"):
        assert_close(got[name], ref[name])
    nets = {"gating": model.gating, "motion": model.motion, "film": model.film}
    checked = 0
    for key, value in ref.items():
        if "." in key:
            net, pname = key.split(".")
            assert_close(nets[net].params.grads[pname], value)
            checked += 1
    assert checked == sum(len(n.params.names()) for n in nets.values())   # every parameter


def test_skipping_the_clip_gradient_changes_no_parameter_gradient(rng, conv_method):
    """Training calls backward(dz, need_input_grads=False): same parameter gradients, dclip None."""
    model, x, p, clip = small_model(rng)
    dz = rng.standard_normal(model.forward(x, p, clip).shape)
    model.zero_grad()
    full = model.backward(dz)
    grads_full = [ps.grad.copy() for ps in model.parameter_sets()]
    model.forward(x, p, clip)
    model.zero_grad()
    lean = model.backward(dz, need_input_grads=False)
    assert lean["clip"] is None and full["clip"] is not None
    assert_close(lean["x"], full["x"])
    assert_close(lean["p"], full["p"])
    for ps, g in zip(model.parameter_sets(), grads_full):
        np.testing.assert_array_equal(ps.grad, g)
