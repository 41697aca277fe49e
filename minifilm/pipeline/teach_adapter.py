"""A taught style's own adapter, when no FiLM vector of the network reaches its clip
(docs/teaching-released.md, step 7).

    is the clip outside the style space? (:func:`adapter_kind`: the distance test finetune prints)
    -> replay: the known styles nearest the style's vector walk a figure-eight at the clip's
       speed, every frame's input and the unmodified network's output recorded (:func:`replay_rows`)
    -> the adapter fitted on the clip's rows, as the FiLM vector was (the same labels, features and
       joint axes), with the replay making up a share of every minibatch (train/adapter_fit.py)
    -> the style walked with its adapter and checked as a FiLM vector's walk is

PAPER: the paper adds a style through FiLM alone; its comparison (Sec. 5) gives every style a
residual adapter. Here a style gets one only when FiLM does not reach its clip.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Callable, Mapping, Optional

import numpy as np

from minifilm.model.adapters import KINDS
from minifilm.runtime.adapted import AdaptedNetwork
from minifilm.runtime.control import make_script
from minifilm.runtime.controller import Controller
from minifilm.runtime.walk_checks import walk_report
from minifilm.synthetic.generator import rest_motion
from minifilm.train.adapter_fit import AdapterRows, AdapterSettings, FrozenPhi, fit_adapter

MODES = ("auto", "off") + KINDS
AUTO_KIND = "lowrank"          # what --adapter auto teaches (reports/2026-12-06_adapters.md)
#: outside the style space also when the fitted vector's loss on the clip stays this many times
#: the nearest known style's loss on its own motion (released styles re-fitted: at most about 1)
LOSS_RATIO = 1.25


@dataclass
class AdapterPlan:
    """mode: 'auto' (an adapter when the clip lies outside the style space), 'off', or a kind
    ('residual', 'lowrank': always); settings: how it is fitted; replay_styles: known styles
    walked for the replay; replay_seconds: how long each walks."""
    mode: str = "auto"
    settings: AdapterSettings = field(default_factory=AdapterSettings)
    replay_styles: int = 16
    replay_seconds: float = 8.0

    def __post_init__(self):
        if self.mode not in MODES:
            raise ValueError(f"adapter: {self.mode!r}, expected one of {', '.join(MODES)}")


def adapter_kind(plan: AdapterPlan, far: bool, loss: float, own_loss: float) -> Optional[str]:
    """The kind of adapter to fit, or None. ``far``: finetune's distance test (input numbers
    beyond 5 σ, or the nearest style's loss 3x its own); ``loss``: the fitted vector's loss on the
    clip; ``own_loss``: the nearest known style's loss on its own motion."""
    if plan.mode == "off":
        return None
    if plan.mode != "auto":
        return plan.mode
    outside = far or (own_loss > 0 and loss > LOSS_RATIO * own_loss)
    return AUTO_KIND if outside else None


class RecordedNetwork:
    """A network with every frame's raw inputs x, phases p and outputs z recorded, each frame's
    as one array (B, ...) for its batch of characters."""

    def __init__(self, network):
        self._network, self.x, self.p, self.z = network, [], [], []

    def __getattr__(self, name):
        return getattr(self._network, name)

    def predict(self, x, p, cond):
        z = self._network.predict(x, p, cond)
        self.x.append(np.array(x, np.float64))
        self.p.append(np.array(p, np.float64))
        self.z.append(np.array(z, np.float64))
        return z


def released_controller(network, layout, fps: float = 60.0) -> Controller:
    """A controller driving ``network`` as ``generate`` drives the released network (every frame put
    on the 100STYLE skeleton and fed back)."""
    return Controller(network, layout, fps=fps, skeleton=Controller.skeleton_for(layout, rest_motion()),
                      feed_back_fit=True)


def replay_rows(controller: Callable, network, films: np.ndarray, speed: float, seconds: float = 8.0):
    """Every vector of ``films`` (S, 4H) walks a figure-eight at ``speed`` for ``seconds``, one batch,
    driven by ``controller(network)`` (e.g. :func:`released_controller`): -> raw x (N, x_dim),
    p (N, 8), z (N, z_dim) of every frame after the first second (the start from the mean pose),
    and each row's vector index."""
    rec = RecordedNetwork(network)
    ctrl = controller(rec)
    fps = ctrl.fps
    v = float(np.clip(speed, 0.3, 4.0))
    n = int(round(seconds * fps))
    ctrl.run([make_script("figure8", seconds, speed=v) for _ in films], n, np.asarray(films, np.float32))
    k0 = int(round(fps))
    X, P, Z = (np.stack(a[k0:]) for a in (rec.x, rec.p, rec.z))              # (T, S, ...)
    style = np.tile(np.arange(len(films)), X.shape[0])
    return X.reshape(-1, X.shape[-1]), P.reshape(-1, P.shape[-1]), Z.reshape(-1, Z.shape[-1]), style


def fit_style_adapter(model, network, controller: Callable, rows_xpz, film: np.ndarray,
                      known: Mapping[str, np.ndarray], speed: float, plan: AdapterPlan, kind: str,
                      log: Callable[[str], None] = print):
    """Fit a ``kind`` adapter for the style ``film`` on the clip's normalised rows ``rows_xpz``
    (x, p, z) through ``model``'s frozen Ω and Φ (``network``: the same on the inference path,
    whose layer norm it takes), with replay from the ``plan.replay_styles`` known styles nearest
    ``film`` walked by ``controller(network)``. -> (StyleAdapter, figures for the pack)."""
    t0 = time.perf_counter()
    names = list(known)
    V = np.stack([known[n] for n in names]).astype(np.float32)
    near = np.argsort(np.linalg.norm(V - film, axis=1))[:plan.replay_styles]
    x, p, z, idx = replay_rows(controller, network, V[near], speed, plan.replay_seconds)
    st = network.stats
    phi = FrozenPhi.of(model, ln_unbiased=network.hidden.ln_unbiased, ln_eps=network.hidden.ln_eps)
    films = np.concatenate([np.asarray(film, np.float32)[None], V[near]])
    clip = AdapterRows.make(model, phi, *rows_xpz, 0)
    replay = AdapterRows.make(model, phi, st.normalize_x(x), st.normalize_p(p), st.normalize_z(z), idx + 1)
    settings = AdapterSettings(**{**asdict(plan.settings), "kind": kind})
    log(f"fitting a {kind} adapter: {len(clip)} clip rows, {len(replay)} replay rows of {len(near)} known styles")
    fit = fit_adapter(phi, clip, films, replay, settings)
    info = {"kind": kind, "rank": fit.adapter.rank, "steps": fit.steps, "best_step": fit.best_step,
            "replay": settings.replay, "noise": settings.noise, "replay_styles": [names[i] for i in near],
            "holdout_loss_film_alone": fit.start_loss, "holdout_loss": fit.holdout_loss,
            "replay_loss": fit.replay_loss, "seconds": time.perf_counter() - t0}
    return fit.adapter, info


def adapted_check(network, layout, film, adapter, clip, toes, rollouts):
    """The style walked with its adapter, checked as finetune checks a FiLM vector's walk
    (``rollouts``: walks.candidate_rollouts): -> WalkReport."""
    r, path = rollouts(AdaptedNetwork(network, [adapter]), layout, adapted_condition(film)[None], clip.speed)
    return walk_report(r, 0, toes, path, clip_steps_per_s=clip.steps_per_s, clip_hips=clip.hips)


def adapted_condition(film) -> np.ndarray:
    """The condition of a style with the one adapter of an AdaptedNetwork: [film | 1]."""
    return np.concatenate([np.asarray(film, np.float32), [1.0]]).astype(np.float32)
