"""Every comparison variant through the one inference path, and driven by the runtime controller.

:func:`variant_network` builds a :class:`~minifilm.runtime.network.RuntimeNetwork` for any variant
of ``variants.py``: the same expert stack, with the variant's own gate (Ω, or the PFNN's phase
function) and hidden-layer modulation (FiLM, the one-hot shift, or a residual adapter). Its ``p``
argument is the variant's own gate input, as its training data holds it (LPN: the local phases,
normalised by the network; MANN: the end effectors' normalised velocities; PFNN: the global
phase in [0, 1)).

:class:`VariantRuntime` is what :class:`~minifilm.runtime.controller.Controller` drives: it reads
the controller's raw x and running local phases, builds the variant's gate input, and writes the
output back into the LPN's layout (next phases, phase updates, contacts). The PFNN's phase
update advances the right foot's phase pair (so the controller's phase average gives exactly the
new phase); the MANN has no phase, so the phase slots stay constant.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from minifilm.baselines.phase_function import catmull_rom_weights
from minifilm.baselines.variant_data import phase_angle
from minifilm.dataset.stats import NormStats
from minifilm.nn import functional as F
from minifilm.runtime.network import FilmHidden, GatingMLP, RuntimeNetwork


class PhaseGate:
    """The PFNN's gate at inference: global phase (B, 1) in [0, 1) -> spline weights (B, 4)."""

    def __init__(self, n_points: int):
        self.n_points = n_points

    def __call__(self, x_norm, phase):
        return catmull_rom_weights(phase, self.n_points)


class OneHotHidden:
    """The one-hot variants' hidden layers: ELU(F + Σ_k α_k E[k, s]) in layer 0, ELU(F) in layer 1.
    cond: style ids (B,), or (B, S) weights of a blended one-hot vector."""

    def __init__(self, onehot):
        self.onehot = onehot

    def __call__(self, layer, f, alpha, cond):
        if layer == 0:
            f = f + self.onehot.forward(cond, alpha)
        return F.elu_forward(f)[0]


class AdapterHidden:
    """The residual-adapter variants' hidden layers: adapter(ELU(F)) in layer 0, ELU(F) in layer 1
    (the PFNN's CP adapter reads the spline weights α as its phase weights). cond: style ids (B,)."""

    def __init__(self, adapter):
        self.adapter = adapter

    def __call__(self, layer, f, alpha, cond):
        h = F.elu_forward(f)[0]
        return self.adapter.forward(h, cond, alpha) if layer == 0 else h


def variant_network(model, stats: NormStats, dtype=None) -> RuntimeNetwork:
    """The variant ``model`` (a VariantModel or LPNFilm) as a RuntimeNetwork computing in ``dtype``
    (default: the model's). ``stats``: x and z statistics of the variant's input and output; p
    statistics are used for the LPN only (the other gates read their input as it is)."""
    dtype = model.dtype if dtype is None else dtype
    if model.modulation == "film" and model.backbone == "lpn":
        return RuntimeNetwork.from_model(model, stats, dtype=dtype)
    cb = model.backbone_config
    m = model.motion.params.params
    experts = [(m[f"W{l}"], m[f"b{l}"]) for l in range(3)]
    if model.backbone == "pfnn":
        gate = PhaseGate(cb.n_experts)
    else:
        g = model.gating.params.params
        norm = stats if model.backbone == "lpn" else NormStats.identity(cb.x_dim, cb.z_dim, cb.phase_dim)
        gate = GatingMLP([(g[f"W{l}"], g[f"b{l}"]) for l in range(3)], norm, dtype=dtype)
    if model.modulation == "film":
        hidden = FilmHidden(cb.hidden, cb.ln_unbiased, cb.ln_eps)
    elif model.modulation == "onehot":
        hidden = OneHotHidden(model.film)
    else:
        hidden = AdapterHidden(model.film)
    return RuntimeNetwork(gate, experts, stats, hidden, dtype)


class VariantRuntime:
    """A network for the Controller made from any comparison variant (see the module docstring).

    stats: the LPN's statistics (x, z in the LPN layout, p of the local phases); info: what
    :func:`minifilm.baselines.variant_data.variant_data` returned for the training split.
    cond (the Controller's ``film`` argument, per frame): FiLM variants: a FiLM vector (4H,) or
    (B, 4H); one-hot / Resad: style ids (B,) or one id, or for one-hot soft weights (B, S) (an
    interpolated one-hot vector; the one-hot term is linear in it, so this blends the style rows).
    """

    def __init__(self, model, stats: NormStats, layout, info: Optional[dict] = None, dtype=None):
        self.model, self.stats, self.layout = model, stats, layout
        self.info = info or {"backbone": "lpn"}
        self.backbone = self.info["backbone"]
        self.modulation = getattr(model, "modulation", "film")
        self.x_dim, self.z_dim = layout.x_dim, layout.z_dim
        self.n_motion = layout.z_phases.start
        self.net = variant_network(model, self._variant_stats(), dtype)

    def _variant_stats(self) -> NormStats:
        """The LPN's statistics with z cut to the variant's output columns (motion, [phase
        update,] contacts), so the network hands back raw values."""
        st, L = self.stats, self.layout
        if self.backbone == "lpn":
            return st
        m = self.n_motion
        zc = np.arange(L.z_contacts.start, L.z_contacts.stop)
        mean, std = [st.z_mean[:m]], [st.z_std[:m]]
        if self.backbone == "pfnn":
            mean.append([self.info["phase_update_mean"]])
            std.append([self.info["phase_update_std"]])
        mean.append(st.z_mean[zc])
        std.append(st.z_std[zc])
        return NormStats(st.x_mean, st.x_std, np.concatenate(mean), np.concatenate(std), st.p_mean, st.p_std)

    def _gate_input(self, x_raw, p_raw):
        if self.backbone == "lpn":
            return p_raw                                   # normalised inside the LPN's gate
        if self.backbone == "mann":
            cols = self.info["gate_columns_of_x"]
            return (x_raw[:, cols] - self.stats.x_mean[cols]) / self.stats.x_std[cols]
        pair = 2 * self.info["phase_slot"] + np.arange(2)
        return phase_angle(p_raw[:, pair])[:, None]

    def _cond(self, cond, batch):
        if self.modulation == "film":
            return cond
        cond = np.asarray(cond)
        if cond.ndim == 2:
            if self.modulation != "onehot":
                raise ValueError(f"VariantRuntime: {self.model.name} takes style ids, not blend weights")
            return cond
        return np.broadcast_to(cond.astype(np.int64), (batch,))

    def predict(self, x_raw, p_raw, cond):
        """Raw x (B, x_dim), the controller's raw local phases p (B, 8) -> raw z (B, z_dim) in the
        LPN's layout."""
        L = self.layout
        x_raw = np.asarray(x_raw, dtype=np.float64)
        p_raw = np.asarray(p_raw, dtype=np.float64)
        gate_in = self._gate_input(x_raw, p_raw)
        zv = self.net.predict(x_raw, gate_in, self._cond(cond, len(x_raw))).astype(np.float64)
        if self.backbone == "lpn":
            return zv
        m = self.n_motion
        z = np.zeros((len(x_raw), L.z_dim))
        z[:, :m] = zv[:, :m]
        c0, c1 = self.info["contact_columns"]
        z[:, L.z_contacts] = zv[:, c0:c1]
        new_p = p_raw.copy()
        if self.backbone == "pfnn":
            pair = 2 * self.info["phase_slot"] + np.arange(2)
            dphase = zv[:, self.info["phase_update_column"]]
            amp = np.maximum(np.linalg.norm(p_raw[:, pair], axis=1), 1e-3)
            angle = 2 * np.pi * (gate_in[:, 0] + dphase)
            new_p[:, pair] = amp[:, None] * np.stack([np.sin(angle), np.cos(angle)], axis=1)
        z[:, L.z_phases] = new_p
        z[:, L.z_phase_updates] = new_p - p_raw
        return z
