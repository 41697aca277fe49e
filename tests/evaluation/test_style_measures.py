"""Style measures: Fréchet distance and rank on synthetic windows whose answer is known."""
import numpy as np
import pytest
from scipy.linalg import sqrtm

from minifilm.evaluation.style_measures import (StyleSpace, classifier_spread, frechet_distance, gaussian,
                                                recognition, reproduced, style_report)


def random_cov(rng, d):
    A = rng.normal(size=(d, d))
    return A @ A.T / d + 0.1 * np.eye(d)


def test_frechet_matches_the_sqrtm_formula():
    rng = np.random.default_rng(0)
    d = 6
    mu1, mu2 = rng.normal(size=d), rng.normal(size=d)
    c1, c2 = random_cov(rng, d), random_cov(rng, d)
    ref = np.sum((mu1 - mu2) ** 2) + np.trace(c1 + c2 - 2 * np.real(sqrtm(c1 @ c2)))
    assert frechet_distance(mu1, c1, mu2, c2) == pytest.approx(ref, rel=1e-9)
    assert frechet_distance(mu1, c1, mu2, c2) == pytest.approx(frechet_distance(mu2, c2, mu1, c1), rel=1e-9)


def test_identical_is_zero_shift_is_its_square():
    rng = np.random.default_rng(1)
    c = random_cov(rng, 5)
    mu = rng.normal(size=5)
    assert frechet_distance(mu, c, mu, c) == pytest.approx(0.0, abs=1e-10)
    shift = np.zeros(5)
    shift[2] = 3.0
    assert frechet_distance(mu, c, mu + shift, c) == pytest.approx(9.0, rel=1e-9)
    # equal means, variances 1 and 4 in one dimension: (1 - 2)^2 = 1
    assert frechet_distance(np.zeros(1), np.eye(1), np.zeros(1), 4 * np.eye(1)) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="must be"):
        frechet_distance(mu, c, mu[:3], c)


def test_gaussian_of_samples():
    X = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 2.0]])
    mu, cov = gaussian(X)
    np.testing.assert_allclose(mu, [1, 1])
    np.testing.assert_allclose(cov, np.eye(2))
    with pytest.raises(ValueError):
        gaussian(X[:1])


def windows_of(rng, n, offset, scale=1.0, T=8, C=6):
    """n windows (n, T, C): each a constant pose `offset` + noise, moving with std `scale`."""
    base = rng.normal(size=(n, 1, C)) * 0.3 + offset
    return base + scale * rng.normal(size=(n, T, C))


def style_windows(rng, n=80):
    C = 6
    offsets = {"A": np.zeros(C), "B": np.r_[3.0, np.zeros(C - 1)], "C": np.r_[0.0, -3.0, np.zeros(C - 2)]}
    return {k: windows_of(rng, n, o) for k, o in offsets.items()}, offsets


def test_style_space_ranks_the_right_style_first():
    rng = np.random.default_rng(2)
    real, offsets = style_windows(rng)
    space = StyleSpace.fit(real, dims=8)
    for name, off in offsets.items():
        new = windows_of(rng, 60, off)                 # fresh samples of the same style
        assert space.rank(new, name) == 1, name
        others = [n for n in offsets if n != name]
        assert all(space.rank(new, o) > 1 for o in others)
    d_same = space.distances(real["A"])["A"]
    assert d_same == pytest.approx(0.0, abs=1e-8)      # the style's own windows: identical distributions
    near = space.distances(windows_of(rng, 60, offsets["A"] + np.r_[0.5, np.zeros(5)]))["A"]
    far = space.distances(windows_of(rng, 60, offsets["A"] + np.r_[2.0, np.zeros(5)]))["A"]
    assert 0 < near < far
    # a motion that holds style A's mean pose but never moves is not style A (std feature differs)
    still = windows_of(rng, 60, offsets["A"], scale=0.0)
    assert space.distances(still)["A"] > 10 * space.distances(windows_of(rng, 60, offsets["A"]))["A"]
    rep = style_report(space, windows_of(rng, 60, offsets["B"]), "B", [0.9, 0.85, 0.95])
    assert rep["rank"] == 1 and rep["nearest"] == "B" and rep["reproduced"]
    with pytest.raises(KeyError):
        space.rank(still, "Z")


def test_reproduced_needs_both_measures_and_the_minimum():
    assert reproduced(1, [0.9, 0.8, 0.95])
    assert not reproduced(2, [1.0, 1.0, 1.0])          # classifier fooled, distance not
    assert not reproduced(1, [0.99, 0.99, 0.5])        # one seed disagrees: the mean (0.83) would pass
    s = classifier_spread([0.5, 1.0])
    assert s == dict(min=0.5, mean=0.75, seeds=2)
    p = np.array([[0.1, 0.9], [0.8, 0.2], [0.3, 0.7], [0.4, 0.6]])
    assert recognition(p, 1) == 0.75 and recognition(p[None], 0) == 0.25


def test_fit_needs_windows():
    rng = np.random.default_rng(3)
    with pytest.raises(ValueError, match="at least 2"):
        StyleSpace.fit({"A": windows_of(rng, 1, 0.0), "B": windows_of(rng, 5, 1.0)})


def test_summaries_measure_exactly_as_the_windows_they_summarise():
    """The study keeps (M, 2C) summaries instead of (M, T, C) windows (a 95-style measure of raw
    windows held several GB): every measure must be the same either way."""
    from minifilm.evaluation.style_classifier import window_summary
    rng = np.random.default_rng(3)
    real, offsets = style_windows(rng)
    a = StyleSpace.fit(real, dims=8)
    b = StyleSpace.fit({k: window_summary(v) for k, v in real.items()}, dims=8, summarised=True)
    np.testing.assert_array_equal(a.basis, b.basis)
    new = windows_of(rng, 60, offsets["C"] + 0.3)
    s = window_summary(new)
    assert a.distances(new) == b.distances(s, summarised=True)
    assert a.rank(new, "C") == b.rank(s, "C", summarised=True) == 1
    assert style_report(a, new, "C", [0.9]) == style_report(b, s, "C", [0.9], summarised=True)
