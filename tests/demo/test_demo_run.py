"""Shift runs (minifilm/demo/character.py, Controller.run_feed): the released network runs only when
shown a run, so while Shift is held a perfect run is blended into its trajectory input; without
Shift, or for sources without a run feed, the input is the paper's."""
import numpy as np

from demo_helpers import released_source, tiny_source  # noqa: F401  (fixtures)
from minifilm.demo import calibrations
from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import RUN_BLEND, Character, DemoSettings
from minifilm.demo.protocol import InputMessage
from minifilm.features.layout import CURRENT_SAMPLE
from minifilm.runtime.calibration import CALIBRATION_COMMANDS, CALIBRATION_DIRECTIONS, SpeedCalibration
from minifilm.runtime.controller import Controller


def fake_measure(source, name):
    c = np.array(CALIBRATION_COMMANDS)
    return SpeedCalibration(c, np.stack([np.minimum(0.45 * c, top) for top in (1.8, 1.2, 1.0)]),
                            CALIBRATION_DIRECTIONS)


def test_a_full_run_feed_is_a_perfect_straight_run_and_none_is_the_papers_input(released_source):
    src = released_source
    ctrl = Controller(src.network, src.layout)
    ctrl.reset(np.array([[1.0, 2.0]]), np.array([[0.0, 1.0]]))
    ctrl._target = (np.array([[1.0, 0.0]]), np.array([[3.0, 0.0]]))       # facing and running along +x
    paper = ctrl.build_input()
    ctrl.run_feed, ctrl.run_feed_speed = np.zeros(1), 8.0
    assert np.array_equal(ctrl.build_input(), paper)                     # weight 0: unchanged
    ctrl.run_feed = np.ones(1)
    x = ctrl.build_input()
    L = src.layout
    times = np.r_[-ctrl.past_frames / 60.0, np.asarray(L.trajectory_seconds)[CURRENT_SAMPLE:]]
    for s, t in enumerate(times):
        cols = L.trajectory_columns("x", s)
        # the root faces +z, so its frame is the world's: the run is along +x at 8 m/s, facing +x
        np.testing.assert_allclose(x[0, cols[:2]], [8.0 * t, 0.0], atol=1e-9)
        np.testing.assert_allclose(x[0, cols[2:]], [1.0, 0.0], atol=1e-9)
    others = np.setdiff1d(np.arange(L.x_dim), np.concatenate([L.trajectory_columns("x", s) for s in range(len(times))]))
    assert np.array_equal(x[0, others], paper[0, others])               # the pose is the network's own


def test_shift_blends_the_run_feed_in_and_out_and_says_what_it_does(released_source, monkeypatch):
    monkeypatch.setattr(calibrations, "measure", fake_measure)
    ch = Character(1, released_source, Calibrations(released_source, first=["Neutral"], background=False),
                   DemoSettings(style="Neutral"))
    ch.submit(InputMessage((0.0, 1.0), 0.0, 0.0, seq=1))                 # W: a walk
    frame, _ = ch.step(steps=5)
    assert ch.ctrl.run_feed is None and ch.run_feed == 0.0
    ch.submit(InputMessage((0.0, 1.0), 0.0, 1.0, seq=2))                 # Shift+W
    n = int(round(RUN_BLEND * 60))
    frame, _ = ch.step(steps=n // 2)
    assert 0.3 < ch.run_feed < 0.7
    frame, _ = ch.step(steps=n)
    assert ch.run_feed == 1.0 and ch.ctrl.run_feed_speed == released_source.run_feed_speed
    assert "Shift: Neutral runs at this network's own running pace" in frame["speedNote"]
    assert "it cannot run faster" in frame["speedNote"]                  # said plainly, not a cap
    assert "1.80" in frame["speedNote"]                                 # what the walk's calibration tops at
    ch.submit(InputMessage((0.0, 1.0), 0.0, 0.0, seq=3))                 # Shift let go
    ch.step(steps=n + 1)
    assert ch.run_feed == 0.0 and ch.ctrl.run_feed is None


def test_a_trained_run_has_no_run_feed(tiny_source):
    ch = Character(1, tiny_source, Calibrations(tiny_source), DemoSettings(style=tiny_source.default_style()))
    ch.submit(InputMessage((0.0, 1.0), 0.0, 1.0, seq=1))
    ch.step(steps=30)
    assert tiny_source.run_feed_speed is None and ch.ctrl.run_feed is None


def test_with_shift_the_released_neutral_runs_faster_than_any_command_made_it(released_source, monkeypatch):
    monkeypatch.setattr(calibrations, "measure", fake_measure)
    ch = Character(1, released_source, Calibrations(released_source, first=["Neutral"], background=False),
                   DemoSettings(style="Neutral"))
    ch.submit(InputMessage((0.0, 1.0), 0.0, 1.0, seq=1))
    roots, contacts = [], []
    for _ in range(8 * 15):                                             # 8 s, in batches of 4 steps
        frame, notices = ch.step(steps=4)
        assert notices == []
        roots.append(frame["root"])
        contacts.append(frame["contacts"])
    roots, contacts = np.array(roots[60:]), np.array(contacts[60:])     # the last 4 s
    speed = np.linalg.norm(np.diff(roots, axis=0), axis=1).sum() / ((len(roots) - 1) * 4 / 60)
    # the loop's best was 1.8 m/s at any command (benchmarks/run_speed.py); shown a run, it runs
    assert speed > 1.95, speed
    assert np.mean(np.all(contacts < 0.5, axis=1)) > 0.2                # flight: neither foot in contact
