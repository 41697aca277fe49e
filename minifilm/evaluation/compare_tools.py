"""Pieces shared by the comparison (minifilm/evaluation/compare.py) and examples/finetune_new_style.py.

- `select_styles`: the styles a comparison runs on (all, named, or N spread over the names);
- `style_subset`: the frames and clips of some styles of a dataset as a TrainData, normalised with
  given statistics and with the style ids renumbered 0 .. S-1 (to hold a style out of training);
- `motion_errors`: test MSE and bone-length loss on the output columns every variant predicts
  (trajectory + joints), so variants with different outputs are compared on the same numbers;
- `film_codes` / `film_separation`: FiLM vectors of many clips per style, their silhouette and a
  2-D PCA embedding (Figure 11);
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from minifilm.dataset.arrays import TrainData
from minifilm.dataset.stats import NormStats
from minifilm.evaluation.metrics import pca_2d, silhouette_samples
from minifilm.model.losses import bone_length_loss


# ---------------------------------------------------------------------------- data
def select_styles(available: Sequence[str], spec: Optional[Sequence[str]], keep: Sequence[str] = ()) -> list:
    """The styles a comparison runs on: all of ``available`` (spec None), the named ones, or with a
    single whole number N, N styles spread evenly over the sorted names (so a 100-style set cut to
    20 still spans the alphabet rather than its first fifth), always including ``keep`` (the
    held-out style and the interpolation pair, when named). Returns sorted names.

    ValueError for a name that is not available or N outside 3 .. len(available).
    """
    names = sorted(set(available))
    if not spec:
        return names
    if len(spec) == 1 and spec[0].strip().isdigit():
        n = int(spec[0])
        if not 3 <= n <= len(names):
            raise ValueError(f"--styles {n}: give between 3 and {len(names)} styles (one is held out, "
                             f"two are interpolated)")
        kept = [k for k in keep if k in names]
        rest = [x for x in names if x not in kept]
        picks = np.linspace(0, len(rest) - 1, max(n - len(kept), 0)).round().astype(int) if rest else []
        return sorted(set(kept) | {rest[i] for i in picks})
    chosen = [x.strip() for x in spec if x.strip()]
    unknown = [x for x in chosen if x not in names]
    if unknown:
        raise ValueError(f"--styles: {', '.join(map(repr, unknown))} not in the data ({len(names)} styles: "
                         f"{', '.join(names[:12])}{' ...' if len(names) > 12 else ''})")
    return sorted(set(chosen))


def fit_stats(ds, styles: Sequence[str]) -> NormStats:
    """Normalisation statistics from the training rows of `styles` only (a held-out style must not
    leak into them)."""
    ids = [ds.styles.index(s) for s in styles]
    rows = np.isin(ds.train.style, ids)
    if not np.any(rows):
        raise ValueError(f"fit_stats: no training rows for styles {list(styles)}")
    return NormStats.fit(ds.train.x[rows], ds.train.p[rows], ds.train.z[rows])


def style_subset(ds, split: str, styles: Sequence[str], normalizer, dtype=np.float32) -> TrainData:
    """Rows of `split` whose style is in `styles`, normalised with `normalizer`, style ids
    renumbered to positions in `styles`. Clips come from the split itself when every chosen style
    has one there, else from the training split (validation / test windows are usually shorter
    than a clip; the clip is the style condition, not a target)."""
    unknown = [s for s in styles if s not in ds.styles]
    if unknown:
        raise ValueError(f"style_subset: styles {unknown} are not in the dataset ({ds.styles})")
    ids = np.array([ds.styles.index(s) for s in styles])
    remap = np.full(len(ds.styles), -1)
    remap[ids] = np.arange(len(ids))
    sp = ds.split(split)
    rows = np.isin(sp.style, ids)
    cs = sp if set(ids.tolist()) <= set(sp.clip_style[np.isin(sp.clip_style, ids)].tolist()) else ds.train
    crow = np.isin(cs.clip_style, ids)
    n = normalizer
    return TrainData(x=n.normalize_x(sp.x[rows]).astype(dtype), p=n.normalize_p(sp.p[rows]).astype(dtype),
                     z=n.normalize_z(sp.z[rows]).astype(dtype), style=remap[sp.style[rows]],
                     clips=n.normalize_clip(cs.clips[crow], ds.layout.x_joints).astype(dtype),
                     clip_style=remap[cs.clip_style[crow]], style_names=list(styles))


def steps_per_epoch(style: np.ndarray, batch_size: int) -> int:
    """Style-balanced minibatches in one epoch of rows labelled ``style`` (N,): every style gives as
    many batches as the smallest one holds (a batch is at most that style's row count)."""
    counts = np.bincount(style)
    counts = counts[counts > 0]
    size = min(batch_size, counts.min())
    return int(counts.min() // size * len(counts))


# ---------------------------------------------------------------------------- test errors
def motion_errors(model, data: TrainData, layout, stats, motion_columns: int, batch: int = 512, seed: int = 0,
                  style_kw: bool = False) -> dict:
    """Test MSE and BLL (Eq. 5-7) over the first `motion_columns` output columns (trajectory and
    joints, predicted by every variant), per style and averaged over styles (each style weighted
    equally). data: the variant's TrainData; one clip of the frame's style drawn per frame."""
    rng = np.random.default_rng([seed, 1])
    pos = layout.joint_columns("z", "position")
    parents = np.asarray(layout.parents)
    zm, zs = np.asarray(stats.z_mean)[:motion_columns], np.asarray(stats.z_std)[:motion_columns]
    per_style = {}
    for s in np.unique(data.style):
        frames = np.nonzero(data.style == s)[0]
        pool = np.nonzero(data.clip_style == s)[0]
        mse = bll = 0.0
        for a in range(0, len(frames), batch):
            idx = frames[a:a + batch]
            clips = data.clips[pool[rng.integers(0, len(pool), len(idx))]]
            kw = {"style": data.style[idx]} if style_kw else {}
            pred = np.asarray(model.forward(data.x[idx], data.p[idx], clips, **kw), dtype=np.float64)
            pred, target = pred[:, :motion_columns], data.z[idx, :motion_columns].astype(np.float64)
            mse += float(np.mean((pred - target) ** 2)) * len(idx)
            bll += bone_length_loss(pred, target, pos, parents, zm, zs)[0] * len(idx)
        name = data.style_names[s] if s < len(data.style_names) else str(s)
        per_style[name] = {"mse": mse / len(frames), "bll": bll / len(frames)}
    return {"mse": float(np.mean([v["mse"] for v in per_style.values()])),
            "bll": float(np.mean([v["bll"] for v in per_style.values()])), "per_style": per_style}


# ---------------------------------------------------------------------------- FiLM codes
def film_codes(model, clips: np.ndarray, batch: int = 32) -> np.ndarray:
    """Ψ(clip) for every clip: (M, T, C) -> (M, 4H) float64."""
    out = [np.asarray(model.film_parameters(clips[a:a + batch]), dtype=np.float64)
           for a in range(0, len(clips), batch)]
    return np.concatenate(out)


def film_separation(codes: np.ndarray, labels: np.ndarray, focus=None) -> dict:
    """Silhouette of FiLM codes (N, D) grouped by style labels (N,), in the full space and in the
    2-D PCA plane; with `focus` (a label, or several: the held-out styles), also the mean
    silhouette of those styles' points alone (is a held-out style a cluster of its own?) and, per
    focus label, its own mean ('focus_each'). Returns the numbers and the 2-D embedding."""
    labels = np.asarray(labels)
    full = silhouette_samples(codes, labels)
    Y, ratio = pca_2d(codes)
    flat = silhouette_samples(Y, labels)
    out = {"silhouette": float(full.mean()), "silhouette_2d": float(flat.mean()), "embedding": Y,
           "explained": ratio}
    if focus is not None:
        chosen = np.isin(labels, focus)
        out["focus_silhouette"] = float(full[chosen].mean())
        out["focus_silhouette_2d"] = float(flat[chosen].mean())
        out["focus_each"] = {int(k): float(full[labels == k].mean()) for k in np.atleast_1d(focus)}
    return out
