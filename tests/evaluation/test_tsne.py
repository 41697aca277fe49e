"""t-SNE in NumPy: perplexity calibration, the exact gradient (float64 check), separable clusters."""
import numpy as np
import pytest

from gradcheck_report import other
from minifilm.evaluation.metrics import silhouette_samples
from minifilm.evaluation.tsne import (conditional_affinities, joint_affinities, kl_and_gradient, squared_distances,
                                      tsne)
from minifilm.nn.gradcheck import numerical_gradient, rel_error


def clusters(rng, k=4, n=20, d=10, spread=8.0):
    centres = rng.normal(size=(k, d)) * spread
    X = np.concatenate([c + rng.normal(size=(n, d)) for c in centres])
    return X, np.repeat(np.arange(k), n)


def test_squared_distances():
    X = np.array([[0.0, 0.0], [3.0, 4.0], [1.0, 0.0]])
    np.testing.assert_allclose(squared_distances(X), [[0, 25, 1], [25, 0, 20], [1, 20, 0]], atol=1e-12)


@pytest.mark.parametrize("perplexity", [2.0, 5.0, 15.0])
def test_binary_search_hits_the_perplexity(perplexity):
    rng = np.random.default_rng(0)
    X, _ = clusters(rng, n=10)
    P, beta = conditional_affinities(squared_distances(X), perplexity)
    np.testing.assert_allclose(P.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(np.diag(P) == 0) and np.all(beta > 0)
    H = -np.sum(np.where(P > 0, P * np.log(np.where(P > 0, P, 1)), 0), axis=1)
    np.testing.assert_allclose(np.exp(H), perplexity, rtol=1e-4)


def test_perplexity_out_of_range_is_refused():
    with pytest.raises(ValueError, match="perplexity"):
        conditional_affinities(squared_distances(np.eye(4)), 10.0)


def test_joint_affinities_symmetric_and_normalised():
    rng = np.random.default_rng(1)
    P = joint_affinities(rng.normal(size=(30, 5)), 8.0)
    np.testing.assert_allclose(P, P.T)
    assert P.sum() == pytest.approx(1.0, abs=1e-9) and np.all(np.diag(P) == 0)


@pytest.mark.gradcheck
def test_gradient_is_exact():
    rng = np.random.default_rng(2)
    X, _ = clusters(rng, k=3, n=5, d=4)
    P = joint_affinities(X, 4.0)
    Y = rng.normal(size=(len(X), 2))
    _, grad = kl_and_gradient(Y, P)
    num = numerical_gradient(lambda: kl_and_gradient(Y, P)[0], Y, h=1e-4)
    other("t-SNE: KL divergence wrt the embedding", rel_error(grad, num), 1e-7)


def test_separable_clusters_stay_separate_and_seeded():
    rng = np.random.default_rng(3)
    X, labels = clusters(rng)
    Y = tsne(X, perplexity=10, iters=400, seed=0)
    assert Y.shape == (len(X), 2) and np.all(np.isfinite(Y))
    assert silhouette_samples(Y, labels).mean() > 0.8
    np.testing.assert_array_equal(Y, tsne(X, perplexity=10, iters=400, seed=0))
    # shuffled labels are not clusters in the embedding: the silhouette can tell
    assert silhouette_samples(Y, rng.permutation(labels)).mean() < 0.2
    with pytest.raises(ValueError, match="finite"):
        tsne(np.full((5, 2), np.nan))
