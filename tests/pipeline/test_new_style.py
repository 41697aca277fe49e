"""Teaching a trained run a new style from a clip (minifilm finetune, pipeline/new_style.py):
the new style joins the library, the trained styles keep their vectors and motion bit for bit,
the original checkpoint is never written over, and a clip at another frame rate is resampled."""
import hashlib
import shutil

import numpy as np
import pytest

from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.editing import resample
from minifilm.pipeline.new_style import teach_style
from minifilm.pipeline.run_folder import RunFolder
from minifilm.pipeline.self_fed import SelfFed
from minifilm.runtime.control import figure_eight
from minifilm.synthetic.generator import default_dataset


@pytest.fixture(scope="module")
def trained(tiny_run, tmp_path_factory):
    """A copy of the session's tiny trained run (tests/conftest.py), which these tests teach."""
    out = tmp_path_factory.mktemp("new_style") / "run"
    shutil.copytree(tiny_run, out)
    return out


def rollout(folder, style, seconds=0.5):
    f = RunFolder.load(folder)
    x0, p0 = f.start_states([style])
    n = int(round(seconds * f.fps))
    return f.controller().run([figure_eight(seconds)], n, f.styles()[style][None], phases=p0, start_x=x0).positions


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_a_new_style_joins_and_the_trained_ones_stay_bit_identical(trained, tmp_path):
    before_vectors = {n: RunFolder.load(trained).styles()[n].copy() for n in ("Neutral", "LeftHop")}
    before_motion = rollout(trained, "Neutral")
    model_digest = digest(trained / "model.npz")
    clip = default_dataset(styles=["Limp"], gaits=["FW"], seconds=6.0, seed=3)[0].motion
    path = tmp_path / "limp_30fps.bvh"
    write_bvh(resample(clip, 30.0), path)                    # another frame rate than the run's 60
    lines = []
    r = teach_style(trained, "MyLimp", [path], steps=20, log=lines.append)
    assert any("resampled" in line for line in lines), lines
    library = RunFolder.load(trained).styles()
    assert library.names[-1] == "MyLimp" and len(library.names) == 3
    for name, vector in before_vectors.items():
        np.testing.assert_array_equal(library[name], vector)
    np.testing.assert_array_equal(rollout(trained, "Neutral"), before_motion)
    assert digest(trained / "model.npz") == model_digest                  # never written over
    assert r.checkpoint == trained / "model-MyLimp.npz" and r.checkpoint.is_file()
    assert np.all(np.isfinite(rollout(trained, "MyLimp")))               # the new style runs
    assert "MyLimp" in RunFolder.load(trained).starts()


def test_an_existing_name_needs_replace(trained, tmp_path):
    path = tmp_path / "clip.bvh"
    write_bvh(read_bvh(trained / "data" / "LeftHop_FW.bvh"), path)
    with pytest.raises(ValueError, match="already has a style of that name"):
        teach_style(trained, "Neutral", [path], steps=5, log=lambda m: None)
    old = RunFolder.load(trained).styles()["Neutral"].copy()
    teach_style(trained, "Neutral", [path], steps=5, replace=True, log=lambda m: None)
    assert not np.array_equal(RunFolder.load(trained).styles()["Neutral"], old)


def test_rollout_aware_rounds_keep_the_trained_styles_and_the_best_psi(trained, tmp_path):
    before_vectors = {n: RunFolder.load(trained).styles()[n].copy() for n in ("Neutral", "LeftHop")}
    before_motion = rollout(trained, "Neutral")
    clip = default_dataset(styles=["Limp"], gaits=["FW"], seconds=6.0, seed=3)[0].motion
    path = tmp_path / "limp.bvh"
    write_bvh(clip, path)
    lines = []
    r = teach_style(trained, "SelfFedLimp", [path], steps=10, log=lines.append,
                    self_fed=SelfFed(rounds=2, horizon=12, every=30, steps=5))
    assert len(r.rollout_errors) == 3 and all(np.isfinite(r.rollout_errors))
    assert sum(line.startswith("    round") for line in lines) == 2, lines
    library = RunFolder.load(trained).styles()
    for name, vector in before_vectors.items():
        np.testing.assert_array_equal(library[name], vector)
    np.testing.assert_array_equal(rollout(trained, "Neutral"), before_motion)
    assert np.all(np.isfinite(rollout(trained, "SelfFedLimp")))


@pytest.mark.parametrize("bad", [dict(rounds=-1), dict(horizon=0), dict(every=1.5), dict(steps="10")])
def test_self_fed_settings_are_checked(bad):
    with pytest.raises(ValueError, match="SelfFed"):
        SelfFed(**bad)


def test_the_command_runs_rollout_rounds_and_says_what_it_kept(trained, tmp_path, capsys):
    from minifilm import cli
    path = tmp_path / "limp.bvh"
    write_bvh(default_dataset(styles=["Limp"], gaits=["FW"], seconds=6.0, seed=4)[0].motion, path)
    with pytest.raises(SystemExit) as done:
        cli.main(["finetune", "--run", str(trained), "--name", "CliLimp", "--steps", "5", "--rollout-rounds", "1",
                  str(path)])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert "rollouts along the clip" in out and "(kept" in out, out
    assert "CliLimp" in RunFolder.load(trained).styles()


def test_a_file_without_steps_is_taken_beside_one_with_steps_but_not_alone(trained, tmp_path):
    stand = tmp_path / "stand.bvh"
    walk = tmp_path / "walk.bvh"
    write_bvh(default_dataset(styles=["Limp"], gaits=["ID"], seconds=6.0, seed=4)[0].motion, stand)
    write_bvh(default_dataset(styles=["Limp"], gaits=["FW"], seconds=6.0, seed=4)[0].motion, walk)
    with pytest.raises(ValueError, match="fewer than two foot steps"):
        teach_style(trained, "Standing", [stand], steps=5, log=lambda m: None)
    assert "Standing" not in RunFolder.load(trained).styles()
    teach_style(trained, "StandAndWalk", [stand, walk], steps=5, log=lambda m: None)
    assert "StandAndWalk" in RunFolder.load(trained).styles()
