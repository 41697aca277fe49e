"""Building a dataset with worker processes (build_dataset's ``workers``, minifilm/parallel.py): the
data set of one process, the same cache, the same error for a bad file, and from the command a
clean stop. The data are synthetic BVH files of different lengths (so that the workers finish out
of order), with a mirrored style and a style without a clip-gait file (its clips come from other
gaits)."""
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from child_process import Child, minifilm_argv

import minifilm.dataset.cache as cache_module
from minifilm.dataset.build import build_dataset
from minifilm.dataset.dataset import Dataset
from minifilm.dataset.splits import SPLITS
from minifilm.motion.bvh import BVHError
from minifilm.synthetic.generator import default_dataset, write_dataset

FLOATS, WHOLE = ("x", "p", "z", "clips"), ("style", "file", "frame", "clip_style", "clip_file")
#: (style, gait, seconds): the first file is the longest, later ones shorter and longer again
FILES = [("Neutral", "FW", 4.0), ("Neutral", "BW", 1.5), ("Neutral", "TR", 2.0), ("LeftHop", "BW", 3.0),
         ("LeftHop", "FR", 1.5), ("Limp", "FW", 1.5), ("Limp", "SW", 3.0), ("Limp", "FR", 2.5)]
OPTIONS = dict(mirror_styles=("Neutral",), clip_seconds=1.0, clip_stride_seconds=0.5, seed=3)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("bvh")
    clips = [default_dataset(seed=1, seconds=s, styles=[style], gaits=[gait])[0] for style, gait, s in FILES]
    write_dataset(out, clips, truth=False)
    return out


@pytest.fixture
def pinned_code(monkeypatch):
    """The code's fingerprint in the cache key pinned: an edit elsewhere while the tests run changes nothing."""
    monkeypatch.setattr(cache_module, "source_fingerprint", lambda: "pinned")


def assert_same(a: Dataset, b: Dataset) -> None:
    """The same rows, clips, ids and statistics. Ids exactly; the float32 numbers to 1e-5: a file is
    labelled by the same code wherever it runs, but a worker may round a sum in another order (its
    BLAS kernel or thread count, on another CPU) by float32's 6e-8 relative per operation, and a
    feature passes through tens of operations; a row of another file or frame differs by far more."""
    for name in SPLITS:
        for key in FLOATS + WHOLE:
            x, y = getattr(a.split(name), key), getattr(b.split(name), key)
            assert x.dtype == y.dtype and x.shape == y.shape, (name, key)
            if key in WHOLE:
                np.testing.assert_array_equal(x, y, err_msg=f"{name} {key}")
            else:
                np.testing.assert_allclose(x, y, rtol=1e-5, atol=1e-5, err_msg=f"{name} {key}")
    for key in ("x_mean", "x_std", "p_mean", "p_std", "z_mean", "z_std"):
        np.testing.assert_allclose(getattr(a.stats, key), getattr(b.stats, key), rtol=1e-5, atol=1e-6, err_msg=key)
    assert (a.files, a.styles, a.fps, a.layout, a.settings) == (b.files, b.styles, b.fps, b.layout, b.settings)


@pytest.mark.parametrize("split_unit", ["segments", "files"])
def test_two_workers_build_the_data_set_of_one_process(folder, tmp_path, pinned_code, split_unit):
    one = build_dataset(folder, cache_dir=tmp_path / "one", progress=False, workers=1, split_unit=split_unit, **OPTIONS)
    two = build_dataset(folder, cache_dir=tmp_path / "two", progress=False, workers=2, split_unit=split_unit, **OPTIONS)
    assert multiprocessing.active_children() == []              # the workers are gone
    assert len(one.train) and len(one.train.clips) and len(one.val)
    assert {one.files[c]["gait"] for c in one.train.clip_file} >= {"FW", "BW"}   # LeftHop's from other gaits
    assert any(f["mirrored"] for f in one.files)
    assert_same(one, two)
    assert one.cache_key == two.cache_key and one.cache_path.name == two.cache_path.name   # not in the key


def test_an_executor_given_labels_the_files(folder):
    """An executor with concurrent.futures' interface (threads here: MPI's under mpiexec) is used as given."""
    with ThreadPoolExecutor(2) as given:
        made = build_dataset(folder, progress=False, workers=given, **OPTIONS)
        assert given.submit(len, "open").result() == 4             # still open
    assert_same(made, build_dataset(folder, progress=False, workers=1, **OPTIONS))


def test_a_malformed_file_gives_the_same_error_whatever_the_worker_count(folder, tmp_path):
    for p in folder.glob("*.bvh"):
        os.symlink(p, tmp_path / p.name)
    bad = tmp_path / "Limp_FR.bvh"                  # the last file; its header is fine, a frame is not
    bad.unlink()
    lines = (folder / "Limp_FR.bvh").read_text().split("\n")
    k = lines.index("MOTION") + 5
    lines[k] = lines[k].replace(" ", " x", 1)
    bad.write_text("\n".join(lines))
    seen = {}
    for workers in (1, 2):
        with pytest.raises(BVHError) as info:
            build_dataset(tmp_path, progress=False, workers=workers, **OPTIONS)
        e = info.value
        seen[workers] = (str(e), e.line, getattr(e, "__notes__", []))
        assert multiprocessing.active_children() == []
    assert seen[1] == seen[2]
    assert seen[1][0].startswith(f"{bad}, line {k + 1}:") and seen[1][2] == []     # the file named once


def test_workers_must_be_a_whole_number_of_at_least_one(folder):
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="build_dataset: workers must be a whole number >= 1"):
            build_dataset(folder, progress=False, workers=bad)


def test_the_command_takes_workers_and_says_how_it_shares_the_files(folder):
    run = subprocess.run([sys.executable, "-m", "minifilm", "dataset", str(folder), "--no-cache", "--workers", "2",
                          "--clip-seconds", "1"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-800:]
    assert "[dataset] 8 files in 2 worker processes" in run.stderr
    assert "[dataset] 8/8 files" in run.stderr and "built in" in run.stdout
    refused = subprocess.run([sys.executable, "-m", "minifilm", "dataset", str(folder), "--no-cache", "--workers", "0"],
                             capture_output=True, text=True, timeout=300)
    assert refused.returncode == 2 and "--workers" in refused.stderr and "must be >= 1" in refused.stderr


def children(pid: int) -> set:
    """The processes whose parent is ``pid`` (Linux /proc)."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError):
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            found.add(int(stat.parent.name))
    return found


def running(pid: int) -> bool:
    """Whether process ``pid`` still runs (a zombie, ended but not yet waited for, does not)."""
    try:
        return "zombie" not in Path(f"/proc/{pid}/status").read_text().lower()
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="POSIX signals, and /proc to see the workers")
def test_ctrl_c_while_the_workers_label_stops_cleanly_with_no_cache_and_no_worker(folder, tmp_path):
    """Ctrl-C in a terminal (SIGINT to the command and its workers at once), once the first file is
    back and the workers are at others: exit 130, one line, no worker left, no cache written. The
    workers run with the command's one BLAS thread."""
    cache = tmp_path / "cache"
    with Child(minifilm_argv("dataset", folder, "--workers", "2", "--cache", cache, "--clip-seconds", "1")) as proc:
        proc.until("[dataset] 1/8 files", start=True)
        workers = children(proc.pid)
        for pid in workers:                                     # the command's one BLAS thread, inherited
            assert b"OPENBLAS_NUM_THREADS=1" in Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
        os.killpg(proc.pid, signal.SIGINT)
        rest = proc.end(timeout=120)
        assert proc.returncode == 130 and rest.strip().endswith("interrupted"), rest[-800:]
        assert "Traceback" not in rest, rest[-2000:]
        assert len(workers) >= 2, workers                       # (and the pool's resource tracker)
        deadline = time.monotonic() + 30                        # (how long to wait, not a timing)
        while [pid for pid in workers if running(pid)] and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not [pid for pid in workers if running(pid)]    # (checked before the session is killed)
    assert not cache.exists() or list(cache.iterdir()) == []   # no cache, whole or half
