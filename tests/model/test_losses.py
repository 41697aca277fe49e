"""Eq. (5)-(7): MSE and bone-length loss, values from independent loops and closed forms,
gradients by finite differences (float64)."""
import numpy as np
import pytest

from minifilm.model.losses import bone_length_loss, mse_loss

# 5 joints, positions scattered over the output vector (not a fixed 24 + 12 j rule)
PARENTS = np.array([-1, 0, 1, 1, 3])
POS_IDX = np.array([[3, 4, 5], [10, 11, 12], [0, 1, 2], [20, 22, 21], [15, 16, 17]])
D = 24


def make(seed, N=4):
    rng = np.random.default_rng(seed)
    return (rng.standard_normal((N, D)), rng.standard_normal((N, D)),
            rng.standard_normal(D), 0.5 + rng.random(D))


def test_mse_closed_form():
    pred, target, _, _ = make(0)
    loss, d = mse_loss(pred, target)
    assert loss == pytest.approx(((pred - target) ** 2).sum() / pred.size)
    np.testing.assert_allclose(d, 2 * (pred - target) / pred.size)


def test_bone_length_loss_matches_eq_6_7_loop():
    pred, target, mean, std = make(1)
    loss, _ = bone_length_loss(pred, target, POS_IDX, PARENTS, mean, std)
    total = 0.0
    for n in range(pred.shape[0]):
        per_frame = 0.0
        bones = [(PARENTS[j], j) for j in range(5) if PARENTS[j] >= 0]
        for bp, b in bones:
            zt = lambda j: target[n, POS_IDX[j]] * std[POS_IDX[j]] + mean[POS_IDX[j]]
            zh = lambda j: pred[n, POS_IDX[j]] * std[POS_IDX[j]] + mean[POS_IDX[j]]
            per_frame += abs(np.linalg.norm(zt(bp) - zt(b)) - np.linalg.norm(zh(bp) - zh(b)))
        total += per_frame / len(bones)          # Eq. (6), B = 4 bones
    assert loss == pytest.approx(total / pred.shape[0])   # Eq. (7)


def test_bone_length_loss_ignores_rigid_motion_and_other_columns():
    pred, target, mean, std = make(2)
    # prediction = target moved rigidly in metres (rotation about y + translation): same bone lengths
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    pos = target[:, POS_IDX] * std[POS_IDX] + mean[POS_IDX]
    moved = pos @ R.T + np.array([0.3, -0.1, 2.0])
    pred = target.copy()
    pred[:, POS_IDX] = (moved - mean[POS_IDX]) / std[POS_IDX]
    other = np.setdiff1d(np.arange(D), POS_IDX)
    pred[:, other] += 5.0                          # non-position columns do not matter
    loss, _ = bone_length_loss(pred, target, POS_IDX, PARENTS, mean, std)
    assert loss == pytest.approx(0.0, abs=1e-12)


def test_bone_length_loss_closed_form_one_bone():
    # root at origin, child at (0, 2, 0) in the target and (0, 3, 0) predicted: |2 - 3| = 1
    idx = np.array([[0, 1, 2], [3, 4, 5]])
    target = np.array([[0, 0, 0, 0, 2, 0.0]])
    pred = np.array([[0, 0, 0, 0, 3, 0.0]])
    loss, d = bone_length_loss(pred, target, idx, [-1, 0], np.zeros(6), np.ones(6))
    assert loss == pytest.approx(1.0)
    # longer predicted bone: the gradient pulls the child down and the parent up
    np.testing.assert_allclose(d, [[0, -1, 0, 0, 1, 0]])


def test_bad_arguments_are_named():
    pred, target, mean, std = make(5)
    with pytest.raises(ValueError, match="positions_idx must be"):
        bone_length_loss(pred, target, POS_IDX[:, :2], PARENTS, mean, std)
    with pytest.raises(ValueError, match="parents"):
        bone_length_loss(pred, target, POS_IDX, PARENTS[:3], mean, std)
    with pytest.raises(ValueError, match="out of range"):
        bone_length_loss(pred, target, POS_IDX + 10, PARENTS, mean, std)
    with pytest.raises(ValueError, match="differ"):
        mse_loss(pred, target[:, :3])
