"""A trained run's new style refined by the motion it makes (pipeline/run_motion_refit.py,
``minifilm finetune --run --motion-rounds N``): the stored vector moves only along the trained
styles' principal directions, the trained styles keep their vectors, and a run the walks cannot
drive is refused before anything is written."""
import hashlib
import json
import shutil
from dataclasses import replace

import numpy as np
import pytest

from minifilm.motion.bvh_write import write_bvh
from minifilm.pipeline.motion_refit import RefitSettings
from minifilm.pipeline.new_style import teach_style
from minifilm.pipeline.run_folder import RunFolder
from minifilm.pipeline.train_small import Settings, run
from minifilm.synthetic.generator import default_dataset

SMALL = RefitSettings(rounds=2, population=4, elite=2, seconds=2.0, directions=2, dims=8, contrast=2)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("run_refit") / "run"
    run(replace(Settings(out=out).quick(), styles=("Neutral", "LeftHop", "Limp"), gaits=("FW",),
                seconds_per_clip=6.0, epochs=1, generate_seconds=0.5))
    return out


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    path = tmp_path_factory.mktemp("run_refit_clip") / "drunk.bvh"
    write_bvh(default_dataset(styles=["Drunk"], gaits=["FW"], seconds=8.0, seed=5)[0].motion, path)
    return path


def copy_of(trained, tmp_path):
    return shutil.copytree(trained, tmp_path / "run", ignore=shutil.ignore_patterns("*.lock"))


def test_the_refined_vector_moves_only_along_the_trained_styles_directions(trained, clip, tmp_path):
    plain, refined = copy_of(trained, tmp_path / "a"), copy_of(trained, tmp_path / "b")
    before = {n: RunFolder.load(trained).styles()[n].copy() for n in ("Neutral", "LeftHop", "Limp")}
    teach_style(plain, "Drunk", [clip], steps=10, log=lambda m: None)
    lines = []
    r = teach_style(refined, "Drunk", [clip], steps=10, motion=SMALL, log=lines.append)
    assert r.refit is not None and len(r.refit.history) == SMALL.rounds
    assert any(line.startswith("[finetune] refining by motion: 2 rounds of 4 walks") for line in lines), lines
    library = RunFolder.load(refined).styles()
    for name, vector in before.items():                 # the trained styles' vectors untouched
        np.testing.assert_array_equal(library[name], vector)
    start = RunFolder.load(plain).styles()["Drunk"].astype(np.float64)     # mean Ψ: the same fine-tuning
    moved = library["Drunk"].astype(np.float64) - start
    np.testing.assert_array_equal(library["Drunk"], r.refit.film)
    # the search's moves lie in the span of the trained vectors' differences from their mean
    V = np.stack(list(before.values())).astype(np.float64)
    basis = np.linalg.svd(V - V.mean(axis=0), full_matrices=False)[2][:SMALL.directions]
    off_span = moved - (moved @ basis.T) @ basis
    assert np.linalg.norm(off_span) <= 1e-4 * max(np.linalg.norm(start), 1.0)
    assert r.refit.score < r.refit.start_score and np.linalg.norm(moved) > 0      # it did move


def test_a_run_at_another_rate_is_refused_before_anything_is_written(trained, clip, tmp_path):
    folder = copy_of(trained, tmp_path)
    meta = json.loads((folder / "run.json").read_text())
    meta["fps"] = 30.0
    (folder / "run.json").write_text(json.dumps(meta))
    digests = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir() if p.is_file()}
    with pytest.raises(ValueError, match=r"--motion-rounds: the run is at 30 fps; the walks of the refinement are at"):
        teach_style(folder, "Drunk", [clip], steps=5, motion=SMALL, log=lambda m: None)
    assert {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir() if p.is_file()} == digests
