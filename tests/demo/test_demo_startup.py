"""Start-up and honest read-outs: the calibration cache (minifilm/demo/calibration_cache.py)
keyed by the network, how it is driven and each style, written atomically, a corrupt one ignored with a warning; the
demo command serves its page without measuring anything first; a command beyond what the style
can reach is scaled and said; the frames carry what the page needs for its read-outs."""
import json
import math
import os
import time
from dataclasses import replace

import numpy as np
import pytest

from demo_helpers import RELEASED, released_source, tiny_source  # noqa: F401  (fixtures)
from minifilm.demo import calibrations
from minifilm.demo.calibration_cache import (CALIBRATION_VERSION, CalibrationCache, calibration_key, max_speed,
                                             style_digest)
from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import REACHABLE, Character, DemoSettings, RateCounter
from minifilm.demo.protocol import InputMessage
from minifilm.demo.server import held_out
from minifilm.runtime.calibration import (CALIBRATION_COMMANDS, CALIBRATION_DIRECTIONS, RUN_CALIBRATION_COMMANDS,
                                          SpeedCalibration)
from minifilm.runtime.heading import HeadingFollow
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import StyleLibrary


def fake(name="Neutral", k=1.0, commands=CALIBRATION_COMMANDS):
    """A calibration at the commands and directions really measured: forwards up to 1.8 m/s,
    sideways 1.2, backwards 1.0."""
    c = np.array(commands)
    achieved = np.stack([np.minimum(0.45 * c, top) for top in (1.8, 1.2, 1.0)])
    return SpeedCalibration(c, k * achieved, CALIBRATION_DIRECTIONS)


def run_fake(k=1.0):
    return fake(k=k, commands=RUN_CALIBRATION_COMMANDS)


def test_the_key_follows_the_network_and_how_it_is_driven(tiny_source):
    key = calibration_key(tiny_source)
    assert len(key) == 20 and calibration_key(tiny_source) == key
    reloaded = RuntimeNetwork.from_arrays(tiny_source.network.to_arrays())
    assert calibration_key(replace(tiny_source, network=reloaded)) == key
    arrays = tiny_source.network.to_arrays()
    arrays["expert.W1"] = arrays["expert.W1"].copy()
    arrays["expert.W1"][0, 3, 5] = np.nextafter(arrays["expert.W1"][0, 3, 5], np.inf)     # one weight, one bit
    assert calibration_key(replace(tiny_source, network=RuntimeNetwork.from_arrays(arrays))) != key
    assert calibration_key(replace(tiny_source, fps=30.0)) != key
    assert calibration_key(replace(tiny_source, calibration_commands=(0.5, 1.0))) != key
    options = dict(tiny_source.options, position_bias=tiny_source.options["position_bias"] + 0.25)
    assert calibration_key(replace(tiny_source, options=options)) != key
    options = dict(tiny_source.options, heading_follow=HeadingFollow(tau=0.3))
    assert calibration_key(replace(tiny_source, options=options)) != key


def test_a_style_entry_follows_its_vector_and_start(tiny_source, tmp_path):
    name = tiny_source.default_style()
    cache = CalibrationCache(tiny_source, tmp_path)
    cache.put(name, run_fake())
    assert sorted(CalibrationCache(tiny_source, tmp_path).load()) == [name]
    films = {n: tiny_source.library[n] for n in tiny_source.library.names}
    films[name] = films[name] * 1.01                                 # re-taught under the same name
    retaught = replace(tiny_source, library=StyleLibrary(films))
    assert CalibrationCache(retaught, tmp_path).load() == {}
    x, p = tiny_source.starts[name]                                  # the run has start frames
    moved = replace(tiny_source, starts=dict(tiny_source.starts, **{name: (x + 0.01, p)}))
    assert CalibrationCache(moved, tmp_path).load() == {}


def test_a_cache_round_trips_and_is_written_atomically(tiny_source, tmp_path):
    where = str(tmp_path / "cache")                          # a folder given as text works as a Path
    a, b = tiny_source.library.names[:2]
    cache = CalibrationCache(tiny_source, where)
    assert cache.load() == {}
    cache.put(a, run_fake())
    cache.put(b, run_fake(k=0.5))
    assert sorted(os.listdir(where)) == [cache.path.name]                   # no temporary left
    again = CalibrationCache(tiny_source, where).load()
    assert sorted(again) == sorted([a, b])
    np.testing.assert_allclose(again[b].achieved, run_fake(k=0.5).achieved)
    assert again[a].command_for(1.0) == pytest.approx(run_fake().command_for(1.0))


def test_recalibrating_reads_no_entry_and_keeps_the_others(tiny_source, tmp_path):
    a, b = tiny_source.library.names[:2]
    cache = CalibrationCache(tiny_source, tmp_path)
    cache.put(a, run_fake())
    cache.put(b, run_fake())
    fresh = CalibrationCache(tiny_source, tmp_path, ignore_cached=True)
    assert fresh.load() == {}
    fresh.put(a, run_fake(k=0.5))                                   # measured again: replaces a, keeps b
    again = CalibrationCache(tiny_source, tmp_path).load()
    np.testing.assert_allclose(again[a].achieved, run_fake(k=0.5).achieved)
    np.testing.assert_allclose(again[b].achieved, run_fake().achieved)


@pytest.mark.parametrize("content", [
    b"{not json", b"", b"[]", json.dumps({"version": "other", "styles": {}}).encode(),
    json.dumps({"version": CALIBRATION_VERSION, "styles": {"N": {"style": "0", "commanded": [1, 2], "achieved": [[1]],
                                                                 "directions": [0]}}}).encode(),
    json.dumps({"version": CALIBRATION_VERSION, "styles": {"N": {"style": "0", "commanded": [1], "achieved": [[1e400]],
                                                                 "directions": [0]}}}).encode(),
    b"[" * 100000,
])
def test_a_corrupt_cache_is_ignored_with_one_warning(tiny_source, tmp_path, capsys, content):
    name = tiny_source.default_style()
    cache = CalibrationCache(tiny_source, tmp_path / "cache")
    cache.path.parent.mkdir(parents=True)
    cache.path.write_bytes(content)
    assert cache.load() == {}
    err = capsys.readouterr().err
    assert err.count("warning: ignoring the speed calibration cache") == 1 and "Traceback" not in err
    cache.put(name, run_fake())                         # and it is rewritten whole
    assert sorted(CalibrationCache(tiny_source, tmp_path / "cache").load()) == [name]


def test_a_cache_that_is_not_a_regular_file_is_ignored(tiny_source, tmp_path, capsys):
    cache = CalibrationCache(tiny_source, tmp_path / "cache")
    cache.path.mkdir(parents=True)
    assert cache.load() == {}
    assert "ignoring" in capsys.readouterr().err


def test_an_unwritable_cache_folder_is_a_warning_not_an_error(tiny_source, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    CalibrationCache(tiny_source, blocker / "cache").put(tiny_source.default_style(), run_fake())
    assert "could not write the speed calibration cache" in capsys.readouterr().err


def test_the_cache_folder_follows_xdg_cache_home(monkeypatch, tmp_path):
    from minifilm.demo.calibration_cache import cache_folder
    monkeypatch.delenv("MINIFILM_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cache_folder() == tmp_path / "minifilm"
    monkeypatch.setenv("MINIFILM_CACHE", str(tmp_path / "own"))
    assert cache_folder() == tmp_path / "own"


def test_cached_styles_are_not_measured_again(released_source, tmp_path, monkeypatch):
    measured = []
    monkeypatch.setattr(calibrations, "measure", lambda source, name: measured.append(name) or fake())
    cache = CalibrationCache(released_source, tmp_path, shipped=None)
    Calibrations(released_source, first=["Neutral"], background=False, cache=cache)
    assert measured == ["Neutral"]
    cal = Calibrations(released_source, first=["Neutral"], background=False,
                       cache=CalibrationCache(released_source, tmp_path, shipped=None))
    assert measured == ["Neutral"] and cal.has("Neutral")
    assert cal.progress() == {"state": "done", "done": 0, "total": 0, "measuring": None, "known": 1}


def tampered(how, style="0123456789abcdef"):
    """The cache entry of fake() for ``style`` (a digest) changed as a hostile or broken file would change it."""
    entry = {"style": style, "commanded": list(CALIBRATION_COMMANDS), "achieved": fake().achieved[:, 1:].tolist(),
             "directions": list(CALIBRATION_DIRECTIONS)}
    if how == "zeros":
        entry["achieved"] = np.zeros_like(fake().achieved[:, 1:]).tolist()
    elif how == "huge":
        entry["achieved"] = (np.ones_like(fake().achieved[:, 1:]) * 1e300).tolist()
    elif how == "unsorted":
        entry["commanded"] = entry["commanded"][::-1]
    elif how == "other commands":
        entry["commanded"] = [v * 2 for v in entry["commanded"]]
    elif how == "negative":
        entry["achieved"][1][3] = -0.5
    elif how == "directions":
        entry["directions"] = [0.0, 45.0, 180.0]
    return entry


@pytest.mark.parametrize("how", ["zeros", "huge", "unsorted", "other commands", "negative", "directions"])
def test_a_tampered_cache_is_refused_and_measured_again(released_source, tmp_path, monkeypatch, capsys, how):
    measured = []
    monkeypatch.setattr(calibrations, "measure", lambda source, name: measured.append(name) or fake())
    cache = CalibrationCache(released_source, tmp_path, shipped=None)
    entry = tampered(how, style_digest(released_source, "Neutral"))
    cache.path.write_text(json.dumps({"version": CALIBRATION_VERSION, "styles": {"Neutral": entry}}))
    cal = Calibrations(released_source, first=["Neutral"], background=False,
                       cache=CalibrationCache(released_source, tmp_path, shipped=None))
    assert measured == ["Neutral"], how                        # not taken from the file: measured again
    assert "warning: ignoring the speed calibration cache" in capsys.readouterr().err
    assert max_speed(cal._cal["Neutral"], 0.0) == pytest.approx(1.8)
    again = CalibrationCache(released_source, tmp_path, shipped=None).load()   # the file now holds the measurement
    np.testing.assert_allclose(again["Neutral"].achieved, fake().achieved)


def test_an_untampered_entry_is_read_back():
    assert tampered("none")["commanded"] == list(CALIBRATION_COMMANDS)
    from minifilm.demo.calibration_cache import _from_json
    np.testing.assert_allclose(_from_json(tampered("none"), CALIBRATION_COMMANDS).achieved, fake().achieved)
    with pytest.raises(ValueError, match="not the measured"):
        _from_json(tampered("none"), RUN_CALIBRATION_COMMANDS)


def test_max_speed_reads_the_fastest_measured_per_direction():
    assert max_speed(fake(), 0.0) == pytest.approx(1.8)
    assert max_speed(fake(), 90.0) == pytest.approx(1.2)
    assert max_speed(fake(), 45.0) == pytest.approx(1.5)


def test_a_run_beyond_the_style_is_scaled_to_what_it_can_do_and_said(released_source, monkeypatch):
    monkeypatch.setattr(calibrations, "measure", lambda source, name: fake())
    cal = Calibrations(released_source, first=["Neutral"], background=False)
    c = Character(1, released_source, cal, DemoSettings(style="Neutral"))
    c.submit(InputMessage((0.0, 1.0), 0.0, 1.0, seq=7))          # Shift+W: 2.8 m/s asked
    frame, _ = c.step()
    assert frame["commanded"] == pytest.approx(2.8)
    assert frame["maxSpeed"] == pytest.approx(1.8) and frame["reachable"] == pytest.approx(REACHABLE * 1.8)
    assert "1.80 m/s" in frame["speedNote"] and "Neutral" in frame["speedNote"]
    assert math.hypot(*frame["velocity"]) == pytest.approx(2.8, abs=1e-3)      # what was asked
    assert math.hypot(*c.steered) == pytest.approx(REACHABLE * 1.8)             # what it was steered at
    assert frame["inputMs"] is not None and frame["inputMs"] >= 0
    c.submit(InputMessage((0.0, 1.0), 0.0, 0.0, seq=8))          # a walk it can do: as asked
    frame, _ = c.step()
    assert frame["reachable"] == pytest.approx(1.3) and frame["speedNote"] is None


def test_readouts_have_no_value_before_they_have_data(tiny_source):
    source = replace(tiny_source, calibrate=False)
    c = Character(1, source, Calibrations(source), DemoSettings(style=source.default_style()))
    frame, _ = c.step()
    assert frame["inputMs"] is None and frame["sentFps"] is None and frame["maxSpeed"] is None
    assert frame["calibration"] == {"state": "off"}


def test_the_rate_counter_counts_the_last_second_only():
    r = RateCounter()
    assert r.rate() is None
    now = time.monotonic()
    r.times.extend([now - 1.5] + [now - 0.5 + i * 0.01 for i in range(30)])
    assert r.rate() == 30.0


def test_held_out_styles_are_named_as_what_is_known_of_them():
    names = [f"S{i}" for i in range(95)] + ["095", "096", "097", "098", "099"]
    info = held_out(names)
    assert info["ids"] == ["095", "096", "097", "098", "099"] and "WildArms" in info["styles"]
    assert "not documented" in info["note"]
    assert held_out(["Neutral", "LeftHop"]) == {}


def test_the_released_demo_starts_calibrated_from_the_package(tmp_path):
    """The released network's calibrations come with the package: every style is known at the
    first frame, nothing is measured, nothing is written to the cache."""
    from minifilm.demo.client import DemoClient
    from minifilm.demo.process import DemoProcess
    if not (RELEASED / "Xmean.bin").is_file():
        pytest.skip("needs the released network")
    with DemoProcess("--params", RELEASED, cache=tmp_path) as demo:
        with DemoClient(demo.url) as page:
            end = time.monotonic() + 120
            frame = page.next_frame()
            while frame["calibration"]["known"] < 100 and time.monotonic() < end:   # the cache is read on a thread
                frame = page.next_frame()
            assert frame["calibration"] == {"state": "done", "done": 0, "total": 0, "measuring": None, "known": 100}
            page.send({"type": "style", "weights": {"Zombie": 0.5, "Old": 0.3, "Drunk": 0.2}})
            for _ in range(30):
                frame = page.next_frame()
            assert frame["calibration"]["state"] == "done" and frame["calibration"]["total"] == 0
        assert "measuring the speed calibration" not in "".join(demo.lines)
    assert os.listdir(tmp_path) == []


def test_the_released_demo_serves_its_page_without_measuring_first(tmp_path):
    """With --recalibrate, no speed calibration before the URL: the command's own start-up is
    loading the network and binding (timings are for benchmarks/demo_startup.py; here: what
    happens before the URL), then the start style is measured and cached."""
    from minifilm.demo.process import DemoProcess
    if not (RELEASED / "Xmean.bin").is_file():
        pytest.skip("needs the released network")
    with DemoProcess("--params", RELEASED, "--recalibrate", cache=tmp_path) as demo:
        end = time.monotonic() + 60
        while "speed calibration of Neutral in the background" not in "".join(demo.lines) \
                and time.monotonic() < end:
            time.sleep(0.1)
        assert "speed calibration of Neutral in the background" in "".join(demo.lines)      # in the terminal
        from minifilm.demo.client import DemoClient
        with DemoClient(demo.url) as page:
            assert page.hello["calibration"]["state"] in ("measuring", "done")
            frame = page.next_frame()
            assert frame["calibration"]["total"] >= 1
        end = time.monotonic() + 900
        while not os.listdir(tmp_path) and time.monotonic() < end:
            time.sleep(0.5)
        files = os.listdir(tmp_path)
        assert len(files) == 1 and files[0].startswith("calibration-"), files
