"""`minifilm dataset --from-released`: a 100STYLE-named data set made by the released network (small:
2 styles x 3 s), its gait scripts, determinism, and the labelling check against the network."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from minifilm.dataset.build import build_dataset
from minifilm.dataset.manifest import read_manifest, scan_folder
from minifilm.evaluation.label_agreement import agreement, circular_distance, phase_angles, summarise
from minifilm.motion.bvh import read_bvh
from minifilm.phases.label import Labels
from minifilm.phases.local_phases import LocalPhases
from minifilm.pipeline.gait_scripts import GAIT_SHARES, gait_keys, gait_script, gait_seconds
from minifilm.pipeline.from_released import style_seed

STYLES = ("Neutral", "Zombie")


def minifilm(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "minifilm", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


# ----------------------------------------------------------------------------- gait scripts

def commands(gait, seed=0, seconds=20.0):
    """(speeds (T,), movement angle from the facing in degrees (T,)) sampled at 10 Hz."""
    script = gait_script(gait, style_seed(seed, "Neutral", gait), seconds, warmup=1.0)
    out = []
    for t in np.arange(0.0, seconds + 1.0, 0.1):
        facing, v = script.command(t, np.zeros(2), np.array([0.0, 1.0]))
        speed = np.linalg.norm(v)
        ang = np.degrees(np.arccos(np.clip(v @ facing / max(speed, 1e-9), -1, 1))) if speed > 1e-9 else 0.0
        out.append((speed, ang))
    return np.array(out).T


def test_gait_scripts_ask_for_their_gait():
    speed, ang = commands("FW")
    assert np.all(ang < 1) and 0.8 <= speed.min() and speed.max() <= 1.7
    speed, ang = commands("BW")
    assert np.all(ang > 179) and speed.max() <= 1.1
    speed, ang = commands("FR")
    assert speed.min() >= 2.5 and np.all(ang < 1)
    speed, ang = commands("BR")
    assert speed.min() >= 1.4 and np.all(ang > 179)
    for g in ("SW", "SR"):
        speed, ang = commands(g)
        side = ang[speed > 0.1]
        assert np.mean(np.abs(side - 90) < 1) > 0.7, g          # mostly sideways (ramps between)
    speed, _ = commands("ID")
    assert np.all(speed == 0)
    speed, _ = commands("TR1", seconds=40)
    assert speed.min() == 0 and speed.max() >= 2.5 and np.any((speed > 0.8) & (speed < 1.6))


def test_gait_scripts_turn_and_are_seeded():
    a = gait_keys("FW", np.random.default_rng(1), 30.0)
    b = gait_keys("FW", np.random.default_rng(1), 30.0)
    c = gait_keys("FW", np.random.default_rng(2), 30.0)
    assert a == b and a != c
    headings = np.array([k[2] for k in a])
    assert np.ptp(headings) >= 20                              # at least one turn in 30 s
    assert a[-1][0] == pytest.approx(30.0)
    assert sum(GAIT_SHARES.values()) == pytest.approx(1.0)
    assert sum(gait_seconds(60.0).values()) == pytest.approx(60.0)
    with pytest.raises(ValueError, match="no script for gait"):
        gait_keys("XX", np.random.default_rng(0), 5.0)


def test_style_seed_depends_on_style_and_gait_only():
    assert style_seed(0, "Neutral", "FW").random() == style_seed(0, "Neutral", "FW").random()
    assert style_seed(0, "Neutral", "FW").random() != style_seed(0, "Zombie", "FW").random()
    assert style_seed(0, "Neutral", "FW").random() != style_seed(0, "Neutral", "BW").random()
    assert style_seed(0, "Neutral", "FW").random() != style_seed(1, "Neutral", "FW").random()


# ----------------------------------------------------------------------------- label agreement

def fake_labels(phase, amplitude, contacts):
    return Labels(np.asarray(contacts, float), LocalPhases(np.asarray(phase, float), np.asarray(amplitude, float)))


def test_agreement_is_one_and_zero_where_it_must_be():
    F = 120
    phi = (np.arange(F)[:, None] / 60.0 + np.array([0.0, 0.5, 0.1, 0.6])) % 1.0
    amp = np.ones((F, 4))
    vec = np.zeros((F, 8))
    vec[:, 0::2], vec[:, 1::2] = np.sin(2 * np.pi * phi), np.cos(2 * np.pi * phi)
    np.testing.assert_allclose(phase_angles(vec), phi, atol=1e-12)
    contacts = (np.sin(2 * np.pi * phi[:, 2:]) > 0).astype(float)[:, ::-1]
    lab = fake_labels(phi, amp, contacts)
    same = agreement(lab, contacts * 0.9 + 0.05, vec)
    assert same["contacts"] == 1.0 and same["phase_error"] < 1e-9 and same["phase_within"] == 1.0
    shifted = vec.copy()
    shifted[:, 4:] = np.roll(vec[:, 4:], 0, axis=0)
    phi2 = (phi + 0.25) % 1.0
    shifted[:, 0::2], shifted[:, 1::2] = np.sin(2 * np.pi * phi2), np.cos(2 * np.pi * phi2)
    off = agreement(lab, 1 - contacts, shifted)
    assert off["contacts"] == 0.0 and off["phase_error"] == pytest.approx(0.25) and off["phase_within"] == 0.0
    assert circular_distance(0.95, 0.05) == pytest.approx(0.1)
    both = summarise([same, off])
    assert both["contacts"] == 0.5 and both["phase_error"] == pytest.approx(0.125)
    with pytest.raises(ValueError, match="must be"):
        agreement(lab, contacts[:10], vec)


# ----------------------------------------------------------------------------- the command

@pytest.fixture(scope="module")
def made(shared_data, tmp_path_factory):
    """The data set of 2 styles x 3 s, written twice with the same seed (other seeds give other paths:
    test_style_seed_depends_on_style_and_gait_only)."""
    params = shared_data / "released-lpn"
    root = tmp_path_factory.mktemp("released_data")
    outs = {}
    for name, seed in (("a", 0), ("b", 0)):
        proc = minifilm("dataset", "--from-released", params, "--out", root / name, "--styles", *STYLES,
                        "--seconds-per-style", 3, "--seed", seed)
        assert proc.returncode == 0, proc.stderr
        outs[name] = (root / name, proc)
    return params, outs


def test_writes_100style_files_and_a_manifest(made):
    _, outs = made
    out, proc = outs["a"]
    names = sorted(p.name for p in out.glob("*.bvh"))
    assert names == sorted(f"{s}_{g}.bvh" for s in STYLES for g in GAIT_SHARES)
    for f in scan_folder(out):                      # what `minifilm train --data DATA` reads
        assert f.style in STYLES and f.gait in GAIT_SHARES
        m = read_bvh(f.path)
        assert m.n_frames == int(round(3.0 * GAIT_SHARES[f.gait] * 60))
        assert m.fps == pytest.approx(60.0)
        assert np.all(np.isfinite(m.translations))
    assert {(f.style, f.gait) for f in read_manifest(out / "manifest.csv")} == \
        {(s, g) for s in STYLES for g in GAIT_SHARES}
    info = json.loads((out / "dataset.json").read_text())
    assert info["styles"] == list(STYLES) and len(info["files"]) == 16
    # the network's folder is named absolutely, so `compare` finds it from any working folder
    assert Path(info["params"]).is_absolute() and Path(info["params"]).resolve() == Path(made[0]).resolve()
    assert "FW:" in proc.stderr + proc.stdout and "Neutral" in proc.stdout


def test_moves_as_the_gaits_ask(shared_data, tmp_path):
    # the 3-s files above are mostly the run-up from the start pose; a few seconds per gait show the gait
    from minifilm.pipeline.from_released import ReleasedDataSettings, make_released_dataset
    s = ReleasedDataSettings(seconds_per_style=15.0, styles=["Neutral"], gaits=("FW", "FR", "ID"),
                             calibration_commands=(1.0, 3.0, 6.0), calibration_directions=(0.0,), check_labels=False)
    info = make_released_dataset(shared_data / "released-lpn", tmp_path / "d", s, log=lambda m: None)
    speed = {r["gait"]: r["mean_speed"] for r in info["files"]}
    assert speed["ID"] < 0.5 * speed["FW"] and 0.7 < speed["FW"] < speed["FR"], speed
    assert sorted(p.name for p in (tmp_path / "d").glob("*.bvh")) == ["Neutral_FR.bvh", "Neutral_FW.bvh",
                                                                      "Neutral_ID.bvh"]


def test_labels_agree_with_the_network(made):
    _, outs = made
    info = json.loads((outs["a"][0] / "dataset.json").read_text())
    for s in STYLES:
        a = info["label_agreement"][s]
        assert a["contacts"] > 0.7, (s, a)
        assert a["phase_error"] is not None and a["phase_error"] < 0.15, (s, a)


#: BVH channels (cm, degrees) of two runs of one command with one seed, each in its own process.
#: Not bit for bit: a process's float32 sums may take other BLAS kernels (another machine, another
#: memory alignment), and a rollout carries their last bits on. Measured between 1 and 2 worker
#: processes (another batching, so a larger change than two runs of one command): 2.5e-5 cm,
#: 3.9e-6 degrees; standing can grow such round-off to 0.01 in some styles
#: (minifilm/pipeline/from_released.py), while another seed moves the body by metres.
SAME_SEED_CHANNELS = 0.05
#: dataset.json's numbers (speeds, label agreement): 1 against 2 workers, 1.2e-7 relative
SAME_SEED_NUMBERS = 1e-4


def bvh_parts(path):
    """(the header and frame count, the frames' channels (F, C)) of a BVH file."""
    head, _, frames = path.read_text().partition("Frame Time:")
    time_line, _, rows = frames.partition("\n")
    return head + time_line, np.array([row.split() for row in rows.splitlines() if row.strip()], float)


def assert_json_alike(a, b, where=""):
    """Equal JSON but for floats, which agree to SAME_SEED_NUMBERS."""
    assert type(a) is type(b), where
    if isinstance(a, dict):
        assert list(a) == list(b), where
        for k in a:
            assert_json_alike(a[k], b[k], f"{where}/{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_json_alike(x, y, f"{where}[{i}]")
    elif isinstance(a, float):
        assert a == pytest.approx(b, rel=SAME_SEED_NUMBERS, abs=SAME_SEED_NUMBERS), where
    else:
        assert a == b, where


def test_same_seed_same_data(made):
    _, outs = made
    a, b = (outs[k][0] for k in "ab")
    assert sorted(p.name for p in a.iterdir()) == sorted(p.name for p in b.iterdir())
    for p in sorted(a.glob("*.bvh")):
        (head_a, frames_a), (head_b, frames_b) = bvh_parts(p), bvh_parts(b / p.name)
        assert head_a == head_b, p.name
        np.testing.assert_allclose(frames_a, frames_b, rtol=0, atol=SAME_SEED_CHANNELS, err_msg=p.name)
    assert (a / "manifest.csv").read_text() == (b / "manifest.csv").read_text()
    assert_json_alike(json.loads((a / "dataset.json").read_text()), json.loads((b / "dataset.json").read_text()))


def test_train_data_reads_it(made):
    _, outs = made
    ds = build_dataset(outs["a"][0] / "manifest.csv", cache_dir=None, clip_seconds=0.5, clip_stride_seconds=0.25)
    assert sorted(ds.styles) == sorted(STYLES)
    assert ds.split("train").x.shape[0] > 100


def test_bad_requests_are_one_line(made, tmp_path):
    params, outs = made
    proc = minifilm("dataset", "--from-released", params, "--out", tmp_path / "x", "--styles", "NoSuchStyle",
                    "--seconds-per-style", 1)
    assert proc.returncode == 2 and "NoSuchStyle" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "x").exists()
    proc = minifilm("dataset", "--from-released", params, "--seconds-per-style", 1)
    assert proc.returncode == 2 and "--out" in proc.stderr
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    proc = minifilm("dataset", "--from-released", params, "--out", mine, "--styles", "Neutral",
                    "--seconds-per-style", 1, "--no-label-check")
    assert proc.returncode == 2 and (mine / "notes.txt").read_text() == "keep me"


def test_batched_calibration_equals_one_style_at_a_time(shared_data):
    from minifilm.features.layout import FeatureLayout
    from minifilm.motion.skeletons import STYLE100
    from minifilm.pipeline.from_released import calibrate_styles
    from minifilm.runtime.calibration import calibrate_speed
    from minifilm.runtime.controller import Controller
    from minifilm.runtime.released import load_released
    rel = load_released(shared_data / "released-lpn")
    ctrl = Controller(rel.network, FeatureLayout.for_skeleton(STYLE100))
    films = np.stack([rel.styles[s] for s in STYLES])
    together = calibrate_styles(ctrl, films, (1.0, 3.0), (0.0, 180.0), seconds=3.0, batch=3)  # batches cut a style
    for film, cal in zip(films, together):
        alone = calibrate_speed(ctrl, film, commands=(1.0, 3.0), directions=(0.0, 180.0), seconds=3.0, settle=1.5)
        np.testing.assert_allclose(cal.achieved, alone.achieved, rtol=1e-3)
        assert cal.achieved[0, -1] > cal.achieved[0, 1] > 0.3        # a faster command goes faster


def test_odd_style_names_each_get_a_file_and_the_same_command_runs_again(shared_data, tmp_path):
    """Released styles renamed to names that are no file names, or meet in one after safe-making
    (``A:B`` / ``A_B``, ``Neutral_`` / ``neutral_``): each style gets files of its own, the folder is
    read back with every style under its true name, and a second run into the same --out replaces
    the first (it recognises its own output)."""
    from minifilm.pipeline.from_released import ReleasedDataSettings, make_released_dataset
    params = tmp_path / "released"
    params.mkdir()
    for p in (shared_data / "released-lpn").iterdir():
        if p.name != "styles.txt":
            (params / p.name).symlink_to(p)
    odd = ["A:B", "A_B", "Neutral_", "neutral_", "Old Man"]
    lines = (shared_data / "released-lpn" / "styles.txt").read_text().splitlines()
    (params / "styles.txt").write_text("\n".join(f"{line.split()[0]} {odd[i]}" if i < len(odd) else line
                                                 for i, line in enumerate(lines)) + "\n")
    s = ReleasedDataSettings(seconds_per_style=0.5, styles=odd, gaits=("FW",), calibrate=False, check_labels=False)
    out = tmp_path / "made"
    for _ in range(2):
        make_released_dataset(params, out, s, log=lambda m: None)
        assert sorted(f.style for f in scan_folder(out)) == sorted(odd)
        assert len(list(out.glob("*.bvh"))) == len(odd)
    assert sorted(p.name for p in out.glob("*.bvh")) == sorted(
        ["A_B_FW.bvh", "A_B-2_FW.bvh", "Neutral__FW.bvh", "neutral_-2_FW.bvh", "Old Man_FW.bvh"])
