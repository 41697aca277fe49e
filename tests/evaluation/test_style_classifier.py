"""The style classifier: gradient check, a separable toy problem, and rollout features that equal
the dataset's clip features for the same motion."""
import numpy as np
import pytest

from minifilm.synthetic import generator as synthetic
from minifilm.features.compute import clip_features_from_arrays, motion_arrays
from minifilm.motion.skeletons import STYLE100
from gradcheck_report import other
from minifilm.nn.gradcheck import LIMIT, check_gradients
from minifilm.runtime.rollout import Rollout
from minifilm.evaluation.style_classifier import StyleClassifier, cut_windows, rollout_blocks, window_summary


@pytest.mark.gradcheck
@pytest.mark.parametrize("hidden", [0, 5])
def test_gradients_match_finite_differences(hidden):
    rng = np.random.default_rng(0)
    clf = StyleClassifier(6, 3, hidden=hidden, rng=rng)
    s = rng.normal(size=(7, 6))
    y = rng.integers(0, 3, size=7)
    clf.loss(s, y, weight_decay=0.1)
    analytic = {k: (clf.params.params[k], clf.params.grads[k].copy()) for k in clf.params.params}
    errors = check_gradients(lambda: clf.loss(s, y, weight_decay=0.1), analytic)
    other(f"style classifier: cross-entropy + weight decay, hidden {hidden}", errors, LIMIT)


def test_loss_is_cross_entropy():
    clf = StyleClassifier(2, 3, hidden=0)
    clf.params.data[:] = 0.0                                   # all logits 0 -> uniform p = 1/3
    assert clf.loss(np.ones((4, 2)), np.array([0, 1, 2, 0])) == pytest.approx(np.log(3))


def test_learns_a_separable_toy_problem():
    rng = np.random.default_rng(1)
    centres = np.array([[3.0, 0, 0, 0], [0, 3.0, 0, 0], [0, 0, 3.0, 0]])
    y = rng.integers(0, 3, size=300)
    X = centres[y] + rng.normal(0, 0.5, (300, 4)) + 10.0      # offset: fit must standardise
    clf = StyleClassifier(4, 3, hidden=8, rng=rng)
    history = clf.fit(X[:200], y[:200], epochs=40, rng=rng)
    assert history[-1] < history[0]
    assert np.mean(clf.predict(X[200:]) == y[200:]) > 0.95
    p = clf.predict_proba(X[200:])
    assert np.allclose(p.sum(axis=1), 1.0)


def test_window_summary_and_cutting():
    block = np.arange(10, dtype=float)[:, None] * np.array([[1.0, 2.0]])
    w = cut_windows(block, 4, 3)                               # starts 0, 3, 6
    assert w.shape == (3, 4, 2)
    s = window_summary(w)
    assert s[1, 0] == pytest.approx(4.5)                       # mean of 3..6
    assert s[1, 1] == pytest.approx(9.0)
    assert s[1, 2] == pytest.approx(np.std([3, 4, 5, 6]))


def test_rollout_blocks_equal_dataset_clip_features():
    clip = synthetic.generate_style("Neutral", "FW", 2.0, np.random.default_rng(0))
    m = clip.motion
    pos, rot, vel, root_pos, root_rot = motion_arrays(m, STYLE100)
    F = len(pos)
    facing = root_rot[:, :, 2][:, [0, 2]]                       # LookRotation's forward column
    z = np.zeros((1, F, 2))
    r = Rollout(pos[None], rot[None], np.zeros((1, F, 2)), np.zeros((1, F, 8)),
                root_pos[None][..., [0, 2]], facing[None], z, m.fps)
    blocks = rollout_blocks(r, warmup_seconds=0.0)[0]          # (F, 12 J)
    ref = clip_features_from_arrays(pos, rot, vel, root_pos, root_rot, m.fps, clip_seconds=1.0,
                                    stride_seconds=1.0, dtype=np.float64)[0]    # frames 1 .. 60
    np.testing.assert_allclose(blocks[1:1 + len(ref)], ref, atol=1e-9)
