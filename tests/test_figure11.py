"""scripts/figure11.py on FiLM codes whose answer is known: a held-out style's clips mixed into a
trained style's cluster (before) and in a cluster of their own (after)."""
from __future__ import annotations

import importlib.util

import numpy as np

from repo_paths import REPO_ROOT


def load():
    spec = importlib.util.spec_from_file_location("figure11", REPO_ROOT / "scripts" / "figure11.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def codes(rng, centres, n=15):
    X = np.concatenate([c + rng.normal(size=(n, len(c))) for c in centres])
    return X, np.repeat(np.arange(len(centres)), n)


def test_held_style_silhouette_rises_when_it_becomes_a_cluster():
    fig = load()
    rng = np.random.default_rng(0)
    trained = [rng.normal(size=12) * 6 for _ in range(3)]
    before_X, labels = codes(rng, trained + [trained[0] + 0.1])     # style 3 on top of style 0
    after_X, _ = codes(rng, trained + [rng.normal(size=12) * 6])   # style 3 on its own
    before = fig.held_silhouettes(before_X, labels, [3], iters=700)
    after = {3: fig.held_silhouettes(after_X, labels, [3], iters=700)}
    assert before["embedding"].shape == (len(labels), 2)
    rows = fig.compare(before, after, [3])
    assert rows[0]["before_full"] < 0.1 < 0.6 < rows[0]["after_full"]
    assert rows[0]["before_2d"] < rows[0]["after_2d"] and rows[0]["after_2d"] > 0.6
    assert rows[0]["higher"]


def test_pick_clips_spreads_over_each_style():
    fig = load()
    clip_style = np.array([0] * 10 + [1] * 3 + [2] * 7)
    idx = fig.pick_clips(clip_style, [2, 0], 4)
    assert list(clip_style[idx]) == [2] * 4 + [0] * 4
    assert idx[4] == 0 and idx[7] == 9                  # first and last clip of style 0
    assert len(fig.pick_clips(clip_style, [1], 50)) == 3
    try:
        fig.pick_clips(clip_style, [5], 3)
    except ValueError as e:
        assert "no clips" in str(e)
    else:
        raise AssertionError("a style without clips must be refused")
