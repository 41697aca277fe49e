"""Speed calibration in the demo (minifilm/demo/calibrations.py): the released network is commanded
through its style's calibration (a mix through the mix of the commands), other styles are measured
in slices (the frame loop's idle time) when first asked for, to the same speeds as measured all at
once, and sources that need none pass velocities unchanged."""
import json
import time
from dataclasses import replace

import numpy as np

from demo_helpers import released_source, tiny_source  # noqa: F401  (fixtures)
from minifilm.demo import calibrations
from minifilm.demo.calibrations import Calibrations
from minifilm.runtime.calibration import CALIBRATION_COMMANDS, RUN_CALIBRATION_COMMANDS, SpeedCalibration


def fake_measure(source, name):
    """A network that reaches 40 % of any command forwards and 80 % sideways and backwards
    (Zombie: half of that), instead of the 2 s measurement of the real one."""
    k = 0.5 if name == "Zombie" else 1.0
    return SpeedCalibration(np.array([1.0, 2.0, 4.0, 8.0]), k * np.array([[0.4, 0.8, 1.6, 3.2], [0.8, 1.6, 3.2, 6.4],
                                                                         [0.8, 1.6, 3.2, 6.4]]), (0.0, 90.0, 180.0))


def test_commands_go_through_the_styles_calibration(released_source, monkeypatch):
    monkeypatch.setattr(calibrations, "measure", fake_measure)
    cal = Calibrations(released_source, first=["Neutral"], background=False)
    assert cal.has("Neutral") and not cal.has("Zombie")
    facing = np.array([0.0, 1.0])
    np.testing.assert_allclose(cal.command(np.array([0.0, 1.2]), facing, {"Neutral": 1.0}), [0.0, 3.0])
    np.testing.assert_allclose(cal.command(np.array([-1.2, 0.0]), facing, {"Neutral": 1.0}), [-1.5, 0.0])
    # a style not measured yet borrows the start style's calibration
    np.testing.assert_allclose(cal.command(np.array([0.0, 1.2]), facing, {"Zombie": 1.0}), [0.0, 3.0])
    cal._cal["Zombie"] = fake_measure(None, "Zombie")
    cal._memo.clear()
    np.testing.assert_allclose(cal.command(np.array([0.0, 1.2]), facing, {"Zombie": 1.0}), [0.0, 6.0])
    # a mix is commanded with the mix of the commands
    np.testing.assert_allclose(cal.command(np.array([0.0, 1.2]), facing, {"Neutral": 0.25, "Zombie": 0.75}),
                               [0.0, 0.25 * 3.0 + 0.75 * 6.0])
    assert not cal.command(np.zeros(2), facing, {"Neutral": 1.0}).any()


def test_other_styles_are_measured_in_slices_when_first_asked_for(released_source):
    cal = Calibrations(released_source, first=[], background=True)
    woken = []
    cal.on_request = lambda: woken.append(1)
    cal.request(["Zombie", "Zombie"])
    assert woken == [1] and cal.pending() and cal.requested == 1 and not cal.has("Zombie")
    slices = 0
    while cal.pending():
        cal.run_slice()
        slices += 1
        assert slices <= 500
    # the Controller made, then reset, then 480 network steps (8 s at 60 fps), then the result
    assert slices == 483 and cal.has("Zombie") and cal.progress()["state"] == "done"
    command = cal.command(np.array([0.0, 1.0]), np.array([0.0, 1.0]), {"Zombie": 1.0})
    assert command[0] == 0.0 and command[1] > 1.5               # the network walks slower than asked
    cal.request(["Zombie"])                                     # measured: nothing more to do
    assert not cal.pending() and woken == [1]


def test_a_calibration_measured_in_slices_is_the_one_measured_at_once(tiny_source):
    # a trained run's source: its small network measures fast
    source = tiny_source
    name = source.library.names[-1]                                # a style with its own start frame
    assert name in source.starts
    at_once = calibrations.measure(source, name)
    cal = Calibrations(source, first=[], background=True)
    cal.request([name])
    for _ in range(100_000):                                       # (a bound: it ends long before)
        if not cal.pending():
            break
        cal.run_slice()
    assert not cal.pending()
    sliced = cal._cal[name]
    np.testing.assert_array_equal(sliced.commanded, at_once.commanded)
    np.testing.assert_array_equal(sliced.achieved, at_once.achieved)
    np.testing.assert_array_equal(sliced.directions, at_once.directions)
    assert at_once.achieved.max() > 0                              # it measured motion


def test_closing_drops_the_measurement_in_hand_and_the_queue(released_source):
    cal = Calibrations(released_source, first=[], background=True)
    cal.request(["Zombie", "Old"])
    for _ in range(5):
        cal.run_slice()
    assert cal.progress()["measuring"] == "Zombie"
    cal.close()
    assert not cal.pending()
    cal.run_slice()                                             # a last call from the frame loop: nothing
    cal.request(["Angry"])
    assert not cal.pending() and not cal.has("Zombie")


def test_sources_without_calibration_pass_velocities_unchanged(tiny_source):
    source = replace(tiny_source, calibrate=False)                # minifilm demo --no-calibrate
    cal = Calibrations(source, first=[source.default_style()])
    assert not cal.enabled
    v = np.array([0.3, 1.1])
    np.testing.assert_array_equal(cal.command(v, np.array([0.0, 1.0]), {"Neutral": 1.0}), v)
    cal.request(["LeftHop"])                                      # nothing to measure
    assert not cal.pending()


def measured_styles(folder) -> set:
    """The styles of the speed-calibration cache file in ``folder`` (written after each one)."""
    files = list(folder.glob("calibration-*.json"))
    return set(json.loads(files[0].read_text())["styles"]) if files else set()


def test_sigterm_ends_the_server_at_once_with_calibrations_queued(released_source, tmp_path):
    # One page asks for a mix of all 100 styles and then for ten single styles: measurements
    # (--recalibrate: none is taken from the package) queue for the frame loop's idle time, each
    # written to the cache when done. SIGTERM must end the server there, not after the queue: the
    # cache then holds what it held when the signal went, or the one measurement in hand besides
    # (events, not times: a loaded machine measures more slowly, and the queue takes minutes).
    import signal

    from demo_helpers import RELEASED
    from minifilm.demo.client import DemoClient
    from minifilm.demo.process import DemoProcess

    demo = DemoProcess("--params", RELEASED, "--recalibrate", cache=tmp_path)
    try:
        with DemoClient(demo.url) as page:
            page.next_frame()
            names = page.hello["styles"]
            page.send({"type": "style", "weights": {n: 1 / len(names) for n in names}, "seconds": 1})
            for n in names[:10]:
                page.send({"type": "style", "weights": {n: 1.0}, "seconds": 1})
            end = time.monotonic() + 300                       # a deadline, not a measure
            while page.next_frame()["calibration"].get("state") != "measuring" and time.monotonic() < end:
                pass
            assert page.next_frame()["calibration"]["state"] == "measuring"
        before = measured_styles(tmp_path)
        demo.proc.send_signal(signal.SIGTERM)
        demo.proc.wait(300)                                    # a deadline, not a measure
        assert len(measured_styles(tmp_path) - before) <= 1, sorted(measured_styles(tmp_path) - before)
        assert len(before) < 50                                # the queue was still long
    finally:
        demo.stop()


def test_only_the_styles_that_matter_in_a_mix_are_measured_heaviest_first():
    assert Calibrations.needed({"A": 0.05, "B": 0.45, "C": 0.5}) == ["C", "B"]
    everything = {f"S{i:03d}": 0.01 for i in range(100)}            # a blend of all 100 styles
    assert Calibrations.needed(everything) == ["S000"]               # one stand-in, not ten minutes of them
    assert Calibrations.needed({"Solo": 1.0}) == ["Solo"]


def test_the_terminal_is_told_how_many_styles_are_queued_and_about_how_long(released_source):
    logs = []
    cal = Calibrations(released_source, first=[], background=True, log=logs.append)
    cal._paces = [6.0]
    cal.request([f"S{i}" for i in range(100)])
    assert "100 style(s) queued, about 10 min at the pace so far" in logs[-1] and "and 95 more" in logs[-1]
    assert "minute or less" not in logs[-1]
    assert calibrations.estimate(12.0) == "10 s" and calibrations.estimate(600.0) == "10 min"
    cal.close()


def test_a_trained_run_is_calibrated_only_with_commands_its_data_holds(tiny_source):
    """A run's source is calibrated (its styles walk slower or faster than asked), with commands up to
    4 m/s, not the released network's 24 m/s."""
    assert tiny_source.calibrate and tiny_source.calibration_commands == RUN_CALIBRATION_COMMANDS
    assert max(RUN_CALIBRATION_COMMANDS) <= 4.0 < max(CALIBRATION_COMMANDS)
    measured = calibrations.measure(tiny_source, tiny_source.default_style())
    np.testing.assert_array_equal(measured.commanded, np.r_[0.0, RUN_CALIBRATION_COMMANDS])
    cal = Calibrations(tiny_source, first=[tiny_source.default_style()], background=False)
    assert cal.enabled and cal.has(tiny_source.default_style())
