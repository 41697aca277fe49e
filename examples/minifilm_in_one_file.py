"""minifilm in one file: Mason, Starke & Komura 2022, *Real-Time Style Modelling of Human
Locomotion via Feature-Wise Transformations and Local Motion Phases*, in NumPy + SciPy.
 1 layers; 2 the networks Ω (gating), Ψ (FiLM generator, Eq. 2), Φ (Eq. 3), ẑ = Φ(x; Ω(p), Ψ(y))
 (Eq. 4); 3 the losses (Eq. 5-7), Adam; 4 local phases (Sec. 4.1, Eq. 1); 5 a BVH reader, the
 x / z / clip features (Sec. 3.2); 6 gradient checks; 7 the runtime (Sec. 4.4); 8 main: label,
 featurise, train (Sec. 4.3), then walk the trained model frame by frame.

    python examples/minifilm_in_one_file.py             # synthetic data, made by the package
    python examples/minifilm_in_one_file.py --data DIR  # <Style>_<Gait>.bvh, 100STYLE skeleton

Nothing here imports minifilm (without --data the package writes synthetic BVH files: `pip install
-e .` first); tests/test_companion.py holds this file equal to the package. "As the package": a
detail the paper leaves open; "PAPER:": where this file departs from the paper, and why.
Letters, one meaning each: n rows of a batch; K experts; I, O a layer's input and output widths;
H hidden width; T frames (of a clip or a file); C channels per frame; J joints. Weights are
(in, out). A phase fit's sinusoid is amp·sin(2π(freq·τ + phase)) + offset (Sec. 4.1.4).
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# as `minifilm train`: small matrices gain little from a second BLAS thread, lose a lot when busy
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
import numpy as np                                      # noqa: E402 (after the settings above)
from scipy.signal import butter, sosfiltfilt            # noqa: E402
from scipy.spatial.transform import Rotation            # noqa: E402

# ==== 1. Layers: out, cache = f_forward(...); d_inputs = f_backward(d_out, cache) ==============
def linear_forward(x, W, b):                    # x (n, I), W (I, O), b (O,) -> (n, O)
    return x @ W + b, (x, W)
def linear_backward(d, cache):
    x, W = cache
    return d @ W.T, x.T @ d, d.sum(0)
def slope_backward(d, slope):                   # an elementwise layer: d_in = d_out ∘ its slope
    return d * slope
def elu_forward(x):                             # x if x > 0 else exp(x) - 1 (expm1: exact near 0)
    out = np.where(x > 0, x, np.expm1(np.minimum(x, 0)))
    return out, np.where(x > 0, 1, out + 1)     # the slope below 0 is exp(x) = out + 1
def relu_forward(x):
    return np.maximum(x, 0), x > 0
def dropout_forward(x, site, drop):             # inverted; drop None (evaluation) or a dict:
    if drop is None:                            # {"rate", "masks": {site: mask}, "rng"}
        return x, 1.0
    if site not in drop["masks"]:
        drop["masks"][site] = drop["rng"].random(x.shape) >= drop["rate"]
    keep = (drop["masks"][site] / (1.0 - drop["rate"])).astype(x.dtype)
    return x * keep, keep
elu_backward = slope_backward
relu_backward = slope_backward
dropout_backward = slope_backward
def softmax_forward(x):                         # over the last axis; minus the max: no overflow
    e = np.exp(x - x.max(-1, keepdims=True))
    y = e / e.sum(-1, keepdims=True)
    return y, y
def softmax_backward(d, y):
    return y * (d - (d * y).sum(-1, keepdims=True))   # (diag(y) - y yᵀ) d, row by row
LN_EPS = 1e-6
def layer_norm_forward(x):
    """The bracket of Eq. (3), (x - μ) / σ per row, with no scale or shift of its own (FiLM's γ, β
    follow). As the package trains: σ unbiased (÷ H-1) and ε = 1e-6 added to σ."""
    centred = x - x.mean(-1, keepdims=True)
    sigma = np.sqrt((centred * centred).sum(-1, keepdims=True) / (x.shape[-1] - 1))
    return centred / (sigma + LN_EPS), (centred, sigma)
def layer_norm_backward(d, cache):
    centred, sigma = cache
    s = sigma + LN_EPS              # y = centred / s, directly and through dσ = centred / ((H-1) σ)
    through_sigma = centred * (d * centred).sum(-1, keepdims=True)
    d_centred = d / s - through_sigma / (s * s * (centred.shape[-1] - 1) * sigma)
    return d_centred - d_centred.mean(-1, keepdims=True)          # through centred = x - mean(x)
def film_forward(h, gamma, beta):
    """FiLM (Perez et al. 2018), the outside of Eq. (3): γ ∘ h + β. h (n, H); γ, β (n, H) or
    (1, H): one style for the whole batch."""
    return gamma * h + beta, (h, gamma)
def film_backward(d, cache):
    h, gamma = cache
    if len(gamma) < len(h):                     # one γ, β for the batch: sum over the rows
        return d * gamma, (d * h).sum(0, keepdims=True), d.sum(0, keepdims=True)
    return d * gamma, d * h, d
def expert_forward(x, alpha, W, b):
    """The gated expert layer (Sec. 4.1), plain: W = Σ_k α_k W_k per sample, then x W. x (n, I),
    α (n, K), W (K, I, O), b (K, O) -> (n, O). (The package skips the blend: 4-8x faster.)"""
    K, I, O = W.shape
    blend = (alpha @ W.reshape(K, I * O)).reshape(-1, I, O)       # (n, I, O) each sample's W
    return np.matmul(x[:, None, :], blend)[:, 0] + alpha @ b, (x, alpha, W, b, blend)
def expert_backward(d, cache):                  # -> dx (n, I), dα (n, K), dW (K, I, O), db (K, O)
    x, alpha, W, b, blend = cache
    K, I, O = W.shape
    d_blend = (x[:, :, None] * d[:, None, :]).reshape(len(x), I * O)   # each sample's dW
    d_alpha = d_blend @ W.reshape(K, I * O).T + d @ b.T          # seen by each α_k: <dW, W_k>
    dx = np.matmul(blend, d[:, :, None])[..., 0]
    return dx, d_alpha, (alpha.T @ d_blend).reshape(K, I, O), alpha.T @ d
def conv1d_forward(x, W, b):
    """'Same' cross-correlation over time (as TF), x (n, T, C), W (width, C, filters) -> (n, T,
    filters), by im2col: each frame's window is one row, the convolution one product."""
    width, C, n_filters = W.shape
    n, T, _ = x.shape
    padded = np.pad(x, ((0, 0), (width // 2, width // 2), (0, 0)))
    cols = np.stack([padded[:, j:j + T] for j in range(width)], axis=2).reshape(n * T, width * C)
    out = (cols @ W.reshape(width * C, n_filters) + b).reshape(n, T, n_filters)
    return out, (cols, x.shape, W)
def conv1d_backward(d, cache):
    cols, (n, T, C), W = cache
    width, _, n_filters = W.shape
    d_rows = d.reshape(n * T, n_filters)
    d_cols = (d_rows @ W.reshape(width * C, n_filters).T).reshape(n, T, width, C)
    d_padded = np.zeros((n, T + width - 1, C), d.dtype)
    for j in range(width):                      # col2im: each window hands its gradient back
        d_padded[:, j:j + T] += d_cols[:, :, j]
    dW = (cols.T @ d_rows).reshape(width, C, n_filters)
    return d_padded[:, width // 2:width // 2 + T], dW, d_rows.sum(0)
def max_pool_forward(x):                        # pairs of frames: (n, T, C) -> (n, T // 2, C)
    end = x.shape[1] // 2 * 2                   # as the package: an odd last frame is dropped,
    even, odd = x[:, 0:end:2], x[:, 1:end:2]    # a tie goes to the first frame of the pair
    return np.maximum(even, odd), (x.shape, even >= odd)
def max_pool_backward(d, cache):
    shape, first_won = cache
    dx = np.zeros(shape, d.dtype)
    dx[:, 0:2 * first_won.shape[1]:2] = d * first_won
    dx[:, 1:2 * first_won.shape[1]:2] = d * ~first_won
    return dx

# ==== 2. Networks Ω, Ψ, Φ and the style model (Eq. 2-4); backward = forward steps reversed =====
# sizes named as the package's ModelConfig, and main()'s settings (the data gives x_dim, z_dim)
SMALL = dict(n_experts=4, hidden=128, gating_hidden=32, conv_filters=32, conv_kernel=9,
             film_dense=128, phase_dim=8,
             dropout=0.2,   # PAPER: 0.3; 0.2 keeps a 4x narrower network stepping (as the package)
             lr=5e-4,       # PAPER: 1e-4; a higher rate so that a few minutes train something
             epochs=30)     # PAPER: 90; at 12 (seed 0) Neutral's walk froze after a stride
PAPER = dict(n_experts=8, hidden=512, gating_hidden=32,          # Sec. 4.3: Φ and Ω
             conv_filters=256, conv_kernel=25, film_dense=2048,  # Sec. 4.3: Ψ
             dropout=0.3, lr=1e-4, epochs=90,                    # Sec. 4.3: training
             phase_dim=8, x_dim=348, z_dim=342, clip_channels=300,   # Sec. 4.1.4, Sec. 3.2
             clip_frames=240)      # Sec. 3.2: y ∈ R^{240×300}, 4 s of 60 fps capture
TABLE_2 = {"Φ + Ω (A.S.N.)": 4_935_928, "Ψ (S.M.N.)": 35_668_530}   # Sec. 5.2.1, LPN FiLM
def param_shapes(cfg):                          # {name: (shape, fan_in, fan_out)}; a bias: 0, 0
    K, H, n_filters = cfg["n_experts"], cfg["hidden"], cfg["conv_filters"]
    gate = [cfg["phase_dim"], cfg["gating_hidden"], cfg["gating_hidden"], K]
    motion = [cfg["x_dim"], H, H, cfg["z_dim"]]
    shapes = {}
    for layer in range(3):
        for net, widths, experts in [("omega", gate, ()), ("phi", motion, (K,))]:
            fan_in, fan_out = widths[layer:layer + 2]
            shapes[f"{net}.W{layer}"] = ((*experts, fan_in, fan_out), fan_in, fan_out)
            shapes[f"{net}.b{layer}"] = ((*experts, fan_out), 0, 0)
    flat = cfg["clip_frames"] // 4 * n_filters                   # frames after two poolings
    width = cfg["conv_kernel"]
    for name, shape in [("conv0", (width, cfg["clip_channels"], n_filters)),
                        ("conv1", (width, n_filters, n_filters)),
                        ("dense0", (flat, cfg["film_dense"])),
                        ("dense1", (cfg["film_dense"], 4 * H))]:
        fan_out = shape[-1] * (width if name.startswith("conv") else 1)    # TF's conv fans
        shapes[f"psi.{name}_W"] = (shape, int(np.prod(shape[:-1])), fan_out)
        shapes[f"psi.{name}_b"] = ((shape[-1],), 0, 0)
    return shapes
def init_params(cfg, rng, dtype=np.float32):
    """Glorot-uniform weights, zero biases; γ's biases 1: FiLM starts near the identity."""
    params = {}
    for name, (shape, fan_in, fan_out) in param_shapes(cfg).items():
        params[name] = np.zeros(shape, dtype)
        if fan_in > 0:                          # a weight
            limit = np.sqrt(6.0 / (fan_in + fan_out)).astype(dtype)
            params[name] = rng.uniform(-1, 1, shape).astype(dtype) * limit
    H = cfg["hidden"]
    params["psi.dense1_b"][0:H] = 1.0                            # γ1 (the layout: γ1, β1, γ2, β2)
    params["psi.dense1_b"][2 * H:3 * H] = 1.0                    # γ2
    return params
def omega_forward(params, p, drop):
    """Ω, the gating network (Sec. 4.1): local phases p (n, 8) -> expert weights α (n, K); three
    dense layers, dropout before each; ELU, ELU, softmax."""
    h, caches = p, []
    for layer, activation in enumerate([elu_forward, elu_forward, softmax_forward]):
        h, c_drop = dropout_forward(h, f"gating{layer}", drop)
        h, c_lin = linear_forward(h, params[f"omega.W{layer}"], params[f"omega.b{layer}"])
        h, c_act = activation(h)
        caches.append((c_drop, c_lin, c_act))
    return h, caches
def omega_backward(d, caches, grads):           # d: dα -> dp
    for layer, act_backward in [(2, softmax_backward), (1, elu_backward), (0, elu_backward)]:
        c_drop, c_lin, c_act = caches[layer]
        d, dW, db = linear_backward(act_backward(d, c_act), c_lin)
        grads[f"omega.W{layer}"], grads[f"omega.b{layer}"] = dW, db
        d = dropout_backward(d, c_drop)
    return d
def psi_forward(params, clip, drop):
    """Ψ, the FiLM generator (Eq. 2): style clips (M, T, C) -> [γ1, β1, γ2, β2] (M, 4H). Two blocks
    conv1d -> ReLU -> max-pool, flatten (time-major), dense -> ReLU, dense. PAPER: dropout 0.3
    "everywhere" (Sec. 4.3); Ψ's one dropout is before its last dense layer, as in the package and
    the original code (Ω and Φ have one before every layer)."""
    h, blocks = clip, []
    for layer in (0, 1):
        h, c_conv = conv1d_forward(h, params[f"psi.conv{layer}_W"], params[f"psi.conv{layer}_b"])
        h, c_relu = relu_forward(h)
        h, c_pool = max_pool_forward(h)
        blocks.append((c_conv, c_relu, c_pool))
    pooled_shape = h.shape                                       # (M, T // 4, filters)
    flat = h.reshape(len(h), -1)
    h, c_dense0 = linear_forward(flat, params["psi.dense0_W"], params["psi.dense0_b"])
    h, c_relu = relu_forward(h)
    h, c_drop = dropout_forward(h, "film_dense", drop)
    film, c_dense1 = linear_forward(h, params["psi.dense1_W"], params["psi.dense1_b"])
    return film, (blocks, pooled_shape, c_dense0, c_relu, c_drop, c_dense1)
def psi_backward(d_film, cache, grads):
    blocks, pooled_shape, c_dense0, c_relu, c_drop, c_dense1 = cache
    d, grads["psi.dense1_W"], grads["psi.dense1_b"] = linear_backward(d_film, c_dense1)
    d = relu_backward(dropout_backward(d, c_drop), c_relu)
    d, grads["psi.dense0_W"], grads["psi.dense0_b"] = linear_backward(d, c_dense0)
    d = d.reshape(pooled_shape)
    for layer in (1, 0):
        c_conv, c_relu, c_pool = blocks[layer]
        d = relu_backward(max_pool_backward(d, c_pool), c_relu)
        d, grads[f"psi.conv{layer}_W"], grads[f"psi.conv{layer}_b"] = conv1d_backward(d, c_conv)
    return d
def phi_forward(params, x, alpha, film, drop):
    """Φ: x (n, x_dim), α (n, K), film (n or 1, 4H) -> ẑ (n, z_dim). Hidden layer i = 1, 2 is
    Eq. (3), h(i) = ELU(γ(i) ∘ LN(F(i)) + β(i)): the paper's F(i), the layer's features, is the
    gated experts on h(i-1); the output layer is gated experts alone; dropout before each layer."""
    gammas_betas = np.split(film, 4, axis=1)                      # [γ1, β1, γ2, β2]
    h, caches = x, []
    for layer in (0, 1):
        gamma, beta = gammas_betas[2 * layer:2 * layer + 2]
        h, c_drop = dropout_forward(h, f"motion{layer}", drop)
        feats, c_exp = expert_forward(h, alpha, params[f"phi.W{layer}"], params[f"phi.b{layer}"])
        normed, c_norm = layer_norm_forward(feats)                # (F(i) - μ) / σ
        modulated, c_film = film_forward(normed, gamma, beta)     # γ ∘ · + β
        h, c_elu = elu_forward(modulated)                         # h(i)
        caches.append((c_drop, c_exp, c_norm, c_film, c_elu))
    h, c_drop = dropout_forward(h, "motion2", drop)
    z, c_exp = expert_forward(h, alpha, params["phi.W2"], params["phi.b2"])
    return z, (caches, c_drop, c_exp)
def phi_backward(dz, cache, grads):             # -> dx, dα, d_film
    caches, c_drop, c_exp = cache
    d, d_alpha, grads["phi.W2"], grads["phi.b2"] = expert_backward(dz, c_exp)
    d, d_film = dropout_backward(d, c_drop), []
    for layer in (1, 0):
        c_drop, c_exp, c_norm, c_film, c_elu = caches[layer]
        d, d_gamma, d_beta = film_backward(elu_backward(d, c_elu), c_film)
        d, d_alpha_layer, dW, db = expert_backward(layer_norm_backward(d, c_norm), c_exp)
        grads[f"phi.W{layer}"], grads[f"phi.b{layer}"] = dW, db
        d = dropout_backward(d, c_drop)
        d_alpha = d_alpha + d_alpha_layer
        d_film = [d_gamma, d_beta] + d_film
    return d, d_alpha, np.concatenate(d_film, axis=1)
def model_forward(params, x, p, clip, drop=None):
    """Eq. (4), ẑ = Φ(x; Ω(p), Ψ(y)): x (n, x_dim), p (n, 8), clip (n or 1, T, C) -> (n, z_dim)."""
    alpha, c_omega = omega_forward(params, p, drop)
    film, c_psi = psi_forward(params, clip, drop)
    z, c_phi = phi_forward(params, x, alpha, film, drop)
    return z, (c_omega, c_psi, c_phi)
def model_backward(dz, cache):                  # -> ({name: gradient}, dx, dp, d_clip)
    c_omega, c_psi, c_phi = cache
    grads = {}
    dx, d_alpha, d_film = phi_backward(dz, c_phi, grads)
    dp = omega_backward(d_alpha, c_omega, grads)
    return grads, dx, dp, psi_backward(d_film, c_psi, grads)

# ==== 3. Training: L = L_mse + L_bll (Eq. 5-7) on one-style minibatches, and Adam ==============
def mse_loss(pred, target):
    """Eq. (5) on one minibatch (one style): the mean of (z - ẑ)² over the samples and the features.
    PAPER: Eq. (5) sums over the features; the mean, as the package and the original code, weighs
    L_mse z_dim times less against L_bll (a mean over bones). -> loss, d_pred."""
    diff = pred - target
    return float(np.mean(diff * diff)), (2.0 / diff.size) * diff
def bone_length_loss(pred, target, pos_cols, parents, z_mean, z_std):
    """Eq. (6)-(7): the mean over samples and bones of | ‖z_bp - z_b‖ - ‖ẑ_bp - ẑ_b‖ |; pos_cols
    (J, 3) each joint's columns in z, parents (J,), -1 for the root; positions in metres."""
    child = np.nonzero(parents >= 0)[0]
    parent, std, mean = parents[child], z_std[pos_cols], z_mean[pos_cols]
    pos_hat = pred[:, pos_cols] * std + mean                     # (n, J, 3)
    pos = target[:, pos_cols] * std + mean
    bone_hat = pos_hat[:, parent] - pos_hat[:, child]
    len_hat = np.linalg.norm(bone_hat, axis=-1)
    diff = np.linalg.norm(pos[:, parent] - pos[:, child], axis=-1) - len_hat
    unit = bone_hat / np.where(len_hat > 0, len_hat, np.inf)[..., None]   # 0 for a zero bone
    d_bone = unit * (-np.sign(diff) / diff.size)[..., None]      # d|diff| / d‖v̂‖ = -sign(diff)
    d_pos = np.zeros_like(pos_hat)
    np.add.at(d_pos, (slice(None), parent), d_bone)
    np.add.at(d_pos, (slice(None), child), -d_bone)
    d_pred = np.zeros_like(pred)
    d_pred[:, pos_cols] = d_pos * std
    return float(np.mean(np.abs(diff))), d_pred
def adam_step(params, grads, state, lr, beta1=0.9, beta2=0.999, eps=1e-8):
    """Adam (Kingma & Ba 2014), in place on params; state = {"t": 0, "m": {}, "v": {}}."""
    state["t"] += 1
    for name, grad in grads.items():
        m = state["m"][name] = beta1 * state["m"].get(name, 0.0) + (1 - beta1) * grad
        v = state["v"][name] = beta2 * state["v"].get(name, 0.0) + (1 - beta2) * grad * grad
        m[np.abs(m) < 1e-30] = 0.0    # a dead unit's m decays to subnormals, slow on many CPUs
        m_hat = m / (1 - beta1 ** state["t"])
        v_hat = v / (1 - beta2 ** state["t"])
        params[name] -= lr * m_hat / (np.sqrt(v_hat) + eps)

# ==== 4. Local phases (Sec. 4.1): contacts, sources, a per-frame sinusoid fit, Eq. (1) =========
def foot_contacts(toes, fps):
    """Sec. 4.1.2: toes (T, 2, 3) [right, left] -> (T, 2) 1 when slow (|v| ≤ 0.15 m/s) AND near
    the floor (≤ 0.01 m). PAPER: the paper does not say where the floor is (the original: y = 0);
    here, as the package, the slow samples' median height. PAPER: the paper does not smooth the
    labels; as the original and the package, a majority vote over 11 frames (at 60 fps) does."""
    vel = np.diff(toes, axis=0, prepend=toes[:1]) * fps
    vel[0] = vel[1]                             # backward differences; frame 0 copies frame 1
    height = toes[..., 1]
    slow = np.linalg.norm(vel, axis=-1) <= 0.15
    enough = slow.sum() >= max(1, 0.02 * height.size)
    floor = np.median(height[slow]) if enough else np.percentile(height, 2.0)
    raw = (slow & (np.abs(height - floor) <= 0.01)).astype(float)
    half = int(np.floor(10 / 60 * fps / 2 + 0.5))
    out = raw.copy()
    for k in range(len(raw)):
        votes = raw[max(k - half, 0):k + half + 1]
        margin = 2 * votes.sum(0) - len(votes)  # for minus against; a tie keeps the raw value
        out[k] = np.where(margin > 0, 1.0, np.where(margin < 0, 0.0, raw[k]))
    return out
def pca_source(local, facing=(0.0, 0.0, 1.0)):
    """Sec. 4.1.3: hips-local positions (T, 3), centred, on their first principal component,
    directed forward (as the package, one exactly sideways by its x)."""
    centred = local - local.mean(0)
    pc1 = np.linalg.eigh(centred.T @ centred / (len(centred) - 1))[1][:, -1]   # largest
    along = pc1 @ np.asarray(facing)
    return centred @ (-pc1 if along < 0 or (along == 0 and pc1[0] <= 0) else pc1)
def butterworth(x, fps, cutoff=4.0):            # 2nd-order zero-phase low-pass along axis 0
    if len(x) <= 1:
        return x.copy()
    sos = butter(2, min(cutoff, 0.4 * fps) / (fps / 2), output="sos")
    return sosfiltfilt(sos, x, axis=0, padtype="constant", padlen=min(9, len(x) - 1))
def preprocess_source(g, fps):
    """Sec. 4.1.4: normalise in a 1 s window (each frame by its window's mean and std, ends
    repeated; a still window divides by 1), low-pass at 4 Hz, and set values under 1e-3 to 0."""
    half = int(np.floor(fps / 2 + 0.5))
    windows = np.lib.stride_tricks.sliding_window_view(np.pad(g, half, mode="edge"), 2 * half + 1)
    std = np.where(windows.std(1) < 1e-6, 1.0, windows.std(1))
    v = butterworth((g - windows.mean(1)) / std, fps)
    v[np.abs(v) < 1e-3] = 0.0
    return v
FREQUENCIES = np.geomspace(0.25, 4.0, 48)       # Hz: the frequency grid of the fit
def sinusoid_basis(tau, freqs, fps):            # (G, E, 3): [sin 2πfτ, cos 2πfτ, 1], τ in frames
    angle = (2 * np.pi / fps) * tau[None, :] * freqs[:, None]
    return np.stack([np.sin(angle), np.cos(angle), np.ones_like(angle)], axis=-1)
def solve_window(basis, w, y, vmin, vmax):
    """Weighted least squares of y ≈ s·sin(2π freq τ) + c·cos(2π freq τ) + offset, a 3x3 system
    per candidate freq; basis (G, E, 3), w and y (E,). As the original: offset in [vmin, vmax]
    (else clipped), amp = |(s, c)| ≤ vmax - vmin. -> coef (G, 3) = (s, c, offset), errors (G,)."""
    weighted = basis.transpose(0, 2, 1) * w
    gram = weighted @ basis                     # XᵀWX; then XᵀWy
    rhs = weighted @ y
    gram += (1e-10 * np.trace(gram, axis1=1, axis2=2) + 1e-300)[:, None, None] * np.eye(3)
    coef = np.linalg.solve(gram, rhs[..., None])[..., 0]         # (a ridge, as the package)
    yy = np.sum(w * y * y)
    sse = yy - np.sum(coef * rhs, axis=1)
    amp_max = vmax - vmin
    too_big = coef[:, 0] ** 2 + coef[:, 1] ** 2 > amp_max ** 2
    bad = (coef[:, 2] < vmin) | (coef[:, 2] > vmax) | too_big
    could_win = sse < np.min(sse[~bad], initial=np.inf)          # as the package: only these
    for i in np.nonzero(bad & could_win)[0]:
        offset = np.clip(coef[i, 2], vmin, vmax)
        if offset != coef[i, 2]:
            coef[i, :2] = np.linalg.solve(gram[i, :2, :2], rhs[i, :2] - gram[i, :2, 2] * offset)
        coef[i, :2] *= min(1.0, amp_max / max(np.hypot(coef[i, 0], coef[i, 1]), 1e-300))
        coef[i, 2] = offset
        sse[i] = yy - 2 * coef[i] @ rhs[i] + coef[i] @ gram[i] @ coef[i]
    return coef, sse
def fit_window(k, v, half, width):
    """Frame k's fit: `width` data frames around k (shifted inwards at the ends), `half` frames
    each side pulling towards the neighbours' fits, weight (1 - i/half)². -> None if still, else
    τ (offsets from k), is_data, the frames (clamped), weights, vmin, vmax (bounds)."""
    n_frames = len(v)
    first = min(max(k - half, 0), n_frames - width)
    if np.abs(v[first:first + width]).sum() < 1e-3:
        return None
    frames = np.arange(first - half, first + width + half)
    is_data = (frames >= first) & (frames < first + width)
    outside = np.where(frames < first, first - frames, frames - first - width + 1)
    near = np.where(is_data, 0.0, (1 - outside / half) ** 2) * ((frames >= 0) & (frames < n_frames))
    looked_at = v[max(first - half, 0):first + width + half]
    return (frames - k, is_data, np.clip(frames, 0, n_frames - 1), is_data + near,
            looked_at.min(), looked_at.max())
def fit_sinusoids(v, fps, sweeps=3):
    """Sec. 4.1.4: around every frame k, fit amp·sin(2π(freq·τ + phase)) + offset, τ = t - t_k,
    to the source v (T,) over 0.5 s, the neighbours' fits of the previous sweep pulling at the
    edges (sweep 0: the data alone). Per frame a grid of frequencies, then a parabola through the
    best three. The paper's a·sin(f t - s) + b is the same curve: a = amp, f = 2π freq (rad/s),
    b = offset, s = 2π(freq t_k - phase); its φ = (f t - s) mod 2π is 2π phase at t = t_k.
    PAPER: a genetic algorithm fits it; this (as the package) minimises the same loss
    deterministically, so a run can be repeated. -> amp, freq (Hz), phase (cycles), each (T,)."""
    n_frames, half = len(v), max(1, int(np.floor(fps / 4 + 0.5)))
    width = min(2 * half + 1, n_frames)         # 0.5 s of data, as the original
    log_freqs = np.log(FREQUENCIES)
    all_tau = np.arange(-width - 2 * half, width + 2 * half + 1)   # every offset a window uses
    grid_basis = sinusoid_basis(all_tau, FREQUENCIES, fps)
    windows = [fit_window(k, v, half, width) for k in range(n_frames)]   # the same every sweep
    fitted = np.zeros(n_frames)
    for sweep in range(sweeps):
        coef, freq = np.zeros((n_frames, 3)), np.zeros(n_frames)
        for k, window in enumerate(windows):
            if window is None:                  # skipped: all parameters 0
                continue
            tau, is_data, frames, weights, vmin, vmax = window
            w = weights if sweep else is_data * 1.0
            y = np.where(is_data, v[frames], fitted[frames])       # data, then neighbours' fits
            grid_coef, sse = solve_window(grid_basis[:, tau - all_tau[0]], w, y, vmin, vmax)
            best, shift = np.argmin(sse), 0.0   # shift: the parabola's minimum, in grid steps
            if 0 < best < len(sse) - 1 and sse[best - 1] - 2 * sse[best] + sse[best + 1] > 0:
                curvature = sse[best - 1] - 2 * sse[best] + sse[best + 1]
                shift = np.clip(0.5 * (sse[best - 1] - sse[best + 1]) / curvature, -1, 1)
            f = np.exp(log_freqs[best] + shift * (log_freqs[1] - log_freqs[0]))
            refined_basis = sinusoid_basis(tau, np.array([f]), fps)
            refined_coef, refined_sse = solve_window(refined_basis, w, y, vmin, vmax)
            if refined_sse[0] < sse[best]:
                coef[k], freq[k] = refined_coef[0], f
            else:
                coef[k], freq[k] = grid_coef[best], FREQUENCIES[best]
        fitted = coef[:, 1] + coef[:, 2]        # each curve at its own frame: τ = 0
    amp = np.hypot(coef[:, 0], coef[:, 1])
    phase = np.mod(np.arctan2(coef[:, 1], coef[:, 0]) / (2 * np.pi), 1.0)
    phase[(amp == 0) | (phase >= 1.0)] = 0.0
    # PAPER: f_i is the fit's own (Sec. 4.1.4), as in the original code. 0.5 s pins the phase down
    # better than the frequency, so here (as the package) freq is re-read as the slope of the
    # unwrapped phase over the second around each frame (all of it fitted). Only the amplitude's
    # window (local_phases) reads it; the phase is the fit's.
    second = int(round(fps / 2))
    cycles, t = np.unwrap(2 * np.pi * phase) / (2 * np.pi), np.arange(n_frames) / fps
    for k in range(second, n_frames - second if second >= 1 else 0):
        around = slice(k - second, k + second + 1)
        if np.all(amp[around] > 0):
            tc = t[around] - t[around].mean()
            freq[k] = np.clip(tc @ cycles[around] / (tc @ tc), FREQUENCIES[0], FREQUENCIES[-1])
    return amp, freq, phase
SLOTS = ("left hand", "right hand", "left foot", "right foot")
CONTACT_COLUMN = {"left foot": 1, "right foot": 0}       # contacts are [right, left]
def local_phases(pos, rot, fps, hips, bones, contacts, sources=("pca", "pca", "contact", "contact"),
                 facing=(0.0, 0.0, 1.0)):
    """Sec. 4.1: pos (T, J, 3), rot (T, J, 3, 3) world; hips, bones (4) joints; a 'pca' or
    'contact' source per slot. -> phase (T, 4) cycles, amplitude (T, 4): Eq. (1)'s ‖v_w‖·a, the
    fitted amp times the bone's largest hips-relative speed. PAPER: the paper does not smooth
    them; the original code low-passes both (4 Hz Butterworth, phase as (sin, cos)), as here."""
    local = np.einsum("tji,tbj->tbi", rot[:, hips], pos[:, bones] - pos[:, hips, None])   # hips'
    speed = np.linalg.norm(np.diff(local, axis=0, prepend=local[:1]), axis=-1) * fps
    speed[0] = speed[1]
    n_frames = len(pos)
    phase, amplitude = np.zeros((n_frames, 4)), np.zeros((n_frames, 4))
    for slot, (name, kind) in enumerate(zip(SLOTS, sources)):
        if kind == "contact":
            g = contacts[:, CONTACT_COLUMN[name]]
        else:
            g = pca_source(local[:, slot], facing)
        amp, freq, fitted_phase = fit_sinusoids(preprocess_source(np.asarray(g, float), fps), fps)
        period = np.where(freq > 0, np.floor(fps / np.where(freq > 0, freq, 1) + 0.5), 0)
        half = (period // 2).astype(int)
        for k in range(n_frames):
            # PAPER: ‖v_w‖ "over a one second window"; here, as the original code and the
            # package, over one fitted period around k (shifted inwards at the ends).
            first = min(max(k - half[k], 0), max(n_frames - 1 - 2 * half[k], 0))
            amp[k] *= speed[first:first + 2 * half[k] + 1, slot].max()
        angle = 2 * np.pi * fitted_phase
        sin_cos = butterworth(np.stack([np.sin(angle), np.cos(angle)], 1), fps)
        phase[:, slot] = np.mod(np.arctan2(sin_cos[:, 0], sin_cos[:, 1]) / (2 * np.pi), 1.0)
        zero = np.hypot(sin_cos[:, 0], sin_cos[:, 1]) == 0
        phase[zero | (phase[:, slot] >= 1.0), slot] = 0.0
        amplitude[:, slot] = np.maximum(butterworth(amp, fps), 0.0)
    return phase, amplitude
def phase_vectors(phase, amplitude):            # Eq. (1): amp (sin 2πφ, cos 2πφ), s0 c0 s1 c1 ...
    angle = 2 * np.pi * phase
    return np.stack([amplitude * np.sin(angle), amplitude * np.cos(angle)], -1).reshape(-1, 8)

# ==== 5. Data: BVH files -> world transforms -> x, z and style clips (Sec. 3.2) ================
def read_bvh(path, scale=0.01):
    """-> joint names (End Sites named after their parent + "Site"), parents, world positions
    (T, J, 3) in metres (scale: from centimetres), world rotations (T, J, 3, 3), fps."""
    tokens, i = Path(path).read_text().split(), 0
    names, parents, offsets, channels, stack = [], [], [], [], []
    while tokens[i] != "MOTION":
        if tokens[i] in ("ROOT", "JOINT", "End"):
            names.append(names[stack[-1]] + "Site" if tokens[i] == "End" else tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            channels.append([])
        elif tokens[i] == "{":
            stack = stack + [len(names) - 1]
        elif tokens[i] == "}":
            stack = stack[:-1]
        elif tokens[i] == "OFFSET":
            offsets.append([float(t) for t in tokens[i + 1:i + 4]])
        elif tokens[i] == "CHANNELS":
            channels[-1] = tokens[i + 2:i + 2 + int(tokens[i + 1])]
        i += 1
    n_frames, fps = int(tokens[i + 2]), 1.0 / float(tokens[i + 5])   # Frames: T Frame Time: dt
    values = np.array(tokens[i + 6:], dtype=float).reshape(n_frames, -1)
    pos = np.tile(np.array(offsets) * scale, (n_frames, 1, 1))      # local, made world below
    rot = np.tile(np.eye(3), (n_frames, len(names), 1, 1))
    col = 0                                     # the first value column of joint j
    for j, joint_channels in enumerate(channels):
        for k, channel in enumerate(joint_channels):   # position channels replace the offset
            if channel.endswith("position"):
                pos[:, j, "XYZ".index(channel[0])] = values[:, col + k] * scale
        rot_k = [k for k, channel in enumerate(joint_channels) if channel.endswith("rotation")]
        if rot_k:                               # intrinsic rotations in the channels' order
            order = "".join(joint_channels[k][0] for k in rot_k)
            euler = values[:, [col + k for k in rot_k]]
            rot[:, j] = Rotation.from_euler(order, euler, degrees=True).as_matrix()
        col += len(joint_channels)
    for j, parent in enumerate(parents):        # forward kinematics, parents first; roots stay
        if parent >= 0:
            pos[:, j] = pos[:, parent] + np.einsum("tij,tj->ti", rot[:, parent], pos[:, j])
            rot[:, j] = rot[:, parent] @ rot[:, j]
    return names, np.array(parents), pos, rot, fps
HIPS = "Hips"                                   # the 100STYLE skeleton's names
TOE_TIPS = ("RightToeSite", "LeftToeSite")
PHASE_BONES = ("LeftWristSite", "RightWristSite", "LeftToe", "RightToe")
# PAPER: "every 10 frames for 1 second in the future and past" (Sec. 3.2). As the original code
# and the package, the past is 1/6 s (10 frames at 60 fps) apart and the future 0.2 s (12 frames):
# the released network was trained so.
TRAJECTORY_SECONDS = np.array([-1, -5 / 6, -4 / 6, -3 / 6, -2 / 6, -1 / 6, 0,
                               0.2, 0.4, 0.6, 0.8, 1.0])
FUTURE = 6                                      # the first future sample (0 s included)
def to_root(v, root_rot, root_pos=None):        # world points or directions -> root frame
    return np.einsum("tji,t...j->t...i", root_rot, v if root_pos is None else v - root_pos[:, None])
def features(pos, rot, fps, hips, joints, p, contacts):
    """As minifilm/features/layout.py: x (n, 48 + 12J), z (n, 24 + 12J + 18) for frames 1 .. T-2,
    clip frames (T, 12J). The root: the hips on the floor, facing the hips' +z. z: the next
    frame's future trajectory and joints in the current root's frame, phases p, their change,
    contacts."""
    n_frames = len(pos)
    facing = rot[:, hips, :, 2] * [1, 0, 1]
    facing /= np.linalg.norm(facing, axis=1, keepdims=True)
    up = np.tile([0.0, 1, 0], (n_frames, 1))
    root_rot = np.stack([np.cross([0, 1, 0], facing), up, facing], -1)    # columns: x, y, z
    root_pos = pos[:, hips] * [1, 0, 1]
    vel = np.diff(pos, axis=0, prepend=pos[:1]) * fps
    vel[0] = vel[1]

    def joint_block(frames, root):              # (n, 12 J): [position, forward, up, velocity]
        parts = [to_root(pos[frames][:, joints], root_rot[root], root_pos[root]),
                 to_root(rot[frames][:, joints][..., 2], root_rot[root]),
                 to_root(rot[frames][:, joints][..., 1], root_rot[root]),
                 to_root(vel[frames][:, joints], root_rot[root])]
        return np.concatenate(parts, -1).reshape(len(frames), -1)

    def trajectory(frames, root):               # (n, 48)
        offsets = np.round(TRAJECTORY_SECONDS * fps).astype(int)
        # the package (as the original code) reflects samples past a file's ends; clamped here
        at = np.clip(frames[:, None] + offsets, 0, n_frames - 1)
        where = to_root(root_pos[at], root_rot[root], root_pos[root])
        heading = to_root(root_rot[at][..., 2], root_rot[root])
        samples = np.concatenate([where[..., [0, 2]], heading[..., [0, 2]]], -1)
        return samples.reshape(len(frames), -1)

    now, every = np.arange(1, n_frames - 1), np.arange(n_frames)
    x = np.concatenate([trajectory(now, now), joint_block(now, now)], 1)
    z = np.concatenate([trajectory(now + 1, now)[:, 4 * FUTURE:], joint_block(now + 1, now),
                        p[now + 1], p[now + 1] - p[now], contacts[now + 1]], 1)
    return x, p[now], z, joint_block(every, every)

# ==== 6. Gradient check: every backward pass against centred differences, in float64 ===========
def numerical_gradient(f, x, h=3e-4):
    """(8 (f(x + h) - f(x - h)) - (f(x + 2h) - f(x - 2h))) / 12h for every entry of x: four points,
    error ~h⁴ (two points: ~h², which cannot reach 1e-7 on the model; as the package's
    minifilm/nn/gradcheck.py, which says how h was chosen)."""
    grad = np.zeros_like(x)
    for i in np.ndindex(x.shape):
        old, f_at = x[i], []
        for step in (h, -h, 2 * h, -2 * h):
            x[i] = old + step
            f_at.append(f())
        x[i] = old
        grad[i] = (8 * (f_at[0] - f_at[1]) - (f_at[2] - f_at[3])) / (12 * h)
    return grad
def rel_error(a, b):                            # per entry |a - b| / (|a| + |b|) (as CS231n), the
    return float(np.max(np.abs(a - b) / np.maximum(1e-8, np.abs(a) + np.abs(b))))   # worst one
def spread(shape, rng):                         # distinct values, none near 0: the stencil never
    n = int(np.prod(shape))                     # crosses ReLU's kink or a max-pool tie
    return ((rng.permutation(n) - n / 2 + 0.25) * 4 / n).reshape(shape)
def check_layer(forward, backward, shapes, rng):
    inputs = [spread(shape, rng) for shape in shapes]
    out, cache = forward(*inputs)
    cotangent = rng.standard_normal(out.shape)  # L = Σ out ∘ cotangent, so d_out = cotangent
    grads = backward(cotangent, cache)
    grads = grads if isinstance(grads, tuple) else (grads,)
    loss = lambda: np.sum(forward(*inputs)[0] * cotangent)      # noqa: E731
    return max(rel_error(g, numerical_gradient(loss, x)) for x, g in zip(inputs, grads))
def check_model(seed=0):
    """L_mse + L_bll of Ω + Φ + Ψ at toy sizes, with dropout (fixed masks) and one style clip for
    the batch, as trained below: every parameter, x, p and the clip. One fixed draw: its ELU and
    ReLU inputs, max-pool pairs and bone errors lie >= 5e-3 from their kinks, 8x the stencil's
    reach; a draw within reach measures the kink, not the backward pass (the package's suite
    moves its draws away from kinks: minifilm/evaluation/gradcheck_problem.py)."""
    rng = np.random.default_rng(seed)
    cfg = dict(x_dim=7, z_dim=14, phase_dim=8, n_experts=3, hidden=6, gating_hidden=5,
               clip_frames=10, clip_channels=4, conv_filters=3, conv_kernel=3, film_dense=7)
    params = {name: a + 0.1 * rng.standard_normal(a.shape)
              for name, a in init_params(cfg, rng, np.float64).items()}
    x, p, clip, z = (rng.standard_normal(shape) for shape in [(4, 7), (4, 8), (1, 10, 4), (4, 14)])
    pos_cols = np.arange(12).reshape(4, 3)
    bones = (pos_cols, np.array([-1, 0, 1, 1]), rng.standard_normal(14), 0.5 + rng.random(14))
    drop = {"rate": 0.2, "masks": {}, "rng": rng}

    def loss():
        z_hat, cache = model_forward(params, x, p, clip, drop)
        l_mse, d_mse = mse_loss(z_hat, z)
        l_bll, d_bll = bone_length_loss(z_hat, z, *bones)
        return l_mse + l_bll, d_mse + d_bll, cache
    grads, dx, dp, d_clip = model_backward(*loss()[1:])
    grads, arrays = dict(grads, x=dx, p=dp, clip=d_clip), dict(params, x=x, p=p, clip=clip)
    return {name: rel_error(grads[name], numerical_gradient(lambda: loss()[0], a))
            for name, a in arrays.items()}
def gradient_check(seed=0, limit=1e-7):         # prints one row per check; True if all pass
    rng = np.random.default_rng(seed)
    drop = {"rate": 0.3, "masks": {}, "rng": rng}   # one mask, drawn on the first call
    layers = [("linear", linear_forward, linear_backward, [(4, 5), (5, 3), (3,)]),
              ("ELU", elu_forward, elu_backward, [(4, 5)]),
              ("ReLU", relu_forward, relu_backward, [(4, 5)]),
              ("softmax", softmax_forward, softmax_backward, [(4, 5)]),
              ("dropout", lambda x: dropout_forward(x, "d", drop), dropout_backward, [(4, 5)]),
              ("layer norm", layer_norm_forward, layer_norm_backward, [(4, 6)]),
              ("FiLM", film_forward, film_backward, [(4, 6), (4, 6), (4, 6)]),
              ("FiLM, one style", film_forward, film_backward, [(4, 6), (1, 6), (1, 6)]),
              ("gated experts", expert_forward, expert_backward,
               [(4, 5), (4, 3), (3, 5, 2), (3, 2)]),
              ("conv1d", conv1d_forward, conv1d_backward, [(2, 7, 3), (3, 3, 4), (4,)]),
              ("max-pool", max_pool_forward, max_pool_backward, [(2, 7, 3)])]
    rows = {name: check_layer(forward, backward, shapes, rng)
            for name, forward, backward, shapes in layers}
    rows.update({f"model: {name}": err for name, err in check_model(seed).items()})
    print(f"gradient check (float64, four-point differences; every entry passes under {limit:g}):")
    for name, err in rows.items():
        print(f"  {name:<20} {err:9.2e}  {'ok' if err < limit else 'FAIL'}")
    return all(err < limit for err in rows.values())

# ==== 7. Runtime (Sec. 4.4): frame after frame, the network's z becomes the next x ============
# One character, as the package's Controller with stand=None (the paper's loop). PAPER: no foot
# IK on the predicted contacts (Sec. 4.4; the package's is minifilm/motion/foot_ik.py). 2-vectors
# are floor (x, z) pairs. The root's frame R has the columns [right, up, facing]: world = R local.
def yaw(facing):                                # (2,) unit facing -> R (3, 3)
    return np.array([[facing[1], 0, facing[0]], [0, 1, 0], [-facing[0], 0, facing[1]]])
def turn(v, R):                                 # floor vectors (..., 2) -> R v (R.T: to local)
    return (np.insert(v, 1, 0.0, axis=-1) @ R.T)[..., ::2]
def unit(v, fallback):                          # v / |v| row by row; a zero row takes fallback's
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(length > 1e-8, v / np.maximum(length, 1e-8), fallback)
def runtime_start(x, p, fps):
    """A raw input frame x (x_dim,) and its phases p (8,) as a start: the root at the origin facing
    +z (x's root frame is the world's), x's pose and future trajectory, and the root's past frame
    by frame between x's past samples (as Controller.reset with start_x). -> the state, a dict."""
    trajectory = x[:48].reshape(12, 4)          # [pos x, pos z, dir x, dir z] per sample
    trajectory = np.concatenate([trajectory[:, :2], unit(trajectory[:, 2:], [0.0, 1])], 1)
    known = np.round(TRAJECTORY_SECONDS[:FUTURE + 1] * fps)       # -60, -50, .., -10, 0 frames
    past = np.stack([np.interp(np.arange(known[0], 0), known, trajectory[:FUTURE + 1, c])
                     for c in range(4)], 1)     # the root 60, 59, .., 1 frames ago (at 60 fps)
    pose = x[48:].reshape(-1, 4, 3)             # (J, [position, forward, up, velocity], 3)
    return dict(root=np.zeros(2), facing=np.array([0.0, 1]), past=past[:, :2],
                past_dir=unit(past[:, 2:], [0.0, 1]), future=trajectory[FUTURE:, :2],
                future_dir=trajectory[FUTURE:, 2:], pos=pose[:, 0], fwd=pose[:, 1],
                up=pose[:, 2], vel=pose[:, 3], p=np.array(p, float))
def runtime_step(params, stats, s, facing, velocity, film, fps):
    """One frame for the user's target facing (2,) and velocity (2,) m/s and a style's FiLM vector
    (1, 4H) (Sec. 4.4); stats: the (mean, std) of x, p and z. Advances the state s; -> z."""
    # 1. The user's trajectory blended into the future (Zhang et al. 2018): future sample k of 6
    #    moves 1 - (1 - k/5)^0.75 of the way to the user's, its direction 1 - (1 - k/5)^1.25.
    dt, w = np.mean(np.diff(TRAJECTORY_SECONDS[FUTURE:])), np.arange(6)[:, None] / 5   # dt 0.2 s
    to_user, to_face = 1 - (1 - w) ** 0.75, 1 - (1 - w) ** 1.25
    steps = (1 - to_user[1:]) * np.diff(s["future"], axis=0) + to_user[1:] * velocity * dt
    s["future"] = s["future"][0] + np.concatenate([np.zeros((1, 2)), np.cumsum(steps, 0)])
    s["future_dir"] = unit((1 - to_face) * s["future_dir"] + to_face * facing, s["future_dir"])
    # 2. x (Sec. 3.2): the root's past every 1/6 s and that future, then the last pose, all in the
    #    current root's frame
    R, back = yaw(s["facing"]), -np.round(TRAJECTORY_SECONDS[:FUTURE] * fps).astype(int)
    where = np.concatenate([s["past"][-back], s["future"]]) - s["root"]
    heading = np.concatenate([s["past_dir"][-back], s["future_dir"]])
    root = np.insert(s["root"], 1, 0.0)
    pose = np.stack([s["pos"] - root, s["fwd"], s["up"], s["vel"]], 1) @ R      # R^T v
    trajectory = np.concatenate([turn(where, R.T), turn(heading, R.T)], 1)     # (12, 4)
    x = np.concatenate([trajectory.ravel(), pose.ravel()])
    # 3. Eq. (4) with the style's FiLM vector, on normalised numbers
    (x_mean, x_std), (p_mean, p_std), (z_mean, z_std) = stats
    alpha = omega_forward(params, ((s["p"] - p_mean) / p_std)[None], None)[0]
    z = phi_forward(params, ((x - x_mean) / x_std)[None], alpha, film, None)[0][0] * z_std + z_mean
    # 4. z, read in the current root's frame: the next root and future, the next pose, the phases
    J, future = len(s["pos"]), z[:24].reshape(6, 4)
    new, new_dir = turn(future[:, :2], R) + s["root"], unit(turn(future[:, 2:], R), s["future_dir"])
    pos, s["fwd"], s["up"], s["vel"] = np.moveaxis(z[24:24 + 12 * J].reshape(J, 4, 3) @ R.T, 1, 0)
    # as the original demo: half the predicted position, half the last one moved by the velocity
    s["pos"] = 0.5 * (pos + root) + 0.5 * (s["pos"] + s["vel"] / fps)
    phase, update = z[24 + 12 * J:32 + 12 * J], z[32 + 12 * J:40 + 12 * J]
    s["p"] = 0.5 * phase + 0.5 * (s["p"] + update)    # the predicted phases and the advanced ones
    s["past"] = np.concatenate([s["past"][1:], s["root"][None]])
    s["past_dir"] = np.concatenate([s["past_dir"][1:], s["facing"][None]])
    kept = 0.15         # as the demo, the new future keeps 15 % of the blended one (not sample 0)
    s["future"] = np.concatenate([new[:1], (1 - kept) * new[1:] + kept * s["future"][1:]])
    mixed = (1 - kept) * new_dir[1:] + kept * s["future_dir"][1:]
    s["future_dir"] = np.concatenate([new_dir[:1], unit(mixed, new_dir[1:])])
    s["root"], s["facing"] = new[0], new_dir[0]
    return z

# ==== 8. Main: BVH files -> labels -> features -> one-style minibatches (Sec. 4.3) -> test MSE ==
HOP_LIFTED_FOOT = {"LeftHop": 3, "RightHop": 2}   # the slot of the foot a hopping style lifts
NEEDED = (HIPS, *TOE_TIPS, *PHASE_BONES)
def load_folder(folder, clip_seconds=2.0):
    """Label and featurise every <Style>_<Gait>.bvh in folder; each file's first 80 % of rows
    train, the rest test (the paper does not say; the original holds out a random 10 % window of
    each file for validation and another for test). PAPER: Sec. 3.2 adds the mirror of every
    symmetric style; nothing is mirrored here.
    -> {style: {"train": [x, p, z], "test": [x, p, z], "clips": (m, T, 12J)}}, joint parents."""
    data, errors = {}, []
    for path in sorted(Path(folder).glob("*.bvh")):
        style = path.stem.split("_")[0]
        names, parents, pos, rot, fps = read_bvh(path)
        at = {name: j for j, name in enumerate(names)}
        if any(name not in at for name in NEEDED):
            sys.exit(f"{path}: not on the 100STYLE skeleton (it needs {', '.join(NEEDED)})")
        contacts = foot_contacts(pos[:, [at[name] for name in TOE_TIPS]], fps)
        sources = ["pca", "pca", "contact", "contact"]
        if style in HOP_LIFTED_FOOT:            # a foot that never lands has no contact cycle
            sources[HOP_LIFTED_FOOT[style]] = "pca"
        bones = [at[name] for name in PHASE_BONES]
        phase, amplitude = local_phases(pos, rot, fps, at[HIPS], bones, contacts, sources)
        if path.with_suffix(".truth.npz").exists():   # the synthetic generator's true phases
            with np.load(path.with_suffix(".truth.npz"), allow_pickle=False) as truth:
                miss = np.abs(phase - truth["true_phase"]) % 1
                errors.append(np.minimum(miss, 1 - miss)[truth["phase_active"]])
        # PAPER: x 348, z 342 for 25 joints (Sec. 3.2); the package exports the wrists' End Sites
        # too, this file only the 23 joints with channels: x 324, z 318 here.
        joints = [j for j, name in enumerate(names) if not name.endswith("Site")]
        p = phase_vectors(phase, amplitude)
        x, p, z, frames = features(pos, rot, fps, at[HIPS], joints, p, contacts)
        cut = int(0.8 * len(x))
        T = int(round(clip_seconds * fps))      # PAPER: 240 frames, 4 s (Sec. 3.2); 2 s here
        style_data = data.setdefault(style, {"train": [], "test": [], "clips": [], "fps": fps})
        style_data["train"].append((x[:cut], p[:cut], z[:cut]))
        style_data["test"].append((x[cut:], p[cut:], z[cut:]))
        starts = range(0, cut - T + 1, T // 2)  # a clip every T / 2 frames
        style_data["clips"] += [frames[first:first + T] for first in starts]
    for style_data in data.values():
        for split in ("train", "test"):
            style_data[split] = [np.concatenate(a) for a in zip(*style_data[split])]
        style_data["clips"] = np.stack(style_data["clips"])
    if errors:
        error = np.median(np.concatenate(errors))
        print(f"[phases] median error against the generator's true phases: {error:.3f} cycles")
    feature_parents = [joints.index(parents[j]) if parents[j] in joints else -1 for j in joints]
    return data, np.array(feature_parents)
def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, help="a folder of <Style>_<Gait>.bvh (100STYLE skeleton)")
    ap.add_argument("--seconds", type=float, default=5.0, help="synthetic seconds per clip")
    ap.add_argument("--config", choices=["small", "paper"], default="small",
                    help="the sizes and training settings: SMALL or the PAPER's")
    ap.add_argument("--epochs", type=int, help="default: the config's")
    ap.add_argument("--lr", type=float, help="default: the config's")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    settings = {"small": SMALL, "paper": PAPER}[args.config]
    epochs = settings["epochs"] if args.epochs is None else args.epochs
    lr = settings["lr"] if args.lr is None else args.lr
    batch = 32                  # the paper gives none; the original's (minifilm/train/batches.py)
    start = time.perf_counter()
    if args.data is not None and not any(args.data.glob("*.bvh")):
        sys.exit(f"no .bvh files in {args.data}")
    if not gradient_check():
        sys.exit("the gradient check failed")
    # Ψ: no reading of the layers Sec. 4.3 describes gives Table 2's count (see the package's
    counts = dict.fromkeys(TABLE_2, 0)          # minifilm/model/film_generator.py)
    for name, (shape, _, _) in param_shapes(PAPER).items():
        counts["Ψ (S.M.N.)" if name.startswith("psi") else "Φ + Ω (A.S.N.)"] += int(np.prod(shape))
    for part, count in counts.items():
        print(f"[model] PAPER {part}: {count:,} parameters; Table 2: {TABLE_2[part]:,}")
    with tempfile.TemporaryDirectory() as tmp:  # the synthetic files live only as long as this
        if args.data is None:           # PAPER: 100STYLE is 60 fps (Sec. 3.1); 30 halves the work
            cmd = [sys.executable, str(Path(__file__).with_name("make_synthetic.py")), tmp,
                   "--seconds", str(args.seconds), "--fps", "30", "--gaits", "FW,FR,TR",
                   "--seed", str(args.seed)]
            made = subprocess.run(cmd, capture_output=True, text=True)
            if made.returncode != 0:
                sys.exit(f"{' '.join(cmd)} failed:\n{made.stderr}\n"
                         "Install minifilm (pip install -e .) or pass --data.")
            print("[data]", made.stdout.strip().splitlines()[-1])
        data, parents = load_folder(args.data or tmp)
    styles = sorted(data)
    print(f"[labels] {len(styles)} styles labelled ({time.perf_counter() - start:.0f} s so far)")

    # as the package: every column by the training rows' mean and std, clips by x's joint columns
    stats = []
    for rows in (np.concatenate([data[s]["train"][k] for s in styles]) for k in range(3)):  # x p z
        stats.append((rows.mean(0), np.where(rows.std(0) < 1e-6, 1, rows.std(0))))
    x_joints = slice(4 * len(TRAJECTORY_SECONDS), None)
    for style_data in data.values():
        for split in ("train", "test"):
            style_data[split] = [((a - mean) / std).astype(np.float32)
                                 for a, (mean, std) in zip(style_data[split], stats)]
        clips = (style_data["clips"] - stats[0][0][x_joints]) / stats[0][1][x_joints]
        style_data["clips"] = clips.astype(np.float32)
    _, T, C = data[styles[0]]["clips"].shape
    x_dim, z_dim = len(stats[0][0]), len(stats[2][0])
    z_joints = 4 * (len(TRAJECTORY_SECONDS) - FUTURE)             # z's joint block starts here
    pos_cols = z_joints + 12 * np.arange(len(parents))[:, None] + np.arange(3)
    bones = (pos_cols, parents, *stats[2])

    rng = np.random.default_rng(args.seed)
    config = dict(settings, x_dim=x_dim, z_dim=z_dim, clip_frames=T, clip_channels=C)
    params, adam = init_params(config, rng), {"t": 0, "m": {}, "v": {}}
    print(f"[model] {args.config}: {sum(a.size for a in params.values()):,} parameters; "
          f"x {x_dim}, p 8, z {z_dim}, clips {T} x {C}")
    steps = min(len(data[s]["train"][0]) for s in styles) // batch   # Sec. 4.3: one epoch is
    for epoch in range(1, epochs + 1):                               # the shortest style once
        t0, losses = time.perf_counter(), []
        order = {s: rng.permutation(len(data[s]["train"][0])) for s in styles}
        for step in range(steps):
            for s in styles:                    # one style per minibatch, in a fixed order
                x, p, z = (a[order[s][step * batch:(step + 1) * batch]] for a in data[s]["train"])
                # which clip: the paper does not say (minifilm/train/batches.py); one random
                # clip of the style for the whole minibatch, the cheapest (the original: one each)
                clip = data[s]["clips"][rng.integers(len(data[s]["clips"]))][None]
                drop = {"rate": config["dropout"], "masks": {}, "rng": rng}
                z_hat, cache = model_forward(params, x, p, clip, drop)
                l_mse, d_mse = mse_loss(z_hat, z)
                l_bll, d_bll = bone_length_loss(z_hat, z, *bones)
                adam_step(params, model_backward(d_mse + d_bll, cache)[0], adam, lr)
                losses.append((l_mse, l_bll))
        l_mse, l_bll = np.mean(losses, axis=0)
        print(f"[train] epoch {epoch:2d}: L_mse {l_mse:.4f}  L_bll {l_bll:.4f}  "
              f"({time.perf_counter() - t0:.1f} s)", flush=True)

    errors, films = {}, {}
    for s in styles:                            # a style's FiLM vector: Ψ over its clips, averaged
        x, p, z = data[s]["test"]
        films[s] = psi_forward(params, data[s]["clips"], None)[0].mean(0, keepdims=True)  # Sec. 4.4
        alpha = omega_forward(params, p, None)[0]
        errors[s] = mse_loss(phi_forward(params, x, alpha, films[s], None)[0], z)[0]
    print("[test] MSE of the normalised z: " + ", ".join(f"{s} {e:.4f}" for s, e in errors.items()))
    print(f"[test] MSE {np.mean(list(errors.values())):.4f} (predicting the mean scores about 1)")
    for s in styles[:2]:                        # Sec. 4.4: the model on its own, frame by frame
        x, p, _ = (a[0] * std + mean for a, (mean, std) in zip(data[s]["test"], stats))  # raw
        fps, state = data[s]["fps"], runtime_start(x, p, data[s]["fps"])
        print(f"[generate] {s}, asked to go on as its first test frame did "
              f"({np.hypot(*x[44:46]):.1f} m/s): time, root (m), hips' height, contacts R L, "
              "the feet's phases L R (cycles)")
        for frame in range(1, int(2 * fps) + 1):
            z = runtime_step(params, stats, state, unit(x[46:48], [0, 1]), x[44:46], films[s], fps)
            feet = np.mod(np.arctan2(state["p"][4::2], state["p"][5::2]) / (2 * np.pi), 1)  # Eq. 1
            (x_root, z_root), hips = state["root"], state["pos"][0, 1]
            if frame % round(fps / 5) == 0:
                print(f"  {frame / fps:.1f} s  ({x_root:5.2f}, {z_root:5.2f})  {hips:.2f}  "
                      f"{z[-2]:4.1f} {z[-1]:4.1f}  {feet[0]:.2f} {feet[1]:.2f}")
    print(f"{time.perf_counter() - start:.0f} s in all")

if __name__ == "__main__":
    main()
