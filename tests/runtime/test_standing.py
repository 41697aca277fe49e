"""Standing still at a zero command (minifilm/runtime/standing.py, issue 26).

The released network, asked to stop after walking, kept walking backwards and sideways at about
0.4 m/s with its feet stepping. With the runtime's StandStill it stops within a second and stands:
root speed under 0.05 m/s and no contact changes while nothing is asked; it walks on afterwards.
"""
import numpy as np
import pytest

from minifilm.demo.source import DemoSource
from minifilm.runtime.control import make_script, stop_and_go
from minifilm.runtime.controller import Controller
from minifilm.runtime.standing import StandStill
from repo_paths import need_data


def test_the_root_weight_fades_from_one_to_zero_over_the_settle_time():
    s = StandStill(settle=0.5)
    w = s.root_weight(np.array([0.0, 0.125, 0.25, 0.5, 3.0]))
    assert w[0] == 1.0 and w[-1] == 0.0 and w[-2] == 0.0 and w[2] == pytest.approx(0.5)
    assert np.all(np.diff(w) <= 0)


def test_only_still_rows_get_their_future_pinned_to_the_root():
    fut = np.arange(2 * 6 * 2, dtype=float).reshape(2, 6, 2)
    out = StandStill.pin_future(fut, np.array([True, False]))
    assert np.all(out[0] == fut[0, 0]) and np.array_equal(out[1], fut[1])


def test_turning_on_the_spot_is_not_idle_and_moving_is_not_still():
    v = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    target = np.array([[0.0, 1.0], [np.sin(0.01), np.cos(0.01)], [0.0, 1.0]])   # row 1: being turned
    previous = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])
    assert StandStill.still(v).tolist() == [True, True, False]
    assert StandStill.idle(v, target, previous).tolist() == [True, False, False]
    f = StandStill(phase_tau=0.1).phase_factor(np.array([True, False]), 1 / 60)
    assert f[0] == pytest.approx(np.exp(-1 / 6)) and f[1] == 1.0


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_settings_must_be_positive_seconds(bad):
    with pytest.raises(ValueError, match="settle"):
        StandStill(settle=bad)
    with pytest.raises(ValueError, match="phase_tau"):
        StandStill(phase_tau=bad)


def test_stop_and_go_walks_stands_walks_and_stands():
    s = make_script("stop_and_go", 8.0, speed=1.0)
    speeds = [s.speed(t) for t in (0.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5)]
    assert speeds == [1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0]
    with pytest.raises(ValueError):
        stop_and_go(seconds=0)


@pytest.fixture(scope="module")
def released(shared_data):
    return DemoSource.released(need_data(shared_data / "released-lpn", "the released network"), calibrate=False)


def stand_measures(src, stand, style="Neutral"):
    """Walk 2 s, then nothing for 4 s: (root speed m/s over the last 3 s, contact changes then,
    walking speed before)."""
    ctrl = Controller(src.network, src.layout, fps=60, skeleton=Controller.skeleton_for(src.layout, src.skeleton),
                      feed_back_fit=True, stand=stand)
    from minifilm.runtime.control import CommandScript
    script = CommandScript([(0, 2.0, 0, 0), (2, 2.0, 0, 0), (2.01, 0, 0, 0), (6, 0, 0, 0)])
    r = ctrl.run(script, 360, src.library[style])
    speed = np.linalg.norm(np.diff(r.root_positions[0], axis=0), axis=1) * 60
    changes = int(np.abs(np.diff((r.contacts[0, 180:] > 0.5).astype(int), axis=0)).sum())
    return speed[180:].max(), changes, speed[60:120].mean()


def test_the_released_network_stands_when_nothing_is_asked_and_did_not_without(released):
    top, changes, walk = stand_measures(released, StandStill())
    assert walk > 0.3                           # it did walk first
    assert top < 0.05 and changes == 0, (top, changes)
    top_off, changes_off, _ = stand_measures(released, None)
    assert top_off > 0.2 and changes_off > 0    # the paper's loop alone: it keeps walking
