"""minifilm in one file: Mason, Starke & Komura 2022, *Real-Time Style Modelling of Human Locomotion
via Feature-Wise Transformations and Local Motion Phases*, in NumPy + SciPy. Read it top to bottom:

 1. layers    forward/backward pairs: linear, ELU, ReLU, softmax, dropout, layer norm, FiLM, the gated
              expert layer (Sec. 4.1), conv1d by im2col, max-pool
 2. networks  Ω (gating), Ψ (FiLM generator, Eq. 2), Φ (Eq. 3) and ẑ = Φ(x; Ω(p), Ψ(y)) (Eq. 4)
 3. training  the losses (Eq. 5-7) and Adam in its textbook m̂ / v̂ form
 4. phases    foot contacts, the contact and PCA sources, a per-frame sinusoid fit, Eq. (1) (Sec. 4.1)
 5. data      a small BVH reader and the x / z / clip features (Sec. 3.2)
 6. checking  two-sided numerical gradients of every layer and of the whole model
 7. main      label, featurise, train on style-balanced minibatches (Sec. 4.3), print the test MSE

    python examples/minifilm_in_one_file.py               # synthetic data, made by the package
    python examples/minifilm_in_one_file.py --data DIR    # your <Style>_<Gait>.bvh files (100STYLE skeleton)

Nothing here imports minifilm. Without --data the package writes synthetic BVH files into a temporary
folder (examples/make_synthetic.py, run in a subprocess: `pip install -e .` first); from the files on,
everything happens in this file. It computes the package's function, not an approximation of it:
tests/test_companion.py gives both the same weights and compares outputs and every gradient, and
compares the phases with the package's vectorised labelling on real files. Where the package chose a
detail, this file makes the same choice and says "as the package". Simpler here: the features
(trajectory samples past a file's ends are clamped, not reflected; End Sites are not feature joints),
one style clip per minibatch, a per-file 80/20 train/test split; no mirroring or validation set.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as `minifilm train`: small matrices gain little from
os.environ.setdefault("OMP_NUM_THREADS", "1")        # a second BLAS thread, and lose a lot on a busy machine
import numpy as np                                                    # noqa: E402 (after the settings above)
from scipy.signal import butter, sosfiltfilt                          # noqa: E402
from scipy.spatial.transform import Rotation                          # noqa: E402


# ==== 1. Layers: out, cache = f_forward(...); d_inputs = f_backward(dout, cache). Weights are (in, out). ====
def linear_forward(x, W, b):                     # x (B, I), W (I, O), b (O,) -> (B, O)
    return x @ W + b, (x, W)

def linear_backward(d, cache):
    x, W = cache
    return d @ W.T, x.T @ d, d.sum(0)

def elu_forward(x):                              # x if x > 0 else exp(x) - 1 (expm1: exact near 0)
    out = np.where(x > 0, x, np.expm1(np.minimum(x, 0)))
    return out, (x, out)

def elu_backward(d, cache):
    x, out = cache
    return d * np.where(x > 0, 1, out + 1)       # the slope below 0 is exp(x) = out + 1

def relu_forward(x):
    return np.maximum(x, 0), x

def relu_backward(d, x):
    return d * (x > 0)

def softmax_forward(x):                          # over the last axis; minus the max so exp cannot overflow
    e = np.exp(x - x.max(-1, keepdims=True))
    y = e / e.sum(-1, keepdims=True)
    return y, y

def softmax_backward(d, y):
    return y * (d - (d * y).sum(-1, keepdims=True))   # (diag(y) - y yᵀ) d, row by row

def dropout_forward(x, site, drop):
    """Inverted dropout at a named site (the package's site names). drop: None in evaluation, or
    {"rate", "masks", "rng"}: a site's keep-mask is drawn once and replayed by later passes."""
    if drop is None:
        return x, None
    if site not in drop["masks"]:
        drop["masks"][site] = drop["rng"].random(x.shape) >= drop["rate"]
    keep = (drop["masks"][site] / (1.0 - drop["rate"])).astype(x.dtype)
    return x * keep, keep

def dropout_backward(d, keep):
    return d if keep is None else d * keep

LN_EPS = 1e-6

def layer_norm_forward(x):
    """The bracket of Eq. (3), (x - μ) / σ per row, without a scale or shift of its own (FiLM's γ, β
    follow). As the package trains: σ unbiased (÷ H-1) and ε = 1e-6 added to σ."""
    xc = x - x.mean(-1, keepdims=True)
    sigma = np.sqrt((xc * xc).sum(-1, keepdims=True) / (x.shape[-1] - 1))
    return xc / (sigma + LN_EPS), (xc, sigma)

def layer_norm_backward(d, cache):
    xc, sigma = cache
    s = sigma + LN_EPS                           # y = xc / s, directly and through dσ/dxc = xc / ((H-1) σ)
    dxc = d / s - xc * (d * xc).sum(-1, keepdims=True) / (s * s * (xc.shape[-1] - 1) * sigma)
    return dxc - dxc.mean(-1, keepdims=True)     # through xc = x - mean(x)

def film_forward(h, gamma, beta):
    """FiLM (Perez et al. 2018), the outside of Eq. (3): γ ∘ h + β. h (B, H); γ, β (B, H), or (1, H):
    one style for the whole batch (then their gradients are summed over the batch)."""
    return gamma * h + beta, (h, gamma)

def film_backward(d, cache):
    h, gamma = cache
    fold = (lambda a: a.sum(0, keepdims=True)) if len(gamma) < len(h) else (lambda a: a)
    return d * gamma, fold(d * h), fold(d)

def expert_forward(x, alpha, W, b):
    """The gated expert layer (Sec. 4.1), plain: blend the K experts' weights by the gating weights,
    W = Σ_k α_k W_k for each sample, then multiply. x (B, I), α (B, K), W (K, I, O), b (K, O) -> (B, O).
    (The package sums the same terms without building the (B, I, O) blend: one product, 4-8x faster.)"""
    K, I, O = W.shape
    Wb = (alpha @ W.reshape(K, I * O)).reshape(-1, I, O)         # (B, I, O) each sample's blend
    return np.matmul(x[:, None, :], Wb)[:, 0] + alpha @ b, (x, alpha, W, b, Wb)

def expert_backward(d, cache):                   # -> dx (B, I), dα (B, K), dW (K, I, O), db (K, O)
    x, alpha, W, b, Wb = cache
    K, I, O = W.shape
    dWb = (x[:, :, None] * d[:, None, :]).reshape(len(x), I * O)   # gradient of each sample's blend,
    dalpha = dWb @ W.reshape(K, I * O).T + d @ b.T                 # ... seen by each α_k: <dW_b, W_k>
    return np.matmul(Wb, d[:, :, None])[..., 0], dalpha, (alpha.T @ dWb).reshape(K, I, O), alpha.T @ d

def conv1d_forward(x, W, b):
    """1-D convolution over time with 'same' zero padding (a cross-correlation, as TF):
    y[b, t, f] = Σ_j Σ_c x[b, t + j - k//2, c] W[j, c, f] + b[f]; x (B, T, C), W (k, C, F) -> (B, T, F).
    im2col: each frame's k-frame window is one row, and the convolution is one matrix product."""
    k, C, F = W.shape
    B, T, _ = x.shape
    xp = np.pad(x, ((0, 0), (k // 2, k // 2), (0, 0)))
    cols = np.stack([xp[:, j:j + T] for j in range(k)], axis=2).reshape(B * T, k * C)
    return (cols @ W.reshape(k * C, F) + b).reshape(B, T, F), (cols, x.shape, W)

def conv1d_backward(d, cache):
    cols, (B, T, C), W = cache
    k, _, F = W.shape
    d2 = d.reshape(B * T, F)
    dcols = (d2 @ W.reshape(k * C, F).T).reshape(B, T, k, C)
    dxp = np.zeros((B, T + k - 1, C), d.dtype)
    for j in range(k):                           # col2im: each window hands its gradient back to its frames
        dxp[:, j:j + T] += dcols[:, :, j]
    return dxp[:, k // 2:k // 2 + T], (cols.T @ d2).reshape(k, C, F), d2.sum(0)

def max_pool_forward(x):
    """Max over pairs of frames, (B, T, C) -> (B, T // 2, C); as the package, an odd last frame is
    dropped and a tie goes to the first frame of the pair."""
    even, odd = x[:, 0:x.shape[1] // 2 * 2:2], x[:, 1:x.shape[1] // 2 * 2:2]
    return np.maximum(even, odd), (x.shape, even >= odd)

def max_pool_backward(d, cache):
    shape, first = cache
    dx = np.zeros(shape, d.dtype)
    dx[:, 0:2 * first.shape[1]:2], dx[:, 1:2 * first.shape[1]:2] = d * first, d * ~first
    return dx


# ==== 2. Networks Ω, Ψ, Φ and the style model (Eq. 2-4). Backward passes are the forward steps reversed. ====
SMALL = dict(n_experts=4, hidden=128, gating_hidden=32, conv_filters=32, conv_kernel=9, film_dense=128,
             phase_dim=8, dropout=0.2)              # the package's small model (ModelConfig.small)

def init_params(c, rng, dtype=np.float32):
    """Glorot-uniform weights, zero biases, except γ's output biases at 1 so that FiLM starts near the
    identity (as the package). c: the sizes, named as the fields of the package's ModelConfig."""
    def glorot(shape, fan_in, fan_out):
        return rng.uniform(-1, 1, shape).astype(dtype) * np.sqrt(6.0 / (fan_in + fan_out)).astype(dtype)
    K, H, k, C = c["n_experts"], c["hidden"], c["conv_kernel"], c["clip_channels"]
    Fn, D = c["conv_filters"], c["film_dense"]
    P, gate, motion = {}, [c["phase_dim"], c["gating_hidden"], c["gating_hidden"], K], [c["x_dim"], H, H, c["z_dim"]]
    for l in range(3):
        P[f"omega.W{l}"], P[f"omega.b{l}"] = glorot(gate[l:l + 2], *gate[l:l + 2]), np.zeros(gate[l + 1], dtype)
        P[f"phi.W{l}"] = glorot([K] + motion[l:l + 2], *motion[l:l + 2])      # K experts (K, in, out)
        P[f"phi.b{l}"] = np.zeros((K, motion[l + 1]), dtype)
    flat = c["clip_frames"] // 4 * Fn                 # frames left after two poolings x filters
    for name, shape, fans in [("conv0", (k, C, Fn), (k * C, k * Fn)), ("conv1", (k, Fn, Fn), (k * Fn, k * Fn)),
                              ("dense0", (flat, D), (flat, D)), ("dense1", (D, 4 * H), (D, 4 * H))]:
        P[f"psi.{name}_W"], P[f"psi.{name}_b"] = glorot(shape, *fans), np.zeros(shape[-1], dtype)
    P["psi.dense1_b"][0:H] = P["psi.dense1_b"][2 * H:3 * H] = 1.0
    return P

def omega_forward(P, p, drop):
    """Ω, the gating network (Sec. 4.1): local phases p (B, 8) -> expert weights α (B, K).
    Three dense layers, dropout before each; ELU, ELU, softmax."""
    h, caches = p, []
    for l, act in enumerate([elu_forward, elu_forward, softmax_forward]):
        h, c_drop = dropout_forward(h, f"gating{l}", drop)
        h, c_lin = linear_forward(h, P[f"omega.W{l}"], P[f"omega.b{l}"])
        h, c_act = act(h)
        caches.append((c_drop, c_lin, c_act))
    return h, caches

def omega_backward(dalpha, caches, G):
    d = dalpha
    for l, act_backward in [(2, softmax_backward), (1, elu_backward), (0, elu_backward)]:
        c_drop, c_lin, c_act = caches[l]
        d, G[f"omega.W{l}"], G[f"omega.b{l}"] = linear_backward(act_backward(d, c_act), c_lin)
        d = dropout_backward(d, c_drop)
    return d

def psi_forward(P, clip, drop):
    """Ψ, the FiLM generator (Eq. 2): style clips (M, T, C) -> {γ1, β1, γ2, β2} (M, 4H). Two blocks
    conv1d -> ReLU -> max-pool, flatten (time-major), dense -> ReLU, dense. As the package and the
    original code, its one dropout is before the last dense layer."""
    h, caches = clip, []
    for l in (0, 1):
        h, c_conv = conv1d_forward(h, P[f"psi.conv{l}_W"], P[f"psi.conv{l}_b"])
        h, c_relu = relu_forward(h)
        h, c_pool = max_pool_forward(h)
        caches.append((c_conv, c_relu, c_pool))
    h, c_d0 = linear_forward(h.reshape(len(h), -1), P["psi.dense0_W"], P["psi.dense0_b"])
    h, c_relu = relu_forward(h)
    h, c_drop = dropout_forward(h, "film_dense", drop)
    film, c_d1 = linear_forward(h, P["psi.dense1_W"], P["psi.dense1_b"])
    return film, (caches, c_d0, c_relu, c_drop, c_d1)

def psi_backward(dfilm, cache, G):
    caches, c_d0, c_relu, c_drop, c_d1 = cache
    d, G["psi.dense1_W"], G["psi.dense1_b"] = linear_backward(dfilm, c_d1)
    d = relu_backward(dropout_backward(d, c_drop), c_relu)
    d, G["psi.dense0_W"], G["psi.dense0_b"] = linear_backward(d, c_d0)
    d = d.reshape(caches[1][2][1].shape)                          # back to the pooled (M, T // 4, F)
    for l in (1, 0):
        c_conv, c_relu, c_pool = caches[l]
        d = relu_backward(max_pool_backward(d, c_pool), c_relu)
        d, G[f"psi.conv{l}_W"], G[f"psi.conv{l}_b"] = conv1d_backward(d, c_conv)
    return d

def phi_forward(P, x, alpha, film, drop):
    """Φ, motion synthesis: x (B, x_dim), α (B, K), film (B or 1, 4H) -> ẑ (B, z_dim). Hidden layer
    i = 1, 2 is Eq. (3), h(i) = ELU(γ(i) ∘ LN(F(i)) + β(i)) with F(i) the gated experts applied to
    h(i-1); the output layer is gated experts alone. As the package: dropout before every layer."""
    H, h, caches = film.shape[1] // 4, x, []
    for l in (0, 1):
        gamma, beta = film[:, 2 * l * H:(2 * l + 1) * H], film[:, (2 * l + 1) * H:(2 * l + 2) * H]
        h, c_drop = dropout_forward(h, f"motion{l}", drop)
        f, c_exp = expert_forward(h, alpha, P[f"phi.W{l}"], P[f"phi.b{l}"])    # F(i)
        n, c_norm = layer_norm_forward(f)                                       # (F - μ) / σ
        m, c_film = film_forward(n, gamma, beta)                                # γ ∘ · + β
        h, c_elu = elu_forward(m)                                               # h(i)
        caches.append((c_drop, c_exp, c_norm, c_film, c_elu))
    h, c_drop = dropout_forward(h, "motion2", drop)
    z, c_exp = expert_forward(h, alpha, P["phi.W2"], P["phi.b2"])
    return z, (caches, c_drop, c_exp)

def phi_backward(dz, cache, G):                  # -> dx, dα, dfilm
    caches, c_drop, c_exp = cache
    d, dalpha, G["phi.W2"], G["phi.b2"] = expert_backward(dz, c_exp)
    d, dfilm = dropout_backward(d, c_drop), []
    for l in (1, 0):
        c_drop, c_exp, c_norm, c_film, c_elu = caches[l]
        d, dgamma, dbeta = film_backward(elu_backward(d, c_elu), c_film)
        d, da, G[f"phi.W{l}"], G[f"phi.b{l}"] = expert_backward(layer_norm_backward(d, c_norm), c_exp)
        d, dalpha, dfilm = dropout_backward(d, c_drop), dalpha + da, [dgamma, dbeta] + dfilm
    return d, dalpha, np.concatenate(dfilm, axis=1)

def model_forward(P, x, p, clip, drop=None):
    """Eq. (4), ẑ = Φ(x; Ω(p), Ψ(y)): x (B, x_dim), p (B, 8), clip (B, T, C), one per sample, or
    (1, T, C), one for the whole batch (a minibatch holds one style, Sec. 4.3) -> ẑ (B, z_dim)."""
    alpha, c_omega = omega_forward(P, p, drop)
    film, c_psi = psi_forward(P, clip, drop)
    z, c_phi = phi_forward(P, x, alpha, film, drop)
    return z, (c_omega, c_psi, c_phi)

def model_backward(dz, cache):                   # -> ({name: gradient}, dx, dp, dclip)
    c_omega, c_psi, c_phi = cache
    G = {}
    dx, dalpha, dfilm = phi_backward(dz, c_phi, G)
    return G, dx, omega_backward(dalpha, c_omega, G), psi_backward(dfilm, c_psi, G)


# ==== 3. Training: L = L_mse + L_bll (Eq. 5-7) on style-balanced minibatches, and Adam =================
def mse_loss(pred, target):
    """Eq. (5) on one minibatch (one style): the mean of (z - ẑ)² over the samples and, as the package
    and the original code, over the features. -> loss, dpred."""
    diff = pred - target
    return float(np.mean(diff * diff)), (2.0 / diff.size) * diff

def bone_length_loss(pred, target, pos_cols, parents, z_mean, z_std):
    """Eq. (6)-(7): the mean over samples and bones of | ‖z_bp - z_b‖ - ‖ẑ_bp - ẑ_b‖ |. pos_cols (J, 3):
    each joint's position columns in z; parents (J,), -1 for the root: as the package, every (parent,
    joint) pair is a bone, positions are de-normalised first (metres), and |·| at 0 has slope 0."""
    child = np.nonzero(parents >= 0)[0]
    par, std, mean = parents[child], z_std[pos_cols], z_mean[pos_cols]
    pos_hat, pos = pred[:, pos_cols] * std + mean, target[:, pos_cols] * std + mean   # (N, J, 3)
    vec_hat = pos_hat[:, par] - pos_hat[:, child]
    len_hat = np.linalg.norm(vec_hat, axis=-1)
    diff = np.linalg.norm(pos[:, par] - pos[:, child], axis=-1) - len_hat
    unit = vec_hat / np.where(len_hat > 0, len_hat, np.inf)[..., None]      # d‖v‖/dv (0 for a zero-length bone)
    dvec = unit * (-np.sign(diff) / diff.size)[..., None]                   # d|diff|/d‖v̂‖ = -sign(diff)
    dpos = np.zeros_like(pos_hat)
    np.add.at(dpos, (slice(None), par), dvec)
    np.add.at(dpos, (slice(None), child), -dvec)
    dpred = np.zeros_like(pred)
    dpred[:, pos_cols] = dpos * std
    return float(np.mean(np.abs(diff))), dpred

def adam_step(P, G, state, lr, beta1=0.9, beta2=0.999, eps=1e-8):
    """Adam (Kingma & Ba 2014), in place on P; state = {"t": 0, "m": {}, "v": {}}."""
    state["t"] += 1
    t = state["t"]
    for name, g in G.items():
        m = state["m"][name] = beta1 * state["m"].get(name, 0.0) + (1 - beta1) * g
        v = state["v"][name] = beta2 * state["v"].get(name, 0.0) + (1 - beta2) * g * g
        m[np.abs(m) < 1e-30] = 0.0               # a dead unit's m decays to subnormal floats, slow on many CPUs
        m_hat, v_hat = m / (1 - beta1 ** t), v / (1 - beta2 ** t)
        P[name] -= lr * m_hat / (np.sqrt(v_hat) + eps)


# ==== 4. Local phases (Sec. 4.1): contacts, sources, a per-frame sinusoid fit, Eq. (1) =================
def foot_contacts(toes, fps):
    """Sec. 4.1.2: a toe tip is in contact when slow (|v| ≤ 0.15 m/s) AND near the floor (|y - floor|
    ≤ 0.01 m). toes (F, 2, 3) [right, left] -> (F, 2) 0/1. As the package: the floor is the median
    height of the slow samples, and an 11-frame (at 60 fps) majority vote smooths the result."""
    v = np.diff(toes, axis=0, prepend=toes[:1]) * fps
    v[0] = v[1]                                   # backward differences; frame 0 copies frame 1
    y, slow = toes[..., 1], np.linalg.norm(v, axis=-1) <= 0.15
    floor = np.median(y[slow]) if slow.sum() >= max(1, 0.02 * y.size) else np.percentile(y, 2.0)
    raw = (slow & (np.abs(y - floor) <= 0.01)).astype(float)
    half, out = int(np.floor(10 / 60 * fps / 2 + 0.5)), raw.copy()
    for k in range(len(raw)):
        window = raw[max(k - half, 0):k + half + 1]
        ones, zeros = window.sum(0), len(window) - window.sum(0)
        out[k] = np.where(ones > zeros, 1.0, np.where(zeros > ones, 0.0, raw[k]))   # a tie keeps the raw value
    return out

def pca_source(local, facing=(0.0, 0.0, 1.0)):
    """Sec. 4.1.3, the contact-free source: the bone's hips-local positions (F, 3), centred, projected
    on their first principal component, directed forward (so in-sync and opposite limbs differ; as the
    package, a component exactly sideways is directed by its x)."""
    c = local - local.mean(0)
    pc1 = np.linalg.eigh(c.T @ c / (len(c) - 1))[1][:, -1]      # the largest eigenvalue's eigenvector
    along = pc1 @ np.asarray(facing)
    return c @ (-pc1 if along < 0 or (along == 0 and pc1[0] <= 0) else pc1)

def butterworth(x, fps, cutoff=4.0):
    """2nd-order Butterworth low-pass run forwards and backwards along axis 0 (as the package: edge
    values padded, the cutoff at most 0.4 fps)."""
    sos = butter(2, min(cutoff, 0.4 * fps) / (fps / 2), output="sos")
    return sosfiltfilt(sos, x, axis=0, padtype="constant", padlen=min(9, len(x) - 1)) if len(x) > 1 else x.copy()

def preprocess_source(g, fps):
    """Sec. 4.1.4: normalise in a 1 s window (each frame by its window's mean and std, ends repeated;
    a still window divides by 1), low-pass at 4 Hz, and set values under 1e-3 to 0."""
    half = int(np.floor(fps / 2 + 0.5))
    windows = np.lib.stride_tricks.sliding_window_view(np.pad(g, half, mode="edge"), 2 * half + 1)
    v = butterworth((g - windows.mean(1)) / np.where(windows.std(1) < 1e-6, 1.0, windows.std(1)), fps)
    v[np.abs(v) < 1e-3] = 0.0
    return v

FREQUENCIES = np.geomspace(0.25, 4.0, 48)        # Hz: the frequency grid of the fit

def sinusoid_basis(tau, freqs, fps):             # (G, E, 3): [sin 2πFτ, cos 2πFτ, 1] for offsets τ in frames
    angle = (2 * np.pi / fps) * tau[None, :] * freqs[:, None]
    return np.stack([np.sin(angle), np.cos(angle), np.ones_like(angle)], axis=-1)

def solve_window(X, w, y, vmin, vmax):
    """Weighted least squares of y ≈ c1 sin(2πFτ) + c2 cos(2πFτ) + B for each candidate F: for a fixed
    frequency it is linear, a 3x3 system. X (G, E, 3), w and y (E,). The original's bounds: B in [vmin,
    vmax] (else clipped, (c1, c2) re-solved) and A = |(c1, c2)| ≤ vmax - vmin (else scaled down).
    -> c (G, 3) = (c1, c2, B), weighted squared errors (G,)."""
    Xw = X.transpose(0, 2, 1) * w
    A, r, yy = Xw @ X, Xw @ y, np.sum(w * y * y)                 # Xᵀ W X, Xᵀ W y, yᵀ W y
    A += (1e-10 * np.trace(A, axis1=1, axis2=2) + 1e-300)[:, None, None] * np.eye(3)   # a ridge, as the package
    c = np.linalg.solve(A, r[..., None])[..., 0]
    sse, amax = yy - np.sum(c * r, axis=1), vmax - vmin
    bad = (c[:, 2] < vmin) | (c[:, 2] > vmax) | (c[:, 0] ** 2 + c[:, 1] ** 2 > amax ** 2)
    for g in np.nonzero(bad & (sse < np.min(sse[~bad], initial=np.inf)))[0]:   # as the package: only
        B = np.clip(c[g, 2], vmin, vmax)                         # candidates that could still win
        if B != c[g, 2]:
            c[g, :2] = np.linalg.solve(A[g, :2, :2], r[g, :2] - A[g, :2, 2] * B)
        c[g, :2] *= min(1.0, amax / max(np.hypot(c[g, 0], c[g, 1]), 1e-300))
        c[g, 2] = B
        sse[g] = yy - 2 * c[g] @ r[g] + c[g] @ A[g] @ c[g]
    return c, sse

def fit_sinusoids(v, fps, sweeps=3):
    """Sec. 4.1.4: around every frame k, fit A sin(2π(Fτ + φ)) + B (τ = t - t_k) to the source v (F,)
    over 0.5 s (2P+1 frames, shifted inwards at the ends) plus P frames each side that pull towards
    the neighbours' fits of the previous sweep, weighted (1 - i/P)² (sweep 0 fits the data alone).
    Per frame: a grid of frequencies, then a parabola through the best three. (The original runs a
    genetic algorithm; the package and this minimise the same loss deterministically.)
    -> amplitude A, frequency F (Hz), phase φ (cycles), each (F,)."""
    n, P = len(v), max(1, int(np.floor(fps / 4 + 0.5)))
    L, logf = min(2 * P + 1, n), np.log(FREQUENCIES)
    X_grid, windows = sinusoid_basis(np.arange(-L - 2 * P, L + 2 * P + 1), FREQUENCIES, fps), []
    for k in range(n):                            # the windows are the same in every sweep
        lo = min(max(k - P, 0), n - L)
        j = np.arange(lo - P, lo + L + P)
        data, ext = (j >= lo) & (j < lo + L), v[max(lo - P, 0):lo + L + P]   # bounds: all samples looked at
        near = np.where(data, 0.0, (1 - np.where(j < lo, lo - j, j - lo - L + 1) / P) ** 2) * ((j >= 0) & (j < n))
        still = np.abs(v[lo:lo + L]).sum() < 1e-3                  # skipped: all parameters 0
        windows.append(None if still else (j - k, data, np.clip(j, 0, n - 1), data + near, ext.min(), ext.max()))
    coef, freq, fit = np.zeros((n, 3)), np.zeros(n), np.zeros(n)
    for sweep in range(sweeps):
        coef, freq = np.zeros((n, 3)), np.zeros(n)
        for k, win in enumerate(windows):
            if win is None:
                continue
            tau, data, j, w, vmin, vmax = win
            w = w if sweep else data * 1.0                          # sweep 0: the data alone
            y = np.where(data, v[j], fit[j])                        # the data, then the neighbours' fits
            c, sse = solve_window(X_grid[:, tau + L + 2 * P], w, y, vmin, vmax)
            b, delta = np.argmin(sse), 0.0
            if 0 < b < len(sse) - 1 and sse[b - 1] - 2 * sse[b] + sse[b + 1] > 0:
                delta = np.clip(0.5 * (sse[b - 1] - sse[b + 1]) / (sse[b - 1] - 2 * sse[b] + sse[b + 1]), -1, 1)
            f = np.exp(logf[b] + delta * (logf[1] - logf[0]))
            c_f, sse_f = solve_window(sinusoid_basis(tau, np.array([f]), fps), w, y, vmin, vmax)
            coef[k], freq[k] = (c_f[0], f) if sse_f[0] < sse[b] else (c[b], FREQUENCIES[b])
        fit = coef[:, 1] + coef[:, 2]                                # each curve at its own frame, τ = 0
    amp = np.hypot(coef[:, 0], coef[:, 1])
    phase = np.mod(np.arctan2(coef[:, 1], coef[:, 0]) / (2 * np.pi), 1.0)
    phase[(amp == 0) | (phase >= 1.0)] = 0.0
    # As the package: 0.5 s pins the phase down better than the frequency, so F is re-read as the slope
    # of the unwrapped phase over the second around each frame (where all of it was fitted).
    half, cycles, t = int(round(fps / 2)), np.unwrap(2 * np.pi * phase) / (2 * np.pi), np.arange(n) / fps
    for k in range(half, n - half if half >= 1 else 0):
        s = slice(k - half, k + half + 1)
        if np.all(amp[s] > 0):
            tc = t[s] - t[s].mean()
            freq[k] = np.clip(tc @ cycles[s] / (tc @ tc), FREQUENCIES[0], FREQUENCIES[-1])
    return amp, freq, phase

def local_phases(pos, rot, fps, hips, bones, contacts, sources=("pca", "pca", "contact", "contact"),
                 facing=(0.0, 0.0, 1.0)):
    """The local phases of [left hand, right hand, left foot, right foot] (Sec. 4.1). pos (F, J, 3),
    rot (F, J, 3, 3) world transforms; hips and bones (4) joint indices; contacts (F, 2) [right, left];
    a 'pca' or 'contact' source per slot. -> phase (F, 4) cycles, amplitude (F, 4). The amplitude
    (Eq. 1's ‖v_w‖ a): A x the bone's largest hips-relative speed within one fitted period; as the
    package, phase and amplitude are then smoothed by the 4 Hz filter."""
    local = np.einsum("fji,fbj->fbi", rot[:, hips], pos[:, bones] - pos[:, hips, None])   # R_hipsᵀ (p - p_hips)
    speed = np.linalg.norm(np.diff(local, axis=0, prepend=local[:1]), axis=-1) * fps
    speed[0] = speed[1]
    n, phase, amplitude = len(pos), np.zeros((len(pos), 4)), np.zeros((len(pos), 4))
    for slot, kind in enumerate(sources):
        g = contacts[:, {2: 1, 3: 0}[slot]] if kind == "contact" else pca_source(local[:, slot], facing)
        A, F, ph = fit_sinusoids(preprocess_source(np.asarray(g, float), fps), fps)
        half = (np.where(F > 0, np.floor(fps / np.where(F > 0, F, 1) + 0.5), 0) // 2).astype(int)
        for k in range(n):                        # one period around k, shifted inwards at the ends
            lo = min(max(k - half[k], 0), max(n - 1 - 2 * half[k], 0))
            A[k] *= speed[lo:lo + 2 * half[k] + 1, slot].max()
        sc = butterworth(np.stack([np.sin(2 * np.pi * ph), np.cos(2 * np.pi * ph)], 1), fps)
        phase[:, slot] = np.mod(np.arctan2(sc[:, 0], sc[:, 1]) / (2 * np.pi), 1.0)
        phase[(np.hypot(sc[:, 0], sc[:, 1]) == 0) | (phase[:, slot] >= 1.0), slot] = 0.0
        amplitude[:, slot] = np.maximum(butterworth(A, fps), 0.0)
    return phase, amplitude

def phase_vectors(phase, amplitude):             # Eq. (1): amplitude (sin 2πφ, cos 2πφ), interleaved (F, 8)
    return np.stack([amplitude * np.sin(2 * np.pi * phase), amplitude * np.cos(2 * np.pi * phase)], -1).reshape(-1, 8)


# ==== 5. Data: BVH files -> world transforms -> x, z and style clips (Sec. 3.2) ========================
def read_bvh(path, scale=0.01):
    """-> joint names (End Sites named after their parent + "Site"), parents, world positions (F, J, 3)
    in metres (scale: from centimetres), world rotations (F, J, 3, 3), fps."""
    tokens, i = Path(path).read_text().split(), 0
    names, parents, offsets, channels, stack = [], [], [], [], []
    while tokens[i] != "MOTION":
        if tokens[i] in ("ROOT", "JOINT", "End"):
            names.append(names[stack[-1]] + "Site" if tokens[i] == "End" else tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            channels.append([])
        elif tokens[i] in ("{", "}"):
            stack = stack + [len(names) - 1] if tokens[i] == "{" else stack[:-1]
        elif tokens[i] == "OFFSET":
            offsets.append([float(t) for t in tokens[i + 1:i + 4]])
        elif tokens[i] == "CHANNELS":
            channels[-1] = tokens[i + 2:i + 2 + int(tokens[i + 1])]
        i += 1
    F, fps = int(tokens[i + 2]), 1.0 / float(tokens[i + 5])
    values = np.array(tokens[i + 6:], dtype=float).reshape(F, -1)
    local_t, local_R, col = np.tile(np.array(offsets) * scale, (F, 1, 1)), np.tile(np.eye(3), (F, len(names), 1, 1)), 0
    for j, ch in enumerate(channels):
        for k, c in enumerate(ch):                # position channels replace the offset
            if c.endswith("position"):
                local_t[:, j, "XYZ".index(c[0])] = values[:, col + k] * scale
        rot = [k for k, c in enumerate(ch) if c.endswith("rotation")]
        if rot:                                   # intrinsic rotations in the order of the channels
            local_R[:, j] = Rotation.from_euler("".join(ch[k][0] for k in rot), values[:, [col + k for k in rot]],
                                                degrees=True).as_matrix()
        col += len(ch)
    pos, R = np.zeros((F, len(names), 3)), np.zeros((F, len(names), 3, 3))
    for j, p in enumerate(parents):               # forward kinematics, parents first
        R[:, j] = local_R[:, j] if p < 0 else R[:, p] @ local_R[:, j]
        pos[:, j] = local_t[:, j] if p < 0 else pos[:, p] + np.einsum("fij,fj->fi", R[:, p], local_t[:, j])
    return names, np.array(parents), pos, R, fps

HIPS, TOE_TIPS = "Hips", ("RightToeSite", "LeftToeSite")          # the 100STYLE skeleton's names
PHASE_BONES = ("LeftWristSite", "RightWristSite", "LeftToe", "RightToe")
TRAJECTORY_SECONDS = np.array([-1, -5 / 6, -4 / 6, -3 / 6, -2 / 6, -1 / 6, 0, 0.2, 0.4, 0.6, 0.8, 1.0])

def to_root(v, R, r=None):                        # world points (r given) or directions per frame -> Rᵀ (v - r)
    return np.einsum("fji,f...j->f...i", R, v if r is None else v - r[:, None])

def features(pos, rot, fps, hips, joints, p, contacts):
    """In the package's layout (minifilm/features/layout.py): x (N, 48 + 12J) and z (N, 24 + 12J + 18)
    for the frames 1 .. F-2, and clip frames (F, 12J). The root is the hips on the floor, facing the
    hips' +z; 12 trajectory samples [x, z, dir x, dir z] from -1 s to +1 s; per joint [position,
    forward, up, velocity] relative to the root. z: the next frame's future trajectory and joints
    relative to the current root, its phases p, their change, its contacts."""
    F = len(pos)
    f = rot[:, hips, :, 2] * [1, 0, 1]
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    R, r = np.stack([np.cross([0, 1, 0], f), np.tile([0.0, 1, 0], (F, 1)), f], -1), pos[:, hips] * [1, 0, 1]
    vel = np.diff(pos, axis=0, prepend=pos[:1]) * fps
    vel[0] = vel[1]

    def joint_block(i, root):                     # (n, 12 J)
        P, Q = pos[i][:, joints], rot[i][:, joints]
        return np.concatenate([to_root(P, R[root], r[root]), to_root(Q[..., 2], R[root]), to_root(Q[..., 1], R[root]),
                               to_root(vel[i][:, joints], R[root])], -1).reshape(len(i), -1)

    def trajectory(i, root):                      # (n, 48); samples past the ends are clamped
        s = np.clip(i[:, None] + np.round(TRAJECTORY_SECONDS * fps).astype(int), 0, F - 1)
        at, to = to_root(r[s], R[root], r[root]), to_root(R[s][..., 2], R[root])
        return np.concatenate([at[..., [0, 2]], to[..., [0, 2]]], -1).reshape(len(i), -1)

    i = np.arange(1, F - 1)
    x = np.concatenate([trajectory(i, i), joint_block(i, i)], 1)
    z = np.concatenate([trajectory(i + 1, i)[:, 24:], joint_block(i + 1, i), p[i + 1], p[i + 1] - p[i],
                        contacts[i + 1]], 1)
    return x, p[i], z, joint_block(np.arange(F), np.arange(F))


# ==== 6. Gradient check: every backward pass against two-sided differences, in float64 =================
def numerical_gradient(f, x, h=1e-5):            # (f(x + h e_i) - f(x - h e_i)) / 2h for every entry of x
    grad = np.zeros_like(x)
    for i in np.ndindex(x.shape):
        old = x[i]
        x[i] = old + h
        f_plus = f()
        x[i] = old - h
        grad[i] = (f_plus - f()) / (2 * h)
        x[i] = old
    return grad

def rel_error(a, b):
    """max|a - b| / max(|a| + |b|): the worst entry against the largest gradient. (Two-sided differences
    carry ~1e-11 of rounding, which a per-entry ratio would report on tiny entries; the package's suite
    uses a four-point stencil for that, minifilm/nn/gradcheck.py.)"""
    return float(np.max(np.abs(a - b)) / max(1e-12, np.max(np.abs(a) + np.abs(b))))

def check_layer(forward, backward, *inputs, rng):  # L = Σ out ∘ R (so dout = R): the worst input's error
    out, cache = forward(*inputs)
    R = rng.standard_normal(out.shape)
    grads = backward(R, cache)
    grads = grads if isinstance(grads, tuple) else (grads,)
    loss = lambda: np.sum(forward(*inputs)[0] * R)
    return max(rel_error(g, numerical_gradient(loss, x)) for x, g in zip(inputs, grads))

def check_model(rng):
    """L_mse + L_bll of Ω + Φ + Ψ at toy sizes, with dropout (fixed masks) and one style clip for the
    batch, as trained below: every parameter, x, p and the clip."""
    c = dict(x_dim=7, z_dim=14, phase_dim=8, n_experts=3, hidden=6, gating_hidden=5, clip_frames=10,
             clip_channels=4, conv_filters=3, conv_kernel=3, film_dense=7)
    P = {name: a + 0.1 * rng.standard_normal(a.shape) for name, a in init_params(c, rng, np.float64).items()}
    x, p, clip, z = (rng.standard_normal(shape) for shape in [(4, 7), (4, 8), (1, 10, 4), (4, 14)])
    bones = np.arange(12).reshape(4, 3), np.array([-1, 0, 1, 1]), rng.standard_normal(14), 0.5 + rng.random(14)
    drop = {"rate": 0.2, "masks": {}, "rng": rng}

    def loss():
        z_hat, cache = model_forward(P, x, p, clip, drop)
        (l1, d1), (l2, d2) = mse_loss(z_hat, z), bone_length_loss(z_hat, z, *bones)
        return l1 + l2, d1 + d2, cache
    G, dx, dp, dclip = model_backward(*loss()[1:])
    grads, arrays = dict(G, x=dx, p=dp, clip=dclip), dict(P, x=x, p=p, clip=clip)
    return {name: rel_error(grads[name], numerical_gradient(lambda: loss()[0], a)) for name, a in arrays.items()}

def gradient_check(seed=0, limit=1e-7):           # prints one row per check; True when every row passes
    rng = np.random.default_rng(seed)
    r, away = lambda *shape: rng.standard_normal(shape), lambda a: a + 0.1 * np.sign(a)   # away from ReLU's kink
    drop = {"rate": 0.3, "masks": {}, "rng": rng}   # one mask, drawn on the first call, for every call
    rows = {"linear": check_layer(linear_forward, linear_backward, r(4, 5), r(5, 3), r(3), rng=rng),
            "ELU": check_layer(elu_forward, elu_backward, away(r(4, 5)), rng=rng),
            "ReLU": check_layer(relu_forward, relu_backward, away(r(4, 5)), rng=rng),
            "softmax": check_layer(softmax_forward, softmax_backward, r(4, 5), rng=rng),
            "dropout": check_layer(lambda x: dropout_forward(x, "d", drop), dropout_backward, r(4, 5), rng=rng),
            "layer norm": check_layer(layer_norm_forward, layer_norm_backward, r(4, 6), rng=rng),
            "FiLM": check_layer(film_forward, film_backward, r(4, 6), r(4, 6), r(4, 6), rng=rng),
            "FiLM, one style": check_layer(film_forward, film_backward, r(4, 6), r(1, 6), r(1, 6), rng=rng),
            "gated experts": check_layer(expert_forward, expert_backward, r(4, 5), r(4, 3), r(3, 5, 2), r(3, 2),
                                         rng=rng),
            "conv1d": check_layer(conv1d_forward, conv1d_backward, r(2, 7, 3), r(3, 3, 4), r(4), rng=rng),
            "max-pool": check_layer(max_pool_forward, max_pool_backward, r(2, 7, 3), rng=rng),
            **{f"model: {name}": err for name, err in check_model(rng).items()}}
    print(f"gradient check (float64, two-sided differences; passes under {limit:g}):")
    for name, err in rows.items():
        print(f"  {name:<20} {err:9.2e}  {'ok' if err < limit else 'FAIL'}")
    return all(err < limit for err in rows.values())


# ==== 7. Main: BVH files -> labels -> features -> style-balanced training (Sec. 4.3) -> test MSE =======
def load_folder(folder, clip_seconds=2.0):
    """Label and featurise every <Style>_<Gait>.bvh in folder; each file's first 80 % of rows train, the
    rest test. -> {style: {"train": [x, p, z], "test": [x, p, z], "clips": (n, T, 12J)}}, joint parents."""
    data, errors = {}, []
    for path in sorted(Path(folder).glob("*.bvh")):
        style = path.stem.split("_")[0]
        names, parents, pos, rot, fps = read_bvh(path)
        at = {name: j for j, name in enumerate(names)}
        if any(n not in at for n in (HIPS, *TOE_TIPS, *PHASE_BONES)):
            sys.exit(f"{path}: not on the 100STYLE skeleton (it needs {HIPS}, {', '.join(TOE_TIPS + PHASE_BONES)})")
        contacts = foot_contacts(pos[:, [at[n] for n in TOE_TIPS]], fps)
        sources = ["pca", "pca", "contact", "contact"]               # a hopping style's lifted foot: PCA
        sources[3 if style == "LeftHop" else 2 if style == "RightHop" else 0] = "pca"
        phase, amplitude = local_phases(pos, rot, fps, at[HIPS], [at[n] for n in PHASE_BONES], contacts, sources)
        if path.with_suffix(".truth.npz").exists():                  # the synthetic generator's true phases
            with np.load(path.with_suffix(".truth.npz"), allow_pickle=False) as truth:
                e = np.abs(phase - truth["true_phase"]) % 1
                errors.append(np.minimum(e, 1 - e)[truth["phase_active"]])
        joints = [j for j, name in enumerate(names) if not name.endswith("Site")]
        x, p, z, frames = features(pos, rot, fps, at[HIPS], joints, phase_vectors(phase, amplitude), contacts)
        cut, T = int(0.8 * len(x)), int(round(clip_seconds * fps))
        d = data.setdefault(style, {"train": [], "test": [], "clips": []})
        d["train"].append((x[:cut], p[:cut], z[:cut]))
        d["test"].append((x[cut:], p[cut:], z[cut:]))
        d["clips"] += [frames[s:s + T] for s in range(0, cut - T + 1, T // 2)]      # 2 s clips every 1 s
    for d in data.values():
        d["train"], d["test"] = ([np.concatenate(a) for a in zip(*d[split])] for split in ("train", "test"))
        d["clips"] = np.stack(d["clips"])
    if errors:
        error = np.median(np.concatenate(errors))
        print(f"[phases] median error against the generator's true phases: {error:.3f} cycles")
    return data, np.array([joints.index(parents[j]) if parents[j] in joints else -1 for j in joints])

def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, help="a folder of <Style>_<Gait>.bvh files on the 100STYLE skeleton")
    ap.add_argument("--seconds", type=float, default=5.0, help="synthetic seconds per style and gait")
    ap.add_argument("--epochs", type=int, default=12)
    ap.add_argument("--lr", type=float, default=5e-4)
    ap.add_argument("--seed", type=int, default=0)
    args, B, start = ap.parse_args(), 32, time.perf_counter()
    if args.data is not None and not any(args.data.glob("*.bvh")):
        sys.exit(f"no .bvh files in {args.data}")
    if not gradient_check(args.seed):
        sys.exit("the gradient check failed")
    with tempfile.TemporaryDirectory() as tmp:        # the synthetic files live only as long as this
        if args.data is None:
            cmd = [sys.executable, str(Path(__file__).with_name("make_synthetic.py")), tmp, "--seconds",
                   str(args.seconds), "--fps", "30", "--gaits", "FW,FR,TR", "--seed", str(args.seed)]
            made = subprocess.run(cmd, capture_output=True, text=True)
            if made.returncode != 0:
                sys.exit(f"{' '.join(cmd)} failed:\n{made.stderr}\nInstall minifilm (pip install -e .) or pass --data.")
            print("[data]", made.stdout.strip().splitlines()[-1])
        data, parents = load_folder(args.data or tmp)
    styles = sorted(data)
    print(f"[labels] {len(styles)} styles labelled and featurised ({time.perf_counter() - start:.0f} s so far)")

    # normalise every column by the training rows' mean and std, the clips by x's joint columns (as the package)
    stats = [(a.mean(0), np.where(a.std(0) < 1e-6, 1, a.std(0)))
             for a in (np.concatenate([data[s]["train"][k] for s in styles]) for k in range(3))]
    for d in data.values():
        for split in ("train", "test"):
            d[split] = [((a - mean) / std).astype(np.float32) for a, (mean, std) in zip(d[split], stats)]
        d["clips"] = ((d["clips"] - stats[0][0][48:]) / stats[0][1][48:]).astype(np.float32)
    (_, T, C), (x_dim, z_dim) = data[styles[0]]["clips"].shape, (len(stats[0][0]), len(stats[2][0]))
    bones = (24 + 12 * np.arange(len(parents))[:, None] + np.arange(3), parents, *stats[2])  # positions in z

    rng = np.random.default_rng(args.seed)
    config = dict(SMALL, x_dim=x_dim, z_dim=z_dim, clip_frames=T, clip_channels=C)
    P, adam = init_params(config, rng), {"t": 0, "m": {}, "v": {}}
    print(f"[model] {sum(a.size for a in P.values()):,} parameters; x {x_dim}, p 8, z {z_dim}, clips {T} x {C}")
    steps = min(len(data[s]["train"][0]) for s in styles) // B       # an epoch: one pass through the shortest style
    for epoch in range(1, args.epochs + 1):
        t0, losses, order = time.perf_counter(), [], {s: rng.permutation(len(data[s]["train"][0])) for s in styles}
        for step in range(steps):
            for s in styles:                               # one style per minibatch, in a fixed order
                x, p, z = (a[order[s][step * B:(step + 1) * B]] for a in data[s]["train"])
                clip = data[s]["clips"][rng.integers(len(data[s]["clips"]))][None]      # one clip of the style
                z_hat, cache = model_forward(P, x, p, clip, {"rate": config["dropout"], "masks": {}, "rng": rng})
                (l_mse, d_mse), (l_bll, d_bll) = mse_loss(z_hat, z), bone_length_loss(z_hat, z, *bones)
                adam_step(P, model_backward(d_mse + d_bll, cache)[0], adam, args.lr)
                losses.append((l_mse, l_bll))
        l_mse, l_bll = np.mean(losses, axis=0)
        print(f"[train] epoch {epoch:2d}: L_mse {l_mse:.4f}  L_bll {l_bll:.4f}  ({time.perf_counter() - t0:.1f} s)",
              flush=True)

    errors = {}                                      # a style's FiLM vector: Ψ averaged over its clips (Sec. 4.4)
    for s in styles:
        (x, p, z), film = data[s]["test"], psi_forward(P, data[s]["clips"], None)[0].mean(0, keepdims=True)
        errors[s] = mse_loss(phi_forward(P, x, omega_forward(P, p, None)[0], film, None)[0], z)[0]
    print("[test] MSE of the normalised z: " + ", ".join(f"{s} {e:.4f}" for s, e in errors.items()))
    print(f"[test] MSE {np.mean(list(errors.values())):.4f} (predicting the mean scores about 1); "
          f"{time.perf_counter() - start:.0f} s in all")

if __name__ == "__main__":
    main()
