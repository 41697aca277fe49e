"""Files of several rigs pooled into one data set (minifilm train --data ... --rig), and a
clip of another rig taught to the run (minifilm finetune retargets it and says so)."""
from dataclasses import replace

import numpy as np
import pytest

from minifilm.motion.bvh import read_bvh
from minifilm.pipeline.new_style import teach_style
from minifilm.pipeline.run_folder import RunFolder
from minifilm.pipeline.train_small import Settings, run


@pytest.fixture(scope="module")
def pooled(shared_data, tmp_path_factory):
    """A run trained for one epoch on Bandai-1 and Xia files together, retargeted onto 100STYLE."""
    work = tmp_path_factory.mktemp("pooled")
    rows = ["file,style,gait"]
    for name in ("walk_normal_001", "walk-back_normal_001", "walk-left_normal_001"):
        rows.append(f"{shared_data / 'bvh' / 'bandai1' / f'dataset-1_{name}.bvh'},bandai,walk")
    for name in ("neutral_01_000", "sexy_01_000"):
        rows.append(f"{shared_data / 'bvh' / 'xia' / f'{name}.bvh'},xia,walk")
    manifest = work / "pool.csv"
    manifest.write_text("\n".join(rows) + "\n")
    out = work / "run"
    s = replace(Settings(out=out).quick(), epochs=1, generate_seconds=0.5, clip_seconds=0.5, split="segments",
                fps=60.0, rig="100style")
    result = run(s, manifest)
    return out, result


def test_mixed_rigs_train_into_one_run_on_the_target_rig(pooled):
    out, result = pooled
    folder = RunFolder.load(out)
    assert folder.skeleton_name == "100style"
    assert set(folder.styles().names) == {"bandai", "xia"}
    for style in ("bandai", "xia"):                   # every style generates motion on the 100STYLE rig
        m = read_bvh(out / "generated" / f"{style}.bvh")
        assert "Chest4" in m.names and m.n_frames > 10 and np.all(np.isfinite(m.rotations))


def test_finetune_retargets_a_clip_of_another_rig(pooled, shared_data):
    out, _ = pooled
    said = []
    r = teach_style(out, "Elderly", [shared_data / "bandai2" / "dataset-2_walk_elderly_001.bvh"], steps=2,
                    log=said.append)
    assert any("retargeted onto it" in line for line in said), said
    assert "Elderly" in RunFolder.load(out).styles() and r.frames > 0
