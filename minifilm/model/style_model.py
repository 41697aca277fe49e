"""The style model, Eq. (4): z = Φ(x; Ω(p), Ψ(y)).

    α    = Ω(p)                 gating network, local phases -> expert weights   (gating.py)
    film = Ψ(y)                 FiLM generator, style clip -> {γ1, β1, γ2, β2}    (film_generator.py)
    z    = Φ(x; α, film)        gated experts + layer norm + FiLM + ELU, Eq. (3) (motion_net.py)

Backward runs the same steps in reverse: Φ gives dx, dα and dfilm; Ω turns dα into dp; Ψ turns
dfilm into dy. Every parameter gradient is *added* into the networks' ``.params.grads``.

At run time (Sec. 4.4) Ψ is not needed: FiLM vectors are precomputed per style (2048 numbers in
the paper config, minifilm/runtime/style_library.py) and the network runs through
minifilm/runtime/network.py.
"""
from __future__ import annotations

import numpy as np

from minifilm.model.config import ModelConfig
from minifilm.model.film_generator import FilmGenerator, film_shapes
from minifilm.model.gating import GatingNetwork, gating_shapes
from minifilm.model.motion_net import MotionNetwork, motion_shapes
from minifilm.nn import functional as F


def parameter_counts(config: ModelConfig) -> dict:
    """Number of parameters of Ω ('gating'), Φ ('motion'), Ψ ('film') and the FiLM vector per
    style at run time ('per_style', the paper's P.S.R.), computed from the shapes without
    allocating anything. Paper config: Φ + Ω = 4,935,928 (Table 2, A.S.N.), Ψ = 39,214,592
    (Table 2 says 35,668,530; see film_generator.py), per style 2048."""
    def count(shapes):
        return int(sum(np.prod(s) for s in shapes.values()))
    return {"gating": count(gating_shapes(config)), "motion": count(motion_shapes(config)),
            "film": count(film_shapes(config)), "per_style": config.film_dim}


class StyleModel:
    """Ω + Φ + Ψ with explicit forward and backward passes.

    x    (B, x_dim)   normalised input frame features
    p    (B, phase_dim) normalised local phases (Eq. 1)
    clip (B, T, C)    one normalised style clip per sample
    z    (B, z_dim)   normalised output frame features
    """

    def __init__(self, config: ModelConfig, rng: np.random.Generator, dtype=np.float32,
                 with_film_generator: bool = True):
        """with_film_generator=False builds only Ω and Φ: a run-time model driven by precomputed
        FiLM vectors (Sec. 4.4), e.g. the released network, which ships without Ψ."""
        self.config = config
        self.dtype = np.dtype(dtype)
        self.gating = GatingNetwork(config, rng, dtype)   # Ω
        self.motion = MotionNetwork(config, rng, dtype)   # Φ
        self.film = FilmGenerator(config, rng, dtype) if with_film_generator else None   # Ψ
        # what the last forward pass left for backward (each network keeps its own layers' caches):
        # {"film_shape": the FiLM vectors' shape as given, "clips": the gather cache of shared
        # clips or None, present only when Ψ ran}; None before any forward pass
        self._cache = None

    # ---- parameters ----------------------------------------------------------------------
    def parameter_sets(self):
        """[Ω, Φ, Ψ] parameter sets (each one flat buffer); [Ω, Φ] without Ψ."""
        sets = [self.gating.params, self.motion.params]
        return sets if self.film is None else sets + [self.film.params]

    def zero_grad(self):
        for ps in self.parameter_sets():
            ps.zero_grad()

    @property
    def used_masks(self) -> dict:
        """Dropout keep-masks of the last training forward pass, by site name (for replay)."""
        film_masks = {} if self.film is None else self.film.used_masks
        return {**self.gating.used_masks, **self.motion.used_masks, **film_masks}

    def _require_film_generator(self):
        if self.film is None:
            raise RuntimeError("this StyleModel has no FiLM generator Ψ (built with "
                               "with_film_generator=False); use forward_with_film with precomputed FiLM vectors")

    # ---- forward -------------------------------------------------------------------------
    def film_parameters(self, clip, train=False, rng=None, masks=None):
        """Ψ(y): clip (B, T, C) -> FiLM parameters (B, 4H) (Eq. 2)."""
        self._require_film_generator()
        if self._cache is not None:         # Ψ's caches are this pass's now: no backward through Ψ
            self._cache.pop("clips", None)
        return self.film.forward(clip, train=train, rng=rng, masks=masks)

    def forward(self, x, p, clip, train=False, rng=None, masks=None, clip_index=None):
        """Eq. (4): z = Φ(x; Ω(p), Ψ(y)). x (B, x_dim), p (B, 8), clip (B, T, C) -> z (B, z_dim).

        clip_index (B,) ints: shared clips. ``clip`` is then (M, T, C), M <= B, sample b is
        conditioned on clip[clip_index[b]], and Ψ runs on the M clips only (minibatches hold one
        style, so a few clips of it can serve the whole batch: TrainConfig.clips_per_batch).
        """
        self._require_film_generator()
        self._cache = None
        film = self.film.forward(clip, train=train, rng=rng, masks=masks)     # (M, 4H)
        gather = None
        if clip_index is not None:
            film, gather = F.gather_forward(film, clip_index)                 # (B, 4H)
        z = self._omega_phi(x, p, film, train, rng, masks)
        self._cache = {"film_shape": film.shape, "clips": gather}
        return z

    def forward_with_film(self, x, p, film, train=False, rng=None, masks=None, ln_unbiased=None, ln_eps=None):
        """z = Φ(x; Ω(p), film) with FiLM parameters given directly.

        film (B, 4H), or (4H,) shared by the whole batch (a precomputed or blended style).
        """
        film = np.asarray(film)
        self._cache = None
        z = self._omega_phi(x, p, film, train, rng, masks, ln_unbiased, ln_eps)
        self._cache = {"film_shape": film.shape}
        return z

    def _omega_phi(self, x, p, film, train, rng, masks, ln_unbiased=None, ln_eps=None):
        """α = Ω(p), then z = Φ(x; α, film); a shared film (4H,) is broadcast over the batch."""
        if film.ndim == 1:
            film = np.broadcast_to(film, (x.shape[0], film.shape[0]))
        alpha = self.gating.forward(p, train=train, rng=rng, masks=masks)
        return self.motion.forward(x, alpha, film, train=train, rng=rng, masks=masks,
                                   ln_unbiased=ln_unbiased, ln_eps=ln_eps)

    # ---- backward ------------------------------------------------------------------------
    def backward_with_film(self, dz):
        """Backward of `forward_with_film`: dz (B, z_dim) -> (dx, dp, dfilm).

        dfilm has the shape the film was given in ((B, 4H), or (4H,) summed over the batch).
        Gradients of Ω and Φ are added to their .params.grads.
        """
        if self._cache is None:
            raise RuntimeError("StyleModel.backward_with_film needs a preceding forward pass")
        dx, dalpha, dfilm = self.motion.backward(dz)
        dp = self.gating.backward(dalpha)
        if len(self._cache["film_shape"]) == 1:       # one vector served the whole batch
            dfilm = dfilm.sum(axis=0)
        return dx, dp, dfilm

    def backward(self, dz, need_input_grads=True):
        """Backward of `forward`: dz (B, z_dim) -> {'x': dx, 'p': dp, 'clip': dclip}.

        Adds the gradients of every parameter of Ω, Φ and Ψ. With need_input_grads=False the
        clip's gradient (the costly one) is skipped and 'clip' is None; training passes False.
        """
        if self._cache is None or "clips" not in self._cache:
            raise RuntimeError("StyleModel.backward needs a preceding forward(x, p, clip); "
                               "use backward_with_film after forward_with_film")
        gather = self._cache["clips"]
        dx, dp, dfilm = self.backward_with_film(dz)
        if gather is not None:                        # a shared clip gets its samples' gradients
            dfilm = F.gather_backward(dfilm, gather)
        dclip = self.film.backward(dfilm, need_input_grad=need_input_grads)
        return {"x": dx, "p": dp, "clip": dclip}
