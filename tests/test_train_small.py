"""Smoke test: a miniature of ``examples/train_small.py`` (tiny data, one epoch) runs every step
and leaves every promised output behind in a usable state."""
import importlib.util
from pathlib import Path

import numpy as np

from minifilm.train.checkpoint import load_checkpoint
from minifilm.motion.bvh import read_bvh
from minifilm.runtime.style_library import StyleLibrary

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "train_small.py"


def _load_example():
    spec = importlib.util.spec_from_file_location("train_small_example", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_train_small_miniature_end_to_end(tmp_path, capsys):
    example = _load_example()
    result = example.main(["--out", str(tmp_path), "--quick", "--styles", "Neutral,LeftHop",
                           "--gaits", "FW", "--seconds", "6", "--epochs", "1", "--generate-seconds", "0.5"])
    printed = capsys.readouterr().out

    # every step reported
    for tag in ("[data]", "[phases]", "[dataset]", "[train]", "[test]", "[generate]", "[done]"):
        assert tag in printed, f"step {tag} missing from the output"
    assert np.isfinite(result["mse"]) and np.isfinite(result["bll"])
    assert set(result["per_style"]) == {"Neutral", "LeftHop"}

    # the synthetic data went through BVH files
    assert sorted(p.name for p in (tmp_path / "data").glob("*.bvh")) == ["LeftHop_FW.bvh", "Neutral_FW.bvh"]

    # the checkpoint holds the model and the normalisation statistics, and loads without pickle
    meta, arrays = load_checkpoint(tmp_path / "model.npz")
    assert meta["epoch"] == 1
    assert meta["style_names"] == ["LeftHop", "Neutral"]
    assert any(k.startswith("stats.") for k in arrays)

    # one FiLM vector per style, and a generated BVH per style that reads back on the same skeleton
    library = StyleLibrary.load(tmp_path / "styles.npz")
    assert sorted(library.names) == ["LeftHop", "Neutral"]
    for style in ("Neutral", "LeftHop"):
        motion = read_bvh(tmp_path / "generated" / f"{style}.bvh")
        assert motion.n_frames == 30
        assert motion.n_joints == 28
        positions, _ = motion.world()
        assert np.all(np.isfinite(positions))
