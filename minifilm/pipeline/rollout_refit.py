"""A taught FiLM vector refitted at the states the network itself visits (docs/teaching-released.md).

The fit of minifilm/pipeline/teach_released.py sees the clip's rows: the clip's poses, and phases
labelled by minifilm from the clip's motion. When the style walks, the network sees its own poses
and its own phases instead. Here, round by round:

    roll the current vector out straight ahead at the clip's speed, recording every frame's input
    (the network's own pose, trajectory and phases) -> for each visited frame, the clip frame whose
    pose is nearest (normalised joint block) gives the next-frame target (pose and trajectory; the
    phase and contact outputs stay the network's own) -> refit the vector on the clip's rows and
    all visited rows so far (the prior and early stopping as before) -> repeat

(the clip as the expert of DAgger, Ross et al. 2011, matched by pose rather than by time: a
rollout's steps drift out of step with the clip's, a pose match does not).
"""
from __future__ import annotations

from typing import List

import numpy as np

from minifilm.pipeline.teach_adapter import RecordedNetwork
from minifilm.pipeline.teach_released import normalised
from minifilm.pipeline.walks import FPS
from minifilm.runtime.control import CommandScript
from minifilm.runtime.controller import Controller
from minifilm.synthetic.generator import rest_motion
from minifilm.train.film_fit import FitSettings, FrozenRows, StylePrior, fit_film


def visited_rows(rel, layout, film: np.ndarray, clip, seconds: float = 8.0):
    """Rows at the states ``film`` visits walking straight at the clip's speed (the first second
    cut), with the clip's nearest-pose next-frame targets: -> (x, p, z) raw, and the median
    distance from a visited pose to its nearest clip pose (normalised units, per number)."""
    rec = RecordedNetwork(rel.network)
    ctrl = Controller(rec, layout, fps=FPS, skeleton=Controller.skeleton_for(layout, rest_motion()),
                      feed_back_fit=True)
    v = float(np.clip(clip.speed, 0.3, 4.0))
    n = int(round((seconds + 1) * FPS))
    ctrl.run([CommandScript([(0.0, v, 0.0, 0.0), (seconds + 1, v, 0.0, 0.0)])], n, np.asarray(film, np.float32)[None])
    X, P, Zown = (np.stack(a)[int(FPS):, 0] for a in (rec.x, rec.p, rec.z))     # one character
    a = rel.stats.normalize_x(X)[:, layout.x_joints]
    b = rel.stats.normalize_x(clip.x)[:, layout.x_joints]
    d2 = np.sum(a ** 2, 1)[:, None] + np.sum(b ** 2, 1)[None] - 2 * a @ b.T
    nearest = np.argmin(d2, axis=1)
    Z = np.array(clip.z[nearest], np.float64)
    for cols in (layout.z_phases, layout.z_phase_updates, layout.z_contacts):
        Z[:, cols] = Zown[:, cols]            # the network's own phases and contacts, not the labels
    spread = float(np.median(np.sqrt(np.maximum(d2[np.arange(len(a)), nearest], 0) / a.shape[1])))
    return X, P, Z, spread


def rollout_refit(rel, layout, taught, known: dict = None, rounds: int = 2, seconds: float = 8.0,
                  settings: FitSettings = FitSettings(), prior_weight: float = 1.0) -> List[dict]:
    """``rounds`` rounds (module docstring) from ``taught.film``; -> per round {'film', 'loss' on
    the visited rows before and after, 'pose_distance' of the visited poses to the clip's}."""
    known = dict(rel.styles if known is None else known)
    prior = StylePrior.from_vectors(np.stack(list(known.values())).astype(np.float64))
    x0, p0, z0 = normalised(rel.stats, taught.clip)
    xs, ps, zs = [x0], [p0], [z0]
    film, out = np.asarray(taught.film, np.float64), []
    for _ in range(rounds):
        X, P, Z, spread = visited_rows(rel, layout, film, taught.clip, seconds)
        xs.append(rel.stats.normalize_x(X)), ps.append(rel.stats.normalize_p(P)), zs.append(rel.stats.normalize_z(Z))
        visited = FrozenRows(rel.model, xs[-1], ps[-1], zs[-1])
        before = visited.loss(film)
        rows = FrozenRows(rel.model, np.concatenate(xs), np.concatenate(ps), np.concatenate(zs))
        fit = fit_film(rows, prior, start=film, settings=FitSettings(**{**settings.__dict__, "prior_weight": prior_weight}))
        film = np.asarray(fit.film, np.float64)
        out.append(dict(film=film.astype(np.float32), loss_before=float(before), loss_after=float(visited.loss(film)),
                        pose_distance=spread))
    return out
