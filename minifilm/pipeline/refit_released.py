"""The known-answer test of teaching the released network: re-fit one of its own styles.

A style's vector is hidden; the network walks in it (the style's own generated motion, written
on the 100STYLE skeleton as any clip would be: the network's answer is then known), and the
style is taught from that motion with the prior made of the *other* styles only
(:func:`minifilm.pipeline.teach_released.teach`). Found again means:

    film rank      the hidden vector's rank among all the network's vectors by distance from the
                   fitted one in FiLM space (1: nearest)
    output rank    ... by how close their predictions are to the fitted vector's on the held-out
                   last fifth of the clip (rows the fit never saw)
    loss rank      the hidden vector's rank by loss on the clip among all (a check of the labels:
                   with minifilm's labels the true vector should explain its own motion best)

Why the film rank can fail while the output rank holds (:func:`sensitivity`): of the 2,048
directions of a FiLM vector few change the network's output much, so two vectors far apart can
predict nearly the same motion; the rows pin the visible directions and leave the others to the
prior.
"""
from __future__ import annotations

from typing import Callable, Optional

import numpy as np

from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.runtime.control import make_script
from minifilm.runtime.controller import Controller
from minifilm.runtime.start_state import root_joint_indices
from minifilm.pipeline.motion_refit import RefitSettings
from minifilm.pipeline.teach_adapter import AdapterPlan
from minifilm.pipeline.teach_released import FrozenRows, clip_rows, normalised, teach
from minifilm.pipeline.walks import FPS
from minifilm.synthetic.generator import rest_motion
from minifilm.train.film_fit import FitSettings


def generated_motions(rel, names, seconds: float, script: str = "figure8", speed: float = 1.3):
    """The network's own motion in each style (one batch), first second cut: Motions on 100STYLE."""
    layout, skeleton = FeatureLayout.for_skeleton(STYLE100), rest_motion()
    ctrl = Controller(rel.network, layout, fps=FPS, skeleton=Controller.skeleton_for(layout, skeleton),
                      feed_back_fit=True)
    n = int(round((seconds + 1) * FPS))
    r = ctrl.run([make_script(script, seconds + 1, speed=speed) for _ in names], n,
                 np.stack([rel.styles[s] for s in names]))
    joints = root_joint_indices(layout, skeleton)
    return [r.to_motion(skeleton, joints, character=b).slice(int(FPS), n) for b in range(len(names))]


def rank_of(values: np.ndarray, i: int) -> int:
    """1 + how many entries are strictly smaller than values[i]."""
    return int(np.sum(values < values[i]) + 1)


def jacobian_gram(rows, film: np.ndarray, idx, eps: float = 1e-2) -> np.ndarray:
    """JᵀJ / n (D, D) of the rows' predicted outputs z (n numbers in all) with respect to the FiLM
    vector (D,), by forward differences (one prediction per direction on the rows ``idx``)."""
    film = np.asarray(film, np.float64)
    base = rows.predict(film, idx).ravel().astype(np.float64)
    J = np.empty((base.size, film.size), np.float64)
    for d in range(film.size):
        f = film.copy()
        f[d] += eps
        J[:, d] = (rows.predict(f, idx).ravel() - base) / eps
    return J.T @ J / base.size


def sensitivity(gram: np.ndarray, error: np.ndarray, other: np.ndarray) -> dict:
    """How much of the fit's error the output can see. gram: JᵀJ/n (D, D) at the true vector;
    error: fitted minus true vector (D,); other: nearest other style minus true vector (D,).
    -> {directions holding 90 / 99 % of the output's sensitivity (the trace of the gram), the share
    of the error's length in those 99 % directions, and the output change per unit length along
    the error and along the direction to the other style (RMS of z per unit of FiLM distance)}."""
    w, V = np.linalg.eigh(gram)
    w, V = np.clip(w[::-1], 0, None), V[:, ::-1]
    cum = np.cumsum(w) / w.sum()
    k90, k99 = int(np.searchsorted(cum, 0.90) + 1), int(np.searchsorted(cum, 0.99) + 1)

    def gain(u):
        return float(np.sqrt(u @ gram @ u / (u @ u)))

    in_k99 = float(np.sum((V[:, :k99].T @ error) ** 2) / (error @ error))
    return dict(dims=int(len(w)), k90=k90, k99=k99, error_share_in_k99=in_k99, gain_error=gain(error),
                gain_other=gain(other), gain_top=float(np.sqrt(w[0])), gain_median=float(np.sqrt(np.median(w))))


def refit(rel, name: str, motion, settings: FitSettings = FitSettings(), prior_weights=(0.3, 1.0, 3.0),
          by_motion: Optional[RefitSettings] = RefitSettings(), log: Callable[[str], None] = lambda m: None) -> dict:
    """Teach ``name`` from ``motion`` with its own vector hidden; -> ranks and figures (module
    docstring), the fitted vector ('film') and the output's sensitivity (:func:`sensitivity`).
    by_motion: the refinement by the motion the vector makes, as ``finetune`` runs it (None: the
    teacher-forced fit alone)."""
    names = list(rel.styles)
    V = np.stack([rel.styles[n] for n in names]).astype(np.float64)
    i = names.index(name)
    known = {n: rel.styles[n] for n in names if n != name}
    layout = FeatureLayout.for_skeleton(STYLE100)
    taught = teach(rel, layout, f"{name}-refit", [motion], [f"{name} (generated)"], known=known, settings=settings,
                   prior_weights=prior_weights, require_steps=False, motion=by_motion, log=log,
                   adapter=AdapterPlan("off"))   # the FiLM vector is what is measured; the network's motion walks,
    # whatever minifilm's contact labels find in it (BentKnees: fewer than two steps in 30 s)
    x, p, z = normalised(rel.stats, clip_rows([motion], [name], name, require_steps=False))
    rows = FrozenRows(rel.model, x, p, z)
    held = np.arange(int(0.8 * len(rows)), len(rows))
    fitted = rows.predict(taught.film, held)
    output_d = np.array([np.mean((rows.predict(v, held) - fitted) ** 2) for v in V])
    losses = np.array([rows.loss(v, held) for v in V])
    film_d = np.linalg.norm(V - taught.film, axis=1)
    others = np.linalg.norm(V - V[i], axis=1)
    others[i] = np.inf
    probe = held[np.linspace(0, len(held) - 1, 24).astype(int)]      # 24 rows: J is (24 z, 2048)
    sens = sensitivity(jacobian_gram(rows, V[i], probe), taught.film - V[i], V[int(np.argmin(others))] - V[i])
    return dict(style=name, film=taught.film, sensitivity=sens, nearest_other=names[int(np.argmin(others))],
                film_rank=rank_of(film_d, i), output_rank=rank_of(output_d, i),
                loss_rank=rank_of(losses, i), nearest_film=names[int(np.argmin(film_d))],
                nearest_output=names[int(np.argmin(output_d))], true_loss=float(losses[i]),
                fitted_loss=float(rows.loss(taught.film, held)), start_loss=taught.distance.start_loss,
                seconds=taught.seconds, labelled_steps_per_s=taught.clip.steps_per_s, steps_per_s=taught.check.steps_per_s,
                clip_steps_per_s=taught.clip.steps_per_s, walks=not taught.check.problems(),
                candidates=taught.candidates)
