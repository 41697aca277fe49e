"""How far can Ψ-only fine-tuning go? Ceilings for the new style of studies/new_style.py.

    python studies/new_style.py --all --epochs 30 --work runs/new_style     # first: runs and fine-tuned styles
    python studies/new_style_ceiling.py --work runs/new_style --all [--oracle]

At run time a style is ONE FiLM vector (Sec. 4.4), so whatever Ψ-only fine-tuning does, the new
style's motion is Φ(x; Ω(p), f) for a single f (4 x hidden numbers). This script bounds what any
f can do with the run's frozen Ω and Φ, for each held-out style of a benchmark work folder:

* sanity: the classifier (trained on the run's data plus the held-out style's other files, as in
  new_style.py) on the fine-tuning clip itself, and the new style's recognition for classifier
  seeds 0-3 (is the measure stable?);
* teacher-forced: the clip's rows replayed one frame at a time (real input x, p). Φ's one-step
  predictions of the next pose (z's joint block) are cut into windows and classified, with the
  new style's vector, with each trained style's vector, and with the best single vector found by
  optimising f itself (Adam on MSE + BLL of the clip's rows, Φ and Ω frozen: no recipe of Ψ
  fine-tuning can reach a lower teacher-forced loss with one vector);
* rollout: the recognition of the optimised vector's generated motion (10 s figure-eight);
* --oracle: a search over f that maximises the classifier's own probability of the new style in
  generated motion (cross-entropy method, 15 x 32 rollouts). Not a method (it uses the
  classifier): it shows what recognition alone can be made to say. Printed beside it, the largest
  deviation of the motion's window statistics from the real held-out files', in standard
  deviations of the classifier's inputs (real files of the style sit within about 2).
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")     # before numpy
ROOT = Path(__file__).resolve().parents[1]

import numpy as np  # noqa: E402

from minifilm.dataset.build import build_dataset  # noqa: E402
from minifilm.dataset.manifest import bandai_files  # noqa: E402
from minifilm.evaluation.style_classifier import (classify_rollout, cut_windows, rollout_blocks,  # noqa: E402
                                                  split_windows, train_style_classifier, window_summary)
from minifilm.pipeline.new_style import clip_training_data, read_clip  # noqa: E402
from minifilm.pipeline.run_folder import RunFolder  # noqa: E402
from minifilm.runtime.control import figure_eight  # noqa: E402
from minifilm.train.trainer import TrainConfig, Trainer  # noqa: E402

from new_style import DATA, clip_files  # noqa: E402


def rollouts(run: RunFolder, style: str, films: np.ndarray, seconds: float = 10.0):
    """B characters along the benchmark's figure-eight from the style's start frame: films (B, D)."""
    x0, p0 = run.start_states([style] * len(films))
    return run.controller().run([figure_eight(seconds) for _ in films], int(round(seconds * run.fps)),
                                np.asarray(films, np.float32), phases=p0, start_x=x0)


def recognised(clf, info, ds, rollout, style) -> np.ndarray:
    """(B,) fraction of each character's windows classified as ``style``."""
    probs = classify_rollout(clf, ds, rollout, window=info["window"], stride=info["stride"])
    return (probs.argmax(axis=2) == ds.styles.index(style)).mean(axis=1)


def teacher_forced(clf, info, ds, run, stats, model, data, film) -> float:
    """Fraction of windows of Φ's one-step predictions (the clip's real inputs) classified as the
    clip's style; film (D,) or None for the real next frames."""
    z = data.z if film is None else model.forward_with_film(data.x, data.p, film)
    joints = stats.denormalize_z(z)[:, run.layout.z_joints]
    w = cut_windows(ds.stats.normalize_clip(joints, run.layout.x_joints), info["window"], info["stride"])
    return float(np.mean(clf.predict(window_summary(w)) == ds.styles.index(data.style_names[0])))


def optimise_film(trainer, model, data, film, steps: int = 1500, lr: float = 1e-2) -> np.ndarray:
    """Adam on one FiLM vector (D,), full batch, MSE + BLL of ``data``; Ω, Φ untouched."""
    f = np.asarray(film, np.float32).copy()
    m, v = np.zeros_like(f), np.zeros_like(f)
    for k in range(1, steps + 1):
        _, _, dpred = trainer.losses(model.forward_with_film(data.x, data.p, f), data.z)
        _, _, g = model.backward_with_film(dpred)
        m = 0.9 * m + 0.1 * g
        v = 0.999 * v + 0.001 * g * g
        f -= lr * (m / (1 - 0.9 ** k)) / (np.sqrt(v / (1 - 0.999 ** k)) + 1e-8)
    return f


def deviation(clf, info, ds, rollout, style, real_mean):
    """Largest |mean window statistic - the real files' mean| of one character, in the classifier's
    standard deviations, and which statistic."""
    L = ds.layout
    block = ds.stats.normalize_clip(rollout_blocks(rollout), L.x_joints)[0]
    s = (window_summary(cut_windows(block, info["window"], info["stride"])).mean(0) - real_mean) / clf.std
    k = int(np.argmax(np.abs(s)))
    half, (j, c) = k // L.clip_dim, divmod(k % L.clip_dim, 12)
    name = f"{('mean', 'sd')[half]} {L.joint_names[j]} {('position', 'forward', 'up', 'velocity')[c // 3]} {'xyz'[c % 3]}"
    return float(abs(s[k])), name


def oracle(clf, info, ds, run, style, start, generations=15, population=32, seed=0):
    """Cross-entropy search of f maximising the classifier's probability of ``style``."""
    rng = np.random.default_rng(seed)
    lib = run.styles()
    sd = np.stack([lib[n] for n in lib.names if n != style]).std(0) + 1e-3
    mu = np.asarray(start, np.float64)
    for _ in range(generations):
        cand = mu + sd * rng.standard_normal((population, len(mu)))
        probs = classify_rollout(clf, ds, rollouts(run, style, cand), window=info["window"], stride=info["stride"])
        score = probs[:, :, ds.styles.index(style)].mean(1)
        elite = cand[np.argsort(-score)[:population // 4]]
        mu, sd = elite.mean(0), 0.7 * sd + 0.3 * elite.std(0)
    return mu


def one(work: Path, style: str, files, with_oracle: bool) -> None:
    run = RunFolder.load(work / "run")
    ds = build_dataset(work / "all_but_clip.csv", cache_dir=work / "cache", progress=False, clip_seconds=2.0,
                       clip_stride_seconds=1.0, seed=0, split_unit="files")
    clf, info = train_style_classifier(ds, seed=0)
    model, stats = run.model_and_stats()
    trainer = Trainer.resume(run.checkpoint, TrainConfig(progress=False), restore_optimizer=False)
    clip, _ = clip_files([f for f in files if f.style == style], 30.0)
    motions = [read_clip(f.path, run, lambda m: None) for f in clip]
    data, _, _ = clip_training_data(motions, [f.path for f in clip], run, stats, model.config.clip_frames, style)
    lib = run.styles()
    seeds = [recognised(*train_style_classifier(ds, seed=s), ds, rollouts(run, style, lib[style][None]), style)[0]
             for s in range(4)]
    print(f"{style}: classifier on held-out real windows {info['heldout_acc']:.2f}, on the clip "
          f"{teacher_forced(clf, info, ds, run, stats, model, data, None):.2f}; new style's motion recognised "
          f"{seeds[0]:.2f} (classifier seeds 0-3: {min(seeds):.2f}-{max(seeds):.2f})", flush=True)
    loss = lambda f: sum(trainer.losses(model.forward_with_film(data.x, data.p, f), data.z)[:2])  # noqa: E731
    best = optimise_film(trainer, model, data, lib[style])
    tf = {n: teacher_forced(clf, info, ds, run, stats, model, data, lib[n]) for n in lib.names}
    tf["optimised"] = teacher_forced(clf, info, ds, run, stats, model, data, best)
    print(f"    teacher-forced one-step predictions recognised as {style}: "
          + ", ".join(f"{n} {v:.2f}" for n, v in tf.items()), flush=True)
    print(f"    one FiLM vector optimised on the clip: loss {loss(lib[style]):.3f} -> {loss(best):.3f}; its motion "
          f"recognised {recognised(clf, info, ds, rollouts(run, style, best[None]), style)[0]:.2f}", flush=True)
    if with_oracle:
        Xw, y = split_windows(ds.train, ds.layout, ds.stats, info["window"], info["stride"])
        real_mean = window_summary(Xw[y == ds.styles.index(style)]).mean(0)
        f = oracle(clf, info, ds, run, style, lib[style])
        for name, film in (("new style's vector", lib[style]), ("oracle vector", f)):
            r = rollouts(run, style, film[None])
            dev, what = deviation(clf, info, ds, r, style, real_mean)
            print(f"    {name}: recognised {recognised(clf, info, ds, r, style)[0]:.2f}; largest deviation from the "
                  f"real files {dev:.1f} sd ({what})", flush=True)
        Hw, hy = split_windows(ds.val, ds.layout, ds.stats, info["window"], info["stride"])
        s = np.abs((window_summary(Hw[hy == ds.styles.index(style)]).mean(0) - real_mean) / clf.std)
        print(f"    reference: the style's validation files deviate at most {s.max():.1f} sd", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, required=True, help="the --work folder of studies/new_style.py")
    ap.add_argument("--data", type=Path, default=DATA / "bandai2")
    ap.add_argument("--holdout", default="feminine")
    ap.add_argument("--all", action="store_true", help="every held-out style found in --work")
    ap.add_argument("--oracle", action="store_true", help="also search f against the classifier (~1 min)")
    a = ap.parse_args()
    files = bandai_files(a.data)
    styles = sorted(p.name for p in a.work.iterdir() if (p / "run").is_dir()) if a.all else [a.holdout]
    for style in styles:
        one(a.work / style, style, files, a.oracle)


if __name__ == "__main__":
    main()
