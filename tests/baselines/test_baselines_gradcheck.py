"""Gradient checks of the comparison (Sec. 5): each style modulation on its own (one-hot rows,
both residual adapters, the PFNN's phase-function layer) and each of the seven variants whole —
dropout on with fixed masks, mixed styles in the batch — on seeds 0-4, and their float32
backward passes against float64 (rows of ``minifilm gradcheck``, one (row, seed) per test)."""
import numpy as np
import pytest

from gradcheck_report import check
from minifilm.evaluation import gradcheck_networks as nets
from minifilm.evaluation.gradcheck_problem import problem_pairs
from minifilm.evaluation.gradcheck_table import SEEDS, cases, float32_cases
from minifilm.baselines.variants import VARIANTS
from minifilm.model.losses import mse_loss

ROWS = [c for c in cases() if c.group in ("modulation", "variant")]
FLOAT32_ROWS = [c for c in float32_cases() if c.name in VARIANTS]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", ROWS, ids=lambda c: c.name)
def test_comparison_gradients(case, seed):
    check(case, seed)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", FLOAT32_ROWS, ids=lambda c: c.name)
def test_variant_float32_backward_matches_float64(case, seed):
    check(case, seed)


@pytest.mark.parametrize("name", [v for v in VARIANTS if "FiLM" not in v])
def test_every_style_in_the_batch_gets_a_gradient_in_every_table(name):
    """The per-style tables of the checked problems: styles 0, 1 and 2 are all in the batch and
    each gets a non-zero gradient in every table (the check covers every style's rows)."""
    pr = nets.variant_problem(name, 0)
    problem_pairs(pr)
    model = pr.model
    style_axis = 1 if model.modulation == "onehot" else 0       # E (K, S, H); adapters (S, ...)
    for k in model.film.params.names():
        g = np.moveaxis(model.film.params.grads[k], style_axis, 0)
        assert np.all(np.abs(g).reshape(3, -1).max(axis=1) > 0), k


def test_style_not_in_batch_gets_no_gradient():
    pr = nets.variant_problem("LPN Resad", 5)
    model, x, p = pr.model, pr.inputs["x"], pr.inputs["p"]
    model.zero_grad()
    style = np.array([0, 0, 2, 2])
    target = np.random.default_rng(0).standard_normal((len(x), model.backbone_config.z_dim))
    _, d = mse_loss(model.forward(x, p, None, style=style), target)
    model.backward(d)
    assert np.all(model.film.params.grads["A"][1] == 0) and np.abs(model.film.params.grads["A"][0]).max() > 0


def test_onehot_with_blended_style_weights_blends_the_style_rows():
    """A blended one-hot vector (B, S) gives the blend of the pure styles' first-layer terms
    (its gradients are the row 'one-hot style rows (blended)' of the table)."""
    pr = nets.variant_problem("LPN one-hot", 4)
    model, p = pr.model, pr.inputs["p"]
    rng = np.random.default_rng(4)
    w = rng.dirichlet(np.ones(3), size=len(p))
    alpha = model.gating.forward(p)
    mixed = model.film.forward(w, alpha)
    pure = [model.film.forward(np.full(len(p), s), alpha) for s in range(3)]
    np.testing.assert_allclose(mixed, sum(w[:, [s]] * pure[s] for s in range(3)), atol=1e-12)
