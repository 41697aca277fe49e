"""Smoke test: the fine-tuning example's miniature runs end to end and reports sane numbers."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from minifilm.evaluation.metrics import silhouette_samples, silhouette_score

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "finetune_new_style.py"


def test_quick_run(tmp_path):
    spec = importlib.util.spec_from_file_location("finetune_new_style", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    r = mod.run(out=tmp_path, quick=True)
    assert r["holdout"] not in r["seen"]
    assert r["finetune_steps"] > 0 and r["finetune_seconds"] > 0
    for tag in ("before", "after"):
        for group in ("new", "seen"):
            assert np.isfinite(r[tag][group]["mse"]) and r[tag][group]["mse"] > 0
    # the point of the example: fine-tuning Ψ on the new style lowers that style's test error
    # (MSE and bone-length loss), while the seen styles change only through Ψ's shared weights
    assert r["after"]["new"]["mse"] < r["before"]["new"]["mse"]
    assert r["after"]["new"]["bll"] < r["before"]["new"]["bll"]
    assert abs(r["after"]["seen"]["mse"] - r["before"]["seen"]["mse"]) < 0.05 * r["before"]["seen"]["mse"]
    # the separations it reports are those of the FiLM codes' embedding it returns
    labels = np.asarray(r["labels"])
    held_out = r["styles"].index(r["holdout"])
    for tag in ("before", "after"):
        Y, sep = r["embedding"][tag], r["separation"][tag]
        assert sep["silhouette_2d"] == pytest.approx(silhouette_score(Y, labels), abs=1e-12)
        assert sep["focus_silhouette_2d"] == pytest.approx(silhouette_samples(Y, labels)[labels == held_out].mean(),
                                                           abs=1e-12)
    # only Ψ was trained: Ω and Φ of the fine-tuned checkpoint equal the base checkpoint's
    with np.load(tmp_path / "base.npz") as a, np.load(tmp_path / "finetuned.npz") as b:
        frozen = [k for k in a.files if k.startswith(("gating", "motion")) and not k.startswith("adam")]
        changed = [k for k in a.files if k.startswith("film")]
        assert frozen and changed
        assert all(np.array_equal(a[k], b[k]) for k in frozen)
        assert any(not np.array_equal(a[k], b[k]) for k in changed)
    assert (tmp_path / "film_codes.png").is_file()
