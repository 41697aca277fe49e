"""minifilm/files/lock.py: one lock per folder, whatever path or link names it; every whole-folder
writer takes it; the lock file goes with its holder. Nothing here waits for time to pass: a second
writer is refused at once, so each case holds the lock in one thread and tries it in another."""
import os
import threading

import pytest

from minifilm.files import FolderInUseError, atomic_directory, folder_lock
from minifilm.files import lock as lock_module
from minifilm.files.lock import lock_path


def refused_elsewhere(folder, what="run folder"):
    """The FolderInUseError another thread of this process gets for ``folder`` (None: it got the lock)."""
    caught = []

    def take():
        try:
            with folder_lock(folder, what):
                caught.append(None)
        except FolderInUseError as e:
            caught.append(e)
    t = threading.Thread(target=take)
    t.start()
    t.join(60)
    assert not t.is_alive(), "the other thread neither took the lock nor was refused"
    return caught[0]


def names_of_one_folder(tmp_path):
    """Ways to name the folder tmp_path/runs/runA: as typed, relative, with a trailing slash, through
    a link to it, through a link to its parent, through a chain of links."""
    runs = tmp_path / "runs"
    (runs / "runA").mkdir(parents=True)
    os.symlink("runA", runs / "alias")
    os.symlink(runs, tmp_path / "elsewhere")
    os.symlink("alias", runs / "alias2")
    return [runs / "runA", runs / "x" / ".." / "runA", f"{runs / 'runA'}/", runs / "alias", tmp_path / "elsewhere" / "runA",
            runs / "alias2", os.path.relpath(runs / "runA")]


def test_every_name_of_a_folder_takes_one_lock(tmp_path):
    names = names_of_one_folder(tmp_path)
    (tmp_path / "runs" / "x").mkdir()
    assert len({lock_path(n) for n in names}) == 1
    for held in names:
        with folder_lock(held):
            for other in names:
                e = refused_elsewhere(other)
                assert e is not None and f"in use by process {os.getpid()}" in str(e), (held, other)
        assert refused_elsewhere(held) is None             # and free again afterwards


def test_a_link_not_yet_leading_anywhere_locks_where_it_will_lead(tmp_path):
    os.symlink("runB", tmp_path / "dangling")               # train --out dangling would make runB
    with folder_lock(tmp_path / "dangling"):
        e = refused_elsewhere(tmp_path / "runB")
        assert e is not None and "runB" in str(e)
    with folder_lock(tmp_path / "runB"):
        assert refused_elsewhere(tmp_path / "dangling") is not None


def test_whole_folder_writers_take_the_lock_and_leave_no_lock_file(tmp_path):
    os.symlink("pack", tmp_path / "link")
    with folder_lock(tmp_path / "link", "style pack folder"):    # a command holding it, reading the pack
        with atomic_directory(tmp_path / "pack", "style pack folder") as d:   # its own write: the same thread
            (d / "styles.npz").write_text("x")
        e = refused_elsewhere(tmp_path / "pack", "style pack folder")
        assert e is not None and "style pack folder" in str(e)
    errors = []

    def write():
        try:
            with atomic_directory(tmp_path / "link", "style pack folder", replaceable=lambda n: True):
                pass
        except FolderInUseError as e:
            errors.append(e)
    holding, done = threading.Event(), threading.Event()

    def hold():
        with folder_lock(tmp_path / "pack"):
            holding.set()
            done.wait()
    holder = threading.Thread(target=hold)
    holder.start()
    assert holding.wait(60), "the holding thread never took the lock"
    try:
        write()
    finally:
        done.set()
        holder.join(60)
    assert errors and f"in use by process {os.getpid()}" in str(errors[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "pack"]      # no lock file, no temporary


def test_a_lock_file_left_by_a_killed_writer_is_used_and_removed(tmp_path):
    stale = lock_path(tmp_path / "run")
    stale.write_text("999999999")                            # unlocked: its process is gone
    with folder_lock(tmp_path / "run"):
        assert stale.read_text() == str(os.getpid())
    assert not stale.exists()


def test_a_lock_file_removed_by_its_holder_while_locking_is_not_kept(tmp_path, monkeypatch):
    """A writer that opened the lock file just as its holder finished (and removed it) must not keep
    a lock on the removed file, which a third writer would not see: it starts over."""
    path = lock_path(tmp_path / "run")
    real, calls = lock_module._try_lock, []

    def holder_finishes_first(fd):
        if not calls:
            os.unlink(path)                                  # the holder is done: its file goes
        calls.append(fd)
        return real(fd)
    monkeypatch.setattr(lock_module, "_try_lock", holder_finishes_first)
    with folder_lock(tmp_path / "run"):
        assert len(calls) == 2 and path.exists()
        monkeypatch.setattr(lock_module, "_try_lock", real)
        assert refused_elsewhere(tmp_path / "run") is not None     # the file a third writer finds is locked


def test_a_lock_file_that_is_a_link_is_refused(tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_text("keep")
    os.symlink(outside, lock_path(tmp_path / "run"))
    with pytest.raises(OSError, match="cannot lock run folder"):
        with folder_lock(tmp_path / "run"):
            pass
    assert outside.read_text() == "keep"
