"""One page's character (minifilm/demo/character.py): messages applied at the next frame, the
toggles, and the guard: a non-finite or exploded frame, or a failing one, resets the character
where it stood and says so; the page never gets a non-finite number."""
import math

import numpy as np
import pytest

from demo_helpers import tiny_source  # noqa: F401  (a fixture)
from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import Character, DemoSettings
from minifilm.demo.protocol import InputMessage, ResetMessage, SettingsMessage, StyleMessage, encode


def character(source, **settings):
    return Character(1, source, Calibrations(source), DemoSettings(style=source.default_style(), **settings))


def all_finite(frame) -> bool:
    numbers = [v for k, v in frame.items() if isinstance(v, (int, float)) and not isinstance(v, bool)]
    numbers += [x for k in ("positions", "contacts", "phases", "root", "facing", "heading", "velocity")
                for x in frame[k]]
    return all(math.isfinite(x) for x in numbers)


def test_frames_carry_what_the_page_draws(tiny_source):
    ch = character(tiny_source)
    frame, notices = ch.step()
    J = tiny_source.layout.n_joints
    assert notices == [] and frame["n"] == 1 and frame["ack"] is None
    assert len(frame["positions"]) == 3 * J and len(frame["phases"]) == 8 and len(frame["contacts"]) == 2
    assert frame["weights"] == {tiny_source.default_style(): 1.0} and all_finite(frame)
    encode(frame)                                     # JSON without NaN


def test_messages_take_effect_at_the_next_frame_and_are_acknowledged(tiny_source):
    ch = character(tiny_source)
    ch.submit(InputMessage((0.0, 1.0), 0.0, 1.0, seq=5))
    frame, _ = ch.step()
    assert frame["ack"] == 5 and frame["commanded"] == pytest.approx(2.8)
    np.testing.assert_allclose(frame["velocity"], [0.0, 2.8])
    other = [n for n in tiny_source.library.names if n != tiny_source.default_style()][0]
    ch.submit(StyleMessage(((other, 1.0),), 0.5, seq=6))
    frame, _ = ch.step()
    assert frame["ack"] == 6 and frame["target"] == {other: 1.0} and other in frame["weights"]
    for _ in range(40):
        frame, _ = ch.step()
    assert frame["weights"] == {other: 1.0}
    assert np.array_equal(ch.mix.film, tiny_source.library[other])


def test_toggles_switch_the_fit_and_foot_locking(tiny_source):
    ch = character(tiny_source)
    assert ch.ctrl.skeleton is not None and ch.ctrl.foot_locker is None
    ch.submit(SettingsMessage(foot_lock=True, fit=False))
    frame, _ = ch.step()
    assert ch.ctrl.skeleton is None and ch.ctrl.foot_locker is not None
    assert frame["footLock"] is True and frame["fit"] is False and all_finite(frame)


def test_reset_brings_the_character_back_to_the_start(tiny_source):
    ch = character(tiny_source)
    ch.submit(InputMessage((0.0, 1.0), 0.0, 0.0))
    for _ in range(60):
        frame, _ = ch.step()
    assert np.hypot(*frame["root"]) > 0.2
    ch.submit(ResetMessage())
    frame, _ = ch.step()
    assert np.hypot(*frame["root"]) < 0.1


@pytest.mark.parametrize("fault", ["nan", "inf", "explode", "raise"])
def test_the_guard_resets_a_character_whose_frame_went_wrong(tiny_source, fault, monkeypatch):
    ch = character(tiny_source)
    ch.submit(InputMessage((0.0, 1.0), 0.0, 0.0))
    for _ in range(30):
        ch.step()
    before = ch.ctrl.state.root[0].copy()
    predict = ch.ctrl.net.predict

    def broken(x, p, film):
        z = predict(x, p, film)
        if fault == "raise":
            raise FloatingPointError("overflow in a layer")
        z[:, 24 + 12 * 3] = {"nan": np.nan, "inf": np.inf, "explode": 1e6}[fault]   # a joint's position x
        return z
    monkeypatch.setattr(ch.ctrl.net, "predict", broken)
    frame, notices = ch.step()
    assert len(notices) == 1 and "reset" in notices[0]
    assert all_finite(frame)
    encode(frame)
    np.testing.assert_allclose(frame["root"], before, atol=0.05)     # where it stood, not at the origin
    monkeypatch.setattr(ch.ctrl.net, "predict", predict)
    for _ in range(10):                                              # and it goes on, W still held
        frame, notices = ch.step()
        assert notices == [] and all_finite(frame) and frame["commanded"] == pytest.approx(1.3)


def test_a_batch_of_steps_is_the_same_motion_as_single_steps_and_sends_the_last_frame(tiny_source):
    one, batched = character(tiny_source), character(tiny_source)
    for ch in (one, batched):
        ch.submit(InputMessage((0.0, 1.0), 0.0, 0.0, seq=1))
    for _ in range(6):
        frame_one, _ = one.step()
    frame_batched, notices = batched.step(steps=6)
    assert notices == [] and frame_batched["n"] == frame_one["n"] == 6
    assert frame_batched["positions"] == frame_one["positions"] and frame_batched["root"] == frame_one["root"]


def test_a_recording_keeps_every_step_of_a_batch_not_only_the_frame_sent(tiny_source):
    from minifilm.demo.record import FrameHistory
    one, batched = character(tiny_source), character(tiny_source)
    kept = {}
    for name, ch in (("one", one), ("batched", batched)):
        kept[name] = FrameHistory(tiny_source.layout.n_joints, tiny_source.fps)
        ch.on_step = kept[name].capture
        ch.submit(InputMessage((0.0, 1.0), 0.0, 0.0, seq=1))
    for _ in range(12):
        one.step()
    batched.step(steps=5)
    batched.step(steps=7)
    assert kept["one"].count == kept["batched"].count == 12
    np.testing.assert_array_equal(kept["one"].last(1.0)[0], kept["batched"].last(1.0)[0])


def test_the_speed_read_out_is_in_metres_per_second_of_the_time_the_stage_gives(tiny_source):
    ch = character(tiny_source)
    ch.submit(InputMessage((0.0, 1.0), 0.0, 0.0, seq=1))
    roots = []
    for k in range(20):                     # 6 steps per 0.2 s of wall time: half of real time
        frame, _ = ch.step(steps=6, now=0.2 * k)
        roots.append(np.array(frame["root"]))
    # the read-out covers the last quarter second or more: here the last two passes, 0.4 s
    expected = np.linalg.norm(roots[-1] - roots[-3]) / 0.4
    assert frame["speed"] == pytest.approx(expected, rel=1e-3, abs=2e-4)
    simulated = np.linalg.norm(roots[-1] - roots[-3]) / (12 / tiny_source.fps)
    assert expected > 0.05 and frame["speed"] < 0.6 * simulated      # not the simulated seconds' speed
