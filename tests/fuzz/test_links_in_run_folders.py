"""Symbolic links inside a run folder (a run unpacked from an archive may hold them): a run's own
files are never written through a link. finetune refuses a run whose styles.npz, starts.npz or the
new style's checkpoint is a link (to a file elsewhere, to another run's file, or dangling) with one
line naming the link, before any work, and nothing outside the folder changes; a link that is only
read (model.npz, run.json) and a run folder that is itself a link work; train replaces a folder
holding links without writing through them."""
import hashlib
import os
import shutil

import pytest

from minifilm.pipeline.run_folder import RunFolder
from in_process import minifilm_here
from test_names_and_outputs import one_error


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def finetune(run, capsys, name="Second"):
    return ["finetune", "--run", run, "--name", name, "--steps", "5", run / "data" / "Neutral_FW.bvh"]


def moved_out(run, name, outside):
    """Move ``run/name`` to ``outside`` and leave a link to it in its place."""
    outside.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(run / name, outside)
    os.symlink(outside, run / name)
    return outside


@pytest.mark.parametrize("name", ["styles.npz", "starts.npz"])
def test_a_state_file_linked_to_a_file_elsewhere_is_refused(run, tmp_path, capsys, name):
    outside = moved_out(run, name, tmp_path / "elsewhere" / name)
    before = digest(outside)
    one_error(finetune(run, capsys), capsys, run / name, "symbolic link", str(outside))
    assert digest(outside) == before and not (run / "model-Second.npz").exists()


def test_a_state_file_linked_to_another_run_s_file_is_refused(run, tiny_run, tmp_path, capsys):
    other = tmp_path / "other"
    shutil.copytree(tiny_run, other, ignore=shutil.ignore_patterns("cache", "generated", "*.png"))
    (run / "starts.npz").unlink()
    os.symlink(other / "starts.npz", run / "starts.npz")
    before = {p.name: digest(p) for p in other.iterdir() if p.is_file()}
    one_error(finetune(run, capsys), capsys, run / "starts.npz", "symbolic link")
    assert {p.name: digest(p) for p in other.iterdir() if p.is_file()} == before


def test_a_dangling_link_where_the_new_checkpoint_goes_is_refused(run, tmp_path, capsys):
    target = tmp_path / "elsewhere" / "planted.npz"
    os.symlink(target, run / "model-Second.npz")
    one_error(finetune(run, capsys), capsys, run / "model-Second.npz", "symbolic link")
    assert not target.exists() and not (tmp_path / "elsewhere").exists()


def test_links_that_are_only_read_and_a_linked_run_folder_work(run, tmp_path, capsys):
    model = moved_out(run, "model.npz", tmp_path / "elsewhere" / "model.npz")
    manifest = moved_out(run, "run.json", tmp_path / "elsewhere" / "run.json")
    before = digest(model), digest(manifest)
    os.symlink(run, tmp_path / "alias")
    code, out = minifilm_here(finetune(tmp_path / "alias", capsys), capsys)
    assert code == 0, out.err[-600:]
    assert (digest(model), digest(manifest)) == before
    assert "Second" in RunFolder.load(run).styles() and (run / "model-Second.npz").is_file()
    assert (tmp_path / "alias").is_symlink() and not (run / "styles.npz").is_symlink()


def test_training_over_a_run_with_links_writes_nothing_through_them(run, tmp_path, capsys):
    outside = {name: moved_out(run, name, tmp_path / "elsewhere" / name) for name in ("styles.npz", "starts.npz")}
    (tmp_path / "elsewhere" / "generated").mkdir()
    (tmp_path / "elsewhere" / "generated" / "mine.bvh").write_text("mine")
    os.symlink(tmp_path / "elsewhere" / "generated", run / "generated")
    before = {str(p): digest(p) for p in (tmp_path / "elsewhere").rglob("*") if p.is_file()}
    code, out = minifilm_here(["train", "--quick", "--styles", "Neutral,LeftHop", "--gaits", "FW", "--seconds", "6",
                        "--epochs", "1", "--generate-seconds", "0.5", "--out", run], capsys)
    assert code == 0, out.err[-600:]
    assert {str(p): digest(p) for p in (tmp_path / "elsewhere").rglob("*") if p.is_file()} == before
    assert not any(p.is_symlink() for p in run.rglob("*"))
    assert all(p.is_file() for p in outside.values())
