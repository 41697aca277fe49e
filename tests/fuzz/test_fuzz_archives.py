"""Fuzzing the archives of a run folder made by a tiny training run: the checkpoint (model.npz), the
style library (styles.npz) and the start frames (starts.npz).

A mutated archive must either load and give exactly the original's result (a prediction of the
network, the style vectors, the start frames), or fail with one error line naming the file: never
NaN, a traceback, a huge allocation, or a silently different network.
"""
import shutil

import numpy as np
import pytest
from harness import outcome
from mutate import array_mutations, byte_mutations, json_member, read_members, write_members

from minifilm.errors import InputError
from minifilm.pipeline.run_folder import RunFolder
from minifilm.train.trainer import Trainer

RNG = np.random.default_rng(190)
BYTES = byte_mutations(RNG)


def copy_run(src, dst):
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("data", "cache", "generated", "*.png"))
    return dst


def load_everything(folder):
    """What a user of the run touches: the runtime network, the training state, styles, starts."""
    run = RunFolder.load(folder)
    net = run.network()
    trainer = Trainer.resume(folder / "model.npz")
    styles = run.styles()
    starts = run.starts()
    name = styles.names[0]
    x, p = starts[name]
    z = net.predict(x[None], p[None], styles[name])
    return z, styles, starts, trainer


@pytest.fixture(scope="module")
def reference(tiny_run):
    return load_everything(tiny_run)


def check(folder, reference, path):
    result, error = outcome(lambda: load_everything(folder), InputError, mentions=[path.name])
    if error is None:
        z, styles, starts, _ = result
        assert np.all(np.isfinite(z))
        np.testing.assert_array_equal(z, reference[0])
        assert styles.names == reference[1].names
        for n in styles.names:
            np.testing.assert_array_equal(styles[n], reference[1][n])
    return error


# ---- byte-level damage of each archive ------------------------------------------------------
@pytest.mark.parametrize("archive", ["model.npz", "styles.npz", "starts.npz"])
@pytest.mark.parametrize("name,edit", BYTES, ids=[n for n, _ in BYTES])
def test_damaged_archive(tiny_run, reference, tmp_path, archive, name, edit):
    folder = copy_run(tiny_run, tmp_path / "run")
    path = folder / archive
    path.write_bytes(edit(path.read_bytes()))
    check(folder, reference, path)


# ---- array-level edits of the checkpoint ------------------------------------------------------
def _checkpoint_cases():
    return array_mutations({}, RNG, ["gating.W0", "gating.b2", "motion.W1", "motion.b0", "film.dense0_W",
                                     "stats.x_std", "stats.z_mean", "stats.p_std", "adam.m.0", "adam.v.1"])


CHECKPOINT_EDITS = _checkpoint_cases()


@pytest.mark.parametrize("name,edit", CHECKPOINT_EDITS, ids=[n for n, _ in CHECKPOINT_EDITS])
def test_edited_checkpoint_arrays(tiny_run, reference, tmp_path, name, edit):
    folder = copy_run(tiny_run, tmp_path / "run")
    path = folder / "model.npz"
    arrays = read_members(path)
    if not all(n in arrays for n in name.split() if "." in n):
        pytest.skip(f"the tiny run has no array named in {name!r}")
    new, raw = edit(arrays)
    write_members(path, new, raw)
    error = check(folder, reference, path)
    if "extra unknown" not in name:
        assert error is not None, f"{name}: loaded as if nothing had changed"


META_EDITS = [
    ("not JSON", lambda m: "{not json"),
    ("a list", lambda m: [1, 2]),
    ("other format", lambda m: {**m, "format": "minifilm-checkpoint-0"}),
    ("hidden 200000", lambda m: {**m, "model_config": {**m["model_config"], "hidden": 200000}}),
    ("hidden 10x", lambda m: {**m, "model_config": {**m["model_config"], "hidden": 10 * m["model_config"]["hidden"]}}),
    ("hidden -1", lambda m: {**m, "model_config": {**m["model_config"], "hidden": -1}}),
    ("hidden 'a'", lambda m: {**m, "model_config": {**m["model_config"], "hidden": "a"}}),
    ("hidden 1.5", lambda m: {**m, "model_config": {**m["model_config"], "hidden": 1.5}}),
    ("n_experts 0", lambda m: {**m, "model_config": {**m["model_config"], "n_experts": 0}}),
    ("dropout nan", lambda m: {**m, "model_config": {**m["model_config"], "dropout": float("nan")}}),
    ("unknown config field", lambda m: {**m, "model_config": {**m["model_config"], "colour": 3}}),
    ("no model_config", lambda m: {k: v for k, v in m.items() if k != "model_config"}),
    ("train_config lr -1", lambda m: {**m, "train_config": {**m["train_config"], "lr": -1}}),
    ("train_config batch 0", lambda m: {**m, "train_config": {**m["train_config"], "batch_size": 0}}),
    ("train_config a string", lambda m: {**m, "train_config": "fast"}),
    ("positions_idx out of z", lambda m: {**m, "positions_idx": [[10**6, 0, 1]] * len(m["positions_idx"])}),
    ("parents after their joints", lambda m: {**m, "parents": list(range(1, len(m["parents"]) + 1))}),
    ("style_names a number", lambda m: {**m, "style_names": 7}),
    ("epoch -5", lambda m: {**m, "epoch": -5}),
    ("rng state garbage", lambda m: {**m, "rng_state": {"bit_generator": "nope"}}),
    ("a comparison variant", lambda m: {**m, "variant": {"name": "LPN One-hot", "n_styles": 2}}),
]


@pytest.mark.parametrize("name,edit", META_EDITS, ids=[n for n, _ in META_EDITS])
def test_edited_checkpoint_metadata(tiny_run, reference, tmp_path, name, edit):
    folder = copy_run(tiny_run, tmp_path / "run")
    path = folder / "model.npz"
    write_members(path, json_member(read_members(path), "meta.json", edit))
    assert check(folder, reference, path) is not None, f"{name}: loaded as if nothing had changed"


# ---- the style library and the start frames ---------------------------------------------------
LIBRARY_EDITS = array_mutations({}, RNG, ["films"], n_each=1) + [
    ("a name twice", lambda a: ({**a, "names": np.array([a["names"][0]] * len(a["names"]))}, {})),
    ("an empty name", lambda a: ({**a, "names": np.array([""] + list(a["names"][1:]))}, {})),
    ("names as numbers", lambda a: ({**a, "names": np.arange(len(a["names"]))}, {})),
    ("films of another width", lambda a: ({**a, "films": np.zeros((len(a["names"]), 12), np.float32)}, {})),
    ("films 1-D", lambda a: ({**a, "films": np.asarray(a["films"])[0]}, {})),
    ("one name too many", lambda a: ({**a, "names": np.array(list(a["names"]) + ["Extra"])}, {})),
]


STARTS_EDITS = array_mutations({}, RNG, ["x", "p"], n_each=1) + [
    ("x of another width", lambda a: ({**a, "x": np.zeros((len(a["names"]), 5))}, {})),
]
SMALL_ARCHIVE_EDITS = [("styles.npz", n, e) for n, e in LIBRARY_EDITS] + [("starts.npz", n, e) for n, e in STARTS_EDITS]


@pytest.mark.parametrize("archive,name,edit", SMALL_ARCHIVE_EDITS, ids=[f"{a}: {n}" for a, n, _ in SMALL_ARCHIVE_EDITS])
def test_edited_style_library_and_start_frames(tiny_run, reference, tmp_path, archive, name, edit):
    folder = copy_run(tiny_run, tmp_path / "run")
    path = folder / archive
    new, raw = edit(read_members(path))
    write_members(path, new, raw)
    error = check(folder, reference, path)
    if "extra unknown" not in name:
        assert error is not None, f"{name}: loaded as if nothing had changed"


def test_there_are_enough_cases():
    n = 3 * len(BYTES) + len(CHECKPOINT_EDITS) + len(META_EDITS) + len(LIBRARY_EDITS) + len(STARTS_EDITS)
    assert n >= 150, n
