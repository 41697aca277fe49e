"""Two writers of one folder at once: every command that writes a folder (a run: train, finetune
--run; a style pack: finetune --params --out; a data set: dataset --from-released --out) is refused
while another holds the folder, whatever path or link each of them names it by, and the folder is
left as it was. The other writer is this test process, holding the folder's lock (no waiting for
time to pass: the command must be refused at once, naming this process)."""
import hashlib
import os
import subprocess
import sys

import pytest

from minifilm.files import folder_lock

TRAIN = ["train", "--quick", "--styles", "Neutral,LeftHop", "--gaits", "FW", "--seconds", "6", "--epochs", "1",
         "--generate-seconds", "0.5"]


def contents(folder):
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def minifilm(*argv):
    return subprocess.run([sys.executable, "-m", "minifilm", *map(str, argv)], capture_output=True, text=True,
                          timeout=600)


def named(folder, how):
    """``folder`` itself, or a link to it (beside it, or through a link to its parent)."""
    if how == "as typed":
        return folder
    if how == "link":
        link = folder.parent / f"link-to-{folder.name}"
        if not os.path.lexists(link):
            os.symlink(folder.name, link)
        return link
    parent = folder.parent.parent / f"link-to-{folder.parent.name}"
    if not os.path.lexists(parent):
        os.symlink(folder.parent, parent)
    return parent / folder.name


NAMINGS = [("as typed", "link"), ("link", "as typed"), ("parent link", "link")]


def refused_while_held(folder, holder_name, argv, what):
    before = contents(folder) if folder.exists() else None
    with folder_lock(holder_name, what):
        r = minifilm(*argv)
    assert r.returncode == 2, r.stdout[-800:] + r.stderr[-800:]
    assert f"in use by process {os.getpid()}" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert (contents(folder) if folder.exists() else None) == before


@pytest.mark.parametrize("held,given", NAMINGS)
def test_finetune_of_a_run_held_by_another_writer(run, tmp_path, held, given):
    refused_while_held(run, named(run, held), ["finetune", "--run", named(run, given), "--name", "Second",
                                               "--steps", "5", run / "data" / "Neutral_FW.bvh"], "run folder")


@pytest.mark.parametrize("held,given", NAMINGS)
def test_training_into_a_run_held_by_another_writer(run, tmp_path, held, given):
    refused_while_held(run, named(run, held), TRAIN + ["--out", named(run, given)], "run folder")


def test_training_into_a_new_folder_through_a_link_held_by_another_writer(tmp_path):
    os.symlink("new-run", tmp_path / "alias")               # leads nowhere yet: train would make new-run
    refused_while_held(tmp_path / "new-run", tmp_path / "new-run", TRAIN + ["--out", tmp_path / "alias"], "run folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["alias"]


@pytest.fixture
def pack(shared_data, tmp_path):
    from minifilm.runtime.released import load_released
    from minifilm.runtime.style_pack import StylePack
    rel = load_released(shared_data / "released-lpn")
    folder = tmp_path / "packs" / "mine"
    StylePack.empty().with_style("First", rel.styles["Neutral"], {"taught_from": []}).save(folder)
    return folder


@pytest.mark.parametrize("held,given", NAMINGS)
def test_teaching_into_a_style_pack_held_by_another_writer(shared_data, pack, held, given):
    clip = shared_data / "bandai2" / "dataset-2_walk_elderly_001.bvh"
    refused_while_held(pack, named(pack, held), ["finetune", "--params", shared_data / "released-lpn", "--name",
                                                 "Second", "--out", named(pack, given), "--steps", "5", clip],
                       "style pack folder")


def test_teaching_into_a_new_style_pack_held_by_another_writer(shared_data, tmp_path):
    clip = shared_data / "bandai2" / "dataset-2_walk_elderly_001.bvh"
    refused_while_held(tmp_path / "pack", tmp_path / "pack", ["finetune", "--params", shared_data / "released-lpn",
                                                             "--name", "A", "--out", tmp_path / "pack", clip],
                       "style pack folder")
    assert list(tmp_path.iterdir()) == []


def test_a_released_data_set_held_by_another_writer(shared_data, tmp_path):
    (tmp_path / "made").mkdir()
    refused_while_held(tmp_path / "made", named(tmp_path / "made", "link"),
                       ["dataset", "--from-released", shared_data / "released-lpn", "--out", tmp_path / "made",
                        "--styles", "Neutral", "--seconds-per-style", "0.5"], "data set folder")
