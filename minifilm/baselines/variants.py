"""The seven models of the paper's comparison (Sec. 5, Table 2): backbone × style modulation.

Backbones (animation synthesis network, A.S.N.)
    PFNN  Holden et al. 2017: one global phase φ in [0, 1) -> 4 control-point weight sets blended by
          a cyclic Catmull-Rom spline (phase_function.py). Output: the 324 motion numbers (trajectory
          + joints) + 1 phase update + 2 contacts = 327.
    MANN  Zhang et al. 2018: 8 experts gated by a network fed the velocities of the 4 end effectors
          (12 numbers; same 32-32 gating sizes as the LPN). Output 324 + 2 contacts = 326.
    LPN   the paper's model: 8 experts gated by the local phases. Output 342 (with phases).
Style modulation (S.M.N., and P.S.R. = parameters per style at run time)
    one-hot  a style one-hot appended to the first layer's input (style_modulation.OneHotShift)
    Resad    a residual adapter on the first hidden layer: PFNN — CP-decomposed, phase-dependent,
             rank 30 (Mason et al. 2018); LPN — full H × H matrix + bias per style
    FiLM     Ψ generating γ, β for both hidden layers (the paper, Eq. 2-3)

Table 2 from the architecture (paper config: x 348, H 512, 95 styles). Let
L(I, O) = 512 I + 512 + 512·512 + 512 + 512 O + O be one set of three-layer weights.
    PFNN A.S.N. = 4 · L(348, 327)                       = 4 · 609,095             = 2,436,380
    MANN A.S.N. = 8 · L(348, 326) + gating(12→32→32→8)  = 4,868,656 + 1,736       = 4,870,392
    LPN  A.S.N. = 8 · L(348, 342) + gating(8→32→32→8)   = 4,934,320 + 1,608       = 4,935,928
    one-hot: the 95 extra input columns of the first layer, per control point / expert, no bias:
        PFNN 4 · 95 · 512 = 194,560 (per style 4 · 512 = 2048); LPN 8 · 95 · 512 = 389,120 (4096)
    PFNN Resad per style: U (512 × 30) + V (30 × 512) + C (4 × 30) + bias 512 = 31,352; × 95 = 2,978,440
    LPN Resad per style: 512 × 512 + 512 = 262,656; × 95 = 24,952,320
    FiLM per style: γ1, β1, γ2, β2 = 4 · 512 = 2048; Ψ itself 39,214,592 here vs 35,668,530 in
        the paper (film_generator.py explains why no reading of the paper's Ψ gives that number).
The arithmetic pins the output sizes (327 = 324 + phase update + 2 contacts; 326 = 324 + 2), the
MANN gating input (12) and the rank-30 CP layout (two H × R factors, 4 × R spline values, one
bias), which is how we know them.

Choices the paper leaves open (ours): the PFNN FiLM and MANN FiLM use the LPN's hidden layer
(layer norm -> FiLM -> ELU, motion_net.py); one-hot and Resad variants use plain ELU layers
(expert_net.py); the adapter sits on the first hidden layer's activation, in both backbones.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from minifilm.baselines.expert_net import ExpertNetwork
from minifilm.baselines.phase_function import PhaseFunction
from minifilm.baselines.style_modulation import (CPResidualAdapter, OneHotShift, ResidualAdapter,
                                                 adapter_shapes, cp_adapter_shapes, onehot_shapes)
from minifilm.model.config import ModelConfig
from minifilm.model.film_generator import FilmGenerator, film_shapes
from minifilm.model.gating import GatingNetwork, gating_shapes
from minifilm.model.motion_net import MotionNetwork, motion_shapes
from minifilm.model.style_model import StyleModel
from minifilm.nn import functional as F

#: name -> (backbone, modulation), in Table 2's order.
SPECS = {
    "PFNN one-hot": ("pfnn", "onehot"),
    "LPN one-hot": ("lpn", "onehot"),
    "PFNN Resad": ("pfnn", "resad"),
    "LPN Resad": ("lpn", "resad"),
    "PFNN FiLM": ("pfnn", "film"),
    "MANN FiLM": ("mann", "film"),
    "LPN FiLM": ("lpn", "film"),
}
VARIANTS = tuple(SPECS)
#: what each backbone's gate reads (its p input)
GATE_INPUT = {"pfnn": "global phase in [0, 1)", "mann": "end-effector velocities", "lpn": "local phases"}
PFNN_CONTROL_POINTS = 4
ADAPTER_RANK = 30


def _spec(name):
    if name not in SPECS:
        raise ValueError(f"unknown variant {name!r}; choose from {VARIANTS}")
    return SPECS[name]


def backbone_config(backbone: str, config: ModelConfig) -> ModelConfig:
    """The LPN's config -> the backbone's: n_experts = blend size, phase_dim = gate input size,
    z_dim = its output size (the LPN's z has phase_dim phases + phase_dim phase updates)."""
    n_phase_out = 2 * config.phase_dim
    if backbone == "lpn":
        return config
    if config.z_dim <= n_phase_out:
        raise ValueError(f"backbone {backbone!r}: z_dim {config.z_dim} must exceed the {n_phase_out} "
                         "phase columns it drops")
    if backbone == "pfnn":
        return replace(config, n_experts=PFNN_CONTROL_POINTS, phase_dim=1, z_dim=config.z_dim - n_phase_out + 1)
    if backbone == "mann":
        n_effectors = config.phase_dim // 2           # one (sin, cos) pair per end effector
        return replace(config, phase_dim=3 * n_effectors, z_dim=config.z_dim - n_phase_out)
    raise ValueError(f"unknown backbone {backbone!r}")


def variant_shapes(name: str, config: ModelConfig, n_styles: int = 95, rank: int = ADAPTER_RANK) -> dict:
    """Parameter shapes without allocating: {'gating': {...}, 'motion': {...}, 'style': {...}}
    plus 'per_style' (numbers stored per style at run time)."""
    backbone, modulation = _spec(name)
    cb = backbone_config(backbone, config)
    K, H = cb.n_experts, cb.hidden
    out = {"gating": {} if backbone == "pfnn" else gating_shapes(cb), "motion": motion_shapes(cb)}
    if modulation == "onehot":
        out["style"], out["per_style"] = onehot_shapes(K, n_styles, H), K * H
    elif modulation == "resad" and backbone == "pfnn":
        out["style"] = cp_adapter_shapes(n_styles, H, rank, PFNN_CONTROL_POINTS)
        out["per_style"] = 2 * H * rank + PFNN_CONTROL_POINTS * rank + H
    elif modulation == "resad":
        out["style"], out["per_style"] = adapter_shapes(n_styles, H), H * H + H
    else:
        out["style"], out["per_style"] = film_shapes(config), config.film_dim
    return out


def variant_parameter_counts(name: str, config: ModelConfig, n_styles: int = 95) -> dict:
    """Table 2's columns: {'asn', 'smn', 'psr'} from the shapes alone."""
    shapes = variant_shapes(name, config, n_styles)
    count = lambda d: int(sum(int(np.prod(s)) for s in d.values()))   # noqa: E731
    return {"asn": count(shapes["gating"]) + count(shapes["motion"]), "smn": count(shapes["style"]),
            "psr": shapes["per_style"]}


class VariantModel:
    """A backbone with one style modulation, with StyleModel's training interface.

    x (B, x_dim); p: PFNN (B, 1) global phase in [0, 1), MANN (B, 12) end-effector velocities,
    LPN (B, 8) local phases; clip (B, T, C) (FiLM only); style (B,) ints (one-hot / Resad only).
    Networks: .gating (Ω, None for the PFNN), .motion (Φ), .film (the style-modulation network:
    Ψ, the one-hot rows or the adapters — the trainer's name for that slot).
    """

    def __init__(self, name: str, config: ModelConfig, rng: np.random.Generator, n_styles: int = 95,
                 dtype=np.float32, rank: int = ADAPTER_RANK, with_film_generator: bool = True):
        """with_film_generator=False (FiLM variants): a run-time model without Ψ, driven by
        precomputed FiLM vectors (forward_with_film), as StyleModel's option."""
        self.name = name
        self.backbone, self.modulation = _spec(name)
        self.config = config
        self.backbone_config = cb = backbone_config(self.backbone, config)
        self.dtype = np.dtype(dtype)
        self.n_styles = n_styles
        self.takes_style_ids = self.modulation != "film"
        self.gating = None if self.backbone == "pfnn" else GatingNetwork(cb, rng, dtype)
        self.gate = PhaseFunction(PFNN_CONTROL_POINTS) if self.backbone == "pfnn" else self.gating
        if self.modulation == "film":
            self.motion = MotionNetwork(cb, rng, dtype)
            self.film = FilmGenerator(config, rng, dtype) if with_film_generator else None
        else:
            self.motion = ExpertNetwork(cb, rng, dtype)
            if self.modulation == "onehot":
                self.film = OneHotShift(cb.n_experts, n_styles, cb.hidden, cb.x_dim + n_styles, rng, dtype)
            elif self.backbone == "pfnn":
                self.film = CPResidualAdapter(n_styles, cb.hidden, rank, rng, PFNN_CONTROL_POINTS, dtype)
            else:
                self.film = ResidualAdapter(n_styles, cb.hidden, rng, dtype)
        # the last forward pass, for backward: {"kind": "clip" | "film" | "style", "film_shape",
        # "gather" (clip_index's cache, or None)}; None before any forward
        self._pass = None

    # ---- parameters ----------------------------------------------------------------------
    def parameter_sets(self):
        return [net.params for net in (self.gating, self.motion, self.film) if net is not None]

    def zero_grad(self):
        for ps in self.parameter_sets():
            ps.zero_grad()

    @property
    def used_masks(self) -> dict:
        out = {}
        for net in (self.gating, self.motion, self.film):
            out.update(getattr(net, "used_masks", {}) if net is not None else {})
        return out

    def _check_p(self, p):
        want = self.backbone_config.phase_dim
        if p.ndim != 2 or p.shape[1] != want:
            raise ValueError(f"{self.name}: p must be (B, {want}) ({GATE_INPUT[self.backbone]}), got {p.shape}")

    # ---- forward / backward ---------------------------------------------------------------
    def forward(self, x, p, clip=None, train=False, rng=None, style=None, masks=None, clip_index=None):
        """-> z (B, z_dim of the backbone). style: (B,) ids; for one-hot also (B, S) weights of
        a blended one-hot vector (interpolating styles, Fig. 8). clip_index: shared clips, as in
        StyleModel.forward."""
        if self.modulation == "film":
            self._require_film_generator()
            if clip is None:
                raise ValueError(f"{self.name}: FiLM needs a style clip")
            film, gather = self.film.forward(clip, train=train, rng=rng, masks=masks), None
            if clip_index is not None:
                film, gather = F.gather_forward(film, clip_index)
            z = self.forward_with_film(x, p, film, train=train, rng=rng, masks=masks)
            self._pass.update(kind="clip", gather=gather)
            return z
        self._check_p(p)
        alpha = self.gate.forward(p, train=train, rng=rng, masks=masks)
        shift = adapter = None
        if self.modulation == "onehot":
            shift = self.film.forward(style, alpha)
        else:
            if style is None:
                raise ValueError(f"{self.name}: needs style ids (forward(..., style=ids))")
            adapter = lambda h: self.film.forward(h, style, alpha)   # noqa: E731 (α = spline weights for the PFNN)
        z = self.motion.forward(x, alpha, train=train, rng=rng, masks=masks, shift=shift, adapter=adapter)
        self._pass = {"kind": "style"}
        return z

    def backward(self, dz, need_input_grads=True):
        """-> {'x': dx, 'p': dp, 'clip': dclip or None}; parameter gradients are added.
        dp is None for the PFNN (the phase is data)."""
        if self._pass is None:
            raise RuntimeError(f"{self.name}: backward called before forward")
        if self.modulation == "film":
            if self._pass["kind"] != "clip":
                raise RuntimeError(f"{self.name}: use backward_with_film after forward_with_film")
            dx, dp, dfilm = self.backward_with_film(dz)
            if self._pass["gather"] is not None:
                dfilm = F.gather_backward(dfilm, self._pass["gather"])
            return {"x": dx, "p": dp, "clip": self.film.backward(dfilm, need_input_grad=need_input_grads)}
        adapter_backward = self.film.backward if self.modulation == "resad" else None
        dx, dalpha, dshift = self.motion.backward(dz, adapter_backward=adapter_backward)
        if self.modulation == "onehot":
            dalpha = dalpha + self.film.backward(dshift)
        dp = self.gating.backward(dalpha) if self.gating is not None else None
        return {"x": dx, "p": dp, "clip": None}

    # ---- FiLM variants: StyleModel's film interface --------------------------------------------
    def film_parameters(self, clip, train=False, rng=None, masks=None):
        self._require_film_generator()
        return self.film.forward(clip, train=train, rng=rng, masks=masks)

    def forward_with_film(self, x, p, film, train=False, rng=None, masks=None, style=None):
        self._require_film()
        self._check_p(p)
        film = np.asarray(film)
        self._pass = {"kind": "film", "film_shape": film.shape}
        if film.ndim == 1:
            film = np.broadcast_to(film, (x.shape[0], film.shape[0]))
        alpha = self.gate.forward(p, train=train, rng=rng, masks=masks)
        return self.motion.forward(x, alpha, film, train=train, rng=rng, masks=masks)

    def backward_with_film(self, dz):
        if self._pass is None or "film_shape" not in self._pass:
            raise RuntimeError(f"{self.name}: backward_with_film called before forward_with_film")
        dx, dalpha, dfilm = self.motion.backward(dz)
        dp = self.gating.backward(dalpha) if self.gating is not None else None
        if len(self._pass["film_shape"]) == 1:      # one vector served the whole batch
            dfilm = dfilm.sum(axis=0)
        return dx, dp, dfilm

    def _require_film(self):
        if self.modulation != "film":
            raise RuntimeError(f"{self.name} has no FiLM generator")

    def _require_film_generator(self):
        self._require_film()
        if self.film is None:
            raise RuntimeError(f"{self.name} was built without its FiLM generator Ψ; use forward_with_film")


class LPNFilm(StyleModel):
    """The paper's model (StyleModel) with the variants' call signature (style ids are ignored)."""

    name = "LPN FiLM"
    takes_style_ids = False
    backbone, modulation = "lpn", "film"

    def forward(self, x, p, clip, train=False, rng=None, masks=None, style=None, clip_index=None):
        return super().forward(x, p, clip, train=train, rng=rng, masks=masks, clip_index=clip_index)

    def forward_with_film(self, x, p, film, train=False, rng=None, masks=None, ln_unbiased=None,
                          ln_eps=None, style=None):
        return super().forward_with_film(x, p, film, train=train, rng=rng, masks=masks,
                                         ln_unbiased=ln_unbiased, ln_eps=ln_eps)


def build_variant(name: str, config: ModelConfig, rng: np.random.Generator, n_styles: int = 95,
                  dtype=np.float32, with_film_generator: bool = True):
    """A freshly initialised model of variant `name` (one of VARIANTS). `config` is the LPN's
    configuration; the backbone's own sizes come from backbone_config. 'LPN FiLM' is a StyleModel.
    with_film_generator=False leaves Ψ out of the FiLM variants (run time only)."""
    _spec(name)
    if name == "LPN FiLM":
        return LPNFilm(config, rng, dtype, with_film_generator=with_film_generator)
    return VariantModel(name, config, rng, n_styles=n_styles, dtype=dtype,
                        with_film_generator=with_film_generator)


def model_from_checkpoint(meta: dict):
    """A freshly built variant for a checkpoint's metadata (the ``build_model`` argument of
    :meth:`minifilm.train.trainer.Trainer.resume`); weights are loaded by the caller."""
    variant = meta.get("variant")
    if not variant:
        raise ValueError("model_from_checkpoint: the checkpoint holds no comparison variant")
    n_styles = variant.get("n_styles")
    return build_variant(variant["name"], ModelConfig.from_dict(meta["model_config"]), np.random.default_rng(0),
                         with_film_generator=meta.get("has_film_generator", True),
                         **({} if n_styles is None else {"n_styles": int(n_styles)}))
