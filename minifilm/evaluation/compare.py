"""Figure 10 and the style metrics of Sec. 5: train the seven variants with one budget on one data
set and compare them (the paper's Sec. 5.2, Figure 10 and Table 2).

    minifilm compare                        # synthetic data (generated here)
    minifilm compare --data /path/to/bandai2 --split-files --holdout feminine
    minifilm compare --variants "LPN FiLM,PFNN one-hot" --budget-steps 50

The command's options are defined in minifilm/cli/compare.py; ``run(args)`` reads them.

One style is held out of training (--holdout). On held-out test frames of the seen styles:
  - test MSE and bone-length loss on the 324 motion outputs every variant predicts (Figure 10),
    overall and per style;
  - style recognition of generated motion: a classifier (minifilm.evaluation.style_classifier) trained on
    the dataset's training rows, applied to 10-second rollouts of every seen style (its accuracy
    on held-out real rows is the ceiling);
  - foot sliding and bone-length variation of those rollouts;
  - interpolation smoothness (Figure 8): the classifier's probability of style B along a blend
    from style A to B, for FiLM (blended FiLM vectors) and one-hot (blended one-hot vectors);
  - FiLM-code separation (Figure 11): silhouette of Ψ(clip) per style before and after
    fine-tuning Ψ alone on the held-out style (LPN FiLM).
Writes reports/compare_<data>.md and PNG plots next to it. The defaults (2500 steps per variant,
one extra seed) take about 12 minutes on synthetic data and 8.5 on Bandai-2 on a shared 2-core
machine with OPENBLAS_NUM_THREADS=1 (multithreaded BLAS thrashes when the cores are busy).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from minifilm.baselines.runtime import VariantRuntime
from minifilm.baselines.variant_data import end_effector_indices, variant_data
from minifilm.baselines.variants import VARIANTS, build_variant
from minifilm.dataset.build import build_dataset, resolve_files
from minifilm.errors import InputError
from minifilm.evaluation.compare_report import write_report
from minifilm.evaluation.compare_tools import (film_codes, film_separation, fit_stats, select_styles, motion_errors,
                                               style_subset)
from minifilm.evaluation.convergence import train_with_curve, validation_subset
from minifilm.evaluation.metrics import interpolation_smoothness, rollout_quality
from minifilm.evaluation.style_classifier import classify_rollout, train_style_classifier
from minifilm.model.config import ModelConfig
from minifilm.motion.skeletons import BUILTIN_SKELETONS
from minifilm.runtime.control import make_script
from minifilm.runtime.controller import Controller, NonFiniteOutputError
from minifilm.synthetic import generator as synthetic
from minifilm.train.finetune import finetune
from minifilm.train.trainer import TrainConfig, Trainer

SYNTH_HOLDOUT = "Drunk"
#: the main job's model (ModelConfig.small) with the paper's dropout, for every variant alike
MODEL = dict(dropout=0.3)
#: a miniature of it (tests and smoke runs)
TINY_MODEL = dict(MODEL, hidden=16, conv_filters=4, film_dense=16, n_experts=2, gating_hidden=8)


def log(msg=""):
    print(msg, flush=True)


# ---------------------------------------------------------------------------- data
def load_data(args):
    cache = Path(args.work) / "cache"
    if args.data in (None, "synthetic"):
        folder = Path(args.work) / "synthetic"      # made once; delete it after changing --styles etc.
        if not any(folder.glob("*.bvh")):
            clips = synthetic.default_dataset(seed=args.seed, seconds=args.seconds, styles=args.styles,
                                              gaits=args.gaits)
            synthetic.write_dataset(folder, clips)
        name = "synthetic"
        extra = {}
    else:
        name = Path(args.data).name
        folder = Path(args.data)
        if not folder.is_dir():
            raise FileNotFoundError(f"--data {folder}: no such folder (give 'synthetic' or a folder of BVH files)")
        extra = {"split_unit": "files"} if args.split_files else {}
        if args.styles:     # the run's style subset (already checked by run): only its files are read
            folder = [f for f in resolve_files(folder) if f.style in set(args.styles)]
    ds = build_dataset(folder, cache_dir=cache, progress=False, clip_seconds=args.clip_seconds,
                       clip_stride_seconds=args.clip_seconds / 2, seed=args.seed, fps=args.fps, **extra)
    return ds, name


def skeleton_of(ds):
    for sk in BUILTIN_SKELETONS:
        if sk.name == ds.skeleton:
            return sk
    raise ValueError(f"compare: dataset skeleton {ds.skeleton!r} is not a built-in skeleton")


class Context:
    """The data every variant shares: seen / held-out styles, statistics, splits, classifier."""

    def __init__(self, ds, holdout, args):
        self.ds, self.args, self.layout = ds, args, ds.layout
        self.holdout = holdout
        self.seen = [s for s in ds.styles if s != holdout]
        self.norm = fit_stats(ds, self.seen)
        self.data = {sp: style_subset(ds, sp, self.seen, self.norm) for sp in ("train", "test")}
        # the fixed validation frames every variant's curve is judged on (minifilm/evaluation/convergence.py)
        val_styles = [s for s in self.seen if np.any(ds.val.style == ds.styles.index(s))]
        self.data["val"] = validation_subset(style_subset(ds, "val", val_styles or self.seen, self.norm)
                                             if val_styles else self.data["test"])
        self.new_train = style_subset(ds, "train", [holdout], self.norm) if holdout else None
        self.all_train = style_subset(ds, "train", self.seen + ([holdout] if holdout else []), self.norm)
        self.skeleton = skeleton_of(ds)
        self.end_effectors = end_effector_indices(self.layout, self.skeleton)
        names = list(self.layout.joint_names)
        # the feet's phase bones (exported joints; the contact sensors are End Sites): [right, left],
        # the order of the contact columns
        self.toes = [names.index(self.skeleton.phase_bones[3]), names.index(self.skeleton.phase_bones[2])]
        t0 = time.perf_counter()
        self.classifier, self.clf_info = train_style_classifier(ds, seed=args.seed)
        log(f"[classifier] {self.clf_info['n_train']} training windows; held-out real accuracy "
            f"{self.clf_info['heldout_acc']:.3f} ({self.clf_info['n_heldout']} windows), "
            f"{time.perf_counter() - t0:.0f} s")


# ---------------------------------------------------------------------------- one variant
def model_config(ctx, sizes):
    """The main job's model for this data set, with ``sizes`` overriding its sizes."""
    L = ctx.layout
    return ModelConfig.small(L.x_dim, L.z_dim, ctx.data["train"].clips.shape[1], L.clip_dim,
                             phase_dim=L.phase_dim, **sizes)


def steps_per_epoch(style, batch_size):
    counts = np.bincount(style)
    counts = counts[counts > 0]
    size = min(batch_size, counts.min())
    return int(counts.min() // size * len(counts))


def train_variant(name, ctx, epochs, seed=None, eval_every=None):
    """Train one variant (model initialisation and batch order from `seed`, default --seed) and
    measure its test errors; the validation loss is recorded every `eval_every` steps (default: a
    tenth of the budget) and, with --until-flat, training goes on in whole epochs until it is flat."""
    a, L = ctx.args, ctx.layout
    seed = a.seed if seed is None else seed
    model = build_variant(name, model_config(ctx, a.model), np.random.default_rng(seed), n_styles=len(ctx.seen))
    vtrain, info = variant_data(name, ctx.data["train"], L, ctx.norm, ctx.end_effectors)
    vtest, _ = variant_data(name, ctx.data["test"], L, ctx.norm, ctx.end_effectors, reference=info)
    vval, _ = variant_data(name, ctx.data["val"], L, ctx.norm, ctx.end_effectors, reference=info)
    trainer = Trainer(model, ctx.norm, TrainConfig(epochs=epochs, batch_size=a.batch_size, lr=a.lr, seed=seed,
                                                   progress=False),
                      positions_idx=L.joint_columns("z", "position"), parents=np.asarray(L.parents),
                      style_names=ctx.seen)
    t0 = time.perf_counter()
    spe = steps_per_epoch(vtrain.style, a.batch_size)
    every = eval_every or max(1, round(epochs * spe / 10))
    max_epochs = max(epochs, math.ceil(a.max_steps / spe)) if getattr(a, "max_steps", None) else 4 * epochs
    curve = train_with_curve(trainer, vtrain, vval, epochs, every, until_flat=getattr(a, "until_flat", False),
                             max_epochs=max_epochs)
    seconds = time.perf_counter() - t0
    errors = motion_errors(model, vtest, L, ctx.norm, L.z_phases.start, seed=a.seed,
                           style_kw=getattr(model, "takes_style_ids", False))
    n_params = sum(ps.size for ps in model.parameter_sets())
    return {"trainer": trainer, "info": info, "seconds": seconds, "steps": trainer.step, "errors": errors,
            "params": n_params, "final_train_loss": trainer.history[-1]["train"]["loss"], "curve": curve}


def style_conditions(model, ctx):
    """Per seen style: the FiLM vector (mean Ψ over its training clips) or the style id."""
    if getattr(model, "takes_style_ids", False):
        return np.arange(len(ctx.seen))
    tr = ctx.data["train"]
    return np.stack([film_codes(model, tr.clips[tr.clip_style == s]).mean(axis=0) for s in range(len(ctx.seen))])


def controller_for(model, info, ctx):
    return Controller(VariantRuntime(model, ctx.norm, ctx.layout, info), ctx.layout, fps=ctx.ds.fps)


def run_rollouts(controller, cond, ids, ctx, seconds):
    """One character per row of `cond` along a figure-eight. ids=True: cond holds style ids or
    one-hot weights, handed to the network every frame; else (B, 4H) FiLM vectors."""
    n = int(round(seconds * ctx.ds.fps))
    scripts = [make_script("figure8", seconds) for _ in range(len(cond))]
    try:
        with np.errstate(all="ignore"):     # a diverging variant overflows; the controller stops it
            return controller.run(scripts, n, (lambda k: cond) if ids else cond)
    except NonFiniteOutputError:
        return None                     # diverged(None): reported as such, not an error of the comparison


def style_recognition(model, info, ctx):
    """Rollouts of every seen style: classifier accuracy per style, foot sliding, bone variation."""
    a = ctx.args
    cond = style_conditions(model, ctx)
    ids = getattr(model, "takes_style_ids", False)
    rollout = run_rollouts(controller_for(model, info, ctx), cond, ids, ctx, a.rollout_seconds)
    if diverged(rollout):
        return {"diverged": True, "accuracy": None, "per_style": {n: None for n in ctx.seen},
                "foot_sliding": None, "foot_sliding_cm_s": None, "path_error": None,
                "direction_error": None, "bone_cv_mean": None, "bone_cv_max": None, "speed": None}
    w, s = ctx.clf_info["window"], ctx.clf_info["stride"]
    probs = classify_rollout(ctx.classifier, ctx.ds, rollout, window=w, stride=s)     # (B, M, classes)
    target = np.array([ctx.ds.styles.index(n) for n in ctx.seen])
    hit = probs.argmax(axis=2) == target[:, None]
    per_style = {n: float(hit[b].mean()) for b, n in enumerate(ctx.seen)}
    quality = rollout_quality(rollout, ctx.layout.parents, ctx.toes)
    return {"diverged": False, "accuracy": float(hit.mean()), "per_style": per_style, **quality,
            "speed": float(np.mean([m["speed"] for m in rollout.metrics(ctx.layout.parents)]))}


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
    """Classifier probability of style B along a blend A -> B (FiLM vectors or one-hot weights)."""
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
    return {"weights": w, "score": score, **interpolation_smoothness(w, score)}


def finetune_separation(result, ctx):
    """Fine-tune Ψ alone on the held-out style; FiLM-code silhouette before and after."""
    a = ctx.args
    trainer = result["trainer"]
    path = Path(a.work) / "lpn_film_base.npz"
    trainer.save(path)
    epochs = max(1, math.ceil(a.finetune_steps / steps_per_epoch(ctx.new_train.style, a.batch_size)))
    new_test = style_subset(ctx.ds, "test", [ctx.holdout], ctx.norm)
    n_motion = ctx.layout.z_phases.start
    before_new = motion_errors(trainer.model, new_test, ctx.layout, ctx.norm, n_motion, seed=a.seed)
    t0 = time.perf_counter()
    ft = finetune(path, ctx.new_train, config=TrainConfig(epochs=epochs, batch_size=a.batch_size, lr=a.lr,
                                                          seed=a.seed + 1, progress=False),
                  style_names=[ctx.holdout])
    seconds = time.perf_counter() - t0
    after_new = motion_errors(ft.model, new_test, ctx.layout, ctx.norm, n_motion, seed=a.seed)
    labels = ctx.all_train.clip_style
    focus = len(ctx.seen)
    sep = {"before": film_separation(film_codes(trainer.model, ctx.all_train.clips), labels, focus),
           "after": film_separation(film_codes(ft.model, ctx.all_train.clips), labels, focus)}
    seen_after = motion_errors(ft.model, ctx.data["test"], ctx.layout, ctx.norm, n_motion, seed=a.seed)
    return {"separation": sep, "labels": labels, "seconds": seconds, "steps": ft.step,
            "before_new": before_new, "after_new": after_new, "seen_after": seen_after}


def flat_line(curve) -> str:
    """One log line on a validation curve (minifilm/evaluation/convergence.py)."""
    verdict = {True: "flat", False: "still falling", None: "not judged"}[curve["flat"]]
    return (f"validation loss {curve['loss'][0]:.4f} -> {curve['loss'][-1]:.4f} in {curve['steps'][-1]} steps; "
            f"last 20 % improved it {100 * curve['improvement']:.1f} %: {verdict}")


# ---------------------------------------------------------------------------- the run
def check_styles(styles, holdout: str, interpolate) -> tuple:
    """InputError unless the held-out style and the two interpolated ones are among ``styles`` (the
    interpolated ones seen in training); returns the interpolation pair. Before any work."""
    if holdout not in styles:
        raise InputError(f"compare: --holdout {holdout!r} is not a style of the data ({', '.join(styles)})")
    seen = [s for s in styles if s != holdout]
    if interpolate is None:
        if len(seen) < 2:
            raise InputError(f"compare: the data has {len(styles)} style(s); at least three are needed "
                             "(one held out, two to interpolate between)")
        return seen[0], seen[1]
    bad = [x for x in interpolate if x not in seen]
    if bad:
        raise InputError(f"compare: --interpolate {','.join(interpolate)}: not seen in training: "
                         f"{', '.join(map(repr, bad))} (the seen styles: {', '.join(seen)})")
    return tuple(interpolate)


def check_variants(names) -> list:
    variants = [v.strip() for v in names.split(",")] if names else list(VARIANTS)
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown or not variants:
        raise InputError(f"compare: unknown variant(s) {unknown}; choose from {list(VARIANTS)}")
    return variants


def run(args):
    t_start = time.perf_counter()
    variants = check_variants(args.variants)
    synthetic_data = args.data in (None, "synthetic")
    if not synthetic_data and not Path(args.data).is_dir():
        raise FileNotFoundError(f"--data {args.data}: no such folder (give 'synthetic' or a folder of BVH files)")
    # the style names, from the file names, before anything is generated or built (as the dataset lists them)
    available = synthetic.STYLES if synthetic_data else {f.style for f in resolve_files(args.data)}
    keep = [x for x in [args.holdout] + (args.interpolate.split(",") if args.interpolate else []) if x]
    try:
        styles = select_styles(available, args.styles, keep)
    except ValueError as e:
        raise InputError(f"compare: {e}") from None
    if args.styles:
        args.styles = styles if args.styles[0].strip().isdigit() else [x.strip() for x in args.styles]
    holdout = args.holdout or (SYNTH_HOLDOUT if synthetic_data and SYNTH_HOLDOUT in styles else styles[-1])
    pa, pb = check_styles(styles, holdout, args.interpolate.split(",") if args.interpolate else None)
    Path(args.work).mkdir(parents=True, exist_ok=True)
    ds, name = load_data(args)
    log(f"[data] {name}: {len(ds.styles)} styles, {len(ds.train)} training frames at {ds.fps:g} fps; "
        f"held out: {holdout}")
    ctx = Context(ds, holdout, args)
    spe = steps_per_epoch(ctx.data["train"].style, args.batch_size)
    epochs = max(1, math.ceil(args.budget_steps / spe))
    log(f"[budget] {args.budget_steps} steps asked -> {epochs} epoch(s) of {spe} style-balanced batches of "
        f"{args.batch_size} = {epochs * spe} steps per variant")
    results = {}
    for v in variants:
        r = train_variant(v, ctx, epochs)
        log(f"[train] {v:<13} {r['params']:>9,} params  {r['steps']} steps in {r['seconds']:.0f} s  "
            f"test MSE {r['errors']['mse']:.4f}  BLL {r['errors']['bll']:.4f}")
        t0 = time.perf_counter()
        r["rollout"] = style_recognition(r["trainer"].model, r["info"], ctx)
        if getattr(r["trainer"].model, "modulation", "film") in ("film", "onehot"):
            r["interp"] = interpolation(r["trainer"].model, r["info"], ctx, pa, pb)
        q, i = r["rollout"], r.get("interp", {})
        log("        rollouts: " + ("diverged" if q["diverged"] else
                                    f"style accuracy {q['accuracy']:.3f}, foot sliding {q['foot_sliding']:.3f} m/s, "
                                    f"bone cv {q['bone_cv_mean']:.4f}")
            + ("" if not i else ", interpolation diverged" if i.get("diverged") else
               f", interpolation score {i['score'][0]:.2f} -> {i['score'][-1]:.2f}, monotonicity "
               f"{i['monotonicity']:.2f}") + f" ({time.perf_counter() - t0:.0f} s)")
        r["seed_errors"], r["curves"] = [r["errors"]], {args.seed: r["curve"]}
        log(f"        {flat_line(r['curve'])}")
        for seed in args.extra_seeds:          # test errors only: how much of a difference is noise
            extra = train_variant(v, ctx, epochs, seed=seed)
            e = extra["errors"]
            r["seed_errors"].append(e)
            r["curves"][seed] = extra["curve"]
            log(f"        seed {seed}: test MSE {e['mse']:.4f}  BLL {e['bll']:.4f}; {flat_line(extra['curve'])}")
        results[v] = r
    ft = None
    if "LPN FiLM" in results and ctx.new_train is not None:
        ft = finetune_separation(results["LPN FiLM"], ctx)
        sb, sa = ft["separation"]["before"], ft["separation"]["after"]
        log(f"[finetune] Ψ only on {holdout}: {ft['steps']} steps in {ft['seconds']:.0f} s; held-out test MSE "
            f"{ft['before_new']['mse']:.4f} -> {ft['after_new']['mse']:.4f}; silhouette {holdout} "
            f"{sb['focus_silhouette']:.3f} -> {sa['focus_silhouette']:.3f} (all styles {sb['silhouette']:.3f} -> "
            f"{sa['silhouette']:.3f})")
    total = time.perf_counter() - t_start
    # the sizes the variants were built with (the main job's model with args.model's changes)
    cfg = model_config(ctx, args.model)
    sizes = {k: getattr(cfg, k) for k in ("hidden", "n_experts", "conv_filters", "film_dense", "dropout")}
    path = write_report(Path(args.out), name, ctx, results, ft, dict(epochs=epochs, steps_per_epoch=spe,
                        total_seconds=total, interpolate=(pa, pb), sizes=sizes))
    log(f"[report] {path} ({total:.0f} s in all)")
    return {"name": name, "results": results, "finetune": ft, "report": path, "ctx": ctx}
