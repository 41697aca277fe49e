"""Real clips taught to the released network with an adapter of their own, judged on a figure-eight.

    python benchmarks/teach_adapter.py                                   # the four held-out styles
    python benchmarks/teach_adapter.py --styles normal --routes film lowrank:8:0.25 residual:0:0.5
    python benchmarks/teach_adapter.py --timing --styles elderly         # the teaching time alone

Each style's first --files walk files of ../shared/data/bandai2 are taught as ``minifilm finetune
--params`` teaches them (minifilm/pipeline/teach_released.py: retargeted, resampled, labelled, the
joint axes aligned, a FiLM vector fitted teacher-forced; no refinement by motion), then, per route
``kind:rank:replay[:steps[:noise]]``, an adapter is fitted beside the vector
(minifilm/pipeline/teach_adapter.py); the route ``film`` is the vector alone. Each result walks
--seconds along a figure-eight at the clip's speed, driven as ``minifilm generate`` drives the
released network (its speed calibrated, every frame put on the skeleton and fed back), and the
walk after its first second is judged against the clip:

    steps     foot strikes per second within 25 % of the clip's
    floor     at most 10 % of frames with the lower toe more than 5 cm above the floor or below -3 cm
    hips      median hip height within 8 % of the clip's
    style     at least half of its 0.75 s windows given to the clip's style by a nearest-centroid
              classifier among six styles (minifilm/evaluation/nearest_centroid.py): the five
              Bandai-Namco-2 styles, each from walk and turn files it was not taught from (aligned
              as the clip is), and the released style with the lowest loss on the clip (the one the
              fit starts from), walking the same figure-eight

Pictures (--out): per style and route, <style>_<route>.png, the clip (top row) beside the walk
(bottom row) at 0.5-3.5 s, and a GIF of both (benchmarks/teach_pictures.py).
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from minifilm.evaluation.nearest_centroid import NearestCentroid  # noqa: E402
from minifilm.evaluation.style_judge import motion_block, rows_block, summaries  # noqa: E402
from minifilm.features.layout import FeatureLayout  # noqa: E402
from minifilm.motion.bvh_write import write_bvh  # noqa: E402
from minifilm.motion.skeletons import STYLE100  # noqa: E402
from minifilm.pipeline.joint_axes import align_axes  # noqa: E402
from minifilm.pipeline.teach_adapter import (AdapterPlan, adapted_condition, fit_style_adapter,  # noqa: E402
                                             released_controller)
from minifilm.pipeline.teach_released import clip_rows, normalised, read_clip, teach, teach_released  # noqa: E402
from minifilm.runtime.adapted import AdaptedNetwork  # noqa: E402
from minifilm.runtime.calibration import calibrate_speed  # noqa: E402
from minifilm.runtime.control import make_script  # noqa: E402
from minifilm.runtime.controller import Controller  # noqa: E402
from minifilm.runtime.released import load_released  # noqa: E402
from minifilm.runtime.start_state import root_joint_indices  # noqa: E402
from minifilm.runtime.walk_checks import count_strikes, lowest_toe  # noqa: E402
from minifilm.synthetic.generator import rest_motion  # noqa: E402
from minifilm.train.adapter_fit import AdapterSettings  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
from teach_pictures import clip_and_result  # noqa: E402  (beside this script)
DATA = REPO.parent / "shared" / "data"
STYLES = ("active", "elderly", "exhausted", "feminine", "normal")
FPS = 60.0


def files_of(style: str, content: str, first: int, count: int):
    return sorted((DATA / "bandai2").glob(f"dataset-2_{content}_{style}_*.bvh"))[first:first + count]


def aligned_rows(rel, layout, files, style):
    rows = clip_rows([read_clip(f, log=lambda m: None)[0] for f in files], files, style)
    rows.x, rows.z, _ = align_axes(rows.x, rows.z, layout, rel.stats)
    return rows


def references(rel, layout, taught_files: int):
    """style -> window summaries of its walk files after the taught ones (4) and its first two turn files
    each way, every file aligned on its own as a clip is."""
    out = {}
    for style in STYLES:
        files = (files_of(style, "walk", taught_files, 4) + files_of(style, "walk-turn-left", 0, 2)
                 + files_of(style, "walk-turn-right", 0, 2))
        out[style] = np.concatenate([summaries(rows_block(aligned_rows(rel, layout, [f], style).x, rel.stats, layout))
                                     for f in files])
    return out


def figure_eight(network, layout, cond, speed: float, seconds: float):
    """``cond`` walked along a figure-eight at ``speed`` as ``minifilm generate`` drives the released
    network (the speed calibrated for the style first)."""
    cal = calibrate_speed(Controller(network, layout, fps=FPS), cond)
    ctrl = released_controller(network, layout, FPS)
    return ctrl.run(make_script("figure8", seconds, speed=speed), int(round(seconds * FPS)), cond, calibration=cal)


def walk_motion(r, layout):
    """The walk ``r`` after its first second (the start from the mean pose), as a Motion."""
    skeleton = rest_motion()
    return r.to_motion(skeleton, root_joint_indices(layout, skeleton)).slice(int(FPS), r.positions.shape[1])


def judged(r, clip, layout, stats, classifier, target):
    """The four criteria (module docstring) of the walk ``r`` after its first second -> (figures, motion)."""
    names = list(layout.joint_names)
    k0 = int(FPS)
    P = r.positions[0, k0:]
    toe = lowest_toe(P, [names.index("RightToe"), names.index("LeftToe")])
    steps = count_strikes(r.contacts[0, k0:]) / (len(P) / FPS)
    hips = float(np.median(P[:, 0, 1]))
    motion = walk_motion(r, layout)
    shares = classifier.shares(summaries(motion_block(motion, stats, layout)))
    out = dict(steps_per_s=steps, steps_ratio=steps / clip.steps_per_s, off_floor=float(np.mean((toe > 0.05) | (toe < -0.03))),
               hips=hips, hips_ratio=hips / clip.hips, recognised=shares.get(target, 0.0),
               picked={k: v for k, v in shares.items() if v > 0})
    out["passes"] = dict(steps=abs(out["steps_ratio"] - 1) <= 0.25, floor=out["off_floor"] <= 0.10,
                         hips=abs(out["hips_ratio"] - 1) <= 0.08, style=out["recognised"] >= 0.5)
    out["all"] = all(out["passes"].values())
    return out, motion


def parse_route(text: str):
    """'film' -> None; 'kind:rank:replay[:steps[:noise]]' -> AdapterSettings."""
    if text == "film":
        return None
    parts = text.split(":")
    kw = dict(kind=parts[0], rank=int(parts[1]), replay=float(parts[2]))
    if len(parts) > 3:
        kw["steps"] = int(parts[3])
    if len(parts) > 4:
        kw["noise"] = float(parts[4])
    return AdapterSettings(**kw)


def timing(args, out: Path) -> None:
    """The teaching time of ``minifilm finetune --params NET --name NAME --out PACK CLIP...`` with its
    defaults in one process (teach_released.teach_released, what the command calls), per style."""
    for i, style in enumerate(args.styles):
        files = files_of(style, "walk", 0, args.files)
        t0, c0 = time.perf_counter(), time.process_time()
        taught = teach_released(args.params, style.title(), files, out / f"pack-{i}-{style}", workers=0,
                                log=lambda m: None)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        kind = taught.adapter_info["kind"] if taught.adapter_info else "none"
        print(f"{style}: {taught.clip.seconds:.1f} s of clip taught in {wall:.1f} s ({cpu:.1f} s of CPU; adapter: {kind}; "
              f"the fit and adapter alone {taught.seconds:.1f} s); load {os.getloadavg()[0]:.1f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", type=Path, default=DATA / "released-lpn")
    ap.add_argument("--styles", nargs="*", default=["active", "elderly", "exhausted", "feminine"])
    ap.add_argument("--routes", nargs="*", default=["film", "lowrank:8:0.25"])
    ap.add_argument("--files", type=int, default=2, help="walk files taught from, per style")
    ap.add_argument("--seconds", type=float, default=21.0, help="the figure-eight walk (the first second is cut)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timing", action="store_true", help="time `minifilm finetune --params` itself (its defaults, "
                                                          "one process) on each style's clip; judge nothing")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--out", type=Path, help="folder for the pictures (default: a new temporary folder)")
    args = ap.parse_args()
    rel = load_released(args.params)
    layout = FeatureLayout.for_skeleton(STYLE100)
    out = args.out or Path(tempfile.mkdtemp(prefix="teach-adapter-"))
    out.mkdir(parents=True, exist_ok=True)
    if args.timing:
        return timing(args, out)
    refs = references(rel, layout, args.files)
    rows = []
    for style in args.styles:
        files = files_of(style, "walk", 0, args.files)
        motions = [read_clip(f, log=lambda m: None)[0] for f in files]
        t0 = time.perf_counter()
        taught = teach(rel, layout, style, motions, files, align=True, motion=None, workers=0,
                       adapter=AdapterPlan("off"), log=lambda m: None)
        film_seconds = time.perf_counter() - t0
        clip = taught.clip
        print(f"{style}: {clip.seconds:.1f} s of clip, FiLM vector in {film_seconds:.1f} s; outside the style space: "
              f"{taught.distance.far()} ({taught.distance.share_beyond:.1%} beyond 5 σ; loss {taught.loss:.3f}, the "
              f"nearest style {taught.best_known} on its own motion {taught.distance.known_losses[0]:.3f})", flush=True)
        classifier = None
        if refs is not None:
            own = walk_motion(figure_eight(rel.network, layout, rel.styles[taught.best_known], clip.speed,
                                           args.seconds), layout)
            classifier = NearestCentroid.fit({**refs, f"released {taught.best_known}": summaries(
                motion_block(own, rel.stats, layout))})
            clip_shares = classifier.shares(summaries(rows_block(clip.x, rel.stats, layout)))
            print(f"    the clip itself: {clip_shares.get(style, 0):.2f} of its windows given to {style}", flush=True)
            write_bvh(motions[0], out / f"{style}_clip.bvh", scale=STYLE100.bvh_scale)
        for route in args.routes:
            settings = parse_route(route)
            t1 = time.perf_counter()
            network, cond, info = rel.network, taught.film, {}
            if settings is not None:
                settings = AdapterSettings(**{**settings.__dict__, "seed": args.seed})
                plan = AdapterPlan(settings.kind, settings)
                adapter, info = fit_style_adapter(rel.model, rel.network, lambda n: released_controller(n, layout),
                                                  normalised(rel.stats, clip), taught.film, rel.styles, clip.speed,
                                                  plan, settings.kind, log=lambda m: None)
                network, cond = AdaptedNetwork(rel.network, [adapter]), adapted_condition(taught.film)
            teach_seconds = film_seconds + time.perf_counter() - t1
            row = dict(style=style, route=route, clip_seconds=clip.seconds, teach_seconds=teach_seconds,
                       adapter={k: v for k, v in info.items() if k != "replay_styles"},
                       clip=dict(steps_per_s=clip.steps_per_s, hips=clip.hips, speed=clip.speed))
            print(f"  {route}: taught in {teach_seconds:.1f} s" + (
                f" (held-out loss {info['holdout_loss_film_alone']:.3f} -> {info['holdout_loss']:.3f}, replay "
                f"{info['replay_loss']:.4f})" if info else ""), flush=True)
            if classifier is not None:
                r = figure_eight(network, layout, cond, clip.speed, args.seconds)
                row["judged"], motion = judged(r, clip, layout, rel.stats, classifier, style)
                j = row["judged"]
                print(f"    steps/s {j['steps_per_s']:.2f} (clip {clip.steps_per_s:.2f}, x{j['steps_ratio']:.2f}); off the "
                      f"floor {j['off_floor']:.0%}; hips {j['hips']:.3f} m (clip {clip.hips:.3f}, x{j['hips_ratio']:.3f}); "
                      f"recognised {j['recognised']:.2f} ("
                      + ", ".join(f"{k} {v:.2f}" for k, v in j["picked"].items()) + f"); passes "
                      f"{sum(j['passes'].values())}/4" + (" ALL" if j["all"] else ""), flush=True)
                tag = f"{style}_{route.replace(':', '-')}"
                write_bvh(motion, out / f"{tag}.bvh", scale=STYLE100.bvh_scale)
                clip_and_result(out / f"{style}_clip.bvh", out / f"{tag}.bvh", out, tag, (f"{style} clip", route),
                                log=lambda m: print(m))
            rows.append(row)
    print(f"pictures in {out}; load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1, default=float))


if __name__ == "__main__":
    main()
