"""The comparison's rollouts (minifilm/evaluation/compare.py): every variant driven along the same
commanded figure-eight in every seen style, measured (style recognition and what each style is
taken for, foot sliding, path following, bone lengths, the hands' motion amplitude) and blended
between pairs of styles (Figure 8)."""
from __future__ import annotations

import numpy as np

from minifilm.baselines.runtime import VariantRuntime
from minifilm.evaluation.compare_measures import hand_amplitude, pose_steps, rollout_fid, taken_for
from minifilm.evaluation.compare_tools import film_codes
from minifilm.evaluation.metrics import interpolation_smoothness, rollout_quality
from minifilm.evaluation.style_classifier import classify_rollout, rollout_blocks
from minifilm.runtime.control import make_script
from minifilm.runtime.controller import Controller, NonFiniteOutputError

#: the keys of a rollout summary whose rollouts diverged
EMPTY = ("accuracy", "foot_sliding", "foot_sliding_cm_s", "path_error", "direction_error", "bone_cv_mean",
         "bone_cv_max", "speed", "fid")


def style_conditions(model, ctx):
    """Per seen style: the FiLM vector (mean Ψ over its training clips) or the style id."""
    if getattr(model, "takes_style_ids", False):
        return np.arange(len(ctx.seen))
    tr = ctx.data["train"]
    return np.stack([film_codes(model, tr.clips[tr.clip_style == s]).mean(axis=0) for s in range(len(ctx.seen))])


def controller_for(model, info, ctx):
    return Controller(VariantRuntime(model, ctx.norm, ctx.layout, info), ctx.layout, fps=ctx.ds.fps)


def run_rollouts(controller, cond, ids, ctx, seconds, fps=None):
    """One character per row of `cond` along a figure-eight. ids=True: cond holds style ids or
    one-hot weights, handed to the network every frame; else (B, 4H) FiLM vectors."""
    n = int(round(seconds * (ctx.ds.fps if fps is None else fps)))
    scripts = [make_script("figure8", seconds) for _ in range(len(cond))]
    try:
        with np.errstate(all="ignore"):     # a diverging variant overflows; the controller stops it
            return controller.run(scripts, n, (lambda k: cond) if ids else cond)
    except NonFiniteOutputError:
        return None                     # diverged(None): reported as such, not an error of the comparison


def run_films(network, layout, fps, films, seconds):
    """Characters driven by a run-time network with FiLM vectors films (B, 4H) along the same
    figure-eight as :func:`run_rollouts`, ``seconds`` long at ``fps``; None if it diverged."""
    return run_rollouts(Controller(network, layout, fps=fps), films, False, None, seconds, fps=fps)


def style_recognition(model, info, ctx):
    """Rollouts of every seen style: classifier accuracy per style, foot sliding, bone variation."""
    cond = style_conditions(model, ctx)
    ids = getattr(model, "takes_style_ids", False)
    rollout = run_rollouts(controller_for(model, info, ctx), cond, ids, ctx, ctx.args.rollout_seconds)
    return measure_rollout(rollout, ctx, ctx.seen)


def measure_rollout(rollout, ctx, styles, parents=None, toes=None, hands=None):
    """The rollout summary of characters driven in ``styles`` (one each, in order): classifier
    accuracy (overall and per style), what each style is taken for, the hands' amplitude per style,
    rollout_quality's numbers, the mean root speed and, when the context has its reference
    (compare.Context.fid), the pooled FID-like distance to the real held-out windows. parents /
    toes / hands default to the data set's skeleton (another network's rollout gives its own). A
    diverged rollout gives None for each."""
    parents = ctx.layout.parents if parents is None else parents
    toes = ctx.toes if toes is None else toes
    hands = ctx.hand_columns if hands is None else hands
    if diverged(rollout):
        return {"diverged": True, "per_style": {n: None for n in styles}, "taken_for": {}, "hands": {},
                **{k: None for k in EMPTY}}
    w, s = ctx.clf_info["window"], ctx.clf_info["stride"]
    probs = classify_rollout(ctx.classifier, ctx.ds, rollout, window=w, stride=s)     # (B, M, classes)
    target = np.array([ctx.ds.styles.index(n) for n in styles])
    hit = probs.argmax(axis=2) == target[:, None]
    per_style = {n: float(hit[b].mean()) for b, n in enumerate(styles)}
    quality = rollout_quality(rollout, parents, toes)
    blocks = rollout_blocks(rollout)                                                  # (B, F', 12 J) raw
    second = max(2, int(round(rollout.fps)))
    hand = {n: hand_amplitude(blocks[b], hands, second) for b, n in enumerate(styles)}
    reference = getattr(ctx, "fid", None)
    fid = rollout_fid(reference, ctx.ds, rollout, w, s) if reference else None
    return {"diverged": False, "accuracy": float(hit.mean()), "per_style": per_style, **quality, "fid": fid,
            "taken_for": taken_for(probs, target, list(ctx.ds.styles)), "hands": hand,
            "speed": float(np.mean([m["speed"] for m in rollout.metrics(parents)]))}


def diverged(rollout, limit=10.0):
    """No rollout (the controller stopped at a non-finite frame), non-finite joints, or a joint
    further than `limit` metres from its root: the autoregressive loop has blown up and rollout
    metrics would be meaningless."""
    if rollout is None:
        return True
    P = rollout.positions
    if not np.all(np.isfinite(P)):
        return True
    root = np.zeros(P.shape[:2] + (1, 3))
    root[..., 0, 0], root[..., 0, 2] = rollout.root_positions[..., 0], rollout.root_positions[..., 1]
    return bool(np.abs(P - root).max() > limit)


def interpolation(model, info, ctx, style_a, style_b, n=11):
    """Classifier probability of style B along a blend A -> B (FiLM vectors or one-hot weights),
    and how evenly the pose statistics move along it (compare_measures.pose_steps)."""
    a = ctx.args
    w = np.linspace(0.0, 1.0, n)
    ia, ib = ctx.seen.index(style_a), ctx.seen.index(style_b)
    ids = getattr(model, "takes_style_ids", False)
    if ids:
        cond = np.zeros((n, len(ctx.seen)))
        cond[:, ia], cond[:, ib] = 1 - w, w
    else:
        c = style_conditions(model, ctx)
        cond = (1 - w)[:, None] * c[ia] + w[:, None] * c[ib]
    rollout = run_rollouts(controller_for(model, info, ctx), cond, ids, ctx, a.rollout_seconds)
    if diverged(rollout):
        return {"diverged": True}
    probs = classify_rollout(ctx.classifier, ctx.ds, rollout, window=ctx.clf_info["window"],
                             stride=ctx.clf_info["stride"])
    kb, ka = ctx.ds.styles.index(style_b), ctx.ds.styles.index(style_a)
    pb, pa = probs[:, :, kb].mean(axis=1), probs[:, :, ka].mean(axis=1)
    score = pb / np.maximum(pa + pb, 1e-12)           # B against A only: other styles do not count
    pose = pose_steps(ctx.ds.stats.normalize_clip(rollout_blocks(rollout), ctx.ds.layout.x_joints))
    return {"weights": w, "score": score, "pair": (style_a, style_b), "pose": pose,
            **interpolation_smoothness(w, score)}
