"""Standing still at a zero command (minifilm/runtime/standing.py).

The released network, asked to stop after walking, kept walking backwards and sideways at about
0.4 m/s with its feet stepping. With the runtime's StandStill it stops within a second and stands:
root speed under 0.05 m/s and no contact changes while nothing is asked; it walks on afterwards.
Without the held body (``hold=False``) the root stood but 34 of the 100 styles went on stepping,
shuffling or spinning on the spot; with it they stand too, and moving is the paper's loop, bit
for bit.
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
    with pytest.raises(ValueError, match="release"):
        StandStill(release=bad)


def test_the_feet_are_held_once_at_rest_and_let_go_over_the_release_time():
    s = StandStill(settle=0.5, release=0.1)
    idle, asked = np.array([True]), np.array([False])
    w = None
    for k in range(1, 31):                                  # half a second at rest
        w = s.feet_weight(w, np.array([k / 60]), idle, 1 / 60)
    assert w[0] == pytest.approx(1.0)
    falling = []
    for _ in range(7):                                      # a command: let go over 0.1 s (6 frames)
        w = s.feet_weight(w, np.zeros(1), asked, 1 / 60)
        falling.append(w[0])
    assert falling[:5] == pytest.approx([5 / 6, 4 / 6, 3 / 6, 2 / 6, 1 / 6], abs=1e-12)
    assert falling[5:] == pytest.approx([0.0, 0.0], abs=1e-12) and min(falling) >= 0.0
    assert StandStill(hold=False).feet_weight(None, np.array([3.0]), idle, 1 / 60)[0] == 0.0


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


def idle_figures(src, styles, stand):
    """Walk 2 s, then nothing for 4 s; per style over the last 3 s: (largest root speed over a
    quarter second m/s, contact changes, fastest toe m/s, degrees the facing turned)."""
    ctrl = Controller(src.network, src.layout, fps=60, skeleton=Controller.skeleton_for(src.layout, src.skeleton),
                      feed_back_fit=True, stand=stand)
    from minifilm.runtime.control import CommandScript
    scripts = [CommandScript([(0, 2.0, 0, 0), (2, 2.0, 0, 0), (2.01, 0, 0, 0), (6, 0, 0, 0)]) for _ in styles]
    r = ctrl.run(scripts, 360, np.stack([src.library[s] for s in styles]))
    names = list(src.layout.joint_names)
    toes = [names.index("RightToe"), names.index("LeftToe")]
    out = {}
    for b, style in enumerate(styles):
        root = r.root_positions[b, 180:]
        quarter = np.linalg.norm(root[15:] - root[:-15], axis=1).max() * 4
        changes = int(np.abs(np.diff((r.contacts[b, 180:] > 0.5).astype(int), axis=0)).sum())
        toe = (np.linalg.norm(np.diff(r.positions[b, 180:][:, toes], axis=0), axis=-1) * 60).max()
        heading = np.unwrap(np.arctan2(r.root_facing[b, 180:, 0], r.root_facing[b, 180:, 1]))
        out[style] = (quarter, changes, toe, np.degrees(heading.max() - heading.min()))
    return out


#: styles that did not stand without the held body: Drunk flailed its feet (221 contact changes),
#: Followed's and LawnMower's still feet had contacts hovering about 0.5 (LawnMower's still flip
#: when held, unless the contacts reported are the held feet's), Angry shuffled, SpinClock spun
STEPPERS = ["Drunk", "Followed", "LawnMower", "Angry", "SpinClock"]


def test_styles_that_stepped_on_the_spot_stand_with_the_held_body(released):
    held = idle_figures(released, STEPPERS, StandStill())
    for style, (quarter, changes, toe, turn) in held.items():
        assert quarter < 0.05 and changes == 0 and toe < 0.15 and turn < 1.0, (style, quarter, changes, toe, turn)
    loose = idle_figures(released, STEPPERS, StandStill(hold=False))
    for style, (quarter, changes, toe, turn) in loose.items():
        assert changes > 0 or toe > 0.15 or turn > 5, (style, changes, toe, turn)   # each stepped, one way or another


def test_moving_is_the_papers_loop_bit_for_bit(released):
    """The stand-still changes nothing while something is asked: a figure eight and a strafe with
    the runtime's StandStill and without it give the same frames, to the last bit, even beside a
    third character of the batch that stops and stands (whose frames do differ)."""
    frames = []
    for stand in (StandStill(), None):
        ctrl = Controller(released.network, released.layout, fps=60, stand=stand,
                          skeleton=Controller.skeleton_for(released.layout, released.skeleton), feed_back_fit=True)
        r = ctrl.run([make_script("figure8", 4.0, speed=1.0), make_script("strafe", 4.0, speed=1.0),
                      make_script("stop_and_go", 4.0, speed=1.0)], 240,
                     np.stack([released.library[s] for s in ("Neutral", "Drunk", "Angry")]))
        frames.append(r)
    on, off = frames
    for key in ("positions", "rotations", "contacts", "phases", "root_positions", "root_facing"):
        assert np.array_equal(getattr(on, key)[:2], getattr(off, key)[:2]), key
    assert not np.array_equal(on.positions[2], off.positions[2])


def test_a_turn_on_the_spot_is_finished_before_the_feet_are_held(released):
    """Stopped, the target is turned 180 degrees at 120 degrees a second: the character turns on
    the spot (its own steps) all the way, and then stands."""
    ctrl = Controller(released.network, released.layout, fps=60, feed_back_fit=True,
                      skeleton=Controller.skeleton_for(released.layout, released.skeleton))
    ctrl.reset(np.zeros((1, 2)), np.array([[0.0, 1.0]]))
    heading, toes = [], []
    names = list(released.layout.joint_names)
    toe = [names.index("RightToe"), names.index("LeftToe")]
    for k in range(480):
        t = k / 60
        th = min(max(t - 3.0, 0.0) * np.radians(120), np.pi)
        fr = ctrl.step(np.array([[np.sin(th), np.cos(th)]]), np.array([[0.0, 2.0 if t < 1.5 else 0.0]]),
                       released.library["Neutral"])
        heading.append(np.arctan2(fr["facing"][0, 0], fr["facing"][0, 1]))
        toes.append(fr["positions"][0, toe].copy())
    heading = np.degrees(np.unwrap(heading))
    assert abs(heading[-1] - 180) < 5, heading[-1]
    assert heading[269] < 150                      # when the target stopped turning, it was still on its way
    toe_speed = np.linalg.norm(np.diff(np.array(toes)[-60:], axis=0), axis=-1) * 60
    assert toe_speed.max() < 0.05                  # and then it stood


def test_it_walks_off_at_once_after_standing_and_its_feet_are_let_go_smoothly(released):
    """After 3 s of standing, a command to walk: Neutral's root is faster than 0.3 m/s within 12
    frames (the stand-still without the held body: 11), and no toe jumps in the first frames (the
    held feet are let go over ``release``; let go at once, LeftHop's raised foot jumped 6 cm)."""
    from minifilm.runtime.control import CommandScript
    styles = ["Neutral", "LeftHop"]
    names = list(released.layout.joint_names)
    toes = [names.index("RightToe"), names.index("LeftToe")]
    jumps = {}
    for release in (StandStill().release, 1e-3):
        ctrl = Controller(released.network, released.layout, fps=60, feed_back_fit=True, stand=StandStill(release=release),
                          skeleton=Controller.skeleton_for(released.layout, released.skeleton))
        scripts = [CommandScript([(0, 2.0, 0, 0), (2, 2.0, 0, 0), (2.01, 0, 0, 0), (5, 0, 0, 0), (5.01, 2.0, 0, 0),
                                  (7, 2.0, 0, 0)]) for _ in styles]
        r = ctrl.run(scripts, 420, np.stack([released.library[s] for s in styles]))
        if release > 1e-3:
            speed = np.linalg.norm(np.diff(r.root_positions[0, 240:], axis=0), axis=1) * 60   # [60]: the command's frame
            assert speed[:60].max() < 0.01                 # it stood
            assert speed[60:72].max() > 0.3, speed[60:74].round(2)
        step = np.linalg.norm(np.diff(r.positions[:, 300:303][:, :, toes], axis=1), axis=-1)   # (2 styles, 2 frames, 2 toes)
        jumps[release] = step.max(axis=(1, 2))
    assert jumps[StandStill().release].max() < 0.01, jumps
    assert jumps[1e-3][1] > 0.03, jumps                  # the test can tell


def test_held_rows_ease_into_a_slow_idle_cycle_and_moving_rows_keep_their_phases_bit_for_bit():
    s = StandStill(settle=0.5, idle_amplitude=0.3, idle_hz=0.25)
    phases = np.arange(16, dtype=float).reshape(2, 8) / 7.0
    out = s.idle_phases(phases, np.array([2.0, 0.0]))          # row 0 held for 2 s, row 1 moving
    assert np.array_equal(out[1], phases[1])
    amp = np.linalg.norm(out[0].reshape(4, 2), axis=-1)
    assert np.allclose(amp, 0.3)
    angle = np.arctan2(out[0, 0::2], out[0, 1::2])              # (sin, cos) pairs
    expected = 2 * np.pi * 0.25 * 2.0 + np.array([0.0, np.pi, 0.0, np.pi])
    assert np.allclose(np.cos(angle - expected), 1.0)           # the left and right limbs half a cycle apart
    half = s.idle_phases(phases, np.array([0.25, 0.0]))[0]      # half-way through the hold: a blend
    assert not np.allclose(half, phases[0]) and not np.allclose(np.linalg.norm(half.reshape(4, 2), axis=-1), 0.3)
    assert np.array_equal(StandStill(idle_amplitude=0.0).idle_phases(phases, np.array([2.0, 2.0])), phases)
    with pytest.raises(ValueError, match="idle_amplitude"):
        StandStill(idle_amplitude=-1.0)


def test_an_idle_character_stands_with_its_feet_planted_and_is_not_a_statue(released):
    styles = ["Neutral", "Proud", "ShieldedRight"]
    body = Controller.skeleton_for(released.layout, released.skeleton)
    ctrl = Controller(released.network, released.layout, skeleton=body, feed_back_fit=True)
    from minifilm.runtime.control import CommandScript
    scripts = [CommandScript([(0, 2, 0, 0), (1.0, 2, 0, 0), (1.0 + 1e-6, 0, 0, 0), (7.0, 0, 0, 0)]) for _ in styles]
    r = ctrl.run(scripts, 7 * 60, np.stack([released.library[s] for s in styles]))
    pos, root = r.positions[:, 120:420], r.root_positions[:, 120:420]       # 5 s from 1 s after the stop
    names = list(released.layout.joint_names)
    feet = [names.index(n) for n in ("RightToe", "LeftToe", "RightAnkle", "LeftAnkle")]
    moved = np.linalg.norm(pos - pos[:, :1], axis=-1).max(axis=1)          # (B, J) metres
    assert np.all(np.linalg.norm(np.diff(root, axis=1), axis=-1).sum(axis=1) / 5.0 < 0.05)
    assert np.all(moved[:, feet].max(axis=1) <= 0.02)
    assert np.all(moved.max(axis=1) >= 0.01), moved.max(axis=1)


def test_a_character_stops_as_it_would_alone_beside_one_already_standing(released):
    """Batch rollouts are per character: Zombie, stopping at 3 s beside Neutral (stopped at 1 s,
    its feet held by then), moves as Zombie alone does. (Held feet and feet on their way down were
    kept for the whole batch: a walker's raised foot stayed marked for its later stop.)"""
    from minifilm.runtime.control import CommandScript

    def run(styles, stops):
        ctrl = Controller(released.network, released.layout, fps=60, feed_back_fit=True, stand=StandStill(),
                          skeleton=Controller.skeleton_for(released.layout, released.skeleton))
        scripts = [CommandScript([(0, 1.3, 0, 0), (t, 1.3, 0, 0), (t + 0.01, 0, 0, 0), (6, 0, 0, 0)]) for t in stops]
        return ctrl.run(scripts, 300, np.stack([released.library[s] for s in styles]))

    alone = run(["Zombie"], [3.0])
    together = run(["Neutral", "Zombie"], [1.0, 3.0])
    np.testing.assert_allclose(together.positions[1], alone.positions[0], atol=1e-4)
