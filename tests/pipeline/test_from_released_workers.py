"""`minifilm dataset --from-released --workers N`: the styles driven in worker processes
(minifilm/pipeline/from_released_workers.py) give the data set of one process, to float32
round-off; a worker's error is the error of one process; a killed worker is one WorkerDied naming
it, and leaves no output folder and no process."""
import json
import os
import re
import signal

import numpy as np
import pytest

from minifilm.errors import InputError
from minifilm.pipeline.from_released import ReleasedDataSettings, make_released_dataset, min_seconds_per_style
from minifilm.processes import WorkerDied

STYLES = ("Neutral", "Zombie", "Aeroplane", "Chicken")
GAITS = ("FW", "TR1")


def settings(gaits=GAITS, **kw) -> ReleasedDataSettings:
    """The least data set of STYLES: the least seconds per style, a small calibration grid."""
    return ReleasedDataSettings(seconds_per_style=min_seconds_per_style(gaits), styles=STYLES, gaits=gaits,
                                calibration_commands=(1.0, 3.0), calibration_directions=(0.0, 180.0),
                                calibration_seconds=2.0, **kw)


def worker_ids(lines) -> list:
    found = [re.search(r"(\d+) styles in (\d+) worker processes \(ids ([\d, ]+)\)", line) for line in lines]
    found = [f for f in found if f]
    assert len(found) == 1, lines
    return [int(pid) for pid in found[0].group(3).split(",")]


def running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    status = f"/proc/{pid}/status"
    return not (os.path.exists(status) and "zombie" in open(status).read().lower())


def bvh_numbers(path) -> tuple:
    """(the text up to the frames, the frames' numbers (F, channels))."""
    head, frames = path.read_text().split("Frame Time:")
    rows = frames.splitlines()[1:]
    return head + "Frame Time:" + frames.splitlines()[0], np.array([[float(x) for x in r.split()] for r in rows])


def assert_close(a, b, where=""):
    """JSON values equal: strings, whole numbers, None and the structure exactly; floats within
    1e-4 relative (float32 round-off of a different batch)."""
    if isinstance(a, float) or isinstance(b, float):
        assert isinstance(a, (int, float)) and isinstance(b, (int, float)), (where, a, b)
        assert a == pytest.approx(b, rel=1e-4, abs=1e-9), where
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), (where, a, b)
        for k in a:
            assert_close(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), (where, a, b)
        for i, (x, y) in enumerate(zip(a, b)):
            assert_close(x, y, f"{where}[{i}]")
    else:
        assert a == b, (where, a, b)


def test_workers_make_the_data_set_of_one_process(shared_data, tmp_path):
    params = shared_data / "released-lpn"
    outs, said = {}, {}
    for workers in (1, 2, 3):           # 3: shares of 1, 2 and 1 styles
        said[workers] = []
        outs[workers] = tmp_path / f"w{workers}"
        make_released_dataset(params, outs[workers], settings(), log=said[workers].append, workers=workers)
    assert not any("worker processes" in line for line in said[1])
    for workers in (2, 3):
        pids = worker_ids(said[workers])
        assert len(pids) == workers and os.getpid() not in pids and not [p for p in pids if running(p)]
    one = outs[1]
    names = sorted(p.name for p in one.iterdir())
    assert names == sorted([f"{s}_{g}.bvh" for s in STYLES for g in GAITS] + ["manifest.csv", "dataset.json"])
    info = json.loads((one / "dataset.json").read_text())
    assert [(r["style"], r["gait"]) for r in info["files"]] == [(s, g) for g in GAITS for s in STYLES]
    for workers in (2, 3):
        out = outs[workers]
        assert sorted(p.name for p in out.iterdir()) == names
        assert (out / "manifest.csv").read_text() == (one / "manifest.csv").read_text()
        theirs = json.loads((out / "dataset.json").read_text())
        assert_close(theirs, info, f"{workers} workers: dataset.json")
        for name in names:
            if name.endswith(".bvh"):
                head, x = bvh_numbers(out / name)
                head1, x1 = bvh_numbers(one / name)
                assert head == head1 and x.shape == x1.shape, name
                np.testing.assert_allclose(x, x1, rtol=0, atol=5e-3, err_msg=name)    # cm and degrees


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
def test_a_workers_error_is_the_error_of_one_process(shared_data, tmp_path):
    # a calibration of one frame measures no speed (0 / 0): the gaits are then commanded NaN velocities
    bad = settings(gaits=("FW",), check_labels=False)
    bad.calibration_seconds = 0.01
    raised = {}
    for workers in (1, 2):
        with pytest.raises(InputError, match="target_velocity must be .* finite numbers") as e:
            make_released_dataset(shared_data / "released-lpn", tmp_path / f"w{workers}", bad, log=lambda m: None,
                                  workers=workers)
        raised[workers] = e.value
    assert type(raised[1]) is type(raised[2])       # (the message names the batch's shape: 4 or 2 styles)
    assert list(tmp_path.iterdir()) == []           # no folder, no temporary


def test_a_killed_worker_is_one_error_and_leaves_nothing(shared_data, tmp_path):
    said, pids = [], []

    def log(line):
        said.append(line)
        if "worker processes" in line:
            pids.extend(worker_ids([line]))
        if line.startswith("FW:"):          # BW is sent; FR only after this: worker 1 cannot answer it
            os.kill(pids[1], signal.SIGKILL)

    out = tmp_path / "out"
    with pytest.raises(WorkerDied) as e:
        make_released_dataset(shared_data / "released-lpn", out, settings(gaits=("FW", "BW", "FR")), log=log, workers=2)
    assert re.fullmatch(rf"from-released: worker 1 \(process {pids[1]}\) was killed by SIGKILL while driving gait "
                        r"(BW|FR)", str(e.value)), str(e.value)
    assert not out.exists() and list(tmp_path.iterdir()) == []         # nor a temporary beside it
    assert not [pid for pid in pids if running(pid)]


@pytest.mark.parametrize("bad", [0, -1, True, 1.5, "2"])
def test_a_bad_worker_count_is_one_error_and_writes_nothing(shared_data, tmp_path, bad):
    out = tmp_path / "made"
    with pytest.raises(ValueError, match=r"make_released_dataset: workers must be a whole number >= 1"):
        make_released_dataset(shared_data / "released-lpn", out, settings(), log=lambda m: None, workers=bad)
    assert list(tmp_path.iterdir()) == []
