"""Smoke test: a miniature of the main job (``examples/train_small.py`` = ``minifilm train``: tiny
data, one epoch) runs every step and leaves a run folder that works from any working directory."""
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from minifilm.motion.bvh import read_bvh
from minifilm.pipeline.run_folder import RunFolder, RunFolderError
from minifilm.pipeline.train_small import Settings, run
from minifilm.runtime.style_library import StyleLibrary
from minifilm.train.checkpoint import load_checkpoint

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "train_small.py"
MINI = ["--quick", "--styles", "Neutral,LeftHop", "--gaits", "FW", "--seconds", "6", "--epochs", "1",
        "--generate-seconds", "0.5"]


@pytest.fixture(scope="module")
def mini_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    s = replace(Settings(out=out).quick(), styles=("Neutral", "LeftHop"), gaits=("FW",), seconds_per_clip=6.0,
                epochs=1, generate_seconds=0.5)
    return out, run(s)


def test_train_small_miniature_end_to_end(mini_run, capsys):
    out, result = mini_run
    assert np.isfinite(result["mse"]) and np.isfinite(result["bll"])
    assert set(result["per_style"]) == {"Neutral", "LeftHop"}
    # the synthetic data went through BVH files
    assert sorted(p.name for p in (out / "data").glob("*.bvh")) == ["LeftHop_FW.bvh", "Neutral_FW.bvh"]
    # the checkpoint holds the model and the normalisation statistics, and loads without pickle
    meta, arrays = load_checkpoint(out / "model.npz")
    assert meta["epoch"] == 1
    assert meta["style_names"] == ["LeftHop", "Neutral"]
    assert any(k.startswith("stats.") for k in arrays)
    # one FiLM vector per style, and a generated BVH per style that reads back on the same skeleton
    library = StyleLibrary.load(out / "styles.npz")
    assert sorted(library.names) == ["LeftHop", "Neutral"]
    for style in ("Neutral", "LeftHop"):
        motion = read_bvh(out / "generated" / f"{style}.bvh")
        assert motion.n_frames == 30
        assert motion.n_joints == 28
        positions, _ = motion.world()
        assert np.all(np.isfinite(positions))
    # and the result is visible: every style side by side in a GIF and in the HTML player
    from PIL import Image
    with Image.open(out / "generated" / "styles.gif") as im:
        assert im.n_frames == 15 and im.size == (400, 250)       # 0.5 s at 30 fps, two 200 x 250 panels
    html = (out / "generated" / "index.html").read_text(encoding="utf-8")
    assert "Neutral" in html and "LeftHop" in html and "minifilmPlayer" in html


def test_the_run_folder_works_from_another_directory(mini_run, tmp_path, monkeypatch):
    out, _ = mini_run
    monkeypatch.chdir(tmp_path)               # not the folder the run was made from
    folder = RunFolder.load(out)
    assert folder.fps == pytest.approx(60.0, rel=1e-6) and folder.layout.n_joints == 25
    assert set(folder.starts()) == {"Neutral", "LeftHop"}
    ctl = folder.controller()
    x0, p0 = folder.start_states(["Neutral"])
    from minifilm.runtime.control import straight_walk
    r = ctl.run(straight_walk(1.0), 30, folder.styles()["Neutral"], phases=p0, start_x=x0)
    assert np.all(np.isfinite(r.positions))
    # the dataset cache stores its files relative to itself: it loads from here too
    from minifilm.dataset.dataset import Dataset
    cache = next((out / "cache").glob("dataset-*.npz"))
    ds = Dataset.load(cache)
    assert all(Path(f["path"]).is_file() for f in ds.files)


def test_a_folder_that_is_not_a_run_is_refused(tmp_path):
    with pytest.raises(RunFolderError, match="run.json"):
        RunFolder.load(tmp_path)
    (tmp_path / "run.json").write_text("{not json")
    with pytest.raises(RunFolderError, match="not valid"):
        RunFolder.load(tmp_path)


def test_the_example_and_the_command_take_the_same_options(tmp_path):
    """``python examples/train_small.py`` is ``minifilm train``: the same --help."""
    a = subprocess.run([sys.executable, str(EXAMPLE), "--help"], capture_output=True, text=True, timeout=60)
    b = subprocess.run([sys.executable, "-m", "minifilm", "train", "--help"], capture_output=True, text=True,
                       timeout=60)
    assert a.returncode == b.returncode == 0
    assert a.stdout == b.stdout and "--quick" in a.stdout and "--data" in a.stdout
