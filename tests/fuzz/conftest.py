"""Fixtures of the fuzz suite: one tiny trained run (a few seconds) whose files the cases mutate."""
from dataclasses import replace

import pytest

from minifilm.pipeline.train_small import Settings, run


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """A run folder of the main job in miniature (two synthetic styles, one epoch): model.npz,
    styles.npz, starts.npz, run.json, skeleton.bvh. Tests copy it; they never change it."""
    out = tmp_path_factory.mktemp("fuzz_run")
    s = replace(Settings(out=out).quick(), styles=("Neutral", "LeftHop"), gaits=("FW",), seconds_per_clip=6.0,
                epochs=1, generate_seconds=0.5)
    run(s)
    return out
