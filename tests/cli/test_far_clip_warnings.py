"""A clip far outside a run's data (real capture, retargeted, taught to a tiny run trained on
synthetic motion): ``finetune --run`` and then ``generate`` both say so in words, and a style the
run was trained on does not get those words."""
import shutil

import pytest
from in_process import minifilm_here


@pytest.fixture(scope="module")
def taught(tiny_run, shared_data):
    """The session's tiny trained run (tests/conftest.py; the test copies it) and a clip far outside its data."""
    clip = shared_data / "bandai2" / "dataset-2_walk_elderly_001.bvh"
    return tiny_run, clip


def invoke(argv, capsys):
    """(exit code, all it printed) of ``minifilm ARGV``."""
    code, printed = minifilm_here(argv, capsys)
    return code, printed.out + printed.err


def test_finetune_and_generate_say_the_clip_is_far_outside(taught, tmp_path, capsys):
    base, clip = taught
    folder = tmp_path / "run"
    shutil.copytree(base, folder)
    code, out = invoke(["finetune", "--run", folder, "--name", "Elderly", "--steps", "20", "--adapter-steps", "20",
                        clip], capsys)
    assert code == 0, out
    assert "retargeted" in out
    assert "WARNING: the clip lies far outside the motion the run was trained on" in out
    # far outside: the style got an adapter of its own (--adapter auto), kept in the run folder
    assert "a lowrank adapter of its own" in out and (folder / "adapters.json").is_file()
    code, out = invoke(["generate", "--run", folder, "--style", "Elderly", "--seconds", "2", "--out",
                        tmp_path / "e.bvh"], capsys)
    assert code == 0, out
    warning = [line for line in out.splitlines() if "WARNING" in line]
    assert warning and "was taught from motion far outside the run's data" in warning[0]
    code, out = invoke(["generate", "--run", folder, "--style", "Neutral", "--seconds", "2", "--out",
                        tmp_path / "n.bvh"], capsys)
    assert code == 0, out
    assert "far outside" not in out
    # a trained style walks bit for bit as in the run before the adapted style was taught
    code, out = invoke(["generate", "--run", base, "--style", "Neutral", "--seconds", "2", "--out",
                        tmp_path / "n0.bvh"], capsys)
    assert code == 0, out
    assert (tmp_path / "n.bvh").read_bytes() == (tmp_path / "n0.bvh").read_bytes()


def test_adapter_off_keeps_the_run_without_adapters(taught, tmp_path, capsys):
    base, clip = taught
    folder = tmp_path / "run"
    shutil.copytree(base, folder)
    code, out = invoke(["finetune", "--run", folder, "--name", "Elderly", "--steps", "20", "--adapter", "off", clip],
                       capsys)
    assert code == 0, out
    assert "adapter of its own" not in out and not (folder / "adapters.json").exists()
