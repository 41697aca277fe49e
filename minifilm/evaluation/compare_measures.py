"""Measures behind the claims of the paper's Sec. 5.1 that the comparison reports (definitions in
docs/compare_claims.md). Plain NumPy on feature blocks, rollouts and class probabilities.

- :func:`hand_amplitude`: how much the hands move relative to the body within a second (Sec. 5.1.1:
  the PFNN / MANN get the arms 'stuck' in styles without a single global phase);
- :func:`joint_error`: a network's one-step error on some joints' positions (Sec. 5.1.2, Figure 7:
  the clavicles of ArmsAboveHead);
- :func:`taken_for`: which style a style's generated motion is classified as (Sec. 5.1.2);
- :func:`pose_steps`: how far the pose statistics move per step of a blend (Figure 8);
- :func:`fid_reference` / :func:`rollout_fid`: the pooled FID-like distance of all generated motion
  to the real held-out motion (docs/metrics.md), beside its floor, real against real.
"""
from __future__ import annotations

import re
from typing import Sequence

import numpy as np

from minifilm.evaluation.field_metrics import fid_like
from minifilm.evaluation.style_classifier import cut_windows, rollout_blocks, split_windows, window_summary
from minifilm.evaluation.style_measures import StyleSpace


def hand_amplitude(block: np.ndarray, columns: np.ndarray, window: int) -> float:
    """Mean over 1-window pieces (half-overlapping) of the hands' motion amplitude: per hand, the
    norm of the per-axis standard deviation over time of its root-local position, averaged over
    the hands. block (F, 12 J) raw clip features (metres); columns (H, 3) the hands' position
    columns in that block (``layout.joint_columns('clip', 'position')[hands]``). A hand swinging
    ±a along one axis as a sine reads a / sqrt(2); a hand held still reads 0. NaN if F < window."""
    cols = np.asarray(columns)
    wins = cut_windows(np.asarray(block, np.float64)[:, cols.ravel()], window, max(1, window // 2))
    if len(wins) == 0:
        return float("nan")
    sd = wins.std(axis=1).reshape(len(wins), *cols.shape)          # (M, H, 3)
    return float(np.linalg.norm(sd, axis=2).mean())


def data_hand_amplitude(split, layout, style_id: int, columns: np.ndarray, window: int) -> float:
    """:func:`hand_amplitude` of the real rows of one style of a dataset split, over its runs of
    consecutive frames (runs shorter than a window are skipped), weighted by their windows."""
    vals, weights = [], []
    for a, b in zip(*split.runs()):
        if int(split.style[a]) != style_id or b - a < window:
            continue
        vals.append(hand_amplitude(np.asarray(split.x[a:b, layout.x_joints]), columns, window))
        weights.append((b - a - window) // max(1, window // 2) + 1)
    return float(np.average(vals, weights=weights)) if vals else float("nan")


def joints_named(names: Sequence[str], pattern: str) -> list:
    """Indices of the joints whose name matches ``pattern`` (a regular expression, any case)."""
    rx = re.compile(pattern, re.IGNORECASE)
    return [j for j, n in enumerate(names) if rx.search(n)]


#: the clavicle bones of Figure 7: the collar joints and the shoulders they end in (any skeleton's names)
CLAVICLE_PATTERN = r"collar|clavicle|shoulder"


def joint_error(model, data, layout, joints: Sequence[int], style: int, seed: int = 0, batch: int = 512,
                style_kw: bool = False) -> float:
    """One-step MSE (normalised units) of the predicted next-frame positions of ``joints`` on the
    frames of one style of ``data`` (a variant's TrainData), one clip of the style drawn per frame
    with the generator of ``motion_errors``. NaN when the style has no frames."""
    cols = layout.joint_columns("z", "position")[list(joints)].ravel()
    frames = np.nonzero(data.style == style)[0]
    if not len(frames) or not len(cols):
        return float("nan")
    rng = np.random.default_rng([seed, 1])
    pool = np.nonzero(data.clip_style == style)[0]
    total = 0.0
    for a in range(0, len(frames), batch):
        idx = frames[a:a + batch]
        clips = data.clips[pool[rng.integers(0, len(pool), len(idx))]]
        kw = {"style": data.style[idx]} if style_kw else {}
        pred = np.asarray(model.forward(data.x[idx], data.p[idx], clips, **kw), dtype=np.float64)
        total += float(np.sum((pred[:, cols] - data.z[idx][:, cols]) ** 2))
    return total / (len(frames) * len(cols))


def taken_for(probs: np.ndarray, commanded: Sequence[int], names: Sequence[str]) -> dict:
    """Which style each character's generated motion is classified as. probs (B, M, K) class
    probabilities of M windows of B characters; commanded (B,) the style each character was asked
    for (class index); names (K,) class names. Returns {commanded name: {'right': share of windows
    classified as it, 'other': most frequent other class or None, 'other_share': its share,
    'mistaken': True when that other class wins more windows than the commanded one}}."""
    P = np.asarray(probs)
    pred = P.argmax(axis=2)
    out = {}
    for b, k in enumerate(commanded):
        counts = np.bincount(pred[b], minlength=P.shape[2]) / max(pred.shape[1], 1)
        wrong = counts.copy()
        wrong[k] = -1.0
        o = int(wrong.argmax())
        has_other = wrong[o] > 0
        out[names[k]] = {"right": float(counts[k]), "other": names[o] if has_other else None,
                         "other_share": float(wrong[o]) if has_other else 0.0,
                         "mistaken": bool(has_other and wrong[o] > counts[k])}
    return out


def pose_steps(blocks: np.ndarray) -> dict:
    """How evenly a blend moves the pose: blocks (n, F, C) normalised clip features of the n
    rollouts at blend weights 0, 1/(n-1), .., 1; each rollout's pose statistics are the mean and
    the standard deviation over time of every feature (the style classifier's window summary over
    the whole rollout). Returns 'steps' (n-1,) the distances between neighbouring weights'
    statistics, 'max_over_mean' (1 = every step of the blend moves the pose as far; n - 1 = all of
    it in one step), 'end_to_end' the distance between the two ends, and 'first_half_share' the
    share of the path length walked by the middle weight (0.5 = even; near 0 = the first style
    held until late)."""
    B = np.asarray(blocks, np.float64)
    if B.ndim != 3 or len(B) < 2:
        raise ValueError(f"pose_steps: blocks must be (n >= 2, F, C), got {B.shape}")
    stats = np.concatenate([B.mean(axis=1), B.std(axis=1)], axis=1)      # (n, 2C)
    steps = np.linalg.norm(np.diff(stats, axis=0), axis=1)
    mean = float(steps.mean())
    half = len(steps) // 2
    return {"steps": steps, "max_over_mean": float(steps.max() / mean) if mean > 0 else float("nan"),
            "end_to_end": float(np.linalg.norm(stats[-1] - stats[0])),
            "first_half_share": float(steps[:half].sum() / steps.sum()) if steps.sum() > 0 else float("nan")}


def fid_reference(ds, seen: Sequence[str], window: int, stride: int, dims: int = 32) -> dict:
    """What generated motion is held against by :func:`rollout_fid`: a StyleSpace fitted on the seen
    styles' real training windows (``window`` frames every ``stride``, the classifier's), and the
    summaries of their real held-out windows (validation and test rows). 'real_to_real' is the
    distance of those held-out windows to the training windows: the floor a generator that moved
    exactly like the data would reach, up to sampling noise."""
    ids = {ds.styles.index(s): s for s in seen}

    def summaries(split):
        X, y = split_windows(split, ds.layout, ds.stats, window, stride)
        keep = np.isin(y, list(ids))
        return window_summary(X[keep]), y[keep]

    train, train_style = summaries(ds.train)
    held = np.concatenate([summaries(ds.split(name))[0] for name in ("val", "test")])
    per_style = {ids[k]: train[train_style == k] for k in ids if np.sum(train_style == k) >= 2}
    space = StyleSpace.fit(per_style, dims=dims, summarised=True)
    floor = fid_like(space, held, train, summarised=True) if len(held) >= 2 else float("nan")
    return {"space": space, "real": held if len(held) >= 2 else train, "real_to_real": floor}


def rollout_fid(reference: dict, ds, rollout, window: int, stride: int) -> float:
    """The pooled FID-like distance (field_metrics.fid_like) of every window of every character of
    ``rollout`` to ``reference``'s real held-out windows; NaN with fewer than 2 windows."""
    blocks = ds.stats.normalize_clip(rollout_blocks(rollout), ds.layout.x_joints)      # (B, F', 12 J)
    gen = [window_summary(w) for w in (cut_windows(b, window, stride) for b in blocks) if len(w)]
    gen = np.concatenate(gen) if gen else np.empty((0, 2 * blocks.shape[-1]))
    return fid_like(reference["space"], gen, reference["real"], summarised=True) if len(gen) >= 2 else float("nan")
