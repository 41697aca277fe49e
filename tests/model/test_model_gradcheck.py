"""Whole-model gradient check (Eq. 2-7): every parameter of Ω, Φ and Ψ and the inputs x, p, y,
through loss = MSE + BLL, in float64 with dropout on (fixed masks)."""
import numpy as np
import pytest

from minifilm.model.config import ModelConfig
from minifilm.model.losses import bone_length_loss, mse_loss
from minifilm.model.style_model import StyleModel
from minifilm.nn.gradcheck import check_gradients

# toy skeleton: 4 joints, positions at output columns 2.., chain 0-1-2 and 0-3
PARENTS = np.array([-1, 0, 1, 0])
POS_IDX = 2 + np.arange(12).reshape(4, 3)


def toy_config(dropout=0.3):
    return ModelConfig(x_dim=6, z_dim=15, phase_dim=8, n_experts=3, hidden=5, gating_hidden=4,
                       clip_frames=9, clip_channels=3, conv_filters=3, conv_kernel=3, film_dense=6,
                       dropout=dropout)


def make_problem(seed, dropout=0.3, B=3):
    rng = np.random.default_rng(seed)
    cfg = toy_config(dropout)
    model = StyleModel(cfg, rng, dtype=np.float64)
    for ps in model.parameter_sets():                 # non-zero biases, so their grads matter
        ps.data += 0.1 * rng.standard_normal(ps.size)
    x = rng.standard_normal((B, cfg.x_dim))
    p = rng.standard_normal((B, cfg.phase_dim))
    clip = rng.standard_normal((B, cfg.clip_frames, cfg.clip_channels))
    z = rng.standard_normal((B, cfg.z_dim))
    out_mean = rng.standard_normal(cfg.z_dim)
    out_std = 0.5 + rng.random(cfg.z_dim)
    return model, x, p, clip, z, out_mean, out_std, rng


def test_whole_model_gradients_with_dropout():
    model, x, p, clip, z, mean, std, rng = make_problem(2)
    model.forward(x, p, clip, train=True, rng=rng)
    masks = model.used_masks
    assert set(masks) == {"gating0", "gating1", "gating2", "motion0", "motion1", "motion2", "film_dense"}
    assert any(not m.all() for m in masks.values())   # dropout really drops something

    def loss():
        pred = model.forward(x, p, clip, train=True, masks=masks)
        return mse_loss(pred, z)[0] + bone_length_loss(pred, z, POS_IDX, PARENTS, mean, std)[0]

    model.zero_grad()
    pred = model.forward(x, p, clip, train=True, masks=masks)
    _, d1 = mse_loss(pred, z)
    _, d2 = bone_length_loss(pred, z, POS_IDX, PARENTS, mean, std)
    dinputs = model.backward(d1 + d2)

    pairs = {"x": (x, dinputs["x"]), "p": (p, dinputs["p"]), "clip": (clip, dinputs["clip"])}
    for net_name, ps in zip(("gating", "motion", "film"), model.parameter_sets()):
        for name in ps.names():
            pairs[f"{net_name}.{name}"] = (ps.params[name], ps.grads[name])
    # Step size: with the elementwise metric, centred differences have rounding noise of about
    # ulp(f) / h ~ 1e-11 at h = 1e-5, which fails the smallest gradient entries (~1e-5) of a
    # 900-entry check; h = 1e-4 brings the noise to ~1e-12 while the h^2 truncation error stays
    # ~1e-10. The seed is one whose ReLU / max-pool / |.| inputs are not within h of a kink
    # (a kink crossed by the perturbation is a property of finite differences, not a bug).
    errors = check_gradients(loss, pairs, h=1e-4)
    bad = {k: v for k, v in errors.items() if not v < 1e-6}
    assert not bad, bad
    # every parameter array got a non-trivial gradient (nothing silently disconnected)
    for k, (_, g) in pairs.items():
        assert np.abs(g).max() > 0, k


def test_forward_with_film_gradients_shared_style_vector():
    """A single precomputed FiLM vector (4H,) shared by the batch: dfilm is summed over it."""
    model, x, p, clip, z, mean, std, rng = make_problem(1, dropout=0.0)
    film = model.film_parameters(clip)[0].copy()

    def loss():
        return mse_loss(model.forward_with_film(x, p, film), z)[0]

    model.zero_grad()
    _, d = mse_loss(model.forward_with_film(x, p, film), z)
    dx, dp, dfilm = model.backward_with_film(d)
    assert dfilm.shape == film.shape
    errors = check_gradients(loss, {"x": (x, dx), "p": (p, dp), "film": (film, dfilm)}, h=1e-5)
    assert max(errors.values()) < 1e-6, errors


@pytest.mark.parametrize("seed", range(5))
def test_shared_clips_are_the_per_sample_form_with_clips_repeated(seed):
    """Clips shared by the batch (TrainConfig.clips_per_batch): Ψ runs on M = 2 clips and each
    sample uses one of them (clip_index). That is exactly the per-sample form (checked numerically
    above) with the clips repeated, the dropout masks of Ψ repeated alike, and the gradient of a
    shared clip / of Ψ's parameters the sum over the samples using it (the gather's backward,
    checked numerically in tests/nn/test_gradcheck.py). Both sides analytic, equal to rounding."""
    model, x, p, _, z, mean, std, rng = make_problem(10 + seed, B=4)
    cfg = model.config
    clips = rng.standard_normal((2, cfg.clip_frames, cfg.clip_channels))
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
