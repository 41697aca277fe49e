"""Figure 10 and the style metrics of Sec. 5: train the seven variants with one budget on one data
set and compare them (the paper's Sec. 5.2, Figure 10 and Table 2).

    minifilm compare                        # synthetic data (generated here)
    minifilm compare --data /path/to/bandai2 --split-files --holdout feminine
    minifilm compare --variants "LPN FiLM,PFNN one-hot" --budget-steps 50

The command's options are defined in minifilm/cli/compare.py; ``run(args)`` reads them.

One style or several are held out of training (--holdout). On held-out test frames of the seen styles:
  - test MSE and bone-length loss on the 324 motion outputs every variant predicts (Figure 10),
    overall and per style;
  - style recognition of generated motion: a classifier (minifilm.evaluation.style_classifier) trained on
    the dataset's training rows, applied to 10-second rollouts of every seen style (its accuracy
    on held-out real rows is the ceiling);
  - foot sliding and bone-length variation of those rollouts;
  - interpolation smoothness (Figure 8): the classifier's probability of style B along a blend
    from style A to B, for FiLM (blended FiLM vectors) and one-hot (blended one-hot vectors);
  - a new style (Sec. 5.3.2, Figure 11): every FiLM variant's Ψ alone fine-tuned on the held-out
    styles, their test error and the silhouette of their Ψ(clip) before and after
    (minifilm/evaluation/compare_finetune.py);
  - the field's metrics beside these (minifilm/evaluation/field_metrics.py): foot sliding by height,
    path and direction errors, and a pooled FID-like distance of all rollouts to real windows.
Every training run (variant and seed) records its validation loss on a fixed subset of the
validation rows and is judged flat or still falling at the end (minifilm/evaluation/convergence.py;
--until-flat trains on in whole epochs until it is flat). The report then takes the paper's claims
one by one, each with a verdict by a stated rule (minifilm/evaluation/compare_claims.py,
docs/compare_claims.md), and, for a data set made by the released network or with --released, gives
the released network's own rollouts as one more row (minifilm/evaluation/compare_released.py).
Writes reports/compare_<data>.md and PNG plots next to it. The defaults (2500 steps per variant,
one extra seed) take about 12 minutes on synthetic data and 8.5 on Bandai-2 on a shared 2-core
machine with OPENBLAS_NUM_THREADS=1 (multithreaded BLAS thrashes when the cores are busy).
"""
from __future__ import annotations

import functools
import json
import math
import time
import types
from pathlib import Path

import numpy as np

from minifilm.baselines.variant_data import end_effector_indices, variant_data
from minifilm.baselines.variants import VARIANTS, build_variant
from minifilm.dataset.build import build_dataset, resolve_files
from minifilm.errors import InputError
from minifilm.evaluation.compare_report import write_report
from minifilm.evaluation.compare_measures import (CLAVICLE_PATTERN, data_hand_amplitude, fid_reference, joint_error,
                                                  joints_named)
from minifilm.evaluation.compare_claims_more import table2_figures
from minifilm.evaluation.compare_released import released_rollout
from minifilm.evaluation.compare_rollouts import interpolation, style_recognition
from minifilm.evaluation.compare_finetune import finetune_all
from minifilm.evaluation.compare_tools import fit_stats, motion_errors, select_styles, steps_per_epoch, style_subset
from minifilm.evaluation.convergence import train_with_curve, validation_subset
from minifilm.evaluation.style_classifier import train_style_classifier
from minifilm.model.config import ModelConfig
from minifilm.motion.skeletons import BUILTIN_SKELETONS
from minifilm.parallel import map_in_order, worker_count
from minifilm.synthetic import generator as synthetic
from minifilm.train.trainer import TrainConfig, Trainer

SYNTH_HOLDOUT = "Drunk"
#: the style of the paper's Figure 7 (capacity: its clavicles)
CAPACITY_STYLE = "ArmsAboveHead"
#: the main job's model (ModelConfig.small) with the paper's dropout, for every variant alike
MODEL = dict(dropout=0.3)
#: a miniature of it (tests and smoke runs)
TINY_MODEL = dict(MODEL, hidden=16, conv_filters=4, film_dense=16, n_experts=2, gating_hidden=8)


def log(msg=""):
    print(msg, flush=True)


# ---------------------------------------------------------------------------- data
def load_data(args, workers=None):
    """The data set of the options ``args`` (built once, then read from --work's cache), its name;
    ``workers``: build_dataset's, for the labelling."""
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
                       clip_stride_seconds=args.clip_seconds / 2, seed=args.seed, fps=args.fps, workers=workers,
                       **extra)
    return ds, name


def skeleton_of(ds):
    for sk in BUILTIN_SKELETONS:
        if sk.name == ds.skeleton:
            return sk
    raise ValueError(f"compare: dataset skeleton {ds.skeleton!r} is not a built-in skeleton")


class Context:
    """The data every variant shares: seen / held-out styles, statistics, splits, classifier."""

    def __init__(self, ds, holdouts, args, classifier=True):
        """holdouts: the styles held out of training (a list, possibly empty). classifier=False:
        without the style classifier and the FID-like reference (a training worker needs neither)."""
        self.ds, self.args, self.layout = ds, args, ds.layout
        self.holdouts = list(holdouts)
        self.seen = [s for s in ds.styles if s not in self.holdouts]
        self.norm = fit_stats(ds, self.seen)
        self.data = {sp: style_subset(ds, sp, self.seen, self.norm) for sp in ("train", "test")}
        # the fixed validation frames every variant's curve is judged on (minifilm/evaluation/convergence.py)
        val_styles = [s for s in self.seen if np.any(ds.val.style == ds.styles.index(s))]
        self.data["val"] = validation_subset(style_subset(ds, "val", val_styles or self.seen, self.norm)
                                             if val_styles else self.data["test"])
        self.new_train = style_subset(ds, "train", self.holdouts, self.norm) if self.holdouts else None
        self.all_train = style_subset(ds, "train", self.seen + self.holdouts, self.norm)
        self.skeleton = skeleton_of(ds)
        self.end_effectors = end_effector_indices(self.layout, self.skeleton)
        names = list(self.layout.joint_names)
        # the feet's phase bones (exported joints; the contact sensors are End Sites): [right, left],
        # the order of the contact columns
        self.toes = [names.index(self.skeleton.phase_bones[3]), names.index(self.skeleton.phase_bones[2])]
        # the hands (the arms' phase bones) for the 'stuck arms' of Sec. 5.1.1, and their real amplitude
        # per style; the clavicle joints for Figure 7
        self.hand_columns = hand_columns(self.layout, self.skeleton)
        second = max(2, int(round(ds.fps)))
        self.data_hands = {s: data_hand_amplitude(ds.train, self.layout, ds.styles.index(s), self.hand_columns, second)
                           for s in self.seen}
        self.clavicles = joints_named(names, CLAVICLE_PATTERN)
        if not classifier:
            return
        t0 = time.perf_counter()
        self.classifier, self.clf_info = train_style_classifier(ds, seed=args.seed)
        log(f"[classifier] {self.clf_info['n_train']} training windows; held-out real accuracy "
            f"{self.clf_info['heldout_acc']:.3f} ({self.clf_info['n_heldout']} windows), "
            f"{time.perf_counter() - t0:.0f} s")
        self.fid = fid_reference(ds, self.seen, self.clf_info["window"], self.clf_info["stride"])
        log(f"[fid] style space of {len(self.seen)} seen styles' real windows; real held-out rows against real "
            f"training rows: {self.fid['real_to_real']:.2f} (the floor of the FID-like distance)")


def hand_columns(layout, skeleton) -> np.ndarray:
    """(2, 3) clip-block position columns of the hands (the skeleton's arm phase bones)."""
    names = list(layout.joint_names)
    hands = [names.index(b) for b in skeleton.phase_bones[:2]]
    return layout.joint_columns("clip", "position")[hands]


# ---------------------------------------------------------------------------- one variant
def model_config(ctx, sizes):
    """The main job's model for this data set, with ``sizes`` overriding its sizes."""
    L = ctx.layout
    return ModelConfig.small(L.x_dim, L.z_dim, ctx.data["train"].clips.shape[1], L.clip_dim,
                             phase_dim=L.phase_dim, **sizes)


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
    if CAPACITY_STYLE in ctx.seen:       # Figure 7: the clavicles of ArmsAboveHead, one-step error
        errors["clavicle"] = joint_error(model, vtest, L, ctx.clavicles, ctx.seen.index(CAPACITY_STYLE), seed=a.seed,
                                         style_kw=getattr(model, "takes_style_ids", False))
    n_params = sum(ps.size for ps in model.parameter_sets())
    return {"trainer": trainer, "info": info, "seconds": seconds, "steps": trainer.step, "errors": errors,
            "params": n_params, "final_train_loss": trainer.history[-1]["train"]["loss"], "curve": curve}


def variant_trainer(name, ctx, seed, weights, epoch, step, history):
    """The Trainer of a run trained in a worker process (:func:`trained_runs`): the variant built as
    train_variant builds it, with the run's weights, epoch count, step count and history."""
    a, L = ctx.args, ctx.layout
    model = build_variant(name, model_config(ctx, a.model), np.random.default_rng(seed), n_styles=len(ctx.seen))
    for ps, w in zip(model.parameter_sets(), weights):
        ps.data[...] = w
    trainer = Trainer(model, ctx.norm, TrainConfig(epochs=epoch, batch_size=a.batch_size, lr=a.lr, seed=seed,
                                                   progress=False),
                      positions_idx=L.joint_columns("z", "position"), parents=np.asarray(L.parents),
                      style_names=ctx.seen)
    trainer.epoch, trainer.step, trainer.history = epoch, step, history
    return trainer


#: what a run trained in a worker sends back of train_variant's result (besides its weights)
RUN_FIGURES = ("seconds", "steps", "errors", "params", "final_train_loss", "curve")


@functools.lru_cache(maxsize=1)
def worker_context(args_text: str, holdouts: str) -> Context:
    """The context a worker process trains in, made once per worker from the same options as this
    process's (the data set from --work's cache), without the classifier it does not need."""
    args = types.SimpleNamespace(**json.loads(args_text))
    return Context(load_data(args, workers=1)[0], [h for h in holdouts.split(",") if h], args, classifier=False)


def train_in_worker(job, args_text: str, holdouts: str) -> dict:
    """One run, job = (variant, seed, epochs), in a worker process: train_variant's figures, the
    trainer's epoch and history, and the model's weights (float32 as trained)."""
    variant, seed, epochs = job
    r = train_variant(variant, worker_context(args_text, holdouts), epochs, seed=seed)
    t = r["trainer"]
    return {**{k: r[k] for k in RUN_FIGURES}, "epoch": t.epoch, "history": t.history,
            "weights": [ps.data for ps in t.model.parameter_sets()]}


def trained_runs(variants, ctx, epochs):
    """{(variant, seed): train_variant's result} for every run, trained in --workers processes
    (minifilm/parallel.py): each run depends only on its variant, its seed and the data, so a
    worker trains the run this process would, the same numbers but for float round-off. None with
    one worker (the runs are then trained one after another in the main loop)."""
    a = ctx.args
    jobs = [(v, s, epochs) for v in variants for s in [a.seed] + list(a.extra_seeds)]
    jobs.sort(key=lambda job: "FiLM" not in job[0])    # the longest runs (Ψ on every clip) first: less idle time
    n = worker_count(getattr(a, "workers", None), len(jobs))
    if n <= 1:
        return None
    log(f"[workers] {len(jobs)} training runs in {n} worker processes")
    args_text = json.dumps({k: (str(v) if isinstance(v, Path) else v) for k, v in vars(a).items()}, default=str)
    train = functools.partial(train_in_worker, args_text=args_text, holdouts=",".join(ctx.holdouts))
    runs = map_in_order(train, jobs, n, doing="training", name=lambda job: f"{job[0]}, seed {job[1]}",
                        done=lambda i, r: log(f"[worker] {jobs[i][0]}, seed {jobs[i][1]}: {r['steps']} steps in "
                                              f"{r['seconds']:.0f} s"))
    out = {}
    for (v, seed, _), fig in zip(jobs, runs):
        _, info = variant_data(v, ctx.data["train"], ctx.layout, ctx.norm, ctx.end_effectors)
        trainer = variant_trainer(v, ctx, seed, fig["weights"], fig["epoch"], fig["steps"], fig["history"])
        out[(v, seed)] = {**{k: fig[k] for k in RUN_FIGURES}, "trainer": trainer, "info": info}
    return out


def flat_line(curve) -> str:
    """One log line on a validation curve (minifilm/evaluation/convergence.py)."""
    verdict = {True: "flat", False: "still falling", None: "not judged"}[curve["flat"]]
    return (f"validation loss {curve['loss'][0]:.4f} -> {curve['loss'][-1]:.4f} in {curve['steps'][-1]} steps; "
            f"last 20 % improved it {100 * curve['improvement']:.1f} %: {verdict}")


# ---------------------------------------------------------------------------- the run
#: Figure 8's pair, interpolated by default when both are seen
PAPER_PAIR = ("BentForward", "LeanBack")


def interpolation_pairs(text) -> list:
    """'A,B' or 'A,B;C,D' (the --interpolate option) -> [(A, B), (C, D)]; None -> []."""
    return [tuple(x.strip() for x in part.split(",")) for part in text.split(";")] if text else []


def holdout_names(text) -> list:
    """'A' or 'A,B,C' (the --holdout option) -> ['A', 'B', 'C'] (blanks dropped, order kept, once each)."""
    return list(dict.fromkeys(x.strip() for x in text.split(",") if x.strip())) if text else []


def check_pairs(styles, holdouts, interpolate) -> list:
    """InputError unless the held-out styles (a name or a list) and the interpolated ones are among
    ``styles`` (the interpolated ones seen in training); returns the interpolation pairs.
    ``interpolate``: None (Figure 8's pair when seen, else the first two seen styles), a pair [A, B]
    or a list of pairs. Before any work."""
    holdouts = [holdouts] if isinstance(holdouts, str) else list(holdouts)
    missing = [h for h in holdouts if h not in styles]
    if missing:
        raise InputError(f"compare: --holdout {', '.join(map(repr, missing))} not a style of the data "
                         f"({', '.join(styles)})")
    seen = [s for s in styles if s not in holdouts]
    if not interpolate:
        if len(seen) < 2:
            raise InputError(f"compare: the data has {len(styles)} style(s) and {len(holdouts)} held out; two must "
                             "be seen in training to interpolate between")
        return [PAPER_PAIR] if all(x in seen for x in PAPER_PAIR) else [(seen[0], seen[1])]
    pairs = [tuple(interpolate)] if isinstance(interpolate[0], str) else [tuple(p) for p in interpolate]
    for pair in pairs:
        bad = [x for x in pair if x not in seen]
        if bad:
            raise InputError(f"compare: --interpolate {','.join(pair)}: not seen in training: "
                             f"{', '.join(map(repr, bad))} (the seen styles: {', '.join(seen)})")
    return pairs


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
    pairs = interpolation_pairs(args.interpolate)
    holdouts = holdout_names(args.holdout)
    if args.holdout is not None and not holdouts:
        raise InputError(f"--holdout {args.holdout!r}: names no style (give one, or several separated by commas)")
    keep = holdouts + [s for p in pairs for s in p]
    try:
        styles = select_styles(available, args.styles, keep)
    except ValueError as e:
        raise InputError(f"compare: {e}") from None
    if args.styles:
        args.styles = styles if args.styles[0].strip().isdigit() else [x.strip() for x in args.styles]
    holdouts = holdouts or [SYNTH_HOLDOUT if synthetic_data and SYNTH_HOLDOUT in styles else styles[-1]]
    pairs = check_pairs(styles, holdouts, pairs or None)
    Path(args.work).mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    ds, name = load_data(args)
    log(f"[data] {name}: {len(ds.styles)} styles, {len(ds.train)} training frames at {ds.fps:g} fps; "
        f"held out: {', '.join(holdouts)} ({time.perf_counter() - t0:.0f} s)")
    ctx = Context(ds, holdouts, args)
    spe = steps_per_epoch(ctx.data["train"].style, args.batch_size)
    epochs = max(1, math.ceil(args.budget_steps / spe))
    log(f"[budget] {args.budget_steps} steps asked -> {epochs} epoch(s) of {spe} style-balanced batches of "
        f"{args.batch_size} = {epochs * spe} steps per variant")
    results = {}
    done = trained_runs(variants, ctx, epochs)
    for v in variants:
        r = done[(v, args.seed)] if done else train_variant(v, ctx, epochs)
        log(f"[train] {v:<13} {r['params']:>9,} params  {r['steps']} steps in {r['seconds']:.0f} s  "
            f"test MSE {r['errors']['mse']:.4f}  BLL {r['errors']['bll']:.4f}")
        t0 = time.perf_counter()
        r["rollout"] = style_recognition(r["trainer"].model, r["info"], ctx)
        if getattr(r["trainer"].model, "modulation", "film") in ("film", "onehot"):
            r["interps"] = {p: interpolation(r["trainer"].model, r["info"], ctx, *p) for p in pairs}
            r["interp"] = r["interps"][pairs[0]]
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
            extra = done[(v, seed)] if done else train_variant(v, ctx, epochs, seed=seed)
            e = extra["errors"]
            r["seed_errors"].append(e)
            r["curves"][seed] = extra["curve"]
            log(f"        seed {seed}: test MSE {e['mse']:.4f}  BLL {e['bll']:.4f}; {flat_line(extra['curve'])}")
        results[v] = r
    fts = finetune_all(results, ctx, log)
    ft = fts.get("LPN FiLM")
    released = released_rollout(ctx, args)
    if released and "rollout" in released:
        q = released["rollout"]
        log("[released] " + ("diverged" if q["diverged"] else f"{len(released['styles'])} styles: style accuracy "
                             f"{q['accuracy']:.3f}, foot sliding {q['foot_sliding_cm_s']:.1f} cm/s, path error "
                             f"{q['path_error']:.2f} m"))
    elif released:
        log(f"[released] skipped: {released['skipped']}")
    # the sizes the variants were built with (the main job's model with args.model's changes)
    cfg = model_config(ctx, args.model)
    table2 = table2_figures(variants, cfg, len(ctx.seen))
    total = time.perf_counter() - t_start
    sizes = {k: getattr(cfg, k) for k in ("hidden", "n_experts", "conv_filters", "film_dense", "dropout")}
    path = write_report(Path(args.out), name, ctx, results, ft, dict(epochs=epochs, steps_per_epoch=spe,
                        total_seconds=total, interpolate=pairs[0], pairs=pairs, sizes=sizes,
                        table2=table2, released=released, finetuned=fts))
    log(f"[report] {path} ({total:.0f} s in all)")
    return {"name": name, "results": results, "finetune": ft, "finetuned": fts, "report": path, "ctx": ctx,
            "released": released, "table2": table2}
