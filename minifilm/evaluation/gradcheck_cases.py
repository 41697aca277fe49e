"""The gradient checks of the kit's pairs, the model's blocks and the losses.

Each function takes a seed and returns a :class:`~minifilm.evaluation.gradcheck_problem.Result`:
every entry of every input checked against the four-point stencil (minifilm.nn.gradcheck), the
scalar being ``L = Σ out ∘ r`` (r ~ N(0, 1), summed exactly) for a pair and the loss itself for a
loss, normalised as the method says. Inputs are drawn away from the kinks (ELU / ReLU inputs at
least MARGIN from 0 by construction or by a bias shift, max-pool pairs at least MARGIN apart,
layer-norm rows with σ >= SIGMA_MIN) and a guard counts stencil evaluations that changed a
kink's side. Two cases sit *on* a kink on purpose, with an exact reason why the stencil still
measures the gradient the code takes (see their docstrings): the layer norm of a constant row
and the bone-length loss's degenerate bones.
"""
from __future__ import annotations

import math

import numpy as np

from minifilm.evaluation.gradcheck_problem import (MARGIN, PARENTS, POS_IDX, SIGMA_MIN, Result, bone_lengths,
                                                 result_of, shift_away)
from minifilm.model import blocks
from minifilm.model.dropout import Dropout
from minifilm.model.losses import bone_length_loss, mse_loss
from minifilm.nn import fast_conv
from minifilm.nn import functional as F
from minifilm.nn.gradcheck import compare_gradients, worst_error


def _rng(seed: int, salt: int) -> np.random.Generator:
    return np.random.default_rng([salt, seed])


def away_from_zero(rng, shape, gap=MARGIN):
    """N(0, 1)-like numbers with |x| >= gap."""
    x = rng.standard_normal(shape)
    return np.sign(x) * (gap + np.abs(x))


def rows_with_spread(rng, shape):
    """N(0, 1) rows (last axis) redrawn until each has σ >= SIGMA_MIN (a layer norm's input)."""
    x = rng.standard_normal(shape)
    while (bad := np.std(x, axis=-1, ddof=1) < SIGMA_MIN).any():
        x[bad] = rng.standard_normal(x[bad].shape)
    return x


def _signs(values):
    return np.sign(np.concatenate([np.ravel(v) for v in values]))


def _margin(values):
    v = np.abs(np.concatenate([np.ravel(v) for v in values]))
    v = v[v > 0]                                   # exact zeros: both frames of a pool pair dead
    return float(v.min()) if v.size else np.inf


def pair_result(forward, backward, inputs, names, rng, kinks=None, **kw) -> Result:
    """Check ``forward`` / ``backward`` for every named input (None skips an input without a
    gradient) with L = Σ out ∘ r. ``kinks(cache)``: the inputs of the pair's kinks, whose signs
    must not change on any evaluation of the stencil."""
    out, cache = forward(*inputs, **kw)
    r = rng.standard_normal(np.shape(out))
    grads = backward(r, cache)
    grads = grads if isinstance(grads, tuple) else (grads,)
    pairs = {n: (x, np.array(g)) for n, x, g in zip(names, inputs, grads) if n is not None and g is not None}
    base = None if kinks is None else _signs(kinks(cache))
    crossings = 0

    def f():
        nonlocal crossings
        o, c = forward(*inputs, **kw)
        if kinks is not None:
            crossings += not np.array_equal(_signs(kinks(c)), base)
        return math.fsum((o * r).ravel().tolist())

    scale = math.fsum(np.abs(out * r).ravel().tolist())
    margin = np.inf if kinks is None else _margin(kinks(cache))
    return result_of(compare_gradients(f, pairs, scale=scale), crossings, margin)


def merge(results: dict) -> Result:
    """One Result of several configurations {label: Result}: arrays named 'x (label)'."""
    errors, entries, worst, crossings, margin = {}, {}, (-1.0, ""), 0, np.inf
    for label, r in results.items():
        errors.update({f"{k} ({label})": v for k, v in r.errors.items()})
        entries.update({f"{k} ({label})": v for k, v in r.entries.items()})
        crossings += r.crossings
        margin = min(margin, r.margin)
        if worst_error(r.errors) > worst[0]:
            worst = (worst_error(r.errors), f"{label}: {r.worst}")
    return Result(errors, entries, crossings, margin, worst[1])


# ---- the kit (minifilm/nn) --------------------------------------------------------------------
def linear(seed):
    rng = _rng(seed, 1)
    inputs = (rng.standard_normal((4, 5)), rng.standard_normal((5, 3)), rng.standard_normal(3))
    return pair_result(F.linear_forward, F.linear_backward, inputs, ("x", "W", "b"), rng)


def elu(seed):
    rng = _rng(seed, 2)
    return pair_result(F.elu_forward, F.elu_backward, (away_from_zero(rng, (4, 6)),), ("x",), rng,
                       kinks=lambda c: [c[0]])


def relu(seed):
    rng = _rng(seed, 3)
    return pair_result(F.relu_forward, F.relu_backward, (away_from_zero(rng, (4, 6)),), ("x",), rng,
                       kinks=lambda c: [c])


def softmax(seed):
    rng = _rng(seed, 4)
    return pair_result(F.softmax_forward, F.softmax_backward, (rng.standard_normal((4, 6)),), ("x",), rng)


def layer_norm(seed, unbiased=True, eps=1e-6):
    rng = _rng(seed, 5)
    return pair_result(F.layer_norm_forward, F.layer_norm_backward, (rows_with_spread(rng, (4, 8)),), ("x",), rng,
                       unbiased=unbiased, eps=eps)


CONSTANT_ROW_H = 1e-14


def layer_norm_constant_row(seed):
    """A constant row (σ = 0) in training's convention (ε = 1e-6): the code takes the limit
    dx = g/s − mean(g/s). σ = ‖x − mean‖ / sqrt(n) has a kink there, so this is the one case
    whose stencil crosses a kink: along any entry, f(t) = a t / (c |t| + ε), which is
    differentiable at 0 (f'(0) = a / ε) but has a t|t| term, and the four-point stencil measures
    f'(0) (1 − 2 c h / 3ε): a relative error of (2/3) c h / ε ≈ 3e-9 with h = 1e-14 (c < 0.5 for a
    row of 6). A row of zeros makes x ± h exact, so rounding stays ~1e-10 of the gradient."""
    rng = _rng(seed, 6)
    x = np.zeros((2, 6))
    r = rng.standard_normal(x.shape)
    _, cache = F.layer_norm_forward(x, unbiased=True, eps=1e-6)
    dx = F.layer_norm_backward(r, cache)

    def f():
        return math.fsum((F.layer_norm_forward(x, unbiased=True, eps=1e-6)[0] * r).ravel().tolist())

    return result_of(compare_gradients(f, {"x": (x, dx)}, h=CONSTANT_ROW_H))


def film(seed, per_sample=True):
    rng = _rng(seed, 7)
    shape = (4, 5) if per_sample else (5,)
    inputs = (rng.standard_normal((4, 5)), rng.standard_normal(shape), rng.standard_normal(shape))
    return pair_result(F.film_forward, F.film_backward, inputs, ("h", "gamma", "beta"), rng)


def dropout(seed):
    rng = _rng(seed, 8)
    x = rng.standard_normal((4, 6))
    return pair_result(F.dropout_forward, F.dropout_backward, (x,), ("x",), rng, p=0.3, mask=rng.random(x.shape) >= 0.3)


def expert_linear(seed, batch=4):
    rng = _rng(seed, 9 + batch)
    alpha = rng.dirichlet(np.ones(3), size=batch)
    inputs = (rng.standard_normal((batch, 5)), alpha, rng.standard_normal((3, 5, 4)), rng.standard_normal((3, 4)))
    return pair_result(F.expert_linear_forward, F.expert_linear_backward, inputs, ("x", "alpha", "W", "b"), rng)


def expert_blend(seed):
    """The plain form of the gated-expert layer (weights blended per sample), batch 4."""
    rng = _rng(seed, 14)
    alpha = rng.dirichlet(np.ones(3), size=4)
    inputs = (rng.standard_normal((4, 5)), alpha, rng.standard_normal((3, 5, 4)), rng.standard_normal((3, 4)))
    return pair_result(F.expert_blend_forward, F.expert_blend_backward, inputs, ("x", "alpha", "W", "b"), rng)


def gather(seed):
    """y[b] = x[index[b]] with a row used three times and a row not used (shared style clips)."""
    rng = _rng(seed, 15)
    return pair_result(F.gather_forward, F.gather_backward, (rng.standard_normal((3, 4, 2)),), ("x",), rng,
                       index=np.array([2, 0, 2, 2, 0]))


def conv1d(seed, method="im2col"):
    """Kernel sizes and clip lengths, channels-last, 'same' padding: the plain im2col pair, or
    with ``method="fft"`` the fast pair's FFT form. A clip shorter than the
    kernel (T 3, k 7) only with im2col: the taps that never meet the clip have a gradient of
    exactly 0, which the FFT gives as ~1e-17, so the relative error would compare two kinds of
    rounding there (k 25 > T 16 still has every tap meeting some frame)."""
    configs = ([(T, k) for k in (1, 3, 5, 7) for T in (6, 7)] + [(3, 7)] if method == "im2col"
               else [(7, 3), (6, 5), (9, 9), (12, 7), (16, 25)])
    out = {}
    for T, k in configs:
        rng = _rng(seed, 100 * T + k)
        inputs = (rng.standard_normal((2, T, 3)), rng.standard_normal((k, 3, 4)), rng.standard_normal(4))
        if method == "im2col":      # the plain pair (minifilm/nn/conv.py)
            out[f"T {T}, k {k}"] = pair_result(F.conv1d_forward, F.conv1d_backward, inputs, ("x", "W", "b"), rng)
        else:                       # the fast pair forced onto its FFT form (minifilm/nn/fast_conv.py)
            out[f"T {T}, k {k}"] = pair_result(fast_conv.conv1d_fast_forward, fast_conv.conv1d_fast_backward,
                                               inputs, ("x", "W", "b"), rng, method=method)
    return merge(out)


def _pool_pairs(x):
    T2 = x.shape[1] // 2
    return x[:, 0:2 * T2:2] - x[:, 1:2 * T2:2]


def max_pool(seed):
    """T = 6 and 7 (the odd frame is dropped); values distinct and >= 0.1 apart, so no pair is
    near a tie."""
    out = {}
    for T in (6, 7):
        rng = _rng(seed, 16 + T)
        x = (rng.permutation(2 * T * 3) * 0.1).reshape(2, T, 3)
        out[f"T {T}"] = pair_result(F.max_pool1d_forward, F.max_pool1d_backward, (x,), ("x",), rng,
                                    kinks=lambda c, x=x: [_pool_pairs(x)])
    return merge(out)


# ---- the model's blocks (minifilm/model/blocks.py) ----------------------------------------------
def _fixed_dropout(shape, rng, p=0.3):
    return Dropout(p, train=True, masks={"s": rng.random(shape) >= p})


def dense_block(seed):
    rng = _rng(seed, 20)
    x, W, b = rng.standard_normal((4, 5)), rng.standard_normal((5, 3)), rng.standard_normal(3)
    kw = dict(activation="elu", drop=_fixed_dropout(x.shape, rng), site="s")
    b += shift_away(blocks.dense_forward(x, W, b, **kw)[1].act[0], MARGIN)
    return pair_result(blocks.dense_forward, blocks.dense_backward, (x, W, b), ("x", "W", "b"), rng,
                       kinks=lambda c: [c.act[0]], **kw)


def expert_block(seed):
    rng = _rng(seed, 21)
    alpha = rng.dirichlet(np.ones(3), size=4)
    inputs = (rng.standard_normal((4, 5)), alpha, rng.standard_normal((3, 5, 2)), rng.standard_normal((3, 2)))
    return pair_result(blocks.expert_forward, blocks.expert_backward, inputs, ("x", "alpha", "W", "b"), rng,
                       drop=_fixed_dropout((4, 5), rng), site="s")


def film_block(seed):
    """Eq. (3): the layer norm's rows get σ >= SIGMA_MIN (an expert-bias pattern, as the
    networks' set-up does), then β moves the ELU's inputs MARGIN from 0."""
    rng = _rng(seed, 22)
    B, I, O, K = 4, 5, 6, 3
    x, alpha = rng.standard_normal((B, I)), rng.dirichlet(np.ones(K), size=B)
    W, b = rng.standard_normal((K, I, O)), rng.standard_normal((K, O))
    gamma, beta = 1.0 + 0.3 * rng.standard_normal((B, O)), rng.standard_normal((B, O))
    kw = dict(drop=_fixed_dropout((B, I), rng), site="s")
    u = np.linspace(-1.0, 1.0, O)
    for c in (0.0, 0.5, 1.0, 2.0, 4.0):
        if np.std(blocks.film_block_forward(x, alpha, W, b + c * u, gamma, beta, **kw)[1].norm[0],
                  axis=-1, ddof=1).min() >= SIGMA_MIN:
            b += c * u
            break
    beta += shift_away(blocks.film_block_forward(x, alpha, W, b, gamma, beta, **kw)[1].elu[0], MARGIN)
    return pair_result(blocks.film_block_forward, blocks.film_block_backward, (x, alpha, W, b, gamma, beta),
                       ("x", "alpha", "W", "b", "gamma", "beta"), rng, kinks=lambda c: [c.elu[0]], **kw)


def conv_block(seed):
    """conv1d -> ReLU -> max-pool 2: the bias moves every ReLU input MARGIN from 0 and clips
    with a max-pool pair within MARGIN of a tie are redrawn."""
    rng = _rng(seed, 23)
    x, W, b = rng.standard_normal((2, 8, 3)), 0.5 * rng.standard_normal((3, 3, 4)), 0.1 * rng.standard_normal(4)

    def kinks(c):
        h = np.maximum(c.relu, 0)
        return [c.relu, np.where(np.maximum(h[:, 0::2], h[:, 1::2]) > 0, _pool_pairs(h), 0.0)]

    for _ in range(100):
        b += shift_away(blocks.conv_block_forward(x, W, b)[1].relu, MARGIN)
        gaps = np.abs(kinks(blocks.conv_block_forward(x, W, b)[1])[1])
        bad = ((gaps > 0) & (gaps < MARGIN)).reshape(len(x), -1).any(axis=1)
        if not bad.any():
            break
        x[bad] = rng.standard_normal(x[bad].shape)
    return pair_result(blocks.conv_block_forward, blocks.conv_block_backward, (x, W, b), ("x", "W", "b"), rng,
                       kinks=kinks)


# ---- the losses (minifilm/model/losses.py) ------------------------------------------------------
def _loss_result(loss, pred, grad, kinks=None) -> Result:
    value = loss()
    base = None if kinks is None else _signs(kinks())
    crossings = 0

    def f():
        nonlocal crossings
        v = loss()
        if kinks is not None:
            crossings += not np.array_equal(_signs(kinks()), base)
        return v

    margin = np.inf if kinks is None else _margin(kinks())
    return result_of(compare_gradients(f, {"pred": (pred, grad)}, scale=value), crossings, margin)


def mse(seed):
    rng = _rng(seed, 30)
    pred, target = rng.standard_normal((3, 7)), rng.standard_normal((3, 7))
    return _loss_result(lambda: mse_loss(pred, target)[0], pred, mse_loss(pred, target)[1])


def bll(seed, degenerate=None):
    """Eq. (6)-(7) on the toy skeleton (joint 0 has two children). degenerate:

    None          every |ℓ − ℓ̂| and ℓ̂ at least MARGIN from 0 (rows redrawn), kink guard on;
    'equal'       bone 1→2 exactly as long as its target (|·| at 0, where the code takes
                  sign(0) = 0): the bone lies along the x axis in metres, so moving any coordinate
                  of its joints by ±t changes |ℓ − ℓ̂| by the same amount both ways (along the
                  bone ℓ̂ is linear in t, across it even in t): the symmetric stencil measures the
                  code's 0 exactly, whatever h;
    'zero-pred'   bone 1→2 of length 0 in the prediction (‖·‖ at 0, gradient taken as 0): ℓ̂ = |t|
                  along any coordinate, again even in t;
    'zero-target' bone 1→2 of length 0 in the target: |ℓ − ℓ̂| = ℓ̂, smooth, guard on.
    The other bones are kept MARGIN from their kinks.
    """
    rng = _rng(seed, 31)
    N, D = 3, 15
    mean, std = rng.standard_normal(D), 0.5 + rng.random(D)
    pred, target = rng.standard_normal((N, D)), rng.standard_normal((N, D))
    j0, j1, j2, j3 = POS_IDX
    if degenerate in ("equal", "zero-pred"):
        mean[j1], mean[j2], std[j1], std[j2] = 0.0, 0.0, 1.0, 1.0
    elif degenerate == "zero-target":
        mean[j2], std[j2] = mean[j1], std[j1]
    free = np.arange(D) if degenerate in (None, "zero-target") else np.concatenate([j0, j3])
    check = np.ones(3, bool)                           # bones: child 1, 2, 3 (bone_list)
    check[1] = degenerate not in ("equal", "zero-pred")

    def place():
        pred[:, j2] = pred[:, j1] if degenerate in ("equal", "zero-pred") else pred[:, j2]
        if degenerate == "equal":
            pred[:, j2[0]] += 0.8                      # along x: (−0.8, 0, 0) in metres
            target[:, j1], target[:, j2] = pred[:, j1], pred[:, j2]
        if degenerate == "zero-target":
            target[:, j2] = target[:, j1]

    place()
    while True:                                        # the other bones: away from their kinks
        hat, true = bone_lengths(pred, target, mean, std)
        if min(np.abs(true - hat)[:, check].min(), hat[:, check].min()) >= MARGIN:
            break
        pred[:, free], target[:, free] = rng.standard_normal((2, N, len(free)))
        place()
    def kinks():
        hat, true = bone_lengths(pred, target, mean, std)
        return [true - hat, hat]

    loss = lambda: bone_length_loss(pred, target, POS_IDX, PARENTS, mean, std)   # noqa: E731
    return _loss_result(lambda: loss()[0], pred, loss()[1], kinks if check.all() else None)
