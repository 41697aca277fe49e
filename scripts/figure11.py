"""Figure 11: FiLM parameters of many clips per style in 2-D (t-SNE), before and after fine-tuning.

    minifilm train --data DATA_WITHOUT_HELD --out RUN                 # Φ, Ω, Ψ on the trained styles
    minifilm finetune RUN --name Skip Skip_FW.bvh ...                 # Ψ alone, per held-out style
    python scripts/figure11.py --run RUN --data DATA --held Skip Star --png fig11.png

The paper (Sec. 5.3.2, Figure 11) embeds the FiLM vectors Ψ(clip) of 50 clips per style: a style
Ψ has never seen falls among the others, and after fine-tuning Ψ on a short clip of it, its clips
form a cluster of their own. Here, for the run's trained styles (``--trained``, default: the first
15 of the run) and each held-out style: up to ``--clips-per-style`` clips of each from ``--data``
(a data set holding every style, e.g. ``minifilm dataset --from-released``; clips of all its splits),
coded by

* *before*: the run's Ψ as trained;
* *after*: the Ψ fine-tuned on that held-out style (``RUN/model-<NAME>.npz``, written by
  ``minifilm finetune``),

embedded with the NumPy t-SNE of ``minifilm/evaluation/tsne.py``. Reported per held-out style: the
mean silhouette of its clips among all shown styles, in the 2-D embedding and in the full FiLM space
(2,048 numbers in the paper), before and after. The target: higher after, for every held-out style.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Dict, Sequence

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from minifilm.evaluation.metrics import silhouette_samples  # noqa: E402
from minifilm.evaluation.tsne import tsne  # noqa: E402


def pick_clips(clip_style: np.ndarray, style_ids: Sequence[int], per_style: int) -> np.ndarray:
    """Indices of up to ``per_style`` clips of each style (evenly spaced through its clips, so they
    come from all its files), in the order of ``style_ids``."""
    clip_style = np.asarray(clip_style)
    out = []
    for s in style_ids:
        idx = np.flatnonzero(clip_style == s)
        if len(idx) == 0:
            raise ValueError(f"pick_clips: style id {s} has no clips in the data set")
        take = np.unique(np.linspace(0, len(idx) - 1, min(per_style, len(idx))).round().astype(int))
        out.append(idx[take])
    return np.concatenate(out)


def held_silhouettes(codes: np.ndarray, labels: np.ndarray, held: Sequence, seed: int = 0,
                     perplexity: float = 30.0, iters: int = 1000) -> dict:
    """t-SNE of the codes (N, D) and the mean silhouette of each held-out label's points, in 2-D
    and in the full space: {"embedding": (N, 2), "2d": {label: s}, "full": {label: s}}."""
    labels = np.asarray(labels)
    Y = tsne(codes, perplexity=perplexity, iters=iters, seed=seed)
    flat, full = silhouette_samples(Y, labels), silhouette_samples(codes, labels)
    return {"embedding": Y, "2d": {h: float(flat[labels == h].mean()) for h in held},
            "full": {h: float(full[labels == h].mean()) for h in held}}


def compare(before: dict, after: Dict[str, dict], held: Sequence[str]) -> list:
    """Rows (style, 2-D before, 2-D after, full before, full after, higher after in both)."""
    rows = []
    for h in held:
        b2, a2 = before["2d"][h], after[h]["2d"][h]
        bf, af = before["full"][h], after[h]["full"][h]
        rows.append(dict(style=h, before_2d=b2, after_2d=a2, before_full=bf, after_full=af,
                         higher=bool(a2 > b2 and af > bf)))
    return rows


def _tuned_model(path: Path):
    from minifilm.train.checkpoint import build_style_model, load_checkpoint, load_model_arrays
    meta, arrays = load_checkpoint(path)
    model = build_style_model(meta)
    load_model_arrays(model, arrays, path)
    return model


def draw(panels, labels, names, held, path: Path) -> None:
    from minifilm.files import atomic_path
    from minifilm.viewer.deps import pyplot
    plt = pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.2), squeeze=False)
    cmap = plt.get_cmap("tab20")
    dark = ["black", "crimson", "navy", "darkgreen", "darkorange", "purple"]     # the held-out styles
    held_colour = {h: dark[i % len(dark)] for i, h in enumerate(n for n in names if n in held)}
    for ax, (title, Y) in zip(axes[0], panels):
        for k, name in enumerate(names):
            m = labels == k
            big = name in held
            ax.scatter(Y[m, 0], Y[m, 1], s=40 if big else 8, marker="*" if big else "o",
                       color=held_colour[name] if big else cmap(k % 20), label=name if big else None,
                       alpha=1.0 if big else 0.6)
        ax.set_title(title, fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    axes[0][0].legend(fontsize=7, loc="best")
    with atomic_path(path, "--png") as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", type=Path, required=True, help="run folder, with model-<NAME>.npz per held-out style")
    ap.add_argument("--data", type=Path, required=True, help="data set (folder or manifest) holding every style")
    ap.add_argument("--held", nargs="+", required=True, help="held-out style names (fine-tuned into the run)")
    ap.add_argument("--trained", nargs="+", help="trained styles to show (default: the run's first 15)")
    ap.add_argument("--clips-per-style", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0, help="the data set's split seed")
    ap.add_argument("--tsne-seeds", type=int, nargs="+", default=[0],
                    help="t-SNE seeds: the 2-D silhouettes are reported per seed (few points make them noisy)")
    ap.add_argument("--perplexity", type=float, default=30.0)
    ap.add_argument("--iters", type=int, default=1000)
    ap.add_argument("--cache", type=Path, help="data set cache folder (default: build without caching)")
    ap.add_argument("--split", choices=("segments", "files"), default="segments",
                    help="how the data set is split (its training clips are embedded)")
    ap.add_argument("--png", type=Path, help="draw the embeddings (needs matplotlib)")
    ap.add_argument("--json", type=Path, help="write the silhouettes as JSON")
    a = ap.parse_args(argv)

    from minifilm.dataset.build import build_dataset
    from minifilm.evaluation.compare_tools import film_codes
    from minifilm.pipeline.run_folder import RunFolder

    run = RunFolder.load(a.run)
    model, stats = run.model_and_stats()
    trained = a.trained or [n for n in run.styles().names if n not in a.held][:15]
    clip_seconds = model.config.clip_frames / run.fps
    ds = build_dataset(a.data, cache_dir=a.cache, progress=False, clip_seconds=clip_seconds,
                       clip_stride_seconds=clip_seconds / 2, seed=a.seed, split_unit=a.split)
    names = list(trained) + list(a.held)
    missing = [n for n in names if n not in ds.styles]
    if missing:
        raise SystemExit(f"error: {a.data} has no style {missing}; its styles: {ds.styles}")
    # the clips of every split: Ψ is only read here, and a data set of short files has few training clips
    splits = [ds.split(n) for n in ("train", "val", "test")]
    all_clips = np.concatenate([sp.clips for sp in splits])
    all_style = np.concatenate([sp.clip_style for sp in splits])
    idx = pick_clips(all_style, [ds.styles.index(n) for n in names], a.clips_per_style)
    clips = stats.normalize_clip(all_clips[idx], ds.layout.x_joints).astype(np.float32)
    order = {ds.styles.index(n): k for k, n in enumerate(names)}
    labels = np.array([order[s] for s in all_style[idx]])
    held_ids = [names.index(h) for h in a.held]

    codes_before = film_codes(model, clips)
    codes_after = {k: film_codes(_tuned_model(a.run / f"model-{h}.npz"), clips) for h, k in zip(a.held, held_ids)}
    print(f"{len(names)} styles x up to {a.clips_per_style} clips ({len(idx)} codes); t-SNE perplexity "
          f"{a.perplexity:g}, {a.iters} iterations")
    print("| held-out style | t-SNE seed | silhouette 2-D before | after | full space before | after | higher after |")
    print("|---|---|---|---|---|---|---|")
    rows = []
    for ts in a.tsne_seeds:
        before = held_silhouettes(codes_before, labels, held_ids, ts, a.perplexity, a.iters)
        after = {k: held_silhouettes(c, labels, [k], ts, a.perplexity, a.iters) for k, c in codes_after.items()}
        for r in compare(before, after, held_ids):
            rows.append(dict(r, tsne_seed=ts))
            print(f"| {names[r['style']]} | {ts} | {r['before_2d']:.2f} | {r['after_2d']:.2f} | "
                  f"{r['before_full']:.2f} | {r['after_full']:.2f} | {'yes' if r['higher'] else 'NO'} |")
    if a.json:
        from minifilm.files import atomic_write_text
        atomic_write_text(a.json, json.dumps([dict(r, style=names[r["style"]]) for r in rows], indent=1))
    if a.png:
        panels = [("before fine-tuning", before["embedding"])] + [
            (f"after fine-tuning on {names[k]}", after[k]["embedding"]) for k in held_ids]
        draw(panels, labels, names, set(a.held), a.png)
        print(f"figure -> {a.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
