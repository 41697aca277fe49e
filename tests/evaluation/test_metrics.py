"""Style metrics on cases with closed-form answers."""
import numpy as np
import pytest

from minifilm.evaluation.metrics import (bone_length_cv, bone_length_variation, interpolation_smoothness, pca_2d, rollout_quality,
                              silhouette_score)
from minifilm.runtime.rollout import Rollout


def test_silhouette_matches_hand_computation():
    # 1-D points: cluster A = {0, 1}, cluster B = {4}; distances by hand:
    # point 0: a = 1, b = 4 -> s = 3/4;  point 1: a = 1, b = 3 -> s = 2/3;  point 4: alone -> 0
    X = np.array([[0.0], [1.0], [4.0]])
    expected = (3 / 4 + 2 / 3 + 0.0) / 3
    assert silhouette_score(X, np.array(["A", "A", "B"])) == pytest.approx(expected, abs=1e-12)


def test_silhouette_three_clusters_by_hand():
    # A = {0, 2}, B = {10, 12}, C = {5}: point 0: a = 2, b = min(11, 5) = 5 -> 3/5
    # point 2: a = 2, b = min(9, 3) = 3 -> 1/3; point 10: a = 2, b = min(9, 5) = 5 -> 3/5
    # point 12: a = 2, b = min(11, 7) = 7 -> 5/7; point 5: alone -> 0
    X = np.array([[0.0], [2.0], [10.0], [12.0], [5.0]])
    expected = (3 / 5 + 1 / 3 + 3 / 5 + 5 / 7 + 0) / 5
    assert silhouette_score(X, [0, 0, 1, 1, 2]) == pytest.approx(expected, abs=1e-12)


def test_silhouette_separated_vs_mixed():
    rng = np.random.default_rng(0)
    a = rng.normal(0, 0.1, (20, 3))
    b = rng.normal(5, 0.1, (20, 3))
    labels = np.r_[np.zeros(20), np.ones(20)]
    assert silhouette_score(np.vstack([a, b]), labels) > 0.9
    mixed = rng.normal(0, 1, (40, 3))
    assert abs(silhouette_score(mixed, labels)) < 0.15


def test_pca_2d_finds_the_dominant_axes():
    theta = 2 * np.pi * np.arange(200) / 200                 # exactly uncorrelated, zero-mean columns
    t = np.stack([5.0 * np.cos(theta), 2.0 * np.sin(theta)], axis=1)
    X = np.zeros((200, 4))
    X[:, 1], X[:, 3] = t[:, 0], t[:, 1]                      # variance only in columns 1 and 3
    Y, ratio = pca_2d(X)
    assert ratio.sum() == pytest.approx(1.0)
    assert ratio[0] == pytest.approx(25 / 29)                # variances 25/2 and 4/2
    assert np.abs(np.abs(np.corrcoef(Y[:, 0], t[:, 0])[0, 1]) - 1) < 1e-9
    assert np.abs(np.abs(np.corrcoef(Y[:, 1], t[:, 1])[0, 1]) - 1) < 1e-9


def test_smoothness_linear_vs_step():
    w = np.linspace(0, 1, 11)
    lin = interpolation_smoothness(w, w)
    assert lin["monotonicity"] == pytest.approx(1.0)
    assert lin["max_step"] == pytest.approx(0.1)
    assert lin["linear_rmse"] == pytest.approx(0.0, abs=1e-12)
    step = interpolation_smoothness(w, (w > 0.5).astype(float))
    assert step["monotonicity"] == pytest.approx(1.0)
    assert step["max_step"] == pytest.approx(1.0)
    # RMS distance from the line y = w of the step 0/1: sqrt(mean over the 11 points of (s - w)^2)
    assert step["linear_rmse"] == pytest.approx(np.sqrt(np.mean(((w > 0.5) - w) ** 2)))
    zigzag = interpolation_smoothness(w[:3], np.array([0.0, 1.0, 0.5]))
    assert zigzag["monotonicity"] == pytest.approx(0.5 / 1.5)


def test_bone_variation_rigid_vs_stretching():
    F = 50
    parents = [-1, 0, 1]
    rigid = np.zeros((F, 3, 3))
    rigid[:, 1, 1] = 1.0
    rigid[:, 2, 1] = 1.5
    rigid += np.linspace(0, 3, F)[:, None, None]             # translating skeleton, bones fixed
    assert bone_length_variation(rigid, parents)["max"] == pytest.approx(0.0, abs=1e-12)
    stretch = rigid.copy()
    stretch[: F // 2, 2, 1] += 0.25                          # bone 2 is 0.75 for half, 0.5 for half
    v = bone_length_variation(stretch, parents)
    # lengths 0.75 / 0.5 half each: mean 0.625, std 0.125 -> cv 0.2; bone 1 stays at cv 0
    assert v["max"] == pytest.approx(0.2)
    assert v["mean"] == pytest.approx(0.1)
    # per joint: the bone ending at joint j, 0 for the root, so argmax names the stretched bone
    np.testing.assert_allclose(bone_length_cv(stretch.astype(np.float32), parents), [0.0, 0.0, 0.2], atol=1e-6)


def _rollout(toe_x):
    F = len(toe_x)
    pos = np.zeros((1, F, 3, 3))
    pos[0, :, 1, 1] = 1.0
    pos[0, :, 2, 0] = toe_x
    pos[0, :, 1, 0] = toe_x
    contacts = np.ones((1, F, 2))
    z2 = np.zeros((1, F, 2))
    return Rollout(pos, np.zeros((1, F, 3, 3, 3)), contacts, np.zeros((1, F, 8)), z2, z2, z2, 60.0)


def test_sliding_planted_vs_sliding_foot():
    F = 120
    planted = rollout_quality(_rollout(np.zeros(F)), [-1, 0, 1], toes=[2, 2], warmup_seconds=0.5)
    assert planted["foot_sliding"] == pytest.approx(0.0, abs=1e-12)
    sliding = rollout_quality(_rollout(np.arange(F) * 0.5 / 60.0), [-1, 0, 1], toes=[2, 2],
                              warmup_seconds=0.5)
    assert sliding["foot_sliding"] == pytest.approx(0.5)     # 0.5 m/s while in contact


def test_rollout_quality_reads_the_height_based_sliding_and_the_path_error():
    F = 120
    r = _rollout(np.arange(F) * 0.01)                        # toe 1 cm per frame on the floor (y = 0)
    r.targets, r.root_positions = np.zeros((1, F, 2)), np.zeros((1, F, 2))   # _rollout shares one array
    r.targets[0, :, 1] = 1.0                                # commanded 1 m/s along +z ...
    r.root_positions[0, :, 0] = 0.25                        # ... the root stands 25 cm to the side
    q = rollout_quality(r, [-1, 0, 1], toes=[2, 2], warmup_seconds=0.5)
    assert q["foot_sliding_cm_s"] == pytest.approx(60.0)
    # the commanded path starts at the root and runs away at 1 m/s: mean gap over 2 s
    gap = np.hypot(0.0, np.arange(F) / 60.0)
    assert q["path_error"] == pytest.approx(gap.mean())
    assert q["stalled"] == pytest.approx(1.0)              # it never moves while the path does
