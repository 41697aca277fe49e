"""Building a dataset in worker processes (minifilm/dataset/parallel_build.py): the data set of one
process bit for bit, the same cache key, the same error for a bad file, and no process left behind.
The data are synthetic BVH files of different lengths (so that the workers finish out of order),
with a mirrored style and a style without a clip-gait file (its clips come from other gaits)."""
import multiprocessing
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import minifilm.dataset.build as build_module
import minifilm.dataset.cache as cache_module
from minifilm.dataset.build import build_dataset
from minifilm.dataset.dataset import Dataset
from minifilm.dataset.manifest import scan_100style
from minifilm.dataset.parallel_build import LabellingWorkers
from minifilm.dataset.settings import DatasetSettings
from minifilm.dataset.splits import SPLITS
from minifilm.motion.bvh import BVHError
from minifilm.motion.skeletons import builtin_skeleton
from minifilm.processes import WorkerDied
from minifilm.synthetic.generator import default_dataset, write_dataset

ARRAYS = ("x", "p", "z", "style", "file", "frame", "clips", "clip_style", "clip_file")
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


def assert_same(a: Dataset, b: Dataset, metadata: bool = True) -> None:
    """Every array equal, bit for bit; with ``metadata`` also the files, styles, rate, layout and settings."""
    for name in SPLITS:
        for key in ARRAYS:
            x, y = getattr(a.split(name), key), getattr(b.split(name), key)
            assert x.dtype == y.dtype and np.array_equal(x, y), (name, key)
    for key in ("x_mean", "x_std", "p_mean", "p_std", "z_mean", "z_std"):
        assert np.array_equal(getattr(a.stats, key), getattr(b.stats, key)), key
    if metadata:
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
    assert_same(one, Dataset.load(two.cache_path), metadata=False)      # (a loaded cache has lists for tuples)
    assert one.cache_key == two.cache_key and one.cache_path.name == two.cache_path.name


def test_the_worker_count_is_not_in_the_cache_key(folder, tmp_path, pinned_code, monkeypatch):
    made = build_dataset(folder, cache_dir=tmp_path, progress=False, workers=2, **OPTIONS)

    def no_build(*args, **kwargs):
        raise AssertionError("rebuilt: the cache was not found")
    monkeypatch.setattr(build_module, "_build", no_build)
    for workers in (1, 3, None):
        again = build_dataset(folder, cache_dir=tmp_path, progress=False, workers=workers, **OPTIONS)
        assert again.cache_path == made.cache_path and again.cache_key == made.cache_key


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
        seen[workers] = (type(e), str(e), e.line, getattr(e, "__notes__", []))
        assert multiprocessing.active_children() == []
    assert seen[1] == seen[2]
    assert f"{bad}, line {k + 1}:" in seen[1][1]
    assert seen[1][3] == [f"(while building the dataset from {bad})"]


def test_a_killed_worker_stops_the_build_with_one_message(folder):
    settings = DatasetSettings(**OPTIONS)
    jobs = [(f, None) for f in scan_100style(folder)]
    first = jobs[0][0].path
    with pytest.raises(WorkerDied, match=rf"dataset: worker 0 \(process \d+\) was killed by SIGKILL while labelling "
                                         rf"{first}$"):
        with LabellingWorkers(jobs, settings, builtin_skeleton("100style"), 60.0, np.float32, 2) as labelled:
            for p in labelled.procs:
                os.kill(p.pid, signal.SIGKILL)
                p.join()
            labelled.next()
    assert multiprocessing.active_children() == []


def test_the_default_is_every_core_but_one_worker_per_file_and_per_so_many_frames(folder, monkeypatch):
    import minifilm.processes as processes
    asked = []

    def record(files, settings, skeleton, progress, dtype, workers, fps):
        asked.append(workers)
        raise KeyboardInterrupt     # (stop here: only the number is wanted)
    monkeypatch.setattr(build_module, "_build", record)
    frames = sum(s for _, _, s in FILES) * 60 + (4.0 + 1.5 + 2.0) * 60          # Neutral mirrored
    for cores, per_worker, expected in [(16, frames, 1), (16, frames / 3, 3), (16, 1, 8), (2, 1, 2), (1, 1, 1)]:
        monkeypatch.setattr(processes, "usable_cores", lambda: cores)
        monkeypatch.setattr(build_module, "FRAMES_PER_WORKER", int(per_worker))
        with pytest.raises(KeyboardInterrupt):
            build_dataset(folder, progress=False, **OPTIONS)
        assert asked.pop() == expected, (cores, per_worker)
    with pytest.raises(KeyboardInterrupt):
        build_dataset(folder, progress=False, workers=20, **OPTIONS)
    assert asked.pop() == 8                                     # never more than one per file


def test_workers_must_be_a_whole_number_of_at_least_one(folder):
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="workers must be a whole number >= 1"):
            build_dataset(folder, progress=False, workers=bad)


def test_the_command_takes_workers_and_says_how_it_shares_the_files(folder):
    run = subprocess.run([sys.executable, "-m", "minifilm", "dataset", str(folder), "--no-cache", "--workers", "2",
                          "--clip-seconds", "1"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-800:]
    assert "[dataset] 8 files in 2 worker processes (ids " in run.stderr
    assert "[dataset] 8/8 files" in run.stderr and "built in" in run.stdout
    refused = subprocess.run([sys.executable, "-m", "minifilm", "dataset", str(folder), "--no-cache", "--workers", "0"],
                             capture_output=True, text=True, timeout=300)
    assert refused.returncode == 2 and "--workers" in refused.stderr and "must be >= 1" in refused.stderr
