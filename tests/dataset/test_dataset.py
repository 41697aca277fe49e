"""Datasets (minifilm/dataset/build.py, minifilm/dataset/manifest.py): files, splits, mirroring, normalisation,
cache, style-balanced minibatches. Expected values are properties or independent computations."""
import os
from pathlib import Path

import numpy as np
import pytest

import minifilm.dataset.cache as cache_module
from minifilm.dataset.arrays import TrainData
from minifilm.dataset.build import build_dataset
from minifilm.dataset.manifest import (MotionFile, bandai_files, read_manifest, scan_100style,
                                       write_bandai_manifest, write_manifest)
from minifilm.dataset.settings import DatasetSettings
from minifilm.dataset.splits import SPLITS, apply_gap, file_rng, split_files, split_segments
from minifilm.dataset.stats import NormStats
from minifilm.phases.label import Labels
from minifilm.phases.local_phases import LocalPhases


# ----------------------------------------------------------------------------- splits
@pytest.mark.parametrize("n", [10, 37, 158, 1000, 18000])
def test_split_segments_tile_the_file(n):
    orders, starts = set(), set()
    for seed in range(40):
        segs = split_segments(n, np.random.default_rng(seed))
        assert segs[0][0] == 0 and segs[-1][1] == n
        assert all(a < b for a, b, _ in segs)
        assert all(segs[i][1] == segs[i + 1][0] for i in range(len(segs) - 1))      # contiguous
        sizes = {s: sum(b - a for a, b, t in segs if t == s) for s in SPLITS}
        assert sizes["val"] == n // 10 and sizes["test"] == n // 10
        assert sum(1 for *_, t in segs if t == "val") == (1 if n >= 10 else 0)    # one window each
        assert sum(1 for *_, t in segs if t == "test") == (1 if n >= 10 else 0)
        order = [t for *_, t in segs if t != "train"]
        orders.add(tuple(order))
        starts.add(next(a for a, _, t in segs if t == "val"))
    assert orders == {("val", "test"), ("test", "val")}          # both orders occur
    assert len(starts) >= min(8, n // 2)                          # positions vary


def test_split_is_seeded_per_file():
    f1, f2 = MotionFile(Path("/x/a.bvh"), "s", "FW"), MotionFile(Path("/y/a.bvh"), "s", "FW")
    a = split_segments(500, file_rng(3, f1))
    assert a == split_segments(500, file_rng(3, f2))             # depends on the name, not the folder
    assert any(split_segments(500, file_rng(s, f1)) != a for s in range(4, 10))


def test_apply_gap_only_between_different_splits():
    segs = [(0, 50, "train"), (50, 60, "val"), (60, 90, "train"), (90, 100, "test")]
    assert apply_gap(segs, 3) == [(0, 47, "train"), (53, 57, "val"), (63, 87, "train"), (93, 100, "test")]
    assert apply_gap([(0, 10, "train"), (10, 12, "val")], 2) == [(0, 8, "train")]


# ----------------------------------------------------------------------------- normalisation
def test_normalizer_statistics_and_file(tmp_path):
    rng = np.random.default_rng(0)
    x = rng.normal(3.0, 2.0, size=(500, 6)).astype(np.float32)
    x[:, 2] = 7.25                                                 # constant column -> std 1
    p, z = rng.normal(size=(500, 8)), rng.normal(size=(500, 4))
    n = NormStats.fit(x, p, z)
    x64 = x.astype(np.float64)
    mean = x64.sum(axis=0) / 500
    std = np.sqrt(((x64 - mean) ** 2).sum(axis=0) / 500)           # biased
    std[2] = 1.0
    np.testing.assert_allclose(n.x_mean, mean, rtol=1e-12)
    np.testing.assert_allclose(n.x_std, std, rtol=1e-12)
    assert n.x_mean.dtype == np.float64 and isinstance(n, NormStats)
    path = n.save(tmp_path / "norm.npz")
    with np.load(path, allow_pickle=False) as d:
        assert sorted(d.files) == sorted(["x_mean", "x_std", "p_mean", "p_std", "z_mean", "z_std"])
    m = NormStats.load(path)
    for k in ("x_mean", "x_std", "p_mean", "p_std", "z_mean", "z_std"):
        np.testing.assert_array_equal(getattr(m, k), getattr(n, k))
    with pytest.raises(ValueError, match="no training rows"):
        NormStats.fit(x[:0], p[:0], z[:0])


def test_mirrored_labels_swap_left_and_right():
    contacts = np.array([[1.0, 0.0], [0.0, 0.5]])
    phase = np.array([[0.1, 0.2, 0.3, 0.4], [0.5, 0.6, 0.7, 0.8]])   # slots LH RH LF RF
    amplitude = np.array([[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0]])
    labels = Labels(contacts, LocalPhases(phase, amplitude))
    m = labels.mirrored()
    np.testing.assert_array_equal(m.contacts, [[0, 1], [0.5, 0]])
    v, mv = labels.vectors, m.vectors                 # (sin, cos) pairs per slot
    np.testing.assert_array_equal(mv[:, [0, 1, 2, 3, 4, 5, 6, 7]], v[:, [2, 3, 0, 1, 6, 7, 4, 5]])


# ----------------------------------------------------------------------------- manifests
def test_manifest_round_trip_and_errors(tmp_path):
    (tmp_path / "a.bvh").write_text("x")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.bvh").write_text("x")
    files = [MotionFile(tmp_path / "a.bvh", "happy", "walk", 5, 90, True),
             MotionFile(tmp_path / "sub" / "b.bvh", "sad", "run")]
    path = write_manifest(files, tmp_path / "m.csv")
    back = read_manifest(path)
    assert [(f.path.resolve(), f.style, f.gait, f.start, f.end, f.mirror) for f in back] == \
        [(f.path.resolve(), f.style, f.gait, f.start, f.end, f.mirror) for f in files]
    bad = tmp_path / "bad.csv"
    bad.write_text("file,style,gait,start,end\na.bvh,happy,walk,10,x\n")
    with pytest.raises(ValueError, match=r"bad.csv: line 2: column 'end' must be a whole frame number"):
        read_manifest(bad)
    bad.write_text("file,style\na.bvh,happy\n")
    with pytest.raises(ValueError, match=r"line 1: .*lacks the column\(s\) \['gait'\]"):
        read_manifest(bad)
    bad.write_text("file,style,gait\nmissing.bvh,happy,walk\n")
    with pytest.raises(FileNotFoundError, match="line 2: file .*missing.bvh does not exist"):
        read_manifest(bad)


def test_bandai_manifest(shared_data, tmp_path):
    path = write_bandai_manifest(shared_data / "bandai2", tmp_path / "bandai2.csv")
    files = read_manifest(path)
    assert len(files) == len(list((shared_data / "bandai2").glob("*.bvh")))
    assert {f.style for f in files} == {"active", "elderly", "exhausted", "feminine", "normal"}
    assert {f.gait for f in files} == {"walk", "run", "walk-turn-left", "walk-turn-right"}
    one = [f for f in files if f.path.name == "dataset-2_walk-turn-left_elderly_003.bvh"][0]
    assert (one.style, one.gait) == ("elderly", "walk-turn-left")


def test_a_folder_named_both_ways_is_one_error_not_half_a_data_set(tmp_path):
    """Read one way, the files named the other way would be left out without a word."""
    from minifilm.dataset.manifest import scan_folder
    for name in ["dataset-2_walk_active_001.bvh", "dataset-2_run_active_001.bvh", "Neutral_FW.bvh"]:
        (tmp_path / name).write_text("x")
    with pytest.raises(ValueError, match=r"both ways .*: 2 as Bandai Namco's .* and 1 as <Style>_<Gait>\.bvh "
                                         r"\('Neutral_FW\.bvh'\).*CSV manifest"):
        scan_folder(tmp_path)
    (tmp_path / "Neutral_FW.bvh").unlink()
    assert [f.style for f in scan_folder(tmp_path)] == ["active", "active"]


def test_scan_100style_names(tmp_path):
    for name in ["Zombie_FW.bvh", "Zombie_ID.bvh", "Aeroplane_TR2.bvh", "Neutral_FR_first3frames.bvh",
                 "notes.txt"]:
        (tmp_path / name).write_text("x")
    got = [(f.path.name, f.style, f.gait) for f in scan_100style(tmp_path)]
    assert got == [("Aeroplane_TR2.bvh", "Aeroplane", "TR2"), ("Zombie_FW.bvh", "Zombie", "FW"),
                   ("Zombie_ID.bvh", "Zombie", "ID")]
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no file in it is named <Style>_<Gait>.bvh.*CSV manifest"):
        scan_100style(tmp_path / "empty")


# ----------------------------------------------------------------------------- building (real data)
SUBSET = ["dataset-2_walk_active_001.bvh", "dataset-2_walk_elderly_001.bvh",
          "dataset-2_run_active_001.bvh", "dataset-2_walk-turn-left_elderly_001.bvh"]


@pytest.fixture(scope="module")
def small(shared_data, tmp_path_factory):
    """A few Bandai files, one style mirrored, cached in a temporary folder.

    The code fingerprint in the cache key is pinned, so that somebody editing the motion modules
    while the tests run cannot turn a cache hit into a rebuild.
    """
    mp = pytest.MonkeyPatch()
    mp.setattr(cache_module, "source_fingerprint", lambda: "pinned")
    cache = tmp_path_factory.mktemp("cache")
    files = [f for f in bandai_files(shared_data / "bandai2") if f.path.name in SUBSET]
    ds = build_dataset(files, cache_dir=cache, progress=False, mirror_styles=("active",), seed=7,
                       clip_seconds=2.0, clip_stride_seconds=1.0)
    yield files, cache, ds
    mp.undo()


def test_build_shapes_and_labels(small):
    files, _, ds = small
    assert ds.styles == ["active", "elderly"] and ds.fps == pytest.approx(30, abs=1e-3)
    assert ds.skeleton == "bandai" and ds.layout.n_joints == 21
    assert len(ds.files) == 6                                   # 4 files + 2 mirrored 'active'
    for name in SPLITS:
        sp = ds.split(name)
        assert sp.x.shape == (len(sp), ds.layout.x_dim) and sp.z.shape == (len(sp), ds.layout.z_dim)
        assert sp.p.shape == (len(sp), 8) and sp.x.dtype == np.float32
        assert np.all(np.isfinite(sp.x)) and np.all(np.isfinite(sp.z))
    # clips: 2 s at 30 fps, only from walk files (the clip gait), in the style of their file
    assert ds.train.clips.shape[1:] == (60, ds.layout.clip_dim) and len(ds.train.clips) > 0
    for name in SPLITS:
        sp = ds.split(name)
        for c, s in zip(sp.clip_file, sp.clip_style):
            assert ds.files[c]["gait"] == "walk" and ds.styles[s] == ds.files[c]["style"]


def test_rows_stay_inside_their_segments(small):
    _, _, ds = small
    for name in SPLITS:
        sp = ds.split(name)
        for src, info in enumerate(ds.files):
            frames = sp.frame[sp.file == src]
            segs = [(a, b) for a, b, s in info["segments"] if s == name]
            inside = np.zeros(frames.shape, bool)
            for a, b in segs:                                    # current frames a+1 .. b-2
                inside |= (frames >= a + 1) & (frames <= b - 2)
            assert inside.all()
            assert frames.size == sum(max(0, b - a - 2) for a, b in segs)
    # the same frames of a file never appear in two splits
    keys = {name: set(zip(ds.split(name).file.tolist(), ds.split(name).frame.tolist())) for name in SPLITS}
    assert not (keys["train"] & keys["val"]) and not (keys["train"] & keys["test"])
    # a mirrored copy uses its original's segments
    for info in ds.files:
        if info["mirrored"]:
            orig = [o for o in ds.files if o["path"] == info["path"] and not o["mirrored"]][0]
            assert orig["segments"] == info["segments"]


def test_mirrored_rows_are_mirror_images(small):
    """Mirroring swaps left and right joints and negates x of every local position and velocity;
    a joint's axes are its partner's, x-negated, times the sign its own reflection S_j gives that
    axis (on the Bandai skeleton -I in the limbs, diag(1, 1, -1) in the spine)."""
    from minifilm.motion.bvh import read_bvh
    from minifilm.motion.editing import joint_reflections, mirror_pairs
    from minifilm.motion.skeletons import BANDAI

    _, _, ds = small
    sym = mirror_pairs(list(BANDAI.joints))
    assert sym.tolist() != list(range(21))
    sp = ds.train
    orig = [i for i, f in enumerate(ds.files) if f["style"] == "active" and not f["mirrored"]][0]
    mirr = [i for i, f in enumerate(ds.files) if f["path"] == ds.files[orig]["path"] and f["mirrored"]][0]
    a, b = sp.file == orig, sp.file == mirr
    np.testing.assert_array_equal(sp.frame[a], sp.frame[b])
    ja = sp.x[a][:, ds.layout.x_joints].reshape(-1, 21, 4, 3)
    jb = sp.x[b][:, ds.layout.x_joints].reshape(-1, 21, 4, 3)
    motion = read_bvh(ds.files[orig]["path"])
    S = joint_reflections(motion)[[motion.index(n) for n in BANDAI.joints]]
    assert np.allclose(np.abs(S), np.abs(S) * np.eye(3))          # diagonal on this skeleton
    sign = np.ones((21, 4, 3))
    sign[:, 1] = S[:, 2, 2][:, None]                              # forward: the rotation's column z
    sign[:, 2] = S[:, 1, 1][:, None]                              # up: its column y
    np.testing.assert_allclose(jb, ja[:, sym] * np.array([-1, 1, 1]) * sign, atol=2e-5)
    ta, tb = sp.x[a][:, :48].reshape(-1, 12, 4), sp.x[b][:, :48].reshape(-1, 12, 4)
    np.testing.assert_allclose(tb, ta * np.array([-1, 1, -1, 1]), atol=2e-5)
    za, zb = sp.z[a], sp.z[b]
    np.testing.assert_array_equal(zb[:, ds.layout.z_contacts], za[:, ds.layout.z_contacts][:, ::-1])
    # the phases: the mirrored rows carry the original's local phases with the left and right
    # slots swapped (slots left hand, right hand, left foot, right foot; one (sin, cos) pair each),
    # in p and in z's next phases and phase updates
    swap = [2, 3, 0, 1, 6, 7, 4, 5]
    assert np.abs(sp.p[a][:, swap] - sp.p[a]).max() > 0.1          # the swap is visible
    np.testing.assert_array_equal(sp.p[b], sp.p[a][:, swap])
    for cols in (ds.layout.z_phases, ds.layout.z_phase_updates):
        np.testing.assert_array_equal(zb[:, cols], za[:, cols][:, swap])


def test_normalisation_from_training_rows_only(small):
    _, _, ds = small
    x = ds.train.x.astype(np.float64)
    np.testing.assert_allclose(ds.stats.x_mean, x.mean(axis=0), atol=1e-9)
    std = x.std(axis=0)
    std[std < 1e-6] = 1.0
    np.testing.assert_allclose(ds.stats.x_std, std, rtol=1e-7, atol=1e-12)
    # the columns that are constant by construction get std 1: sample 6 and the hips' x, z
    assert np.all(ds.stats.x_std[[24, 25, 26, 27, 48, 50]] == 1.0)
    everything = np.concatenate([ds.train.x, ds.val.x, ds.test.x]).astype(np.float64)
    assert not np.allclose(ds.stats.x_mean, everything.mean(axis=0), atol=1e-9)
    td = ds.train_data("train")
    assert isinstance(td, TrainData) and td.style_names == ds.styles
    np.testing.assert_allclose(td.x.mean(axis=0), 0.0, atol=1e-3)
    vd = ds.train_data("val")                                 # val windows are shorter than a clip
    assert len(vd.clips) == len(ds.train.clips)


def test_train_data_normalises_p_z_and_clips_with_the_training_statistics(small):
    """p and z with their own training statistics; the style clips with the statistics of x's
    joint block (the clip's 12 numbers per joint are x's joint features, docs/original-code.md §9);
    every split with the training split's statistics, and clips from the training split when a
    split's own windows are too short."""
    _, _, ds = small
    st, J = ds.stats, ds.layout.x_joints
    for name, a in (("p", ds.train.p), ("z", ds.train.z)):
        a = a.astype(np.float64)
        std = a.std(axis=0)
        std[std < 1e-6] = 1.0
        np.testing.assert_allclose(getattr(st, f"{name}_mean"), a.mean(axis=0), atol=1e-9)
        np.testing.assert_allclose(getattr(st, f"{name}_std"), std, rtol=1e-7, atol=1e-12)
    assert ds.train.clips.shape[-1] == J.stop - J.start
    for name in ("train", "val"):
        td, sp = ds.train_data(name), ds.split(name)
        clips = ds.split(name if len(sp.clips) and set(sp.style) <= set(sp.clip_style) else "train")
        expect = {"p": (sp.p - st.p_mean) / st.p_std, "z": (sp.z - st.z_mean) / st.z_std,
                  "clips": (clips.clips - st.x_mean[J]) / st.x_std[J]}
        for key, want in expect.items():
            got = getattr(td, key)
            assert got.dtype == np.float32 and got.shape == want.shape, key
            np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5, err_msg=f"{name}.{key}")
        np.testing.assert_array_equal(td.clip_style, clips.clip_style)
    td = ds.train_data("train")
    for key in ("p", "z"):                                    # standardised columns (not constant ones)
        a = getattr(td, key).astype(np.float64)
        live = getattr(st, f"{key}_std") != 1.0
        np.testing.assert_allclose(a.mean(axis=0), 0.0, atol=1e-4)
        np.testing.assert_allclose(a[:, live].std(axis=0), 1.0, rtol=1e-4)
    assert ds.train_data("train", dtype=np.float64).p.dtype == np.float64


def test_cache_second_build_is_loaded(small, shared_data):
    files, cache, ds = small
    assert ds.cache_path is not None and ds.cache_path.parent == cache
    again = build_dataset(files, cache_dir=cache, progress=False, mirror_styles=("active",), seed=7,
                          clip_seconds=2.0, clip_stride_seconds=1.0)
    assert again.cache_path == ds.cache_path and again.cache_key == ds.cache_key
    for name in SPLITS:
        for key in ("x", "p", "z", "style", "file", "frame", "clips", "clip_style"):
            np.testing.assert_array_equal(getattr(again.split(name), key), getattr(ds.split(name), key))
    assert again.layout == ds.layout and again.files == ds.files
    np.testing.assert_array_equal(again.stats.z_std, ds.stats.z_std)
    with np.load(ds.cache_path, allow_pickle=False) as d:      # no object arrays inside
        assert all(d[k].dtype != object for k in d.files)
    other = build_dataset(files, cache_dir=cache, progress=False, mirror_styles=("active",), seed=8,
                          clip_gaits=("none",), clip_fallback=False)
    assert other.cache_path != ds.cache_path and len(other.train.clips) == 0


def test_100style_folder_skips_idle_and_keeps_transitions_in_train(shared_data, tmp_path):
    src = shared_data / "bandai2"
    for name, target in [("Happy_FW.bvh", "dataset-2_walk_active_002.bvh"),
                         ("Happy_ID.bvh", "dataset-2_walk_active_003.bvh"),
                         ("Happy_TR1.bvh", "dataset-2_walk-turn-right_active_001.bvh")]:
        os.symlink(src / target, tmp_path / name)
    ds = build_dataset(tmp_path, progress=False)
    assert [(Path(f["path"]).name, f["mirrored"]) for f in ds.files] == [("Happy_FW.bvh", False),
                                                                         ("Happy_TR1.bvh", False)]
    assert ds.files[1]["segments"] == [(0, ds.files[1]["n_frames"], "train")]
    assert len(ds.val) > 0 and set(ds.val.file.tolist()) == {0}


def test_clip_fallback_uses_other_gaits(small):
    """With no file of a clip gait, a style's clips come from its other files (configurable)."""
    files, _, _ = small
    ds = build_dataset(files, progress=False, seed=7, clip_seconds=2.0, clip_stride_seconds=1.0,
                       clip_gaits=("no-such-gait",))
    assert len(ds.train.clips) > 0
    gaits = {ds.files[c]["gait"] for c in ds.train.clip_file}
    assert gaits - {"walk"}                                     # not only walk files


def last_digit_changed(data: bytes) -> bytes:
    """The last digit of the last frame another digit: same size, other motion."""
    i = max(data.rfind(d) for d in b"0123456789")
    return data[:i] + (b"1" if data[i:i + 1] != b"1" else b"2") + data[i + 1:]


def two_frames_swapped(data: bytes) -> bytes:
    lines = data.split(b"\n")
    frames = [i for i, line in enumerate(lines) if line.strip() and line.strip()[:1] in b"-0123456789"]
    a, b = next((i, j) for i in frames for j in frames[::-1] if len(lines[i]) == len(lines[j]) and lines[i] != lines[j])
    lines[a], lines[b] = lines[b], lines[a]
    return b"\n".join(lines)


@pytest.mark.parametrize("change", [last_digit_changed, two_frames_swapped])
def test_a_cache_is_keyed_on_the_files_bytes(shared_data, tmp_path, monkeypatch, change):
    """A file changed in place with its size and modification time kept (cp -p, rsync -t) is never
    served from the cache; one only touched is."""
    import shutil

    monkeypatch.setattr(cache_module, "source_fingerprint", lambda: "pinned")

    src = shared_data / "bandai2" / "dataset-2_walk_normal_001.bvh"
    copy = tmp_path / "Normal_FW.bvh"
    shutil.copy(src, copy)
    cache = tmp_path / "cache"
    first = build_dataset(tmp_path, cache_dir=cache, progress=False, clip_seconds=2.0)
    loaded = build_dataset(tmp_path, cache_dir=cache, progress=False, clip_seconds=2.0)
    assert not first.loaded and loaded.loaded
    assert loaded.cache_key == first.cache_key and loaded.cache_path == first.cache_path
    st = copy.stat()
    os.utime(copy, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))   # touched: the same bytes
    assert build_dataset(tmp_path, cache_dir=cache, progress=False, clip_seconds=2.0).loaded
    st = copy.stat()
    copy.write_bytes(change(copy.read_bytes()))
    os.utime(copy, ns=(st.st_atime_ns, st.st_mtime_ns))            # its time put back
    assert copy.stat().st_size == st.st_size
    again = build_dataset(tmp_path, cache_dir=cache, progress=False, clip_seconds=2.0)
    assert not again.loaded and again.cache_key != first.cache_key and again.cache_path == first.cache_path
    assert len(list(cache.glob("*.npz"))) == 1
    assert build_dataset(tmp_path, cache_dir=cache, progress=False, clip_seconds=2.0).loaded   # and cached anew


def test_split_files_per_style():
    files = [MotionFile(Path(f"/d/{s}_{i:02d}.bvh"), s, "walk") for s in ("a", "b") for i in range(20)]
    files += [MotionFile(Path("/d/c_00.bvh"), "c", "walk"), MotionFile(Path("/d/c_01.bvh"), "c", "run")]
    got = split_files(files, seed=1)
    for s in ("a", "b"):
        splits = [got[f.path] for f in files if f.style == s]
        assert (splits.count("train"), splits.count("val"), splits.count("test")) == (16, 2, 2)
    assert {got[Path("/d/c_00.bvh")], got[Path("/d/c_01.bvh")]} == {"train"}   # too few to split
    assert split_files(files[::-1], seed=1) == got                           # order does not matter
    assert any(split_files(files, seed=s) != got for s in range(2, 6))
    assert set(split_files(files, seed=1, fractions=(1.0, 0.0, 0.0)).values()) == {"train"}


def test_build_with_whole_file_splits(small):
    files, _, _ = small
    ds = build_dataset(files * 1, progress=False, seed=7, split_unit="files",
                       clip_seconds=2.0, clip_stride_seconds=1.0)
    for info in ds.files:                       # every file is one segment of a single split
        assert len(info["segments"]) == 1 and info["segments"][0][:2] == (0, info["n_frames"])
    # reflected samples, counted by hand: offsets of 1/6 s and 0.2 s steps at 30 fps
    offsets = [-30, -25, -20, -15, -10, -5, 0, 6, 12, 18, 24, 30]
    for name, frac in ds.reflected_fraction().items():
        hit = total = 0
        for info in ds.files:
            n, split = info["n_frames"], info["segments"][0][2]
            if split == name:
                for k in range(1, n - 1):
                    hit += sum(1 for o in offsets if not 0 <= k + o <= n - 1)
                    total += len(offsets)
        assert frac == pytest.approx(hit / total if total else 0.0)
    with pytest.raises(ValueError, match="split_unit must be"):
        DatasetSettings(split_unit="frames")


def test_scan_100style_reads_frame_cuts_and_symmetry(tmp_path):
    for name in ["Zombie_FW.bvh", "Zombie_TR.bvh", "Aeroplane_BR.bvh"]:
        (tmp_path / name).write_text("x")
    (tmp_path / "Frame_Cuts.csv").write_text(
        "STYLE_NAME,BR_START,BR_STOP,FW_START,FW_STOP,TR1_START,TR1_STOP,TR2_START,TR2_STOP\n"
        "Aeroplane,300,1200,250,900,400,800,N/A,N/A\n"
        "Zombie,213,5000,985,18548,500,700,N/A,N/A\n")
    (tmp_path / "Dataset_List.csv").write_text(
        "Style Name,Description,Stochastic (Yes/No),Symmetric (Yes/No),Notes\n"
        "Aeroplane,arms out,No,Yes,\nZombie,arms forward,Yes,No,\n")
    got = {f.path.name: (f.start, f.end, f.mirror) for f in scan_100style(tmp_path)}
    assert got == {"Aeroplane_BR.bvh": (299, 1200, True),      # 1-based inclusive -> [START-1, STOP)
                   "Zombie_FW.bvh": (984, 18548, False),
                   "Zombie_TR.bvh": (499, 700, False)}
    (tmp_path / "Frame_Cuts.csv").write_text("STYLE_NAME,FW_START,FW_STOP\nZombie,900,800\n")
    with pytest.raises(ValueError, match=r"Frame_Cuts.csv: line 2: FW cut \[900, 800\]"):
        scan_100style(tmp_path)


def test_resampling_and_errors_name_the_file(shared_data, tmp_path):
    src = shared_data / "bandai2" / "dataset-2_walk_normal_001.bvh"
    os.symlink(src, tmp_path / "Normal_FW.bvh")
    ds = build_dataset(tmp_path, progress=False, fps=60.0, clip_seconds=2.0)
    assert ds.fps == 60.0 and ds.train.clips.shape[1] == 120
    n30 = int(open(src).read().split("Frames:")[1].split()[0])
    assert ds.files[0]["n_frames"] == 2 * (n30 - 1) + 1            # every 30 fps frame plus midpoints
    from minifilm.motion.skeletons import BANDAI

    (tmp_path / "Broken_FW.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    with pytest.raises(ValueError) as info:                         # BVHError is a ValueError
        build_dataset(tmp_path, progress=False, skeleton=BANDAI)
    assert "Broken_FW.bvh" in str(info.value) + "".join(getattr(info.value, "__notes__", []))


def test_mean_std_in_chunks_matches_numpy():
    from minifilm.dataset.stats import _mean_std

    a = np.random.default_rng(3).normal(5.0, 0.01, size=(1000, 4)).astype(np.float32)
    mean, std = _mean_std(a, chunk=64)
    np.testing.assert_allclose(mean, a.astype(np.float64).mean(axis=0), rtol=1e-13)
    np.testing.assert_allclose(std, a.astype(np.float64).std(axis=0), rtol=1e-9)


def test_gap_keeps_splits_apart(shared_data, tmp_path):
    os.symlink(shared_data / "bandai2" / "dataset-2_walk_elderly_002.bvh", tmp_path / "Old_FW.bvh")
    ds = build_dataset(tmp_path, progress=False, gap_seconds=0.5, clip_seconds=2.0, seed=3)
    frames = {name: ds.split(name).frame for name in SPLITS}
    assert all(len(frames[name]) for name in SPLITS)
    for a in SPLITS:
        for b in SPLITS:
            if a < b:     # 0.5 s on each side, plus the segment ends that are never current
                d = np.abs(frames[a][:, None] - frames[b][None, :]).min()
                assert d >= 2 * 15 + 3
