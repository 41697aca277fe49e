"""Start-up and honest read-outs: the calibration cache (minifilm/demo/calibration_cache.py)
keyed by the network's files, written atomically, a corrupt one ignored with a warning; the
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
from minifilm.demo.calibration_cache import CALIBRATION_VERSION, CalibrationCache, max_speed, network_key
from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import REACHABLE, Character, DemoSettings, RateCounter
from minifilm.demo.protocol import InputMessage
from minifilm.demo.server import held_out
from minifilm.runtime.calibration import CALIBRATION_COMMANDS, CALIBRATION_DIRECTIONS, SpeedCalibration


def fake(name="Neutral", k=1.0):
    """A calibration at the commands and directions really measured: forwards up to 1.8 m/s,
    sideways 1.2, backwards 1.0."""
    c = np.array(CALIBRATION_COMMANDS)
    achieved = np.stack([np.minimum(0.45 * c, top) for top in (1.8, 1.2, 1.0)])
    return SpeedCalibration(c, k * achieved, CALIBRATION_DIRECTIONS)


@pytest.fixture
def network(tmp_path):
    folder = tmp_path / "net"
    folder.mkdir()
    (folder / "a.bin").write_bytes(b"\x00" * 64)
    (folder / "b.bin").write_bytes(b"\x01" * 64)
    return folder


def test_the_key_changes_with_any_file_of_the_network(network):
    key = network_key(network)
    assert network_key(network) == key
    (network / "b.bin").write_bytes(b"\x01" * 63 + b"\x02")
    assert network_key(network) != key
    (network / "b.bin").write_bytes(b"\x01" * 64)
    (network / "c.bin").write_bytes(b"")
    assert network_key(network) != key


def test_a_cache_round_trips_and_is_written_atomically(network, tmp_path):
    where = tmp_path / "cache"
    cache = CalibrationCache(network, where)
    assert cache.load() == {}
    cache.put("Neutral", fake())
    cache.put("Zombie", fake(k=0.5))
    assert sorted(p.name for p in where.iterdir()) == [cache.path.name]     # no temporary left
    again = CalibrationCache(network, where).load()
    assert sorted(again) == ["Neutral", "Zombie"]
    np.testing.assert_allclose(again["Zombie"].achieved, fake(k=0.5).achieved)
    assert again["Neutral"].command_for(1.0) == pytest.approx(fake().command_for(1.0))


@pytest.mark.parametrize("content", [
    b"{not json", b"", b"[]", json.dumps({"version": "other", "styles": {}}).encode(),
    json.dumps({"version": CALIBRATION_VERSION, "styles": {"N": {"commanded": [1, 2], "achieved": [[1]],
                                                                 "directions": [0]}}}).encode(),
    json.dumps({"version": CALIBRATION_VERSION, "styles": {"N": {"commanded": [1], "achieved": [[1e400]],
                                                                 "directions": [0]}}}).encode(),
    b"[" * 100000,
])
def test_a_corrupt_cache_is_ignored_with_one_warning(network, tmp_path, capsys, content):
    cache = CalibrationCache(network, tmp_path / "cache")
    cache.path.parent.mkdir(parents=True)
    cache.path.write_bytes(content)
    assert cache.load() == {}
    err = capsys.readouterr().err
    assert err.count("warning: ignoring the speed calibration cache") == 1 and "Traceback" not in err
    cache.put("Neutral", fake())                         # and it is rewritten whole
    assert sorted(CalibrationCache(network, tmp_path / "cache").load()) == ["Neutral"]


def test_a_cache_that_is_not_a_regular_file_is_ignored(network, tmp_path, capsys):
    cache = CalibrationCache(network, tmp_path / "cache")
    cache.path.mkdir(parents=True)
    assert cache.load() == {}
    assert "ignoring" in capsys.readouterr().err


def test_an_unwritable_cache_folder_is_a_warning_not_an_error(network, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    CalibrationCache(network, blocker / "cache").put("Neutral", fake())
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
    cache = CalibrationCache(RELEASED, tmp_path)
    Calibrations(released_source, first=["Neutral"], background=False, cache=cache)
    assert measured == ["Neutral"]
    cal = Calibrations(released_source, first=["Neutral"], background=False, cache=CalibrationCache(RELEASED, tmp_path))
    assert measured == ["Neutral"] and cal.has("Neutral")
    assert cal.progress() == {"state": "done", "done": 0, "total": 0, "measuring": None, "known": 1}


def tampered(how):
    """The cache entry of fake() changed as a hostile or broken file would change it."""
    entry = {"commanded": list(CALIBRATION_COMMANDS), "achieved": fake().achieved[:, 1:].tolist(),
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
    cache = CalibrationCache(RELEASED, tmp_path)
    cache.path.write_text(json.dumps({"version": CALIBRATION_VERSION, "styles": {"Neutral": tampered(how)}}))
    cal = Calibrations(released_source, first=["Neutral"], background=False, cache=CalibrationCache(RELEASED, tmp_path))
    assert measured == ["Neutral"], how                        # not taken from the file: measured again
    assert "warning: ignoring the speed calibration cache" in capsys.readouterr().err
    assert max_speed(cal._cal["Neutral"], 0.0) == pytest.approx(1.8)
    again = CalibrationCache(RELEASED, tmp_path).load()        # and the file now holds the measurement
    np.testing.assert_allclose(again["Neutral"].achieved, fake().achieved)


def test_an_untampered_entry_is_read_back():
    assert tampered("none")["commanded"] == list(CALIBRATION_COMMANDS)
    from minifilm.demo.calibration_cache import _from_json
    np.testing.assert_allclose(_from_json(tampered("none")).achieved, fake().achieved)


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


def test_the_released_demo_serves_its_page_without_measuring_first(tmp_path):
    """No speed calibration before the URL: the command's own start-up is loading the network and
    binding (timings are for benchmarks/demo_startup.py; here: what happens before the URL)."""
    from minifilm.demo.process import DemoProcess
    if not (RELEASED / "Xmean.bin").is_file():
        pytest.skip("needs the released network")
    with DemoProcess("--params", RELEASED, cache=tmp_path) as demo:
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
