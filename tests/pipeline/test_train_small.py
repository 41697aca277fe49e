"""Smoke test: a miniature of the main job (``examples/train_small.py`` = ``minifilm train``: tiny
data, one epoch) runs every step and leaves a run folder that works from any working directory."""
import ast
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

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "train_small.py"
MINI = ["--quick", "--styles", "Neutral,LeftHop", "--gaits", "FW", "--seconds", "6", "--epochs", "1",
        "--generate-seconds", "0.5"]


@pytest.fixture(scope="module")
def mini_run(tiny_job):
    """(run folder, result) of the main job in miniature: the session's (tests/conftest.py), made in
    this process with MINI's settings."""
    return tiny_job


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


class Stop(Exception):
    """Raised by a stand-in main_job: the settings were made, the job is not run."""


def example_settings(argv, monkeypatch):
    """(Settings, data) that ``python examples/train_small.py ARGV`` would run the job with."""
    example = runpy.run_path(str(EXAMPLE), run_name="example")
    seen = {}

    def main_job(settings, data, ranks):
        seen.update(settings=settings, data=data)
        raise Stop
    monkeypatch.setitem(example["main"].__globals__, "main_job", main_job)
    with pytest.raises(Stop):
        example["main"](argv)
    return seen["settings"], seen["data"]


#: every setting of the example: a good value, the Settings field it sets with the value it gets,
#: and a bad value (refused with one line naming the option)
SETTINGS = {
    "--epochs": ("3", "epochs", 3, "0"), "--seed": ("7", "seed", 7, "-1"),
    "--batch-size": ("16", "batch_size", 16, "many"), "--learning-rate": ("1e-3", "learning_rate", 1e-3, "nan"),
    "--clips-per-batch": ("2", "clips_per_batch", 2, "0"), "--styles": ("Neutral,Limp", "styles", ("Neutral", "Limp"), "Nobody"),
    "--gaits": ("FW,TR", "gaits", ("FW", "TR"), "XX"), "--seconds": ("4", "seconds_per_clip", 4.0, "-2"),
    "--clip-seconds": ("1.5", "clip_seconds", 1.5, "0"), "--generate-seconds": ("3", "generate_seconds", 3.0, "inf"),
    "--workers": ("1", "workers", 1, "0"), "--out": ("elsewhere", "out", Path("elsewhere"), ""),
    "--split": ("files", "split", "files", "sideways"), "--fps": ("30", "fps", 30.0, "0"),
    "--rig": ("cmu", "rig", "cmu", "no-such-rig"),
    "--model": ("paper", "model", {"n_experts": 8, "hidden": 512, "gating_hidden": 32, "conv_filters": 256,
                                   "conv_kernel": 25, "film_dense": 2048, "dropout": 0.3, "ln_unbiased": True,
                                   "ln_eps": 1e-6}, "huge"),            # the paper's Sec. 4 sizes
}
OWN_DATA = ("--split", "--fps", "--rig")          # settings for your own data: given with --data


@pytest.mark.parametrize("option", list(SETTINGS))
def test_every_setting_of_the_example_takes_a_good_value_and_refuses_a_bad_one(option, monkeypatch, capsys,
                                                                               tmp_path):
    good, field, value, bad = SETTINGS[option]
    data = ["--data", str(EXAMPLE.parent)] if option in OWN_DATA else []
    monkeypatch.chdir(tmp_path)
    settings, _ = example_settings([*data, option, good], monkeypatch)
    assert getattr(settings, field) == value
    example = runpy.run_path(str(EXAMPLE), run_name="example")
    with pytest.raises(SystemExit) as stop:
        from minifilm.cli import run_command
        run_command(lambda: example["main"]([*data, option, bad]))
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and (option in err[0] or bad in err[0]), err
    assert list(tmp_path.iterdir()) == []                 # refused before anything was written


def test_the_example_s_flags_and_defaults(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    assert example_settings([], monkeypatch)[0] == Settings()
    assert example_settings(["--quick"], monkeypatch)[0] == Settings().quick()
    settings, data = example_settings(["--data", str(EXAMPLE.parent), "--mirror"], monkeypatch)
    assert settings.mirror and data == EXAMPLE.parent
    settings, _ = example_settings(["--quick", "--epochs", "5"], monkeypatch)       # a setting wins over --quick
    assert settings == replace(Settings().quick(), epochs=5)


@pytest.mark.parametrize("argv,says", [(["--workers", "1", "--epochs", "x"], "--epochs"),
                                       (["--no-such-setting", "1"], "--no-such-setting"),
                                       (["--mirror"], "only with --data"),
                                       (["--data", "no/such/folder"], "no/such/folder")])
def test_the_example_s_command_line_refuses_bad_settings_in_one_line(tmp_path, argv, says):
    """Through the real command line (a new Python): exit code 2, one line, nothing written."""
    proc = subprocess.run([sys.executable, str(EXAMPLE), *argv], cwd=tmp_path, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and proc.stdout == "", proc.stdout + proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and says in proc.stderr, proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_split_that_cannot_be_made_names_the_users_folder_also_through_a_rig(tmp_path):
    """With --rig the files are retargeted into the run's own folder first: the error still names
    the folder the user gave, not the retargeted copies (nor a list of internal records)."""
    from minifilm.errors import DataError
    from minifilm.synthetic.generator import default_dataset, write_dataset
    mine = tmp_path / "my data"
    write_dataset(mine, default_dataset(styles=["Neutral", "Limp"], gaits=["FW"], seconds=3.0, seed=1))
    with pytest.raises(DataError) as refused:
        run(replace(Settings(out=tmp_path / "run").quick(), rig="100style", split="files"), data=mine)
    message = str(refused.value)
    assert message.startswith(f"{mine}: the val and test split(s) have no frames") and "MotionFile" not in message


def test_training_over_a_run_says_it_replaces_it_and_its_taught_styles(tmp_path, capsys):
    from minifilm.pipeline.train_small import say_replaced
    say_replaced(tmp_path)                                       # not a run: nothing to say
    (tmp_path / "run.json").write_text("{}")
    (tmp_path / "model-Strut.npz").write_bytes(b"")
    say_replaced(tmp_path)
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "holds an earlier run" in out and "1 style(s) taught to it ('model-Strut.npz')" in out


def test_a_setting_that_cannot_make_a_run_is_refused_before_anything_is_written():
    with pytest.raises(InputError, match="only with your own data"):
        run(replace(Settings(), mirror=True))


def test_the_example_spells_out_the_training_step_and_trains_as_the_job_does(mini_run, tmp_path, capsys):
    """The example's loop is the training step itself -- forward, the losses, the backward pass,
    Adam's update -- and it makes what the main job makes: the same run folder, the same checkpoint
    bit for bit (both in this process, with the same BLAS threads: the same arithmetic in the
    same order), so the loop a reader follows is the one Trainer.train_step runs."""
    tree = ast.parse(EXAMPLE.read_text(encoding="utf-8"))
    calls = {ast.unparse(node.func) for node in ast.walk(tree) if isinstance(node, ast.Call)}
    for step in ("model.forward", "trainer.losses", "model.backward", "trainer.update", "trainer.minibatches"):
        assert step in calls, step
    assert not [c for c in calls if c.endswith(("train_epoch", "train_step", ".fit"))], calls
    out, _ = mini_run
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


@pytest.mark.parametrize("workers", [1, 2, None])
def test_workers_is_the_number_of_processes_labelling_the_data_set(tmp_path, monkeypatch, workers):
    """--workers N reaches the data set's builder (1: all in this process; None: every core)."""
    import minifilm.pipeline.train_small as ts
    seen = {}

    def build(*args, **kw):
        seen.update(kw)
        raise KeyboardInterrupt          # stop the job here: only the call is looked at

    monkeypatch.setattr(ts, "build_dataset", build)
    s = replace(Settings().quick(), styles=["Neutral"], gaits=["FW"], seconds_per_clip=6.0, workers=workers)
    with pytest.raises(KeyboardInterrupt):
        ts.prepare_data(s, None, tmp_path)
    assert seen["workers"] == workers
