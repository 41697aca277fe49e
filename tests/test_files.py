"""minifilm/files/atomic.py: atomic writes leave the old file or the new one, never debris, with the
permissions of a plain open(); read_npz refuses broken archives before allocating."""
import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from minifilm.errors import InputError, OutputPathError
from minifilm.files import (atomic_directory, atomic_path, atomic_savez, atomic_write, atomic_write_text,
                            check_writable, read_npz, remove_stale_temporaries)


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


def test_files_and_folders_get_the_usual_permissions(tmp_path, umask_022):
    atomic_write_text(tmp_path / "a.txt", "hi")
    with atomic_path(tmp_path / "b.bin") as tmp:
        open(tmp, "wb").write(b"x")
    with atomic_directory(tmp_path / "folder") as d:
        (d / "f").write_text("x")
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "b.bin").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "folder").stat().st_mode & 0o777 == 0o755


def test_a_failed_write_leaves_the_old_file_and_no_debris(tmp_path):
    atomic_write_text(tmp_path / "a.txt", "old")

    def boom(f):
        f.write(b"half of the new")
        raise RuntimeError("killed")
    with pytest.raises(RuntimeError):
        atomic_write(tmp_path / "a.txt", boom)
    assert (tmp_path / "a.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_a_failed_folder_write_leaves_the_old_folder_whole(tmp_path):
    with atomic_directory(tmp_path / "d", replaceable=str.isdigit) as d:
        for i in range(100):
            (d / f"{i:03d}").write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_directory(tmp_path / "d", replaceable=str.isdigit) as d:
            (d / "000").write_text("new")
            raise RuntimeError("killed")
    assert len(list((tmp_path / "d").iterdir())) == 100
    with atomic_directory(tmp_path / "d", replaceable=str.isdigit) as d:          # fewer files over more: none of the old survive
        for i in range(3):
            (d / f"{i:03d}").write_text("new")
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == ["000", "001", "002"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


def test_a_killed_writer_s_temporary_is_removed_by_the_next_writer(tmp_path):
    """SIGKILL cannot be cleaned up after: the next write of the same file removes the dead
    process's temporary (its pid is in the name), and leaves a live process's alone."""
    code = ("import os, sys; from minifilm.files import atomic_write\n"
            "atomic_write(sys.argv[1], lambda f: (f.write(b'x' * 100), os.kill(os.getpid(), 9)))")
    subprocess.run([sys.executable, "-c", code, str(tmp_path / "model.npz")], check=False)
    debris = [p.name for p in tmp_path.iterdir()]
    assert len(debris) == 1 and debris[0].startswith(".model.npz.") and debris[0].endswith(".tmp")
    live = tmp_path / f".model.npz.{os.getppid()}.abc.tmp"           # a running process's
    live.write_text("busy")
    atomic_savez(tmp_path / "model.npz", {"a": np.zeros(3)})
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["model.npz", live.name])
    assert remove_stale_temporaries(tmp_path / "model.npz") == 0


def test_check_writable_names_the_problem(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputPathError, match="is a folder"):
        check_writable(tmp_path, "--out")
    with pytest.raises(OutputPathError, match="is a file, not a folder"):
        check_writable(tmp_path / "file" / "x.bvh", "--out")
    assert check_writable(tmp_path / "new" / "deeper" / "x.bvh") == tmp_path / "new" / "deeper" / "x.bvh"


def test_read_npz_round_trip_and_refusals(tmp_path):
    path = tmp_path / "a.npz"
    atomic_savez(path, {"x": np.arange(5.0), "s": np.array("text")})
    got = read_npz(path)
    np.testing.assert_array_equal(got["x"], np.arange(5.0))
    path.write_bytes(path.read_bytes()[:-30])
    with pytest.raises(InputError, match=f"archive {path}: not a readable .npz"):
        read_npz(path)
    with pytest.raises(FileNotFoundError):
        read_npz(tmp_path / "missing.npz")
    with pytest.raises(TypeError, match="dtype object"):
        atomic_savez(tmp_path / "o.npz", {"o": np.array([{}], dtype=object)})


def test_read_npz_checks_declared_sizes_before_reading(tmp_path):
    import io
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (10**11,)})
    with zipfile.ZipFile(tmp_path / "forged.npz", "w") as z:
        z.writestr("big.npy", header.getvalue() + b"\0" * 80)
    with pytest.raises(InputError, match="declares 800,000,000,000 bytes but holds"):
        read_npz(tmp_path / "forged.npz")
    atomic_savez(tmp_path / "large.npz", {"a": np.zeros(1000)})
    with pytest.raises(InputError, match="more than"):
        read_npz(tmp_path / "large.npz", max_bytes=4000)
    assert read_npz(tmp_path / "large.npz", max_bytes=None)["a"].shape == (1000,)
