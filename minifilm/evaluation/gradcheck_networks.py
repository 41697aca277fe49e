"""The gradient-check problems of the networks: Ω, Φ, Ψ, the style model and the seven variants.

Each is a toy-sized float64 network of the paper's structure (a handful of units per layer), in
training mode with fixed dropout masks, random inputs and a scalar objective, set up per seed by
minifilm.evaluation.gradcheck_problem (biases shifted so that no ELU / ReLU input lies within
MARGIN of 0 and no layer-norm row has a small σ; clips redrawn away from max-pool ties; loss
targets away from the bone-length loss's kinks). Per seed:

    build the network, add N(0, 0.1²) to every parameter (variants: 0.2², as their residual
    adapters start at zero) so biases and adapters are generic, draw the inputs (N(0, 1); the
    PFNN's phase uniform in [0, 1)) and the dropout masks (rate 0.3), then condition
    (Problem.prepare: masks that leave an array with no gradient at all are drawn again).

Objectives: the networks on their own and the variants use a random projection of the output,
L = Σ r ∘ out with r ~ N(0, 1), which exercises the whole Jacobian; the style model uses the
training objective, MSE + bone-length loss (Eq. 5-7) on a toy skeleton, so the losses' backward
passes are checked in place too.
"""
from __future__ import annotations

import numpy as np

from minifilm.baselines.variants import VariantModel, build_variant
from minifilm.evaluation.gradcheck_problem import (Problem, bll_target, bone_lengths, expert_net_sites, film_generator_sites,
                                                 gating_sites, motion_sites, projection, training_objective)
from minifilm.model.config import ModelConfig
from minifilm.model.film_generator import FilmGenerator
from minifilm.model.gating import GatingNetwork
from minifilm.model.motion_net import MotionNetwork
from minifilm.model.style_model import StyleModel

BATCH = 3


def toy_config(wide: bool = False, variant: bool = False) -> ModelConfig:
    """The paper's structure at toy size. A backward pass is checked as well by a handful of
    units per layer as by hundreds, and the stencil costs four forward passes per entry, so the
    numerical checks run the smallest networks that keep every structural case: 3 experts (a
    softmax, not a sigmoid), a layer norm and FiLM over 3 units, two conv layers of 2 filters on
    2 channels and an odd number of frames (the first max-pool drops one, the second leaves 2
    frames to flatten), a toy skeleton of 4 joints in z (Eq. 6-7). The float32 comparison runs
    one pass per seed, so it takes the ``wide`` sizes: its measure, max|g32 − g64| / max|g64|
    per array, is steadier on larger arrays (worst over seeds 0-29: 7.3e-6 at these sizes,
    1.7e-5 at the small ones, where a 3-entry expert bias of Φ had gradients that cancel).
    ``variant``: z as large as the comparison's backbones need (PFNN output 5, MANN 4)."""
    if wide:
        return ModelConfig(x_dim=6, z_dim=20 if variant else 15, phase_dim=8, n_experts=3, hidden=5,
                           gating_hidden=4, clip_frames=9, clip_channels=3, conv_filters=3, conv_kernel=3,
                           film_dense=6, dropout=0.3)
    return ModelConfig(x_dim=3, z_dim=12 if variant else 14, phase_dim=4, n_experts=3, hidden=3, gating_hidden=3,
                       clip_frames=9, clip_channels=2, conv_filters=2, conv_kernel=3, film_dense=4, dropout=0.3)


def _params(model, labels) -> dict:
    """{label: Parameters} of the model's networks that exist (Ω, Φ, Ψ / style modulation)."""
    return {label: getattr(model, attr).params for label, attr in labels
            if getattr(model, attr, None) is not None and getattr(model, attr).params is not None}


def _perturb(sets, rng, scale):
    for ps in sets:
        ps.data += scale * rng.standard_normal(ps.size)


STYLE_NETS = (("Ω", "gating"), ("Φ", "motion"), ("Ψ", "film"))


# ---- Ω, Φ, Ψ on their own ------------------------------------------------------------------
def omega_problem(seed: int, wide: bool = False) -> Problem:
    """Ω: local phases p -> α, projection objective."""
    rng, cfg = np.random.default_rng(seed), toy_config(wide)
    make = lambda dtype: GatingNetwork(cfg, np.random.default_rng(seed), dtype)   # noqa: E731
    net, masks = make(np.float64), {}
    _perturb([net.params], rng, 0.1)
    inputs = {"p": rng.standard_normal((BATCH, cfg.phase_dim))}
    pr = Problem(net, make, lambda m: {"Ω": m.params}, inputs,
                 lambda m, i: m.forward(i["p"], train=True, masks=masks),
                 lambda m, d: {"p": m.backward(d)}, rng, masks,
                 lambda: _draw(net, lambda: net.forward(inputs["p"], train=True, rng=rng)),
                 sites=gating_sites(net)).prepare()
    pr.objective = projection(rng.standard_normal((BATCH, cfg.n_experts)))
    return pr


def _draw(model, train_pass) -> dict:
    """The dropout masks of one training pass (drawn from the problem's generator)."""
    train_pass()
    return dict(model.used_masks)


def phi_problem(seed: int, wide: bool = False) -> Problem:
    """Φ: x, α and the FiLM parameters (B, 4H) -> z, projection objective."""
    rng, cfg = np.random.default_rng(seed), toy_config(wide)
    make = lambda dtype: MotionNetwork(cfg, np.random.default_rng(seed), dtype)   # noqa: E731
    net, masks = make(np.float64), {}
    _perturb([net.params], rng, 0.1)
    H = cfg.hidden
    film = 0.3 * rng.standard_normal((BATCH, 4 * H))
    film[:, 0:H] += 1.0                                   # γ around 1, β around 0
    film[:, 2 * H:3 * H] += 1.0
    inputs = {"x": rng.standard_normal((BATCH, cfg.x_dim)),
              "alpha": rng.dirichlet(np.ones(cfg.n_experts), size=BATCH), "film": film}

    def forward(m, i, **kw):
        return m.forward(i["x"], i["alpha"], i["film"], train=True, **(kw or {"masks": masks}))

    def backward(m, d):
        dx, dalpha, dfilm = m.backward(d)
        return {"x": dx, "alpha": dalpha, "film": dfilm}

    beta = lambda i: film[:, (2 * i + 1) * H:(2 * i + 2) * H]   # noqa: E731
    pr = Problem(net, make, lambda m: {"Φ": m.params}, inputs, forward, backward, rng, masks,
                 lambda: _draw(net, lambda: forward(net, inputs, rng=rng)), sites=motion_sites(net, beta)).prepare()
    pr.objective = projection(rng.standard_normal((BATCH, cfg.z_dim)))
    return pr


def psi_problem(seed: int, wide: bool = False) -> Problem:
    """Ψ: a style clip -> the FiLM parameters, projection objective."""
    rng, cfg = np.random.default_rng(seed), toy_config(wide)
    make = lambda dtype: FilmGenerator(cfg, np.random.default_rng(seed), dtype)   # noqa: E731
    net, masks = make(np.float64), {}
    _perturb([net.params], rng, 0.1)
    inputs = {"clip": rng.standard_normal((BATCH, cfg.clip_frames, cfg.clip_channels))}
    pr = Problem(net, make, lambda m: {"Ψ": m.params}, inputs,
                 lambda m, i: m.forward(i["clip"], train=True, masks=masks),
                 lambda m, d: {"clip": m.backward(d)}, rng, masks,
                 lambda: _draw(net, lambda: net.forward(inputs["clip"], train=True, rng=rng)),
                 sites=film_generator_sites(net), psi=net).prepare()
    pr.objective = projection(rng.standard_normal((BATCH, cfg.film_dim)))
    return pr


# ---- the style model (Eq. 4) and the variants --------------------------------------------------
def _model_problem(model, make, labels, inputs, forward, backward, rng, masks) -> Problem:
    """A whole model's problem, its kinks in forward order: Ψ (its β feeds Φ), Ω, then Φ."""
    sites, psi = [], None
    film = getattr(model, "film", None)
    if isinstance(film, FilmGenerator) and "clip" in inputs:
        sites += film_generator_sites(film)
        psi = film
    if isinstance(getattr(model, "gating", None), GatingNetwork):
        sites += gating_sites(model.gating)
    if isinstance(model.motion, MotionNetwork):
        H = model.motion.config.hidden
        if "film" in inputs:                        # one FiLM vector (4H,) given for the batch
            beta = lambda i: inputs["film"][(2 * i + 1) * H:(2 * i + 2) * H]   # noqa: E731
        else:
            beta = lambda i: film.params.params["dense1_b"][(2 * i + 1) * H:(2 * i + 2) * H]   # noqa: E731
        sites += motion_sites(model.motion, beta)
    else:
        sites += expert_net_sites(model.motion)
    return Problem(model, make, lambda m: _params(m, labels), inputs, forward, backward, rng, masks,
                   lambda: _draw(model, lambda: forward(model, inputs, rng=rng)), sites=sites, psi=psi).prepare()


def style_model_problem(seed: int, form: str = "per-sample", wide: bool = False) -> Problem:
    """The style model through the training objective (MSE + bone-length loss). form:
    'per-sample' (one clip per sample), 'shared-clip' (2 clips for 4 samples, clip_index), or
    'film-vector' (forward_with_film with one FiLM vector (4H,) for the batch: Ω and Φ)."""
    rng, cfg = np.random.default_rng(seed), toy_config(wide)
    make = lambda dtype: StyleModel(cfg, np.random.default_rng(seed), dtype)   # noqa: E731
    model, masks = make(np.float64), {}
    _perturb(model.parameter_sets(), rng, 0.1)
    B = BATCH + (form == "shared-clip")
    x, p = rng.standard_normal((B, cfg.x_dim)), rng.standard_normal((B, cfg.phase_dim))
    clip = rng.standard_normal((2 if form == "shared-clip" else B, cfg.clip_frames, cfg.clip_channels))
    index = np.array([1, 0, 1, 1]) if form == "shared-clip" else None
    if form == "film-vector":
        labels, inputs = STYLE_NETS[:2], {"x": x, "p": p, "film": model.film_parameters(clip)[0].copy()}

        def forward(m, i, **kw):
            return m.forward_with_film(i["x"], i["p"], i["film"], train=True, **(kw or {"masks": masks}))

        def backward(m, d):
            dx, dp, dfilm = m.backward_with_film(d)
            return {"x": dx, "p": dp, "film": dfilm}
    else:
        labels, inputs = STYLE_NETS, {"x": x, "p": p, "clip": clip}

        def forward(m, i, **kw):
            return m.forward(i["x"], i["p"], i["clip"], train=True, clip_index=index, **(kw or {"masks": masks}))

        backward = lambda m, d: m.backward(d)                                   # noqa: E731
    pr = _model_problem(model, make, labels, inputs, forward, backward, rng, masks)
    mean, std = rng.standard_normal(cfg.z_dim), 0.5 + rng.random(cfg.z_dim)
    target = bll_target(pr.run(), rng, mean, std)
    pr.objective = training_objective(target, mean, std)

    def loss_margin(out):
        hat, true = bone_lengths(out, target, mean, std)
        return float(min(np.abs(true - hat).min(), hat.min()))
    pr.loss_margin = loss_margin
    return pr


def variant_problem(name: str, seed: int, n_styles: int = 3, wide: bool = False) -> Problem:
    """A comparison variant (Sec. 5) on a batch of mixed styles, projection objective."""
    rng, cfg = np.random.default_rng(seed), toy_config(wide, variant=True)

    def make(dtype):
        if name == "LPN FiLM":
            return build_variant(name, cfg, np.random.default_rng(seed), n_styles=n_styles, dtype=dtype)
        # rank 4 instead of 30 for the PFNN's CP adapter: the same code, a quarter of the entries
        return VariantModel(name, cfg, np.random.default_rng(seed), n_styles=n_styles, dtype=dtype, rank=4)

    model, masks = make(np.float64), {}
    _perturb(model.parameter_sets(), rng, 0.2)      # adapters start at 0: move everything off it
    cb = getattr(model, "backbone_config", cfg)
    B = 4
    x = rng.standard_normal((B, cb.x_dim))
    p = rng.random((B, 1)) if cb.phase_dim == 1 else rng.standard_normal((B, cb.phase_dim))
    clip = rng.standard_normal((B, cb.clip_frames, cb.clip_channels))
    kw = {} if name == "LPN FiLM" else {"style": np.array([0, 2, 2, 1])}   # mixed styles, style 1 once
    inputs = {"x": x}
    if cb.phase_dim != 1:                           # the PFNN's phase is data: no gradient
        inputs["p"] = p
    if model.modulation == "film":
        inputs["clip"] = clip

    def forward(m, i, **train):
        phase = i.get("p", p.astype(i["x"].dtype))
        return m.forward(i["x"], phase, i.get("clip"), train=True, **(train or {"masks": masks}), **kw)

    def backward(m, d):
        g = m.backward(d)
        return {k: g[k] for k in inputs}

    labels = (("Ω", "gating"), ("Φ", "motion"), ("Ψ" if model.modulation == "film" else "style", "film"))
    pr = _model_problem(model, make, labels, inputs, forward, backward, rng, masks)
    pr.objective = projection(rng.standard_normal(pr.run().shape))
    return pr
