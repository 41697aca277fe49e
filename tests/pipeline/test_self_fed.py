"""The rollout-aware rows of teaching a style (pipeline/self_fed.py): the geometry that feeds a
predicted pose back, and rollouts that reproduce the clip when the model is perfect."""
import numpy as np
import pytest

from minifilm.dataset.stats import NormStats
from minifilm.features.compute import frame_features
from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import builtin_skeleton
from minifilm.phases.label import label
from minifilm.pipeline.self_fed import into_next_root, rollout_rows
from minifilm.synthetic.generator import default_dataset


@pytest.fixture(scope="module")
def rows():
    """Raw x, p, z (float64) of two synthetic walks that turn, on the 100STYLE skeleton."""
    skeleton = builtin_skeleton("100style")
    out = []
    for item in default_dataset(styles=["Neutral", "Limp"], gaits=["TR"], seconds=4.0, seed=5):
        lab = label(item.motion, skeleton, item.style)
        r = frame_features(item.motion, skeleton, lab.vectors, lab.contacts, dtype=np.float64)
        out.append((r.x, r.p, r.z))
    return FeatureLayout.for_skeleton(skeleton), out


def test_the_next_frame_seen_from_its_own_root_is_the_next_input(rows):
    layout, segments = rows
    for x, _, z in segments:
        moved = into_next_root(z[:-1], z[:-1, layout.z_root_delta], layout)
        assert np.abs(z[:-1, layout.z_root_delta]).max() > 1e-3            # the root does move
        np.testing.assert_allclose(moved, x[1:, layout.x_joints], atol=1e-9)


class Oracle:
    """A 'model' that answers each input with the clip's next frame of the nearest clip input."""

    dtype = np.float64

    def __init__(self, x, z, stats):
        self.x, self.z, self.stats = x, z, stats

    def forward_with_film(self, x_norm, p_norm, film):
        x = x_norm * self.stats.x_std + self.stats.x_mean
        nearest = np.argmin(((x[:, None] - self.x[None]) ** 2).sum(-1), axis=1)
        return self.stats.normalize_z(self.z[nearest])


def stats_of(segments):
    x, p, z = (np.concatenate(a) for a in zip(*segments))
    return NormStats(x.mean(0), x.std(0) + 1e-3, z.mean(0), z.std(0) + 1e-3, p.mean(0), p.std(0) + 1e-3)


def test_a_perfect_model_rolls_out_the_clip_itself(rows):
    layout, segments = rows
    stats = stats_of(segments)
    x_all, _, z_all = (np.concatenate(a) for a in zip(*segments))
    x, p, z, error = rollout_rows(Oracle(x_all, z_all, stats), stats, layout, segments, np.zeros(4), horizon=30,
                                  every=20)
    starts = sum(len(range(0, len(s[0]) - 30, 20)) for s in segments)
    assert len(x) == 30 * starts
    assert error < 1e-6
    # rows step by step: (start, k) ordered by k; k = 29 of the first start is frame 29 of file 0
    np.testing.assert_allclose(x[29 * starts], segments[0][0][29], atol=1e-6)
    np.testing.assert_allclose(p[29 * starts], segments[0][1][29], atol=1e-9)
    np.testing.assert_allclose(z[29 * starts], segments[0][2][29])


def test_a_wrong_model_is_measured_and_its_states_are_its_own(rows):
    layout, segments = rows
    stats = stats_of(segments)
    x_all, _, z_all = (np.concatenate(a) for a in zip(*segments))
    still = Oracle(x_all[:1], z_all[:1], stats)           # always answers the first frame's pose
    x, _, z, error = rollout_rows(still, stats, layout, segments, np.zeros(4), horizon=10, every=40)
    starts = sum(len(range(0, len(s[0]) - 10, 40)) for s in segments)
    assert error > 0.01
    # from the second step on the joints are the model's own, the path (trajectory columns) the clip's
    first = segments[0][0]
    for k in (3, 6, 9):          # (step 1 is the clip's frame 1 again: the oracle answers frame 0's next frame)
        row = x[k * starts]                                  # the first start (frame 0 of file 0), step k
        np.testing.assert_allclose(row[layout.x_trajectory], first[k][layout.x_trajectory])
        assert np.abs(row[layout.x_joints] - first[k][layout.x_joints]).max() > 1e-3
    np.testing.assert_allclose(z[9 * starts], segments[0][2][9])           # the target is the clip's
