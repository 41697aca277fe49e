"""The style judge (minifilm/evaluation/style_judge.py): on a known case a style's own motion ranks
itself first and is recognised by every seed, another style's motion is judged as that style, and a
motion's windows are the normalised joint block of its x rows."""
from types import SimpleNamespace

import numpy as np
import pytest

from minifilm.evaluation.style_classifier import window_summary
from minifilm.evaluation.style_judge import StyleJudge, motion_block, rows_block, summaries, windows
from minifilm.features.compute import frame_features
from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.synthetic.generator import rest_motion

T, C = 12, 8


def style_windows(rng, centre, n):
    """n windows of a 'style': frames around a centre pose, swinging with its own amplitude."""
    t = np.arange(T)[None, :, None]
    swing = np.sin(t / 2.0 + rng.uniform(0, 6, (n, 1, 1))) * (0.5 + np.abs(centre[None, None]))
    return window_summary(centre[None, None] + swing + 0.2 * rng.normal(size=(n, T, C)))


@pytest.fixture(scope="module")
def judged():
    rng = np.random.default_rng(0)
    centres = {f"S{k}": rng.normal(0, 1.5, C) for k in range(4)}
    refs = {n: style_windows(rng, c, 40) for n, c in centres.items()}
    fresh = {n: style_windows(rng, c, 20) for n, c in centres.items()}
    judge = StyleJudge.fit(refs, seeds=(0, 1, 2), hidden=16, epochs=40, dims=6)
    return judge, fresh


def test_a_styles_own_motion_ranks_itself_first(judged):
    judge, fresh = judged
    for name, w in fresh.items():
        r = judge.judge(w, name)
        assert r["rank"] == 1 and r["nearest"][0][0] == name
        assert len(r["recognition"]) == 3 and r["recognition_min"] >= 0.9
        assert r["picked"][0][0] == name


def test_another_styles_motion_is_not_recognised_as_the_target(judged):
    judge, fresh = judged
    r = judge.judge(fresh["S1"], "S0")
    assert r["rank"] > 1 and r["nearest"][0][0] == "S1"
    assert r["recognition_min"] <= 0.1 and r["picked"][0][0] == "S1"
    with pytest.raises(KeyError):
        judge.judge(fresh["S1"], "nobody")


def test_motion_block_is_the_normalised_joint_block_of_the_x_rows():
    layout = FeatureLayout.for_skeleton(STYLE100)
    m = rest_motion()
    rng = np.random.default_rng(1)
    F = 20
    m.rotations = np.broadcast_to(m.rotations, (F,) + m.rotations.shape[1:]).copy()
    m.translations = np.broadcast_to(m.translations, (F,) + m.translations.shape[1:]).copy()
    m.translations[:, 0, 2] += np.linspace(0, 0.4, F)
    m.translations[:, 0, 1] += 0.01 * rng.normal(size=F)
    stats = SimpleNamespace(normalize_clip=lambda c, s: (c - 0.1) / 2.0)
    rows = frame_features(m, STYLE100, np.zeros((F, 8)), np.zeros((F, 2)), fps=60.0, dtype=np.float64)
    block = motion_block(m, stats, layout)
    np.testing.assert_allclose(block[1:F - 1], rows_block(rows.x, stats, layout), atol=1e-9)
    assert windows(block, 5, 5).shape == (4, 5, block.shape[1])
    assert summaries(block, 5, 5).shape == (4, 2 * block.shape[1])
