"""What the environment does to a command, said in one clear line: a file listing 300,000 unknown
keys; a terminal that cannot show a name; a read-only folder (the rule of a read-only file); a full
disk while a run or a cache is written (the user's folder named, the data set kept); temporaries of
killed writers beside any target."""
import errno
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from minifilm.errors import OutputPathError
from minifilm.files import atomic_directory, atomic_write, atomic_write_text, remove_stale_temporaries
from minifilm.body.roles import RigError, roles_from_mapping
from in_process import minifilm_here
from test_names_and_outputs import one_error, tree

FULL = OSError(errno.ENOSPC, "No space left on device")


# ---- long lists ------------------------------------------------------------------------------------
@pytest.mark.parametrize("where", ["top", "left"])
def test_a_map_of_300000_unknown_keys_is_named_in_one_short_line(tiny_run, tmp_path, capsys, where):
    keys = {f"key{i:06d}": "x" for i in range(300_000)}
    mapping = {**keys} if where == "top" else {"hips": "Hips", "spine": "Spine", "neck": "Neck", "right": {},
                                                "left": keys}
    path = tmp_path / "map.json"
    path.write_text(json.dumps(mapping))
    line = one_error(["retarget", tiny_run / "data" / "Neutral_FW.bvh", "--to", "bandai", "--map", path,
                      "--out", tmp_path / "out"], capsys, "map.json", "'key000000'", "and 299,995 more")
    assert len(line) < 600, len(line)


def test_a_huge_value_in_a_map_is_cut_short(tmp_path):
    from minifilm.motion.motion import Motion
    limb = {k: "a" for k in ("shoulder", "elbow", "wrist", "upleg", "knee", "ankle")}
    with pytest.raises(RigError, match="hips must be a joint name") as e:
        roles_from_mapping({"hips": ["x" * 1_000_000], "spine": "a", "neck": "b", "left": limb, "right": limb},
                           Motion.__new__(Motion), "map.json")
    assert len(str(e.value)) < 600


def test_an_archive_of_many_unknown_arrays_is_one_short_line(run, capsys):
    import zipfile

    from mutate import npy_bytes
    with zipfile.ZipFile(run / "styles.npz", "a") as z:
        for i in range(3000):
            z.writestr(f"padding{i:05d}.npy", npy_bytes(np.zeros(0)))
    line = one_error(["generate", "--run", run, "--list-styles"], capsys, "styles.npz", "and 2,995 more")
    assert len(line) < 800, len(line)


# ---- the terminal's encoding ----------------------------------------------------------------------
def test_a_name_the_terminal_cannot_show_says_the_terminal_is_the_cause(run, tmp_path):
    before = tree(run)
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    r = subprocess.run([sys.executable, "-m", "minifilm", "finetune", "--run", str(run), "--name", "Café",
                        "--steps", "5", str(run / "data" / "Neutral_FW.bvh")], capture_output=True, text=True,
                       env=env, timeout=600, encoding="utf-8")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr[-800:]
    assert "terminal's character encoding (ascii)" in r.stderr and "UTF-8" in r.stderr, r.stderr
    assert tree(run) == before                       # said before any work


# ---- read-only folders: the rule of read-only files ------------------------------------------------
def test_a_read_only_run_folder_is_refused_as_a_read_only_file_is(run, capsys):
    """finetune writes a new model-<NAME>.npz into the run: a read-only folder refuses it, also for
    root (who could write it), before any work; so is a read-only styles.npz."""
    before = tree(run)
    os.chmod(run, 0o555)
    try:
        one_error(["finetune", "--run", run, "--name", "Second", "--steps", "5", run / "data" / "Neutral_FW.bvh"],
                  capsys, "read-only", str(run))
    finally:
        os.chmod(run, 0o755)
    assert tree(run) == before
    os.chmod(run / "styles.npz", 0o444)
    one_error(["finetune", "--run", run, "--name", "Second", "--steps", "5", run / "data" / "Neutral_FW.bvh"],
              capsys, "read-only", "styles.npz")


@pytest.mark.parametrize("kind", ["file into it", "folder replaced", "folder made in it"])
def test_read_only_folders_are_never_written(tmp_path, kind):
    folder = tmp_path / "protected"
    folder.mkdir()
    (folder / "mine.txt").write_text("mine")
    os.chmod(folder, 0o555)
    try:
        with pytest.raises(OutputPathError, match="read-only"):
            if kind == "file into it":
                atomic_write_text(folder / "new.txt", "x")
            elif kind == "folder replaced":
                with atomic_directory(folder, replaceable=lambda n: True) as d:
                    (d / "x").write_text("x")
            else:
                with atomic_directory(folder / "inner") as d:
                    (d / "x").write_text("x")
    finally:
        os.chmod(folder, 0o755)
    assert sorted(p.name for p in folder.iterdir()) == ["mine.txt"]


# ---- a full disk -----------------------------------------------------------------------------------
def test_a_full_disk_while_a_folder_is_filled_names_the_user_s_folder(tmp_path):
    def full(f):
        raise FULL
    with pytest.raises(OutputPathError) as e:
        with atomic_directory(tmp_path / "run") as work:
            atomic_write(work / "model.npz", full, "checkpoint")
    assert str(tmp_path / "run" / "model.npz") in str(e.value) and ".tmp" not in str(e.value)
    with pytest.raises(OutputPathError) as e:
        with atomic_directory(tmp_path / "run") as work:
            raise OSError(errno.ENOSPC, "No space left on device", str(work / "pack.json"))
    assert str(tmp_path / "run" / "pack.json") in str(e.value) and ".tmp" not in str(e.value)
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_during_train_names_the_run_folder(tmp_path, capsys, monkeypatch):
    def no_space(fd):
        raise FULL
    monkeypatch.setattr(os, "fsync", no_space)
    line = one_error(["train", "--quick", "--styles", "Neutral", "--gaits", "FW", "--seconds", "6", "--epochs", "1",
                      "--out", tmp_path / "run"], capsys, str(tmp_path / "run"), "No space left")
    assert ".tmp" not in line and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("how", ["full disk", "read-only cache file"])
def test_a_data_set_whose_cache_cannot_be_written_is_returned_with_a_warning(tiny_run, tmp_path, capsys, monkeypatch,
                                                                             how):
    data = shutil.copytree(tiny_run / "data", tmp_path / "data")
    cache = tmp_path / "cache"
    argv = ["dataset", data, "--cache", cache, "--workers", "1", "--clip-seconds", "1"]
    if how == "full disk":
        monkeypatch.setattr(os, "fsync", lambda fd: (_ for _ in ()).throw(FULL))
    else:
        assert minifilm_here(argv, capsys)[0] == 0
        (data / "Neutral_FW.bvh").write_bytes((data / "Neutral_FW.bvh").read_bytes() + b"\n")   # a stale cache
        for p in cache.iterdir():
            os.chmod(p, 0o444)
    code, out = minifilm_here(argv, capsys)
    assert code == 0, out.err[-600:]
    assert "warning: the data set is built, but its cache could not be written" in out.err
    assert "built in" in out.out and "cached" not in out.out
    assert not [p for p in (cache.iterdir() if cache.exists() else []) if p.name.startswith(".")]


# ---- temporaries of killed writers ------------------------------------------------------------------
def test_a_killed_writer_s_temporaries_go_whatever_the_next_target(tmp_path):
    code = ("import os, sys; from minifilm.files import atomic_directory, atomic_write\n"
            "with atomic_directory(sys.argv[1]) as d:\n"
            "    (d / 'model.npz').write_text('half')\n"
            "    atomic_write(sys.argv[2], lambda f: (f.write(b'x'), os.kill(os.getpid(), 9)))")
    subprocess.run([sys.executable, "-c", code, str(tmp_path / "runA"), str(tmp_path / "a.bvh")], check=False)
    left = sorted(p.name for p in tmp_path.iterdir())
    assert len(left) == 3 and all(n.startswith((".runA.", ".a.bvh.", ".runA.lock")) for n in left), left
    atomic_write_text(tmp_path / "other.txt", "x")        # another target in the same folder
    assert sorted(p.name for p in tmp_path.iterdir()) == [".runA.lock", "other.txt"]   # an unlocked lock: used, removed
    assert remove_stale_temporaries(tmp_path / "other.txt") == 0


def test_a_folder_moved_aside_by_a_killed_writer_is_put_back_by_any_writer(tmp_path):
    aside = tmp_path / f".run.{2**22 + 12345}.abcdefgh.old"        # a process id no system gives
    (aside / "folder").mkdir(parents=True)
    (aside / "folder" / "model.npz").write_text("the earlier run")
    atomic_write_text(tmp_path / "notes.txt", "x")
    assert (tmp_path / "run" / "model.npz").read_text() == "the earlier run"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "run"]
    np.testing.assert_equal(remove_stale_temporaries(tmp_path / "notes.txt"), 0)
