"""Teaching a run trained on another rig than 100STYLE (a Bandai-Namco run: its toes are
``Toes_R`` / ``Toes_L``): the adapter's route and the walk that checks the style find the rig's
toes, and the command ends with the style taught, not a traceback."""
import json
import shutil

import pytest

from minifilm import cli
from minifilm.pipeline.run_folder import RunFolder
from minifilm.runtime.held_body import leg_chains, toe_joints

BANDAI2 = "bandai2/dataset-2_walk_{}_{:03d}.bvh"


@pytest.fixture(scope="module")
def bandai_run(shared_data, tmp_path_factory):
    """A one-epoch run on two Bandai-2 walking styles (a few seconds)."""
    root = tmp_path_factory.mktemp("bandai_run")
    data = root / "data"
    data.mkdir()
    for style in ("active", "elderly"):
        shutil.copy(shared_data / BANDAI2.format(style, 1), data)
    with pytest.raises(SystemExit) as done:
        cli.main(["train", "--data", str(data), "--quick", "--epochs", "1", "--clip-seconds", "1",
                  "--out", str(root / "run"), "--workers", "1"])
    assert done.value.code == 0
    return root / "run"


def test_the_rigs_toes_are_found(bandai_run):
    layout = RunFolder.load(bandai_run).layout
    toes = toe_joints(layout.joint_names)
    assert [layout.joint_names[j] for j in toes] == ["Toes_R", "Toes_L"]       # [right, left]
    assert leg_chains(layout.joint_names, layout.parents) is not None          # foot lock has legs to hold


def test_an_adapter_is_taught_on_a_bandai_run(bandai_run, shared_data, capsys):
    with pytest.raises(SystemExit) as done:
        cli.main(["finetune", "--run", str(bandai_run), "--name", "Normal", "--steps", "5", "--adapter", "lowrank",
                  "--adapter-steps", "5", "--rollout-rounds", "0", "--workers", "1",      # 1: all here, as it is
                  str(shared_data / BANDAI2.format("normal", 4))])
    out = capsys.readouterr().out
    assert done.value.code == 0, out
    assert "rolled out 6 s:" in out                                           # the walk that checks it ran
    adapters = json.loads((bandai_run / "adapters.json").read_text())["adapters"]
    assert [a["style"] for a in adapters] == ["Normal"] and adapters[0]["kind"] == "lowrank"
    assert "Normal" in RunFolder.load(bandai_run).styles()


def test_workers_without_walks_to_share_are_refused_but_one_is_taken(bandai_run, shared_data, capsys):
    with pytest.raises(SystemExit) as done:
        cli.main(["finetune", "--run", str(bandai_run), "--name", "Other", "--workers", "2",
                  str(shared_data / BANDAI2.format("normal", 4))])
    err = capsys.readouterr().err.strip().splitlines()
    assert done.value.code == 2 and len(err) == 1 and "--workers 2 is for the walks of --motion-rounds" in err[0]


def test_generate_checks_and_foot_locks_a_bandai_runs_walk(bandai_run, tmp_path, capsys):
    """generate finds the rig's toes too: its foot lock has legs to hold (it ended in a KeyError on
    100STYLE's joint names) and its walk figures and checks are printed."""
    with pytest.raises(SystemExit) as done:
        cli.main(["generate", "--run", str(bandai_run), "--style", "active", "--foot-lock", "--seconds", "2",
                  "--out", str(tmp_path / "locked.bvh")])
    out = capsys.readouterr().out
    assert done.value.code == 0, out
    assert "foot sliding" in out and (tmp_path / "locked.bvh").stat().st_size > 0
