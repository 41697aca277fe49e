"""The nearest-centroid style classifier (minifilm/evaluation/nearest_centroid.py): windows drawn
around three styles' own means are given to their style, its shares add up, and it refuses too
little to fit."""
import numpy as np
import pytest

from minifilm.evaluation.nearest_centroid import NearestCentroid


def clusters(rng, n=40, dims=30, spread=0.5):
    means = {s: rng.standard_normal(dims) * 3 for s in ("a", "b", "c")}
    return means, {s: m + spread * rng.standard_normal((n, dims)) for s, m in means.items()}


def test_windows_go_to_the_style_whose_centroid_is_nearest():
    rng = np.random.default_rng(0)
    means, refs = clusters(rng)
    clf = NearestCentroid.fit(refs, dims=4)
    for s, m in means.items():
        new = m + 0.5 * rng.standard_normal((25, 30))
        assert np.all(clf.classify(new) == s)
        shares = clf.shares(new)
        assert shares[s] == 1.0 and sum(shares.values()) == pytest.approx(1.0) and list(shares)[0] == s
    # windows half way between a and b: split between them, never to c
    half = 0.5 * (means["a"] + means["b"]) + 0.01 * rng.standard_normal((50, 30))
    assert set(clf.classify(half)) <= {"a", "b"}


def test_it_needs_two_styles_with_windows():
    with pytest.raises(ValueError, match="two or more styles"):
        NearestCentroid.fit({"a": np.ones((3, 4))})
    with pytest.raises(ValueError, match="two or more styles"):
        NearestCentroid.fit({"a": np.ones((3, 4)), "b": np.ones((0, 4))})
