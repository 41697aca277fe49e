"""minifilm/files: what an output may replace, what an input may be, names from data, one writer
per run folder (the fuzz families 1-3). Special files are made in the test's own folder (a FIFO,
a socket, and, where the test runs as root, a device node of its own): no test points at /dev."""
import errno
import os
import socket
import stat
import subprocess
import sys
import threading
import unicodedata

import numpy as np
import pytest
from child_process import Child

from minifilm.errors import InputError, OutputPathError
from minifilm.files import (FolderInUseError, atomic_directory, atomic_path, atomic_write, atomic_write_text,
                            check_name, check_writable, child_path, command_inputs, file_name, file_names,
                            folder_lock, note_input, parse_json, read_json, read_regular_bytes)


def make_fifo(path):
    os.mkfifo(path)
    return path


def make_socket(path):
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(path))
    return s


def make_null_device(path):
    """A character device node like /dev/null, in the test's folder (root only)."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, AttributeError, OSError):
        pytest.skip("making a device node needs root")
    return path


# ---- outputs -----------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["fifo", "socket", "device", "folder"])
def test_an_output_never_replaces_a_special_file_or_a_folder(tmp_path, kind):
    target = tmp_path / "out.bvh"
    keep = None
    if kind == "fifo":
        make_fifo(target)
    elif kind == "socket":
        keep = make_socket(target)
    elif kind == "device":
        make_null_device(target)
    else:
        target.mkdir()
    before = os.lstat(target)
    for write in (lambda: atomic_write_text(target, "x"), lambda: check_writable(target, "--out")):
        with pytest.raises(OutputPathError, match="out.bvh") as e:
            write()
        assert "\n" not in str(e.value)
    with pytest.raises(OutputPathError):
        with atomic_path(target) as tmp:
            open(tmp, "w").write("x")
    after = os.lstat(target)
    assert stat.S_IFMT(after.st_mode) == stat.S_IFMT(before.st_mode) and after.st_ino == before.st_ino
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bvh"]          # no debris
    if keep is not None:
        keep.close()


def test_a_symlink_is_followed_and_stays_a_link(tmp_path):
    real = tmp_path / "real.txt"
    real.write_text("old")
    os.chmod(real, 0o640)
    link = tmp_path / "link.txt"
    link.symlink_to(real)
    atomic_write_text(link, "new")
    assert link.is_symlink() and real.read_text() == "new"
    assert stat.S_IMODE(real.stat().st_mode) == 0o640          # the replaced file keeps its mode
    fifo = make_fifo(tmp_path / "fifo")
    (tmp_path / "to_fifo").symlink_to(fifo)
    with pytest.raises(OutputPathError, match="FIFO"):
        atomic_write_text(tmp_path / "to_fifo", "x")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


def test_a_read_only_file_is_refused_even_for_root(tmp_path):
    target = tmp_path / "protected.bvh"
    target.write_text("keep me")
    os.chmod(target, 0o444)
    with pytest.raises(OutputPathError, match="read-only"):
        atomic_write_text(target, "x")
    with pytest.raises(OutputPathError, match="read-only"):
        check_writable(target)
    assert target.read_text() == "keep me" and stat.S_IMODE(target.stat().st_mode) == 0o444


def test_an_output_may_not_replace_an_input_of_the_same_command(tmp_path):
    a = tmp_path / "a.bvh"
    a.write_text("input")
    atomic_write_text(a, "outside a command, writing back in place is allowed")
    with command_inputs():
        note_input(a)
        with pytest.raises(OutputPathError, match="also an input"):
            check_writable(a, "--html")
        link = tmp_path / "link.bvh"
        link.symlink_to(a)
        with pytest.raises(OutputPathError, match="also an input"):
            atomic_write_text(link, "x")
    atomic_write_text(a, "the record ends with the command")


def test_a_folder_that_holds_an_input_is_not_replaced(tmp_path):
    data = tmp_path / "run" / "data"
    data.mkdir(parents=True)
    (data / "Neutral_FW.bvh").write_text("x")
    with command_inputs():
        note_input(data / "Neutral_FW.bvh")
        with pytest.raises(OutputPathError, match="holds an input"):
            with atomic_directory(tmp_path / "run"):
                pass
    assert (data / "Neutral_FW.bvh").read_text() == "x"


def test_a_full_disk_names_the_file(tmp_path):
    def full(f):
        raise OSError(errno.ENOSPC, "No space left on device")
    with pytest.raises(OutputPathError, match=r"model\.npz: No space left"):
        atomic_write(tmp_path / "model.npz", full, "checkpoint")
    with pytest.raises(OutputPathError, match=r"x\.gif: No space left"):
        with atomic_path(tmp_path / "x.gif", "GIF") as tmp:
            raise OSError(errno.ENOSPC, "No space left on device", tmp)
    assert list(tmp_path.iterdir()) == []


def test_folders_are_exchanged_whole(tmp_path):
    ours = {"old", "new"}.__contains__
    with atomic_directory(tmp_path / "run", replaceable=ours) as d:
        (d / "old").write_text("old")
    with atomic_directory(tmp_path / "run", replaceable=ours) as d:
        (d / "new").write_text("new")
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["new"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_a_folder_of_somebody_else_s_files_is_never_replaced(tmp_path):
    (tmp_path / "home").mkdir()
    (tmp_path / "home" / "thesis.tex").write_text("years of work")
    with pytest.raises(OutputPathError, match="thesis.tex"):
        with atomic_directory(tmp_path / "home", "run folder", replaceable={"model.npz"}.__contains__) as d:
            (d / "model.npz").write_text("x")
    assert (tmp_path / "home" / "thesis.tex").read_text() == "years of work"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["home"]


# ---- inputs ------------------------------------------------------------------------------------
def test_only_regular_files_are_read_and_nothing_hangs(tmp_path):
    fifo = make_fifo(tmp_path / "Neutral_FW.bvh")
    code = ("import sys; from minifilm.files import read_regular_bytes\n"
            "try: read_regular_bytes(sys.argv[1], 'BVH file')\n"
            "except ValueError as e: print(e)")
    r = subprocess.run([sys.executable, "-c", code, str(fifo)], capture_output=True, text=True, timeout=60)
    assert "is a FIFO" in r.stdout, r.stdout + r.stderr
    for path, kind in ((tmp_path, "folder"), ("/dev/zero", "character device")):
        with pytest.raises(InputError, match=kind):
            read_regular_bytes(path, "BVH file")


def test_a_file_over_its_limit_is_refused_before_reading(tmp_path):
    big = tmp_path / "run.json"
    big.write_bytes(b" " * 2000)
    with pytest.raises(InputError, match="2,000 bytes, more than the 1,000"):
        read_regular_bytes(big, "run.json", max_bytes=1000)


def test_json_nesting_and_constants_are_one_error(tmp_path):
    deep = tmp_path / "run.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(InputError, match="nested too deeply"):
        read_json(deep, "run folder")
    with pytest.raises(InputError, match="NaN is not a JSON number"):
        parse_json('{"fps": NaN}', "meta.json")


# ---- names -------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["../../../X", "/abs/path/X", "a/b", "a\\b", "..", ".", "x..y", "\x1b[2J",
                                  "error:\nfake", "tab\there", "\u202eevil", "", " padded", "x" * 65])
def test_bad_names_are_refused_and_shown_escaped(name):
    with pytest.raises(InputError) as e:
        check_name(name, "manifest.csv: line 2: column 'style'")
    text = str(e.value)
    assert "\n" not in text and "\x1b" not in text and "\u202e" not in text
    assert text.startswith("manifest.csv: line 2")


@pytest.mark.parametrize("name", ["Neutral", "LeftHop", "old man", "Ünïcode", "a.b", "mixamo:Hips", "x" * 64])
def test_good_names_pass(name):
    assert check_name(name, "here") == name


def test_file_names_made_from_names_stay_in_their_folder(tmp_path):
    for name in ["Neutral", "what?*<>|", ".hidden", "CON", "trailing.", "ünï"]:
        path = child_path(tmp_path, name, ".bvh")
        assert path.parent == tmp_path and not path.name.startswith(".")
    assert file_name("CON") != "CON" and file_name("what?") == "what_"
    names = file_names(["a?b", "a*b", "Neutral", "neutral", "caf\u00e9", "cafe\u0301"])
    assert len({unicodedata.normalize("NFC", n).casefold() for n in names.values()}) == 6


# ---- one writer per folder ----------------------------------------------------------------------
def test_a_second_writer_of_a_folder_is_refused_with_the_holder(tmp_path):
    code = ("import sys, time; from minifilm.files import folder_lock\n"
            "with folder_lock(sys.argv[1]):\n    print('locked', flush=True); time.sleep(60)")
    with Child([sys.executable, "-c", code, tmp_path / "run"]) as holder:
        holder.until("locked", timeout=120)
        with pytest.raises(FolderInUseError, match=f"in use by process {holder.pid}"):
            with folder_lock(tmp_path / "run"):
                pass
    with folder_lock(tmp_path / "run"):             # a killed holder's lock is gone with it
        pass


def test_the_lock_is_exclusive_between_threads_of_one_process_too(tmp_path):
    entered = []

    def take():
        try:
            with folder_lock(tmp_path / "run"):
                entered.append(1)
                threading.Event().wait(0.3)
        except FolderInUseError:
            entered.append(0)
    threads = [threading.Thread(target=take) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
        assert not t.is_alive()
    assert sorted(entered) == [0, 1]
    assert np.sum(entered) == 1
