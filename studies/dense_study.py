"""The dense style space at small scale (reports/2026-12-02_dense_style_space.md): train on styles the released network made, teach held-out styles to Ψ alone, and
measure style with both measures (classifier over seeds, Fréchet rank).

    minifilm dataset --from-released ../shared/data/released-lpn --out study/trained --seconds-per-style 20 \
        --styles Aeroplane ArmsBySide ...                       # the trained styles
    minifilm dataset --from-released ../shared/data/released-lpn --out study/held --seconds-per-style 60 \
        --styles Chicken Proud                                  # the held-out styles
    python studies/dense_study.py --trained study/trained --held study/held --work study/work --epochs 3
    python studies/dense_study.py ... --reuse-run        # fine-tune and measure again on the trained run

Steps, each timed (the load is printed beside):

1. ``minifilm train``'s pipeline on the trained styles (``--epochs``, ``--quick`` for the small model);
2. each held-out style taught from ``--clip-seconds`` of its files (FW, FR, TR1, BW, ... in that
   order) with ``minifilm finetune``'s code (Ψ alone; Ω and Φ frozen), once per ``--variants``:
   ``teacher`` (teacher forcing alone, the paper), ``self-fed`` (then rollout-aware rounds,
   pipeline/self_fed.py) and ``motion`` (then the vector refined by the motion it makes,
   pipeline/run_motion_refit.py), each in its own copy of the run folder; the trained styles' FiLM
   vectors and one trained style's rollout compared bit for bit before and after;
3. every style generated for ``--generate-seconds`` along a figure-eight (one batch), and measured:
   the style classifier (minifilm/evaluation/style_classifier.py) trained on all styles' data, for
   each of ``--seeds`` (recognition min and mean), and the Fréchet distance of the generated
   windows to every style's real windows, with the target's rank
   (minifilm/evaluation/style_measures.py). Reproduced = rank 1 and every seed ≥ 0.8.

The real frames of a held-out style include the clip it was taught from (the data set has no other
motion of the same paths); its other gaits are never seen by the fine-tuning.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import time
from dataclasses import replace
from typing import Optional
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from minifilm.dataset.build import build_dataset  # noqa: E402
from minifilm.dataset.dataset import Dataset  # noqa: E402
from minifilm.dataset.manifest import read_manifest, write_manifest  # noqa: E402
from minifilm.evaluation.style_classifier import (classify_rollout, cut_windows, rollout_blocks,  # noqa: E402
                                                  split_windows, train_style_classifier, window_summary)
from minifilm.evaluation.style_measures import StyleSpace, recognition, style_report  # noqa: E402
from minifilm.motion.bvh import bvh_duration  # noqa: E402
from minifilm.features.compute import clip_features  # noqa: E402
from minifilm.features.layout import FeatureLayout  # noqa: E402
from minifilm.motion.foot_ik import FootLocker  # noqa: E402
from minifilm.motion.skeletons import STYLE100, builtin_skeleton  # noqa: E402
from minifilm.pipeline.from_released import ReleasedDataSettings, calibrate_styles, drive_gaits  # noqa: E402
from minifilm.runtime.calibration import SpeedCalibration  # noqa: E402
from minifilm.runtime.controller import Controller  # noqa: E402
from minifilm.runtime.root_frames import floor_angle  # noqa: E402
from minifilm.runtime.released import load_released  # noqa: E402
from minifilm.synthetic.generator import rest_motion  # noqa: E402
from minifilm.pipeline.new_style import read_clip, teach_style  # noqa: E402
from minifilm.pipeline.run_folder import RunFolder  # noqa: E402
from minifilm.pipeline.motion_refit import RefitSettings  # noqa: E402
from minifilm.pipeline.self_fed import SelfFed  # noqa: E402
from minifilm.pipeline.train_small import Settings, run as train_run  # noqa: E402
from minifilm.runtime.control import figure_eight  # noqa: E402

CLIP_ORDER = ("FW", "FR", "TR1", "BW", "SW", "BR", "SR", "ID")
VARIANTS = {"teacher": None, "self-fed": SelfFed(), "span": None, "motion": None}


def onto_span(vector: np.ndarray, trained: np.ndarray) -> np.ndarray:
    """``vector`` (D,) projected onto the affine span of the trained styles' vectors (S, D): the
    nearest combination mean + sum_k c_k (v_k - mean), by least squares (the "span" variant: the
    new style kept on the trained styles' manifold, one of the routes the study tried)."""
    mean = trained.mean(axis=0)
    basis = (trained - mean).T                                        # (D, S)
    coef, *_ = np.linalg.lstsq(basis, vector - mean, rcond=None)
    return mean + basis @ coef


# ---------------------------------------------------------------- like with like: the data set's own paths
class SpeedLimit:
    """What a trained network is asked for on a gait script: the speed the released network reached in
    the same style and direction when it made the data (the wish, up to that style's top speed).
    The released network needs its calibration to reach a wish; the trained network learned from
    what it reached, so it is asked for exactly that."""

    def __init__(self, calibration: SpeedCalibration):
        self.top = calibration.achieved[:, -1]
        self.directions = np.asarray(calibration.directions, np.float64)

    def apply(self, velocity: np.ndarray, facing: Optional[np.ndarray] = None) -> np.ndarray:
        v = np.asarray(velocity, np.float64)
        n = np.linalg.norm(v)
        angle = 0.0 if facing is None or n <= 1e-9 else floor_angle(v, np.asarray(facing, np.float64))
        top = np.interp(angle, self.directions, self.top)
        return v * min(1.0, top / n) if n > 1e-9 else v * 0.0


def teacher_calibrations(params: Path, names, cache: Path):
    """The released network's speed calibration of each style, as ``minifilm dataset`` measures it (cached)."""
    rel = load_released(params)
    d = ReleasedDataSettings()
    if cache.exists():
        with np.load(cache, allow_pickle=False) as z:
            if list(z["names"]) == list(names):
                return rel, [SpeedCalibration(np.asarray(d.calibration_commands), z["achieved"][k],
                                              tuple(d.calibration_directions)) for k in range(len(names))]
    layout = FeatureLayout.for_skeleton(STYLE100)
    cals = calibrate_styles(Controller(rel.network, layout, fps=60.0), np.stack([rel.styles[n] for n in names]),
                            d.calibration_commands, d.calibration_directions, d.calibration_seconds)
    raw = np.stack([c.achieved[:, 1:] for c in cals])           # without the (0, 0) point the class adds
    np.savez(cache, names=np.array(list(names)), achieved=raw)
    return rel, cals


def gait_windows(controller: Controller, films: np.ndarray, names, gaits, seconds: float, seed: int, calibrations,
                 ds, window: int, stride: int):
    """Drive ``controller`` in each style along the data set's gait scripts (new paths: ``seed``), and cut
    every rollout into normalised windows. Returns (name, gait) -> window summaries (M, 2C)."""
    out = {}
    for gait, first, r in drive_gaits(controller, films, list(names), gaits, seconds, seed, 1.0, calibrations):
        blocks = ds.stats.normalize_clip(rollout_blocks(r, 1.0), ds.layout.x_joints)
        for b, block in enumerate(blocks):
            out[(names[first + b], gait)] = window_summary(cut_windows(block, window, stride))
    return out


def cpu_seconds() -> float:
    """CPU time of this process and of its finished children (training's worker processes)."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def trained_gaits(run: RunFolder):
    """style -> the gaits of its files in the training split of the run's own data set (the run folder's cache)."""
    caches = sorted((run.path / "cache").glob("dataset-*.npz"))
    if not caches:
        raise SystemExit(f"{run.path}: no dataset cache, so the gaits each style was trained on are unknown")
    ds = Dataset.load(caches[0])
    train = ds.split("train")
    out = {}
    for k in np.unique(train.file):
        f = ds.files[int(k)]
        out.setdefault(f["style"], set()).add(f["gait"])
    return out


def real_windows_by_gait(ds, window: int, stride: int):
    """(style, gait) -> summaries (M, 2C) of the real normalised windows from every split of the data set."""
    out = {}
    gait_of = np.array([f.get("gait", "") for f in ds.files])
    for split in ("train", "val", "test"):
        sp = ds.split(split)
        for g in sorted(set(gait_of[sp.file]) if len(sp) else ()):
            keep = gait_of[sp.file] == g
            part = replace(sp, **{k: getattr(sp, k)[keep] for k in ("x", "p", "z", "style", "file", "frame")})
            w, st = split_windows(part, ds.layout, ds.stats, window, stride)
            for k, name in enumerate(ds.styles):
                if np.any(st == k):
                    out.setdefault((name, g), []).append(window_summary(w[st == k]))
    return {key: np.concatenate(v) for key, v in out.items()}


def measure_sets(generated, gaits_of, space_for, probs_of, seeds, ds, label: str):
    """Rows of style_report, one per style of ``gaits_of`` (name -> its gaits): its generated windows of
    those gaits (``generated``: (name, gait) -> window summaries) against every style's real windows of the same
    gaits (``space_for(gaits)`` -> StyleSpace); probs_of(windows) -> {seed: class probabilities}."""
    rows = []
    for name, gaits in gaits_of.items():
        w = np.concatenate([generated[(name, g)] for g in gaits])
        target = ds.styles.index(name)
        probs = probs_of(w)
        rep = style_report(space_for(gaits), w, name, [recognition(probs[k], target) for k in seeds], summarised=True)
        rep.update(set=label, gaits=list(gaits))
        rows.append(rep)
    return rows

def print_rows(rows, lead_headers, lead) -> None:
    """A markdown table of style_report rows: the ``lead`` columns, then both measures and the verdict."""
    print("| " + " | ".join(lead_headers) + " | recognised min / mean over seeds | Fréchet rank | nearest | reproduced |")
    print("|---" * (len(lead_headers) + 4) + "|")
    for x in rows:
        c = x["classifier"]
        print("| " + " | ".join(lead(x)) + f" | {c['min']:.2f} / {c['mean']:.2f} | {x['rank']} | {x['nearest']} | "
              f"{'yes' if x['reproduced'] else 'no'} |")


def load() -> str:
    return f"load {os.getloadavg()[0]:.1f}"


def clip_files(files, style: str, seconds: float):
    """The style's files in CLIP_ORDER, up to ``seconds`` of motion in all."""
    mine = sorted((f for f in files if f.style == style),
                  key=lambda f: CLIP_ORDER.index(f.gait) if f.gait in CLIP_ORDER else 99)
    chosen, total = [], 0.0
    for f in mine:
        d = bvh_duration(f.path)
        if total + d > seconds + 1e-6 and chosen:
            break
        chosen.append(f)
        total += d
    return chosen, total


def vectors_from_clips(run: RunFolder, files, styles, seconds: float) -> None:
    """Replace the run's vectors of ``styles`` by mean Ψ over the clips of each one's first ``seconds`` of
    files in CLIP_ORDER: the same kind of clip a held-out style is taught from (styles.npz rewritten)."""
    model, stats = run.model_and_stats()
    skeleton = builtin_skeleton(run.skeleton_name)
    T = model.config.clip_frames / run.fps
    library = run.styles()
    for style in styles:
        chosen, _ = clip_files(files, style, seconds)
        clips = np.concatenate([clip_features(read_clip(f.path, run, lambda m: None), skeleton, T, T / 2, fps=run.fps)
                                for f in chosen])
        library.add_from_clips(style, model, stats.normalize_clip(clips, run.layout.x_joints))
    library.save(run.path / "styles.npz")


def rollouts(run: RunFolder, names, seconds: float):
    x0, p0 = run.start_states(names)
    lib = run.styles()
    n = int(round(seconds * run.fps))
    return run.controller().run([figure_eight(seconds) for _ in names], n, np.stack([lib[s] for s in names]),
                                phases=p0, start_x=x0)


def gaits_measure(a, ds, base: RunFolder, runs, trained, held, probs, window: int, stride: int) -> dict:
    """Every style driven along the data set's gait scripts on new paths, by the released network (the
    ceiling: the motion the data set is made of) and by the trained networks; each style measured on
    the gaits it was taught (a trained style: the gaits of its training files; a held-out style: the
    gaits of its clip) against every style's real windows of the same gaits."""
    if a.teacher is None:
        raise SystemExit("--measure gaits needs --teacher (the released network's folder)")
    t0 = time.perf_counter()
    taught = trained_gaits(RunFolder.load(a.work / "run"))
    gaits_of = {n: tuple(g for g in CLIP_ORDER if g in taught[n]) for n in trained}
    clip_gaits = tuple(CLIP_ORDER[:3])
    gaits_of.update({n: clip_gaits for n in held})
    every_gait = [g for g in CLIP_ORDER if any(g in v for v in gaits_of.values())]
    names = trained + held
    rel, cals = teacher_calibrations(a.teacher, names, a.work / "teacher-calibration.npz")
    cal_of = dict(zip(names, cals))
    layout = FeatureLayout.for_skeleton(STYLE100)
    teacher = Controller(rel.network, layout, fps=60.0, skeleton=Controller.skeleton_for(layout, rest_motion()),
                         feed_back_fit=True, foot_locker=FootLocker.from_names(layout.joint_names))
    real = real_windows_by_gait(ds, window, stride)
    spaces = {}

    def space_for(gaits):
        if gaits not in spaces:
            spaces[gaits] = StyleSpace.fit({n: np.concatenate([real[(n, g)] for g in gaits if (n, g) in real])
                                            for n in names}, summarised=True)
        return spaces[gaits]

    def probs_of(w):
        return {k: probs[k][2].predict_proba(w) for k in a.seeds}

    def drive(ctrl, films, who, gaits, cal):
        return gait_windows(ctrl, films, who, gaits, a.path_seconds, a.path_seed, cal, ds, window, stride)

    rows = []
    films = np.stack([rel.styles[n] for n in names])
    released = drive(teacher, films, names, every_gait, cals)
    rows += measure_sets(released, {n: gaits_of[n] for n in trained}, space_for, probs_of, a.seeds, ds,
                         "released network, trained styles")
    rows += measure_sets(released, {n: gaits_of[n] for n in held}, space_for, probs_of, a.seeds, ds,
                         "released network, held-out styles")
    lib = base.styles()
    mine = drive(base.controller(), np.stack([lib[n] for n in trained]), trained, every_gait,
                 [SpeedLimit(cal_of[n]) for n in trained])
    rows += measure_sets(mine, {n: gaits_of[n] for n in trained}, space_for, probs_of, a.seeds, ds,
                         "trained network, trained styles")
    for v, run in runs.items():
        lib = run.styles()
        mine = drive(run.controller(), np.stack([lib[n] for n in held]), held, clip_gaits,
                     [SpeedLimit(cal_of[n]) for n in held])
        rows += measure_sets(mine, {n: gaits_of[n] for n in held}, space_for, probs_of, a.seeds, ds,
                             f"{v}, held-out styles")
    print(f"\n[study] gait scripts on new paths (seed {a.path_seed}, {a.path_seconds:g} s per style over the "
          f"gaits), {time.perf_counter() - t0:.0f} s ({load()})")
    print_rows(rows, ("set", "style", "gaits"), lambda x: (x["set"], x["target"], " ".join(x["gaits"])))
    summary = {}
    for label in dict.fromkeys(x["set"] for x in rows):
        mine = [x for x in rows if x["set"] == label]
        summary[label] = dict(styles=len(mine), recognised_mean=float(np.mean([x["classifier"]["mean"] for x in mine])),
                              recognised_min_mean=float(np.mean([x["classifier"]["min"] for x in mine])),
                              rank1=float(np.mean([x["rank"] == 1 for x in mine])),
                              reproduced=int(sum(x["reproduced"] for x in mine)))
        print(f"[study] {label}: {len(mine)} styles, recognised {summary[label]['recognised_mean']:.2f} mean, "
              f"rank 1 for {summary[label]['rank1']:.0%}, reproduced {summary[label]['reproduced']}")
    return dict(rows=rows, summary=summary, seconds=time.perf_counter() - t0)

def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trained", type=Path, required=True, help="data set folder of the trained styles")
    ap.add_argument("--held", type=Path, required=True, help="data set folder of the held-out styles")
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--epochs", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="the quick (smaller) model")
    ap.add_argument("--hidden", type=int, help="hidden units of Φ (default: the small model's 128)")
    ap.add_argument("--input-noise", type=float, default=0.0, help="training: Gaussian noise on the normalised "
                    "inputs (TrainConfig.input_noise; 0 = the paper)")
    ap.add_argument("--fps", type=float, help="resample every file to this rate (data of several frame rates, "
                    "e.g. real capture beside the released network's: studies/real_capture_base.py)")
    ap.add_argument("--clip-seconds", type=float, default=30.0)
    ap.add_argument("--steps", type=int, default=400, help="fine-tuning steps")
    ap.add_argument("--generate-seconds", type=float, default=10.0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--variants", nargs="+", choices=sorted(VARIANTS), default=sorted(VARIANTS, reverse=True))
    ap.add_argument("--rounds", type=int, default=SelfFed.rounds, help="self-fed: rollout rounds")
    ap.add_argument("--round-steps", type=int, default=SelfFed.steps, help="self-fed: fine-tuning steps per round")
    ap.add_argument("--horizon", type=int, default=SelfFed.horizon, help="self-fed: frames per rollout")
    ap.add_argument("--reference-gaits", nargs="+", help="fit the classifier and the real windows of the Fréchet "
                    "measure on files of these gaits only (default: every gait); the figure-eight is forward "
                    "walking, so FW TR1 compares like with like")
    ap.add_argument("--measure", nargs="+", choices=("figure-eight", "gaits"), default=["figure-eight", "gaits"],
                    help="figure-eight: every style walks one figure-eight, measured against all its real frames; "
                    "gaits: every style driven along the data set's own gait scripts on new paths (--path-seed), "
                    "measured against its real frames of the same gaits, beside the released network driven "
                    "the same way (the ceiling; needs --teacher)")
    ap.add_argument("--teacher", type=Path, help="the released network's folder that made the data set")
    ap.add_argument("--path-seed", type=int, default=1, help="gait scripts' seed (the data set's is 0)")
    ap.add_argument("--path-seconds", type=float, default=60.0, help="seconds per style over the gait scripts")
    ap.add_argument("--walk-workers", type=int, default=2, help="motion: worker processes sharing the "
                    "refinement's walks (1: all in this process)")
    ap.add_argument("--reuse-run", action="store_true", help="keep --work/run as trained (skip training)")
    ap.add_argument("--trained-vectors", choices=("library", "clip", "tuned"), default="library",
                    help="the trained styles' FiLM vectors for generating: the run's (mean Ψ over the style's "
                         "training clips), mean Ψ over its --clip-seconds clip, or 'tuned': each trained style "
                         "taught anew from --clip-seconds of its own training files, as a held-out style is")
    a = ap.parse_args()
    VARIANTS["self-fed"] = SelfFed(rounds=a.rounds, steps=a.round_steps, horizon=a.horizon)
    a.work.mkdir(parents=True, exist_ok=True)
    report = {"load_start": os.getloadavg()[0]}
    trained_files = read_manifest(a.trained / "manifest.csv")
    run_dir = a.work / "run"

    s = replace(Settings(), epochs=a.epochs, generate_seconds=a.generate_seconds, seed=0)
    if a.quick:
        s = replace(s.quick(), epochs=a.epochs, generate_seconds=a.generate_seconds)
    s = replace(s, out=run_dir, input_noise=a.input_noise, fps=a.fps, model=dict(s.model, **({"hidden": a.hidden} if a.hidden else {})))
    if not a.reuse_run:
        t0, c0 = time.perf_counter(), cpu_seconds()
        result = train_run(s, a.trained / "manifest.csv")
        report["train_seconds"] = time.perf_counter() - t0
        report["train_cpu_seconds"] = cpu_seconds() - c0
        report["test_mse"] = {k: v for k, v in result.items() if k != "recognition"}
        report["train_recognition"] = result["recognition"]
        print(f"[study] training: {report['train_seconds']:.0f} s, {report['train_cpu_seconds']:.0f} CPU s "
              f"({load()})", flush=True)

    held_files = read_manifest(a.held / "manifest.csv")     # read now: it may be written while training runs
    held = sorted({f.style for f in held_files})
    base = RunFolder.load(run_dir)
    trained = [n for n in base.styles().names if n not in held]
    if a.trained_vectors == "clip":
        folder = a.work / "run-clip-vectors"
        if folder.exists():
            shutil.rmtree(folder)
        shutil.copytree(run_dir, folder, ignore=shutil.ignore_patterns("model-*.npz", "*.lock"))
        vectors_from_clips(RunFolder.load(folder), trained_files, trained, a.clip_seconds)
        base = RunFolder.load(folder)
        print(f"[study] trained styles' vectors: mean Ψ over each one's {a.clip_seconds:g} s clip ({load()})",
              flush=True)
    if a.trained_vectors == "tuned":
        folder = a.work / "run-tuned-vectors"
        if folder.exists():
            shutil.rmtree(folder)
        shutil.copytree(run_dir, folder, ignore=shutil.ignore_patterns("model-*.npz", "*.lock"))
        taught_gaits = trained_gaits(RunFolder.load(run_dir))
        t0, kept = time.perf_counter(), []
        for style in trained:
            own = [f for f in trained_files if f.style == style and f.gait in taught_gaits[style]]
            clip, _ = clip_files(own, style, a.clip_seconds)
            try:
                teach_style(folder, style, [f.path for f in clip], steps=a.steps, log=lambda m: None, replace=True)
            except ValueError as e:           # e.g. no foot step found in the clip: the library's vector stays
                kept.append(style)
                print(f"[study] {style}: kept its library vector ({e})", flush=True)
                continue
            (folder / f"model-{style}.npz").unlink()          # only the vector is kept
        base = RunFolder.load(folder)
        print(f"[study] trained styles' vectors: each taught anew from {a.clip_seconds:g} s of its training "
              f"files ({len(trained) - len(kept)} of {len(trained)}), {time.perf_counter() - t0:.0f} s ({load()})",
              flush=True)
    films_before = {n: base.styles()[n].copy() for n in trained}
    probe = trained[0]
    before = rollouts(base, [probe], 4.0).positions

    report["finetune"], report["bit_identical"], runs = {}, {}, {}
    for v in a.variants:
        folder = a.work / f"run-{v}"
        if folder.exists():
            shutil.rmtree(folder)
        shutil.copytree(base.path, folder, ignore=shutil.ignore_patterns("model-*.npz", "*.lock"))
        for h in held:
            clip, secs = clip_files(held_files, h, a.clip_seconds)
            t0 = time.perf_counter()
            taught = teach_style(folder, h, [f.path for f in clip], steps=a.steps, log=lambda m: None,
                                 self_fed=VARIANTS[v],            # a new style: --replace would be an error
                                 motion=RefitSettings() if v == "motion" else None, workers=a.walk_workers)
            took = time.perf_counter() - t0
            report["finetune"][f"{v}/{h}"] = dict(
                seconds=took, clip_seconds=secs, files=[Path(f.path).name for f in clip], loss_before=taught.loss_before,
                loss_after=taught.loss_after, nearest=taught.nearest, rollout_errors=taught.rollout_errors,
                motion=None if taught.refit is None else {k: getattr(taught.refit, k) for k in
                                                         ("start_distance", "distance", "start_score", "score")})
            if taught.check is not None:            # the plain statistics of a 6 s straight walk against the clip
                k = taught.check
                report["finetune"][f"{v}/{h}"]["walk"] = k.to_dict()
                print(f"[study] {v} {h}: walked 6 s straight: {k.steps_per_s:.2f} steps/s "
                      f"(clip {k.clip_steps_per_s:.2f}), "
                      f"hips {k.hips:.3f} m (clip {k.clip_hips:.3f}), lowest toe on the floor {k.toe_on_floor:.0%}, "
                      f"{k.path_mean:.2f} m off the path", flush=True)
            if taught.refit is not None:
                f = taught.refit
                print(f"[study] {v} {h}: refined by motion, distance {f.start_distance:.0f} -> {f.distance:.0f}, "
                      f"against the nearest trained styles {f.start_score:.2f} -> {f.score:.2f}", flush=True)
            errs = " -> ".join(f"{e * 100:.1f}" for e in taught.rollout_errors)
            print(f"[study] {v} {h}: fine-tuned on {secs:.1f} s ({len(clip)} files) in {took:.1f} s; loss "
                  f"{taught.loss_before:.3f} -> {taught.loss_after:.3f}; rollout error {errs or '-'} cm; nearest "
                  f"trained {taught.nearest} ({load()})", flush=True)
        if v == "span":            # taught by teacher forcing, then moved onto the trained styles' span
            library = RunFolder.load(folder).styles()
            trained_vectors = np.stack([library[n] for n in trained]).astype(np.float64)
            for h in held:
                library.add(h, onto_span(library[h].astype(np.float64), trained_vectors))
            library.save(folder / "styles.npz")
        runs[v] = run = RunFolder.load(folder)
        same_films = all(np.array_equal(films_before[n], run.styles()[n]) for n in trained)
        same_rollout = bool(np.array_equal(before, rollouts(run, [probe], 4.0).positions))
        report["bit_identical"][v] = dict(films=same_films, rollout=same_rollout)
        print(f"[study] {v}: trained styles bit-identical after fine-tuning: FiLM vectors {same_films}, "
              f"rollout of {probe} {same_rollout}", flush=True)

    # every style's data, for the classifier and the real windows
    reference = [f for f in trained_files + held_files if not a.reference_gaits or f.gait in a.reference_gaits]
    every = write_manifest(reference, a.work / ("all.csv" if not a.reference_gaits else
                                                "reference-" + "-".join(a.reference_gaits) + ".csv"))
    ds = build_dataset(every, cache_dir=a.work / "cache", progress=False, clip_seconds=s.clip_seconds, fps=a.fps,
                       clip_stride_seconds=s.clip_seconds / 2, seed=s.seed, split_unit="files")
    t0 = time.perf_counter()
    names = trained + [f"{v}/{h}" for v in a.variants for h in held]
    generated = [rollouts(base, trained, a.generate_seconds)] + [rollouts(runs[v], held, a.generate_seconds)
                                                                 for v in a.variants]
    r = replace(generated[0], **{k: np.concatenate([getattr(g, k) for g in generated]) for k in
                                 ("positions", "rotations", "contacts", "phases", "root_positions", "root_facing",
                                  "targets", "network_positions") if getattr(generated[0], k) is not None})
    print(f"[study] {len(names)} rollouts x {a.generate_seconds:g} s generated in {time.perf_counter() - t0:.0f} s",
          flush=True)
    probs = {}
    for seed in a.seeds:
        clf, info = train_style_classifier(ds, seed=seed)
        probs[seed] = (classify_rollout(clf, ds, r, window=info["window"], stride=info["stride"]), info, clf)
    window, stride = probs[a.seeds[0]][1]["window"], probs[a.seeds[0]][1]["stride"]
    real = {}
    for split in ("train", "val", "test"):
        w, st = split_windows(ds.split(split), ds.layout, ds.stats, window, stride)
        for k, name in enumerate(ds.styles):
            if np.any(st == k):
                real.setdefault(name, []).append(window_summary(w[st == k]))
    space = StyleSpace.fit({n: np.concatenate(v) for n, v in real.items()}, summarised=True)
    # the measure's own resolution: each style's validation and test windows against the others' real windows
    # (its own from the training split), as a generated motion is measured
    train_only = {n: v[0] for n, v in real.items() if len(v[0]) >= 2}
    if len(train_only) == len(real):
        half = StyleSpace.fit(train_only, summarised=True)
        ranks = [half.rank(np.concatenate(v[1:]), n, summarised=True) for n, v in real.items() if sum(len(x) for x in v[1:]) >= 2]
        report["real_rank1"] = float(np.mean(np.array(ranks) == 1))
        print(f"[study] real held-back windows of each style rank 1 by Fréchet distance for "
              f"{report['real_rank1']:.0%} of {len(ranks)} styles (the measure's ceiling)", flush=True)
    if "figure-eight" in a.measure:
        blocks = ds.stats.normalize_clip(rollout_blocks(r), ds.layout.x_joints)
        rows = []
        for b, name in enumerate(names):
            style = name.split("/")[-1]
            target = ds.styles.index(style)
            recs = [recognition(probs[seed][0][b], target) for seed in a.seeds]
            rep = style_report(space, cut_windows(blocks[b], window, stride), style, recs)
            rep["held_out"] = "/" in name
            rep["variant"] = name.split("/")[0] if "/" in name else ""
            rows.append(rep)
        report["styles"] = rows
        tr = [x for x in rows if not x["held_out"]]
        hd = [x for x in rows if x["held_out"]]
        print()
        print_rows(rows, ("style", "held out (variant)"), lambda x: (x["target"], x["variant"]))
        summary = dict(trained_recognised_mean=float(np.mean([x["classifier"]["mean"] for x in tr])),
                       trained_rank1=float(np.mean([x["rank"] == 1 for x in tr])),
                       held_reproduced={v: int(sum(x["reproduced"] for x in hd if x["variant"] == v)) for v in a.variants},
                       held=len(held),
                       classifier_heldout_acc=[probs[k][1]["heldout_acc"] for k in a.seeds], load_end=os.getloadavg()[0])
        report["summary"] = summary
        print(f"\n[study] trained styles: recognised {summary['trained_recognised_mean']:.2f} mean, rank 1 for "
              f"{summary['trained_rank1']:.0%}; held-out reproduced (of {len(held)}) {summary['held_reproduced']}; "
              f"classifier held-out accuracy on real windows {summary['classifier_heldout_acc']} ({load()})")

    if "gaits" in a.measure:
        report["gaits"] = gaits_measure(a, ds, base, runs, trained, held, probs, window, stride)
    (a.work / "report.json").write_text(json.dumps(report, indent=1, default=float))


if __name__ == "__main__":
    main()
