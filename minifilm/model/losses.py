"""The training objective L = L_mse + L_bll (Sec. 4.3, Eq. 5-7), with hand-written gradients.

Both losses are computed on one minibatch, which holds frames of a single style (the paper's
style-balanced minibatches, minifilm/train/batches.py), so the per-style normalisation 1/N_s of
Eq. (5) and (7) becomes a mean over the minibatch; averaging over the style cycle gives the sum
over styles (up to the factor S).
"""
from __future__ import annotations

import numpy as np


def mse_loss(pred, target):
    """Eq. (5) on one minibatch: mean of (z − ẑ)² over the batch *and* the features.

    pred, target (B, D) -> loss (float), dpred (B, D).

    PAPER: Eq. (5) sums the squared error over the D features of z, while Eq. (6) averages the
    bone errors over the bones. The mean divides L_mse by D (342 for 100STYLE), so in
    L = L_mse + L_bll the bone-length term weighs D times more than with the paper's sum (a
    factor on the whole loss would barely matter to Adam; a factor on one term moves the
    balance). The original code takes a mean for both terms (docs/original-code.md §14), and
    the released network was trained so; this follows it.
    """
    if pred.shape != target.shape:
        raise ValueError(f"mse_loss: pred {pred.shape} and target {target.shape} differ")
    diff = pred - target
    loss = float(np.mean(diff * diff))
    dpred = (2.0 / diff.size) * diff
    return loss, dpred.astype(pred.dtype, copy=False)


def bone_list(parents):
    """(parent, child) joint indices of every bone: each joint with parent >= 0."""
    parents = np.asarray(parents, dtype=int)
    child = np.nonzero(parents >= 0)[0]
    return parents[child], child


def bone_length_loss(pred, target, positions_idx, parents, out_mean, out_std):
    """Eq. (6)-(7) on one minibatch: the bone-length loss.

        l_bll(z, ẑ) = 1/B Σ_b | ‖z_bp − z_b‖ − ‖ẑ_bp − ẑ_b‖ |       (Eq. 6, B = number of bones)
        L_bll       = mean over the minibatch of l_bll                 (Eq. 7)

    pred, target   (N, D) normalised outputs ẑ and z
    positions_idx  (J, 3) int columns of each joint's (x, y, z) position in the output vector
                   (from the feature layout; never hard-coded here)
    parents        (J,) parent of each joint, -1 for the root; bones are (parents[j], j)
    out_mean, out_std (D,) output statistics: positions are de-normalised (z*std + mean) first,
                   so bone lengths are in metres, as in the original code.
    Returns loss (float), dpred (N, D). The gradient of |·| at 0 and of ‖·‖ at a zero-length
    bone is taken as 0. The mean over the bones is Eq. (6)'s 1/B; the original code divides its
    sum over the 24 bones of 100STYLE by 25, the joint count (docs/original-code.md §14).
    """
    positions_idx = np.asarray(positions_idx, dtype=int)
    parents = np.asarray(parents, dtype=int)
    if pred.shape != target.shape or pred.ndim != 2:
        raise ValueError(f"bone_length_loss: pred {pred.shape} and target {target.shape} must be equal (N, D)")
    if positions_idx.ndim != 2 or positions_idx.shape[1] != 3:
        raise ValueError(f"bone_length_loss: positions_idx must be (J, 3), got {positions_idx.shape}")
    if parents.shape != (positions_idx.shape[0],):
        raise ValueError(f"bone_length_loss: parents must be ({positions_idx.shape[0]},), got {parents.shape}")
    if positions_idx.min() < 0 or positions_idx.max() >= pred.shape[1]:
        raise ValueError(f"bone_length_loss: positions_idx out of range for {pred.shape[1]} output columns")
    if len(np.unique(positions_idx)) != positions_idx.size:
        raise ValueError("bone_length_loss: positions_idx repeats a column")
    par, child = bone_list(parents)
    n_bones = len(child)
    if n_bones == 0:
        raise ValueError("bone_length_loss: the parent list has no bones")

    std = np.asarray(out_std, dtype=pred.dtype)[positions_idx]     # (J, 3)
    mean = np.asarray(out_mean, dtype=pred.dtype)[positions_idx]
    pos_hat = pred[:, positions_idx] * std + mean                  # (N, J, 3) metres
    pos_true = target[:, positions_idx] * std + mean
    vec_hat = pos_hat[:, par] - pos_hat[:, child]                  # (N, nb, 3)  ẑ_bp − ẑ_b
    vec_true = pos_true[:, par] - pos_true[:, child]
    len_hat = np.sqrt(np.sum(vec_hat * vec_hat, axis=-1))          # (N, nb)
    len_true = np.sqrt(np.sum(vec_true * vec_true, axis=-1))
    diff = len_true - len_hat
    loss = float(np.mean(np.abs(diff)))                            # mean over N and bones

    # backward: d|diff|/dlen_hat = -sign(diff); dlen/dvec = vec / len
    dlen_hat = -np.sign(diff) / diff.size                           # (N, nb)
    safe = np.where(len_hat > 0, len_hat, 1.0)
    dvec = np.where(len_hat[..., None] > 0, vec_hat / safe[..., None], 0.0) * dlen_hat[..., None]
    dpos = np.zeros_like(pos_hat)                                   # (N, J, 3)
    np.add.at(dpos, (slice(None), par), dvec)
    np.add.at(dpos, (slice(None), child), -dvec)
    dpred = np.zeros_like(pred)
    dpred[:, positions_idx] = dpos * std
    return loss, dpred
