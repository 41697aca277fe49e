"""Fitting one FiLM vector through a frozen Ω and Φ (minifilm/train/film_fit.py): the gradient
checked against numerical differences, the precomputed path equal to the model's own forward
pass, the prior's coordinates, and a small known-answer fit (a hidden style found again)."""
import numpy as np
import pytest

from gradcheck_report import other
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.nn.gradcheck import numerical_gradient, rel_error
from minifilm.train.film_fit import FitSettings, FrozenRows, StylePrior, fit_film, prior_loss_and_grad


def tiny(seed=0):
    cfg = ModelConfig.tiny()
    model = StyleModel(cfg, np.random.default_rng(seed), dtype=np.float64, with_film_generator=False)
    rng = np.random.default_rng(seed + 1)
    N = 40
    x, p = rng.normal(size=(N, cfg.x_dim)), rng.normal(size=(N, 8))
    return model, x, p, rng


def random_film(rng, H, n=None):
    shape = (4 * H,) if n is None else (n, 4 * H)
    f = rng.normal(scale=0.3, size=shape)
    f[..., :H] += 1.0                    # γ1 near 1
    f[..., 2 * H:3 * H] += 1.0           # γ2 near 1
    return f


def test_frozen_rows_equal_the_models_forward_pass():
    model, x, p, rng = tiny()
    film = random_film(rng, model.config.hidden)
    z_model = model.forward_with_film(x, p, film, ln_unbiased=False, ln_eps=0.0)
    rows = FrozenRows(model, x, p, np.zeros_like(z_model), dtype=np.float64)
    np.testing.assert_allclose(rows.predict(film), z_model, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rows.predict(film, np.array([3, 7])), z_model[[3, 7]], rtol=1e-12, atol=1e-12)


@pytest.mark.gradcheck
def test_gradient_of_the_loss_wrt_the_film_vector():
    model, x, p, rng = tiny(3)
    H = model.config.hidden
    z = rng.normal(size=(len(x), model.config.z_dim))
    rows = FrozenRows(model, x, p, z, dtype=np.float64)
    film = random_film(rng, H)
    _, grad = rows.loss_and_grad(film)
    num = numerical_gradient(lambda: rows.loss(film), film, h=1e-5)   # ELU kinks: a small step
    errors = {"film": rel_error(grad, num)}
    # and through the prior's whitened coordinates, prior term included
    prior = StylePrior.from_vectors(random_film(rng, H, 12), tau=0.2)
    c, r = prior.coordinates(film)

    def total():
        return rows.loss(prior.film(c, r)) + prior_loss_and_grad(0.7, c, r, 4 * H)[0]
    _, dfilm = rows.loss_and_grad(prior.film(c, r))
    dc, dr = prior.film_backward(dfilm)
    _, dc_p, dr_p = prior_loss_and_grad(0.7, c, r, 4 * H)
    errors["c"] = rel_error(dc + dc_p, numerical_gradient(total, c, h=1e-5))
    errors["r"] = rel_error(dr + dr_p, numerical_gradient(total, r, h=1e-5))
    other("FiLM-vector fit: the loss wrt the vector and the prior's coordinates", errors, 1e-7)


def test_prior_coordinates_invert_the_parametrisation():
    rng = np.random.default_rng(5)
    prior = StylePrior.from_vectors(rng.normal(size=(10, 64)))
    v = rng.normal(size=64)
    np.testing.assert_allclose(prior.film(*prior.coordinates(v)), v, atol=1e-10)
    assert prior.tau > 0 and np.all(prior.scales > 0)


def test_a_hidden_style_is_found_again_among_known_ones():
    """20 styles; each of 3 is hidden in turn, its rows made by the network, and the fit (from the
    prior of the other 19) must land nearer it than any other style."""
    model, x, p, rng = tiny(7)
    H = model.config.hidden
    base = random_film(rng, H)
    directions = rng.normal(size=(4, 4 * H))
    styles = base + rng.normal(size=(20, 4)) @ directions * 0.4 + rng.normal(scale=0.02, size=(20, 4 * H))
    x = np.random.default_rng(1).normal(size=(300, model.config.x_dim))
    p = np.random.default_rng(2).normal(size=(300, 8))
    for hidden in (0, 5, 11):
        z = model.forward_with_film(x, p, styles[hidden], ln_unbiased=False, ln_eps=0.0)
        rows = FrozenRows(model, x, p, z, dtype=np.float64)
        prior = StylePrior.from_vectors(np.delete(styles, hidden, axis=0))
        fit = fit_film(rows, prior, settings=FitSettings(steps=300, batch=64, lr=0.05, prior_weight=0.01))
        d = np.linalg.norm(styles - fit.film, axis=1)
        assert np.argmin(d) == hidden, (hidden, d.round(2))
        assert fit.loss < 0.2 * fit.start_loss
