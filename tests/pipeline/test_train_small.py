"""Smoke test: a miniature of the main job (``examples/train_small.py`` = ``minifilm train``: tiny
data, one epoch) runs every step and leaves a run folder that works from any working directory."""
import ast
import inspect
import os
import runpy
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from minifilm.errors import InputError
from minifilm.motion.bvh import read_bvh
from minifilm.pipeline.run_folder import RunFolder, RunFolderError
from minifilm.pipeline.train_small import Settings, run
from minifilm.runtime.style_library import StyleLibrary
from minifilm.train.checkpoint import load_checkpoint
from minifilm.train.trainer import Trainer

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


def example_settings(argv):
    example = runpy.run_path(str(EXAMPLE), run_name="example")
    return example["job_settings"](*example["override_settings"](argv))


@pytest.mark.parametrize("argv", [[], ["--quick"], MINI, ["--quick", "--epochs", "5", "--clips-per-batch", "32"],
                                  ["--data", str(EXAMPLE.parent), "--split", "files", "--mirror", "--fps", "30"]],
                         ids=["defaults", "quick", "mini", "quick epochs", "own data"])
def test_the_example_s_plain_settings_make_the_command_s_settings(argv):
    """``python examples/train_small.py ARGS`` runs the job ``minifilm train ARGS`` runs: its plain
    values at the top are the command's defaults, and ``--name value`` changes what the option does."""
    from minifilm.cli import Parser
    from minifilm.cli import train as options
    parser = Parser(prog="minifilm train")
    options.add_arguments(parser)
    command = options.settings(parser.parse_args(argv))
    assert example_settings(argv) == command


def test_a_setting_the_example_does_not_have_is_one_clear_error():
    with pytest.raises(InputError, match="--no-such-setting: not a setting"):
        example_settings(["--no-such-setting", "1"])
    with pytest.raises(InputError, match="--epochs"):
        example_settings(["--epochs", "many"])
    with pytest.raises(InputError, match="only with your own data"):
        run(replace(Settings(), mirror=True))          # checked before anything is written


def test_the_example_imports_nothing_from_the_command_line_layer():
    tree = ast.parse(EXAMPLE.read_text(encoding="utf-8"))
    imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    imported |= {a.name for node in ast.walk(tree) if isinstance(node, ast.Import) for a in node.names}
    assert not [m for m in imported if m and m.startswith("minifilm.cli")], imported


def test_the_training_loop_is_written_once(mini_run, tmp_path, capsys):
    """The example runs the Trainer's one epoch loop (Trainer.train_epoch, a Trainer.train_step per
    minibatch) rather than a copy of it, and calls the package for the rest: the same run folder,
    bit for bit the same checkpoint as the main job (pipeline/train_small.py::run, the job of
    ``minifilm train``)."""
    tree = ast.parse(EXAMPLE.read_text(encoding="utf-8"))
    calls = {ast.unparse(node.func) for node in ast.walk(tree) if isinstance(node, ast.Call)}
    assert "trainer.train_epoch" in calls
    assert not [c for c in calls if c.endswith((".forward", ".backward", ".step", ".train_step"))], calls
    epoch_loop = inspect.getsource(Trainer.train_epoch)
    assert "self.train_step(b, pool)" in epoch_loop and "forward(" not in epoch_loop
    out, _ = mini_run
    # in this process, like mini_run: BLAS's rounding depends on its thread count
    runpy.run_path(str(EXAMPLE), run_name="example")["main"]([*MINI, "--out", str(tmp_path / "ex")])
    printed = capsys.readouterr().out
    mine, theirs = np.load(tmp_path / "ex" / "model.npz"), np.load(out / "model.npz")
    assert sorted(mine.files) == sorted(theirs.files)
    for k in theirs.files:
        if theirs[k].dtype.kind == "f":
            np.testing.assert_array_equal(mine[k], theirs[k], err_msg=k)
    made = {p.relative_to(tmp_path / "ex").as_posix() for p in (tmp_path / "ex").rglob("*") if "cache" not in p.parts}
    assert made == {p.relative_to(out).as_posix() for p in out.rglob("*") if "cache" not in p.parts}
    for line in ("[train] ", "        1 ", "[test] MSE per style", "[generate]", "[style]", "[view]", "[done]"):
        assert line in printed


def test_importing_the_example_loads_no_viewer_demo_evaluation_or_scipy_signal():
    """What the example imports before it runs: the core of the job, not the optional parts."""
    code = ("import runpy, sys; runpy.run_path(sys.argv[1], run_name='not_main'); "
            "print('\\n'.join(sorted(sys.modules)))")
    proc = subprocess.run([sys.executable, "-c", code, str(EXAMPLE)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    loaded = proc.stdout.split()
    assert "minifilm.pipeline.train_small" in loaded and "minifilm.model.style_model" in loaded
    bad = [m for m in loaded if m.startswith(("minifilm.viewer", "minifilm.demo", "minifilm.evaluation",
                                              "scipy.signal", "matplotlib"))]
    assert not bad, f"loaded before use: {bad}"


@pytest.mark.parametrize("workers,expected", [(1, 1), (2, None), (None, None)])
def test_workers_1_labels_the_data_set_in_this_process_too(tmp_path, monkeypatch, workers, expected):
    """--workers 1 means one process for the whole job, the data set's labelling included; any
    other count leaves the labelling's own choice (the cores, where the motion pays for a worker)."""
    import minifilm.pipeline.train_small as ts
    seen = {}

    def build(*args, **kw):
        seen.update(kw)
        raise KeyboardInterrupt          # stop the job here: only the call is looked at

    monkeypatch.setattr(ts, "build_dataset", build)
    s = replace(Settings().quick(), styles=["Neutral"], gaits=["FW"], seconds_per_clip=6.0, workers=workers)
    with pytest.raises(KeyboardInterrupt):
        ts.prepare_data(s, None, tmp_path)
    assert seen["workers"] == expected
