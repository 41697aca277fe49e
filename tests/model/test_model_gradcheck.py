"""Gradient checks of the model: its blocks, the losses (with their degenerate branches), Ω, Φ, Ψ
and the style model (Eq. 2-7) in its three forms, each on seeds 0-4, and the float32 backward
passes against float64.

The rows of ``minifilm gradcheck`` run here one (row, seed) per test (minifilm/evaluation/
gradcheck_table.py gives the method and the limits; gradcheck_networks.py the set-up: toy
networks, dropout on with fixed masks, every kink kept MARGIN away and watched by a guard).
"""
import numpy as np
import pytest

from gradcheck_report import check
from minifilm.evaluation import gradcheck_networks as nets
from minifilm.evaluation.gradcheck_problem import MARGIN, PARENTS, POS_IDX, SIGMA_MIN, problem_pairs
from minifilm.evaluation.gradcheck_table import FLOAT32_TOLERANCE, SEEDS, cases, float32_cases
from minifilm.model.losses import bone_length_loss, mse_loss
from minifilm.nn.gradcheck import worst_error

MODEL_ROWS = [c for c in cases() if c.group in ("block", "loss", "network")]
FLOAT32_ROWS = [c for c in float32_cases() if c.name[0] in "ΩΦΨ" or c.name.startswith("style model")]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", MODEL_ROWS, ids=lambda c: c.name)
def test_model_gradients(case, seed):
    """Blocks, losses and whole networks: every entry of every input and parameter array."""
    check(case, seed)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", FLOAT32_ROWS, ids=lambda c: c.name)
def test_float32_backward_matches_float64(case, seed):
    """Training runs in float32: the same backward pass (same parameters, inputs, dropout masks
    and incoming gradient) agrees with float64 to FLOAT32_TOLERANCE, relative, per array."""
    assert case.limit == FLOAT32_TOLERANCE
    check(case, seed)


@pytest.mark.parametrize("form", ["per-sample", "shared-clip", "film-vector"])
def test_the_set_up_keeps_every_kink_away_and_really_drops_units(form):
    """What the whole-model checks rely on: every ELU / ReLU input, max-pool pair and bone-length
    term at least MARGIN from its switch, every layer-norm row at σ >= SIGMA_MIN, a mask at every
    dropout site that really drops units at (nearly) all of them, and every input and parameter
    array with a non-zero gradient (nothing silently disconnected)."""
    for seed in SEEDS:
        pr = nets.style_model_problem(seed, form)
        out, _, _, _, _, pairs = problem_pairs(pr)
        assert pr.margin(out) >= MARGIN and pr.sigma_min() >= SIGMA_MIN
        masks = pr.model.used_masks
        sites = {"gating0", "gating1", "gating2", "motion0", "motion1", "motion2"} | \
            ({"film_dense"} if form != "film-vector" else set())
        assert sites <= set(masks) and sum(not masks[s].all() for s in sites) >= len(sites) - 2
        for name, (_, g) in pairs.items():
            assert np.abs(g).max() > 0, (form, seed, name)


def test_a_wrong_backward_pass_fails_its_row(monkeypatch):
    """Break FiLM's dβ in Φ's backward pass by 1e-6: the Φ row and the whole-model row fail."""
    from minifilm.nn import functional as F
    real = F.film_backward

    def broken(dout, cache):
        dh, dgamma, dbeta = real(dout, cache)
        return dh, dgamma, dbeta * (1 + 1e-6)

    monkeypatch.setattr(F, "film_backward", broken)
    for name in ("Φ motion network (Eq. 3)", "style model, MSE + BLL (Eq. 4-7)"):
        case = next(c for c in cases() if c.name == name)
        assert worst_error(case.check(0).errors) > case.limit


@pytest.mark.parametrize("seed", range(5))
def test_shared_clips_are_the_per_sample_form_with_clips_repeated(seed):
    """Clips shared by the batch (TrainConfig.clips_per_batch): Ψ runs on M = 2 clips and each
    sample uses one of them (clip_index). That is exactly the per-sample form with the clips
    repeated, the dropout masks of Ψ repeated alike, and the gradient of a shared clip / of Ψ's
    parameters the sum over the samples using it. Both sides analytic, equal to rounding (the
    numerical check of both forms is in the table)."""
    pr = nets.style_model_problem(10 + seed, "shared-clip")
    model, (x, p, clips) = pr.model, (pr.inputs[k] for k in ("x", "p", "clip"))
    rng = np.random.default_rng(seed)
    z = rng.standard_normal((len(x), model.config.z_dim))
    mean, std = rng.standard_normal(z.shape[1]), 0.5 + rng.random(z.shape[1])
    index = np.array([1, 0, 1, 1])
    model.forward(x, p, clips, train=True, rng=rng, clip_index=index)
    masks = model.used_masks
    assert masks["film_dense"].shape[0] == 2            # Ψ ran on the two clips only

    def grads(shared):
        model.zero_grad()
        if shared:
            pred = model.forward(x, p, clips, train=True, masks=masks, clip_index=index)
        else:
            pred = model.forward(x, p, clips[index], train=True,
                                 masks={**masks, "film_dense": masks["film_dense"][index]})
        d = mse_loss(pred, z)[1] + bone_length_loss(pred, z, POS_IDX, PARENTS, mean, std)[1]
        out = model.backward(d)
        return pred, out, [ps.grad.copy() for ps in model.parameter_sets()]

    pred_s, in_s, par_s = grads(True)
    pred_r, in_r, par_r = grads(False)
    np.testing.assert_allclose(pred_s, pred_r, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(in_s["x"], in_r["x"], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(in_s["p"], in_r["p"], rtol=1e-12, atol=1e-14)
    summed = np.stack([in_r["clip"][index == m].sum(axis=0) for m in range(2)])
    np.testing.assert_allclose(in_s["clip"], summed, rtol=1e-12, atol=1e-14)
    for gs, gr in zip(par_s, par_r):
        np.testing.assert_allclose(gs, gr, rtol=1e-11, atol=1e-14)
