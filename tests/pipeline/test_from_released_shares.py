"""`minifilm dataset --from-released --workers N`: the styles cut into shares driven by worker
processes (minifilm/pipeline/from_released.py, minifilm/parallel.py) give the data set of one
process, to float32 round-off; a worker's error is the error of one process and leaves no folder."""
import json
import multiprocessing

import numpy as np
import pytest

from minifilm.errors import InputError
from minifilm.pipeline.from_released import ReleasedDataSettings, make_released_dataset, min_seconds_per_style

STYLES = ("Neutral", "Zombie", "Aeroplane", "Chicken")
GAITS = ("FW", "TR1")


def settings(gaits=GAITS, **kw) -> ReleasedDataSettings:
    """The least data set of STYLES: the least seconds per style, a small calibration grid."""
    return ReleasedDataSettings(seconds_per_style=min_seconds_per_style(gaits), styles=STYLES, gaits=gaits,
                                calibration_commands=(1.0, 3.0), calibration_directions=(0.0, 180.0),
                                calibration_seconds=2.0, **kw)


def bvh_numbers(path) -> tuple:
    """(the text up to the frames, the frames' numbers (F, channels))."""
    head, frames = path.read_text().split("Frame Time:")
    rows = frames.splitlines()[1:]
    return head + "Frame Time:" + frames.splitlines()[0], np.array([[float(x) for x in r.split()] for r in rows])


def assert_close(a, b, where=""):
    """JSON values equal: strings, whole numbers, None and the structure exactly; floats within
    1e-4 relative (float32 round-off of a batch of another size)."""
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
    for workers in (1, 3):              # 3: shares of 1, 2 and 1 styles
        said[workers] = []
        outs[workers] = tmp_path / f"w{workers}"
        make_released_dataset(params, outs[workers], settings(), log=said[workers].append, workers=workers)
    assert multiprocessing.active_children() == []
    assert not any("worker processes" in line for line in said[1])
    assert "4 styles in 3 worker processes, each a share of them" in said[3]
    one, three = outs[1], outs[3]
    names = sorted(p.name for p in one.iterdir())
    assert names == sorted([f"{s}_{g}.bvh" for s in STYLES for g in GAITS] + ["manifest.csv", "dataset.json"])
    info = json.loads((one / "dataset.json").read_text())
    assert [(r["style"], r["gait"]) for r in info["files"]] == [(s, g) for g in GAITS for s in STYLES]
    assert sorted(p.name for p in three.iterdir()) == names
    assert (three / "manifest.csv").read_text() == (one / "manifest.csv").read_text()
    assert_close(json.loads((three / "dataset.json").read_text()), info, "3 workers: dataset.json")
    for name in names:
        if name.endswith(".bvh"):
            head, x = bvh_numbers(three / name)
            head1, x1 = bvh_numbers(one / name)
            assert head == head1 and x.shape == x1.shape, name
            # cm and degrees, written with 6 decimals: a batch of another size rounds its float32
            # sums otherwise, which a few seconds of standing can grow to about a centimetre
            # (module docstring of from_released.py); these short files stay within 5e-3
            np.testing.assert_allclose(x, x1, rtol=0, atol=5e-3, err_msg=name)


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
        assert multiprocessing.active_children() == []
    assert type(raised[1]) is type(raised[2])       # (the message names the batch's shape: 4 or 2 styles)
    assert raised[2].__notes__ == ["(while driving gait FW of Neutral, Zombie)"]
    assert list(tmp_path.iterdir()) == []           # no folder, no temporary


@pytest.mark.parametrize("bad", [0, -1, True, 1.5, "2"])
def test_a_bad_worker_count_is_one_error_and_writes_nothing(shared_data, tmp_path, bad):
    out = tmp_path / "made"
    with pytest.raises(ValueError, match=r"make_released_dataset: workers must be a whole number >= 1"):
        make_released_dataset(shared_data / "released-lpn", out, settings(), log=lambda m: None, workers=bad)
    assert list(tmp_path.iterdir()) == []
