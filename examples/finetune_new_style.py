"""Learn a new style by fine-tuning only the FiLM generator Ψ (Sec. 5.3.2, Figure 11).

    python examples/finetune_new_style.py                      # synthetic data, hold out Drunk
    python examples/finetune_new_style.py --holdout Swimming   # another held-out style
    python examples/finetune_new_style.py --data DIR           # your own <Style>_<Gait>.bvh folder
    python examples/finetune_new_style.py --quick              # a miniature of the same run

About a minute on 2 cores (OPENBLAS_NUM_THREADS=1 helps a lot when other jobs share the machine).

Steps:
 1. data:      the synthetic set (as examples/train_small.py makes it) or --data; one style is held
               out: the normalisation statistics and the training see only the other styles;
 2. train:     a small LPN + FiLM model on the seen styles;
 3. before:    test error of the held-out style with Ψ as trained (it has never seen that style);
 4. fine-tune: Ω and Φ frozen, only Ψ trained on the held-out style's training frames
               (minifilm.train.finetune.finetune), timed;
 5. after:     test error of the held-out style again, and of the seen styles (Ψ changed for them too);
               FiLM-code separation (silhouette of Ψ(clip) grouped by style, all styles, before and
               after) and a PCA plot of the codes.
Outputs in --out (default runs/finetune_new_style): base.npz, finetuned.npz, film_codes.png.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from minifilm.cli import report_errors
from minifilm.dataset.build import build_dataset
from minifilm.evaluation.compare_report import draw_film_codes
from minifilm.evaluation.compare_tools import film_codes, film_separation, fit_stats, style_subset
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.synthetic import generator as synthetic
from minifilm.train.finetune import finetune
from minifilm.train.trainer import TrainConfig, Trainer
from minifilm.viewer.deps import pyplot, save_figure

SEED = 0
OUT = Path("runs/finetune_new_style")
HOLDOUT = "Drunk"
GAITS = ("FW", "BW", "FR", "SW", "TR", "ID")
SECONDS = 10.0                     # synthetic seconds per style and gait
FPS = 30                           # resampled from the generator's 60 fps: half the work, same motion
CLIP_SECONDS = 2.0
EPOCHS = 4                         # training on the seen styles
FINETUNE_EPOCHS = 6                # fine-tuning Ψ on the held-out style (an epoch is 1/S as long)
BATCH_SIZE = 32
LEARNING_RATE = 1e-3
MODEL = dict(dropout=0.3)            # overrides of ModelConfig.small, the main job's model
QUICK = dict(SECONDS=6.0, GAITS=("FW", "FR"), EPOCHS=1, FINETUNE_EPOCHS=1, STYLES=synthetic.STYLES[:4],
             HOLDOUT=synthetic.STYLES[3], MODEL=dict(MODEL, hidden=16, conv_filters=4, film_dense=16,
                                                     n_experts=2, gating_hidden=8))


def log(msg=""):
    print(msg, flush=True)


def make_dataset(data, out, styles, gaits, seconds, seed, fps):
    if data is None:
        data = out / "data"
        clips = synthetic.default_dataset(seed=seed, seconds=seconds, styles=styles, gaits=gaits)
        synthetic.write_dataset(data, clips)
        log(f"[data] {len(clips)} synthetic files written to {data}")
    ds = build_dataset(data, cache_dir=out / "cache", progress=False, clip_seconds=CLIP_SECONDS,
                       clip_stride_seconds=CLIP_SECONDS / 2, seed=seed, fps=fps)
    log(f"[data] {len(ds.train)} training frames, {len(ds.styles)} styles at {ds.fps:g} fps")
    return ds


def run(data=None, out=OUT, holdout=HOLDOUT, quick=False, seed=SEED, epochs=None, finetune_epochs=None,
        fps=FPS):
    """The whole experiment; returns a dict of the numbers it printed."""
    s = dict(SECONDS=SECONDS, GAITS=GAITS, EPOCHS=EPOCHS, FINETUNE_EPOCHS=FINETUNE_EPOCHS,
             STYLES=synthetic.STYLES, HOLDOUT=holdout, MODEL=MODEL)
    if quick:
        s.update(QUICK)
    if epochs is not None:
        s["EPOCHS"] = epochs
    if finetune_epochs is not None:
        s["FINETUNE_EPOCHS"] = finetune_epochs
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ds = make_dataset(data, out, s["STYLES"], s["GAITS"], s["SECONDS"], seed, fps)
    holdout = s["HOLDOUT"] if data is None else holdout
    if holdout not in ds.styles:
        raise SystemExit(f"--holdout {holdout!r} is not a style of the dataset ({', '.join(ds.styles)})")
    seen = [st for st in ds.styles if st != holdout]
    norm = fit_stats(ds, seen)
    seen_train, seen_val, seen_test = (style_subset(ds, sp, seen, norm) for sp in ("train", "val", "test"))
    new_train, new_test = (style_subset(ds, sp, [holdout], norm) for sp in ("train", "test"))

    # 2. train on the seen styles
    layout = ds.layout
    config = ModelConfig.small(layout.x_dim, layout.z_dim, seen_train.clips.shape[1], layout.clip_dim,
                               phase_dim=layout.phase_dim, **s["MODEL"])
    model = StyleModel(config, np.random.default_rng(seed))
    tcfg = TrainConfig(epochs=s["EPOCHS"], batch_size=BATCH_SIZE, lr=LEARNING_RATE, seed=seed, progress=False)
    trainer = Trainer(model, norm, tcfg, positions_idx=layout.joint_columns("z", "position"),
                      parents=np.asarray(layout.parents), style_names=seen)
    t0 = time.perf_counter()
    trainer.fit(seen_train, seen_val)
    train_seconds = time.perf_counter() - t0
    trainer.save(out / "base.npz")
    log(f"[train] {s['EPOCHS']} epochs on {len(seen)} seen styles ({trainer.step} steps) in {train_seconds:.0f} s")

    # 3-5. before, fine-tune, after
    before_new = trainer.evaluate(new_test)
    before_seen = trainer.evaluate(seen_test)
    t0 = time.perf_counter()
    ft = finetune(out / "base.npz", new_train, config=TrainConfig(epochs=s["FINETUNE_EPOCHS"], batch_size=BATCH_SIZE,
                                                                   lr=LEARNING_RATE, seed=seed + 1, progress=False),
                  style_names=[holdout])
    finetune_seconds = time.perf_counter() - t0
    ft.save(out / "finetuned.npz")
    after_new = ft.evaluate(new_test)
    after_seen = ft.evaluate(seen_test)
    log(f"[finetune] Ψ only, {s['FINETUNE_EPOCHS']} epochs ({ft.step} steps) on {len(new_train)} frames of "
        f"{holdout}: {finetune_seconds:.1f} s")
    log(f"    {'test MSE / BLL':<28} {'before':>15} {'after':>15}")
    log(f"    {'held-out ' + holdout:<28} {before_new['mse']:>7.4f}/{before_new['bll']:<7.4f} "
        f"{after_new['mse']:>7.4f}/{after_new['bll']:<7.4f}")
    log(f"    {'seen styles (mean)':<28} {before_seen['mse']:>7.4f}/{before_seen['bll']:<7.4f} "
        f"{after_seen['mse']:>7.4f}/{after_seen['bll']:<7.4f}")

    # FiLM codes of the training clips of every style (seen + held out), before and after
    all_styles = seen + [holdout]
    clips = style_subset(ds, "train", all_styles, norm)
    sep = {}
    for tag, m in (("before", model), ("after", ft.model)):
        sep[tag] = film_separation(film_codes(m, clips.clips), clips.clip_style, focus=len(seen))
    log(f"[film] silhouette of Ψ(clip) by style ({len(clips.clips)} clips), all styles / {holdout} alone: "
        f"before {sep['before']['silhouette']:.3f} / {sep['before']['focus_silhouette']:.3f}, "
        f"after {sep['after']['silhouette']:.3f} / {sep['after']['focus_silhouette']:.3f}")
    plot_codes(sep, clips.clip_style, all_styles, holdout, out / "film_codes.png")
    return {"holdout": holdout, "seen": seen, "train_seconds": train_seconds, "train_steps": trainer.step,
            "finetune_seconds": finetune_seconds, "finetune_steps": ft.step,
            "before": {"new": before_new, "seen": before_seen}, "after": {"new": after_new, "seen": after_seen},
            "separation": {k: {kk: vv for kk, vv in v.items() if kk not in ("embedding",)} for k, v in sep.items()},
            "embedding": {k: v["embedding"] for k, v in sep.items()}, "labels": clips.clip_style,
            "styles": all_styles}


def plot_codes(sep, labels, names, holdout, path):
    """Two PCA panels (before / after fine-tuning) of the FiLM codes, coloured by style."""
    try:
        plt = pyplot()
    except ImportError as e:
        log(f"[plot] no PNG: {e}")
        return
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.5))
    draw_film_codes(axes, sep, labels, names, holdout)
    fig.tight_layout()
    log(f"[plot] {save_figure(fig, path, dpi=90)}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, help="folder of <Style>_<Gait>.bvh files (default: synthetic)")
    parser.add_argument("--holdout", default=HOLDOUT, help=f"style held out of training (default {HOLDOUT})")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--epochs", type=int, help=f"training epochs (default {EPOCHS})")
    parser.add_argument("--finetune-epochs", type=int, help=f"fine-tuning epochs (default {FINETUNE_EPOCHS})")
    parser.add_argument("--fps", type=float, default=FPS, help=f"resample to this rate (default {FPS})")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--quick", action="store_true", help="a miniature (4 styles, tiny model, 1 epoch)")
    a = parser.parse_args(argv)
    return run(a.data, a.out, a.holdout, a.quick, a.seed, a.epochs, a.finetune_epochs, a.fps)


if __name__ == "__main__":
    report_errors(lambda: main() and 0)
