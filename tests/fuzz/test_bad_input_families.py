"""The six families of bad-input defects a probe found, one test each, on the cases it
listed. The fuzz tests beside this file go wider; these pin the cases that were reported."""
import re
import shutil
import tracemalloc

import numpy as np
import pytest
from mutate import json_member, read_members, write_members

from minifilm import cli
from minifilm.dataset.build import build_dataset
from minifilm.dataset.survey import check_memory, survey
from minifilm.errors import DataError, InputError
from minifilm.motion.bvh import BVHError, read_bvh
from minifilm.pipeline.run_folder import RunFolder
from minifilm.runtime.controller import NonFiniteOutputError
from minifilm.runtime.released import ReleasedFormatError, load_released, write_released
from minifilm.runtime.style_library import StyleLibrary, StyleLibraryError
from minifilm.train.checkpoint import CheckpointError, load_checkpoint

BANDAI = "bandai2/dataset-2_walk_normal_{:03d}.bvh"


def with_frame_time(text: str, value: str) -> str:
    return re.sub(r"(?im)^(\s*frame\s+time\s*:).*$", rf"\g<1> {value}", text)


def cut(text: str, frames: int) -> str:
    head, rest = re.split(r"(?im)^\s*frames\s*:.*$", text, maxsplit=1)
    lines = [line for line in rest.split("\n") if line.strip()]
    return head + f"Frames: {frames}\n" + "\n".join(lines[:frames + 1]) + "\n"


def bandai_folder(shared_data, tmp_path, n=3):
    folder = tmp_path / "data"
    folder.mkdir(parents=True)
    for i in range(1, n + 1):
        shutil.copy(shared_data / BANDAI.format(i), folder)
    return folder


# ---- 1. non-finite numbers ---------------------------------------------------------------------
def test_family_1_non_finite_numbers_are_refused_where_they_enter(shared_data, tiny_run, tmp_path):
    # one NaN in a released weight file
    folder = tmp_path / "released"
    shutil.copytree(shared_data / "released-lpn", folder)
    w = np.fromfile(folder / "cp1_a2.bin", "<f4")
    w[17] = np.nan
    w.tofile(folder / "cp1_a2.bin")
    with pytest.raises(ReleasedFormatError, match="cp1_a2.bin holds 1 non-finite"):
        load_released(folder)
    # through the API: a NaN style vector is an error at the first frame, not all-NaN positions
    run = RunFolder.load(tiny_run)
    controller, styles = run.controller(), run.styles()
    film = styles[styles.names[0]].copy()
    film[3] = np.nan
    from minifilm.runtime.control import straight_walk
    with pytest.raises(InputError, match="film must be"):
        controller.run(straight_walk(1.0), 10, film)
    # a network that overflows stops at the first non-finite frame
    net = run.network()
    net.layers[2] = (net.layers[2][0] * np.float32(1e38), net.layers[2][1], net.layers[2][2])
    with pytest.raises(NonFiniteOutputError, match="not finite"), np.errstate(over="ignore", invalid="ignore"):
        run.controller(network=net).run(straight_walk(1.0), 10, styles[styles.names[0]])
    # NaN weights or statistics in a checkpoint
    for name in ("motion.W1", "stats.z_std"):
        path = tmp_path / f"nan-{name}.npz"
        arrays = read_members(tiny_run / "model.npz")
        arrays[name] = np.array(arrays[name], copy=True)
        arrays[name].reshape(-1)[0] = np.nan
        write_members(path, arrays)
        shutil.copytree(tiny_run, tmp_path / f"run-{name}", ignore=shutil.ignore_patterns("data", "cache", "generated"))
        shutil.copy(path, tmp_path / f"run-{name}" / "model.npz")
        with pytest.raises(CheckpointError, match="model.npz"):
            RunFolder.load(tmp_path / f"run-{name}").network()
    # 1e308 (and NaN) in a BVH file: the file and line are named, nothing reaches a split
    text = (shared_data / BANDAI.format(1)).read_text()
    lines = text.split("\n")
    k = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 5
    parts = lines[k].split()
    parts[7] = "1e308"
    bad = tmp_path / "huge.bvh"
    bad.write_text("\n".join(lines[:k] + [" ".join(parts)] + lines[k + 1:]))
    with pytest.raises(BVHError, match=rf"huge.bvh, line {k + 1}: expected a finite number"):
        read_bvh(bad)
    # NaN in training data names the array and row, before any training
    from minifilm.dataset.arrays import TrainData
    x = np.zeros((4, 3), np.float32)
    x[2, 1] = np.nan
    with pytest.raises(DataError, match=r"x\[2, 1\] is nan"):
        TrainData(x, np.zeros((4, 8), np.float32), np.zeros((4, 5), np.float32), np.zeros(4),
                  np.zeros((1, 6, 3), np.float32), np.zeros(1))


def test_family_1_non_finite_features_name_the_file_frame_and_column():
    from minifilm.dataset.validate import check_finite
    from minifilm.features.layout import FeatureLayout
    from minifilm.motion.skeletons import builtin_skeleton
    layout = FeatureLayout.for_skeleton(builtin_skeleton("bandai"))
    x = np.zeros((3, layout.x_dim), np.float32)
    x[1, layout.x_joints.start] = np.inf
    with pytest.raises(DataError, match=r"walk.bvh: frame 8: x\[48\] \(Hips, position x"):
        check_finite(x, "x", layout, "walk.bvh", np.array([7, 8, 9]))


# ---- 2. sizes and rates without bound ----------------------------------------------------------
def test_family_2_sizes_and_rates_are_bounded_before_allocating(shared_data, tiny_run, tmp_path):
    text = (shared_data / BANDAI.format(1)).read_text()
    for value, message in (("1e-9", "1e+09 frames per second"), ("100", "0.01 frames per second")):
        path = tmp_path / f"ft-{value}.bvh"
        path.write_text(with_frame_time(text, value))
        with pytest.raises(BVHError, match=re.escape(message)):
            read_bvh(path)
        folder = bandai_folder(shared_data, tmp_path / value)
        shutil.copy(path, folder / "dataset-2_walk_normal_099.bvh")
        tracemalloc.start()
        with pytest.raises(BVHError, match="dataset-2_walk_normal_099.bvh"):
            build_dataset(folder, progress=False)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak < 100 * 2**20
    # a checkpoint whose metadata asks for a huge network is refused before the network exists
    path = tmp_path / "model.npz"
    write_members(path, json_member(read_members(tiny_run / "model.npz"), "meta.json",
                                    lambda m: {**m, "model_config": {**m["model_config"], "hidden": 200000}}))
    tracemalloc.start()
    with pytest.raises(CheckpointError, match="model.npz"):
        load_checkpoint(path)
    assert tracemalloc.get_traced_memory()[1] < 100 * 2**20
    tracemalloc.stop()
    # and a dataset that would not fit in memory says so before it is built
    from minifilm.dataset.manifest import bandai_files
    from minifilm.features.layout import FeatureLayout
    from minifilm.motion.skeletons import builtin_skeleton
    found = bandai_files(bandai_folder(shared_data, tmp_path / "mem"))
    with pytest.raises(DataError, match=r"would need about .* GiB .* more than 0.0 GiB"):
        check_memory(survey(found, None), [False] * len(found), FeatureLayout.for_skeleton(builtin_skeleton("bandai")),
                     60, 30, 4, budget=1000)


# ---- 3. silent wrong results ---------------------------------------------------------------------
def test_family_3_no_silent_wrong_result(shared_data, tiny_run, tmp_path):
    # a 2-frame file among good files: named, instead of a style with 0 rows
    folder = bandai_folder(shared_data, tmp_path)
    short = folder / "dataset-2_walk_feminine_001.bvh"
    short.write_text(cut((shared_data / BANDAI.format(1)).read_text(), 2))
    with pytest.raises(DataError, match="dataset-2_walk_feminine_001.bvh: 2 frames to use"):
        build_dataset(folder, progress=False)
    # a style whose only file is too short for a training row
    short.write_text(cut((shared_data / BANDAI.format(1)).read_text(), 4))
    with pytest.raises(DataError, match="style 'feminine' has no training"):
        build_dataset(folder, progress=False, split_unit="segments")
    # released: a name twice, a name for a missing style
    for edit, message in ((lambda t: t.replace("001 Akimbo", "001 Aeroplane"), "given to two style ids"),
                          (lambda t: t + "555 Ghost\n", "no Style_555_scale1.bin")):
        d = tmp_path / f"released{len(message)}"
        shutil.copytree(shared_data / "released-lpn", d)
        (d / "styles.txt").write_text(edit((d / "styles.txt").read_text()))
        with pytest.raises(ReleasedFormatError, match=message):
            load_released(d)
    # a style library with a name twice, and one of another network's width
    path = tmp_path / "styles.npz"
    write_members(path, {"names": np.array(["A", "A"]), "films": np.zeros((2, 8), np.float32)})
    with pytest.raises(StyleLibraryError, match="named more than once: \\['A'\\]"):
        StyleLibrary.load(path)
    run = RunFolder.load(tiny_run)
    with pytest.raises(StyleLibraryError, match=rf"shape \(2, 8\), .*the network needs {run.film_dim()} numbers"):
        StyleLibrary.load(_library(tmp_path, 8), dim=run.film_dim())


def _library(tmp_path, width):
    path = tmp_path / f"lib{width}.npz"
    write_members(path, {"names": np.array(["A", "B"]), "films": np.zeros((2, width), np.float32)})
    return path


# ---- 4. writes: atomic, no debris, usual permissions (see also tests/test_files.py) -----------------
def test_family_4_released_folder_is_written_whole(shared_data, tmp_path):
    net = load_released(shared_data / "released-lpn")
    target = tmp_path / "out"
    write_released(net.model, net.stats, net.styles, target)
    assert len(list(target.glob("Style_*_scale1.bin"))) == 100
    three = dict(list(net.styles.items())[:3])
    write_released(net.model, net.stats, three, target)          # 3 over 100 leaves 3
    assert len(list(target.glob("Style_*_scale1.bin"))) == 3
    assert list(load_released(target).styles) == list(three)

    class Killed(Exception):
        pass

    import minifilm.runtime.released as released
    original = released._write
    calls = []

    def write_then_die(directory, name, array):
        calls.append(name)
        if len(calls) == 20:
            raise Killed
        original(directory, name, array)
    released._write = write_then_die
    try:
        with pytest.raises(Killed):
            write_released(net.model, net.stats, net.styles, target)
    finally:
        released._write = original
    assert list(load_released(target).styles) == list(three)        # the old folder, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]     # no temporary folder left


def test_family_4_a_killed_training_leaves_no_run(tmp_path, monkeypatch):
    """A run stopped after its checkpoint leaves nothing that could be taken for a run: it was
    being built beside its folder, which is never made (since made stronger than the
    run.json-last rule it replaces)."""
    from dataclasses import replace

    import minifilm.pipeline.train_small as job
    from minifilm.pipeline.run_folder import RunFolderError

    def die(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(job, "style_recognition", die)
    s = replace(job.Settings(out=tmp_path / "run").quick(), styles=("Neutral", "LeftHop"), gaits=("FW",), epochs=1,
                generate_seconds=0.5, seconds_per_clip=6.0)
    with pytest.raises(KeyboardInterrupt):
        job.run(s)
    assert list(tmp_path.iterdir()) == []        # no folder, no temporary, no lock file
    with pytest.raises(RunFolderError, match="no such folder"):
        RunFolder.load(tmp_path / "run")


# ---- 5. arguments checked before the work ------------------------------------------------------
@pytest.mark.parametrize("argv,message", [
    (["generate", "--params", "{P}", "--style2", "Old", "--blend", "1000"], "--blend: 1000.0 must be <= 1.0"),
    (["generate", "--params", "{P}", "--style2", "Old", "--blend", "-1"], "--blend: -1.0 must be >= 0.0"),
    (["generate", "--params", "{P}", "--speed", "-1"], "--speed: -1.0 must be >= 0.0"),
    (["generate", "--params", "{P}", "--switch-to", "Old", "--switch-at", "nan"], "--switch-at: 'nan' is not a finite"),
    (["generate", "--params", "{P}", "--seconds", "-5"], "--seconds: -5.0 must be > 0"),
    (["generate", "--params", "{P}", "--seconds", "nan"], "--seconds: 'nan' is not a finite"),
    (["generate", "--params", "{P}", "--seconds", "0"], "--seconds: 0.0 must be > 0"),
    (["generate", "--params", "{P}", "--png", "{T}/a.png", "--png-every", "0"], "--png-every: 0 must be >= 1"),
    (["generate", "--params", "{P}", "--out", "{T}"], "is a folder"),
    (["compare", "--data", "{T}/missing"], "--data {T}/missing: no such folder"),
    (["table2", "--styles", "-3"], "--styles: -3 must be >= 1"),
    (["compare", "--holdout", " , ", "--work", "{T}/w", "--out", "{T}/r"], "--holdout ' , ': names no style"),
    (["finetune", "--params", "{P}", "--name", "X", "--out", "{T}/pack", "--motion-rounds", "-1", "{B}"],
     "--motion-rounds: -1 must be >= 0"),
    (["finetune", "--params", "{P}", "--name", "X", "--out", "{T}/pack", "--motion-rounds", "1e9", "{B}"],
     "--motion-rounds"),
    (["finetune", "--params", "{P}", "--name", "X", "--out", "{T}/pack", "--workers", "0", "{B}"],
     "--workers: 0 must be >= 1"),
    (["finetune", "--params", "{P}", "--name", "X", "--out", "{T}/pack", "--workers", "1e9", "{B}"], "--workers"),
])
def test_family_5_arguments_are_checked_first(shared_data, tmp_path, capsys, argv, message):
    fill = lambda a: (a.replace("{P}", str(shared_data / "released-lpn")).replace("{T}", str(tmp_path))
                      .replace("{B}", str(shared_data / BANDAI.format(1))))
    with pytest.raises(SystemExit) as e:
        cli.main([fill(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and len(err) == 1 and fill(message) in err[0], err
    assert list(tmp_path.iterdir()) == []


# ---- 6. errors that blamed the wrong thing -----------------------------------------------------
def test_family_6_errors_blame_the_right_thing(shared_data, tmp_path, capsys):
    text = (shared_data / BANDAI.format(1)).read_text()
    cr = tmp_path / "cr.bvh"
    cr.write_bytes(text.replace("\n", "\r").encode())
    assert read_bvh(cr).n_frames == read_bvh(shared_data / BANDAI.format(1)).n_frames
    # a 120 fps file among 30 fps files: the odd one is named, whatever the order
    folder = bandai_folder(shared_data, tmp_path, n=3)
    (folder / "dataset-2_walk_normal_001.bvh").write_text(with_frame_time(text, "0.00833333"))
    with pytest.raises(DataError, match=r"1 of 3 files are not at the others' 30 fps: dataset-2_walk_normal_001.bvh \(120 fps\)"):
        build_dataset(folder, progress=False)
    # phases --out DIR is refused, not quietly written to DIR.png
    (tmp_path / "plots").mkdir()
    with pytest.raises(SystemExit):
        cli.main(["phases", str(shared_data / BANDAI.format(1)), "--out", str(tmp_path / "plots")])
    assert "is a folder" in capsys.readouterr().err
    assert not (tmp_path / "plots.png").exists()
    # a truncated style library is a StyleLibraryError naming it, not a raw BadZipFile
    path = tmp_path / "styles.npz"
    write_members(path, {"names": np.array(["A"]), "films": np.zeros((1, 8), np.float32)})
    path.write_bytes(path.read_bytes()[:-40])
    with pytest.raises(StyleLibraryError, match=f"style library {path}: not a readable .npz"):
        StyleLibrary.load(path)
