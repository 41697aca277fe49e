"""The rollout refit's rows (minifilm/pipeline/rollout_refit.py) on the released network, where the
answer is known: when the "clip" is the network's own rollout in a style, every visited pose finds
itself, the targets are the network's own outputs, and the style's vector explains them exactly."""
from types import SimpleNamespace

import numpy as np
import pytest

from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.rollout_refit import visited_rows
from minifilm.pipeline.teach_adapter import RecordedNetwork
from minifilm.runtime.released import load_released
from minifilm.train.film_fit import FrozenRows


def test_the_recording_passes_everything_through():
    net = SimpleNamespace(film_dim=4, predict=lambda x, p, c: x[:, :2] * 2)
    rec = RecordedNetwork(net)
    z = rec.predict(np.ones((2, 3)), np.zeros((2, 8)), None)
    assert rec.film_dim == 4 and np.all(z == 2) and len(rec.x) == len(rec.p) == len(rec.z) == 1
    assert rec.x[0].shape == (2, 3) and rec.z[0].shape == (2, 2)          # a frame of the whole batch


def test_a_rollout_of_its_own_motion_finds_itself(shared_data):
    rel = load_released(shared_data / "released-lpn")
    layout = FeatureLayout.for_skeleton(STYLE100)
    film = rel.styles["Old"]
    own = SimpleNamespace(x=np.zeros((1, layout.x_dim)), z=np.zeros((1, layout.z_dim)), speed=1.0)
    X, P, _, _ = visited_rows(rel, layout, film, own, seconds=0.25)
    own_z = np.stack([rel.predict(x, p, film) for x, p in zip(X, P)])      # what the network did next
    clip = SimpleNamespace(x=X, z=own_z, speed=1.0)
    X2, P2, Z2, spread = visited_rows(rel, layout, film, clip, seconds=0.25)   # the same rollout again
    assert spread == pytest.approx(0.0, abs=1e-3)
    np.testing.assert_allclose(X2, X, atol=1e-9)
    np.testing.assert_allclose(Z2, own_z, rtol=1e-4, atol=1e-4)
    rows = FrozenRows(rel.model, rel.stats.normalize_x(X2), rel.stats.normalize_p(P2), rel.stats.normalize_z(Z2))
    assert rows.loss(film) < 1e-4 * float(np.mean(rel.stats.normalize_z(own_z) ** 2))
    assert rows.loss(rel.styles["Zombie"]) > 100 * rows.loss(film)
