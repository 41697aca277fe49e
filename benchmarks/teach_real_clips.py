"""Teaching the released network real capture it has never seen: plain figures, clip against result.

    python benchmarks/teach_real_clips.py                       # 4 Bandai-Namco-2 walking styles, 3 files each
    python benchmarks/teach_real_clips.py --styles feminine --files 2

Each style's first --files walk files of ../shared/data/bandai2 (30 fps, 22 joints: retargeted onto
the 100STYLE skeleton and resampled to 60 fps on the way in) are taught to the released network
(minifilm/pipeline/teach_released.py, nothing written), and the new style walks straight ahead
for --seconds at the clip's speed. Printed for the clip and for the result: steps per second, root
speed, median hip height, median hand heights, share of frames with the lowest toe within 3 cm of
the floor, worst bone-length coefficient of variation (the network's own prediction), and the
teaching time. Then, unless --judge-seconds 0, whether the new style's motion is recognised as
itself among all 101 styles (minifilm/pipeline/judge_taught.py): every candidate vector of the fit
and the 100 released styles walk --judge-seconds straight at the clip's speed; the released
styles' references are the first half of their own motion, the new style's is the clip; printed:
the Fréchet rank, the classifier's recognition for each of --seeds (the minimum counts), which
styles the classifiers pick and which released styles lie nearest the clip, for the vector
finetune keeps and for the one nearest the clip by Fréchet distance on the first half; also the
style's next walk file (real, not taught from) judged the same way: what a perfect generator would
score. --rollout-rounds N adds the vectors of N rounds of refitting at the states the network
visits (minifilm/pipeline/rollout_refit.py) to the candidates; --probes N judges N more vectors
near the released styles, none of them fitted, to ask whether any makes motion taken for the
clip (add_probes). Pictures (benchmarks/teach_pictures.py):
<style>.gif, the clip beside the result, and <style>.png, a contact sheet, in --out.
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

from minifilm.features.layout import FeatureLayout  # noqa: E402
from minifilm.motion.measures import bone_length_cv  # noqa: E402
from minifilm.motion.skeletons import STYLE100  # noqa: E402
from minifilm.pipeline.joint_axes import align_axes  # noqa: E402
from minifilm.pipeline.judge_taught import judge_taught  # noqa: E402
from minifilm.pipeline.rollout_refit import rollout_refit  # noqa: E402
from minifilm.pipeline.teach_adapter import AdapterPlan  # noqa: E402
from minifilm.pipeline.teach_released import clip_rows, read_clip, teach  # noqa: E402
from minifilm.pipeline.walks import candidate_rollouts, clip_summaries  # noqa: E402
from minifilm.runtime.released import load_released  # noqa: E402
from minifilm.runtime.walk_checks import count_strikes, lowest_toe  # noqa: E402
from minifilm.phases.label import label  # noqa: E402
from minifilm.motion.bvh_write import write_bvh  # noqa: E402
from minifilm.runtime.start_state import root_joint_indices  # noqa: E402
from minifilm.synthetic.generator import rest_motion  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
from teach_pictures import clip_and_result  # noqa: E402  (beside this script)
from teach_released import refit_settings  # noqa: E402  (beside this script: the --motion option)
DATA = REPO.parent / "shared" / "data"


def figures(positions, contacts, root, fps, names, parents, network_positions=None):
    """Plain statistics of motion: positions (F, J, 3), contacts (F, 2), root (F, 2)."""
    toes = [names.index("RightToe"), names.index("LeftToe")]
    hands = [names.index("RightWrist"), names.index("LeftWrist")]
    toe = lowest_toe(positions, toes)
    return dict(steps_per_s=count_strikes(contacts) / (len(positions) / fps),
                speed=float(np.mean(np.linalg.norm(np.diff(root, axis=0), axis=1)) * fps),
                hips=float(np.median(positions[:, 0, 1])),
                hands=float(np.median(positions[:, hands, 1])),
                toe_on_floor=float(np.mean(np.abs(toe) <= 0.03)), toe_median=float(np.median(toe)),
                bone_cv=float(bone_length_cv(positions if network_positions is None else network_positions,
                                             parents).max()))


def words(j: dict) -> str:
    rec = ", ".join(f"{r:.2f}" for r in j["recognition"])
    near = ", ".join(f"{n} {d:.0f}" for n, d in j["nearest"])
    picked = ", ".join(f"{n} {s:.0%}" for n, s in j["picked"])
    return (f"rank {j['rank']} (distance {j['distance']:.0f}; nearest {near}); recognised min {j['recognition_min']:.2f} "
            f"(seeds {rec}); classifiers pick {picked}")


def unseen_summaries(rel, layout, style: str, taught_files: int):
    """Window summaries of the style's next walk file (not taught from), aligned as the clip is."""
    files = sorted((DATA / "bandai2").glob(f"dataset-2_walk_{style}_*.bvh"))[taught_files:taught_files + 1]
    if not files:
        return None
    motion, _ = read_clip(files[0], log=lambda m: None)
    rows = clip_rows([motion], files, style)
    rows.x, rows.z, _ = align_axes(rows.x, rows.z, layout, rel.stats)
    return clip_summaries(rows, rel.stats, layout)


def add_rollout_rounds(rel, layout, taught, rounds: int, row: dict) -> None:
    """The rollout refit's vectors join the candidates (to be judged beside the fit's)."""
    t0 = time.perf_counter()
    res = rollout_refit(rel, layout, taught, rounds=rounds)
    row["rollout_rounds"] = [{k: v for k, v in r.items() if k != "film"} for r in res]
    for k, r in enumerate(res):
        print(f"    rollout round {k + 1}: visited poses {r['pose_distance']:.2f} σ from the clip's nearest; loss on the "
              f"visited rows {r['loss_before']:.3f} -> {r['loss_after']:.3f}", flush=True)
        taught.candidates.append({"label": f"rollout round {k + 1}"})
    taught.candidate_films = np.concatenate([taught.candidate_films, np.stack([r["film"] for r in res])])
    print(f"    rollout refit: {time.perf_counter() - t0:.0f} s", flush=True)


def add_probes(rel, taught, n: int, seed: int = 0) -> None:
    """``n`` more vectors the network can walk join the candidates, to ask whether any vector near
    the released styles makes motion the judge takes for the clip (a ceiling for teaching in that
    region, not a fit): a third are blends of two of the 10 released styles nearest the kept vector
    (weights 0.25-0.75), a third the kept vector moved along the 16 leading principal directions of
    the released vectors (σ 0.4-1.2 of the styles' spread), a third the kept vector moved past each
    of those 10 styles (1.0-1.5 times the way to it). Seeded, the same for every clip."""
    from minifilm.pipeline.motion_refit import style_directions
    rng = np.random.default_rng(seed)
    names = list(rel.styles)
    V = np.stack([rel.styles[m] for m in names]).astype(np.float64)
    start = np.asarray(taught.film, np.float64)
    near = V[np.argsort(np.linalg.norm(V - start, axis=1))[:10]]
    directions, scales = style_directions(V, 16)
    probes, k = [], n // 3
    for _ in range(k):
        a, b = rng.choice(10, 2, replace=False)
        w = rng.uniform(0.25, 0.75)
        probes.append(w * near[a] + (1 - w) * near[b])
    for _ in range(k):
        probes.append(start + (rng.uniform(0.4, 1.2) * rng.standard_normal(len(scales)) * scales) @ directions)
    for _ in range(n - 2 * k):
        probes.append(start + rng.uniform(1.0, 1.5) * (near[rng.integers(10)] - start))
    for i in range(n):
        taught.candidates.append({"label": f"probe {i + 1}"})
    taught.candidate_films = np.concatenate([taught.candidate_films, np.stack(probes).astype(np.float32)])


def print_ceiling(taught, judged, first_probe: int) -> dict:
    """The best any probe (add_probes) reached: rank, recognition, and how many met both targets."""
    probes = judged["candidates"][first_probe:]
    met = [j for j in probes if j["rank"] == 1 and j["recognition_min"] >= 0.8]
    best_rank = min(j["rank"] for j in probes)
    best_rec = max(j["recognition_min"] for j in probes)
    print(f"    {len(probes)} probe vectors: best rank {best_rank}, best recognition (min of seeds) {best_rec:.2f}; "
          f"rank 1 and recognised >= 0.8: {len(met)}", flush=True)
    return dict(probes=len(probes), best_rank=int(best_rank), best_recognition=float(best_rec), met=len(met),
                rank1=int(sum(j["rank"] == 1 for j in probes)))


def print_judged(style, taught, judged) -> None:
    print(f"    judged among {judged['n_styles']} styles (released styles ranking themselves first: "
          f"{judged['released_self']}/{judged['n_styles'] - 1}); the clip itself is nearest "
          + ", ".join(f"{n} {d:.0f}" for n, d in judged["clip_nearest"]))
    s = judged["released_spread"]
    print(f"    a released style's second half lies {s['own']:.0f} from its first half, {s['nearest_other']:.0f} from "
          f"the nearest other style (medians)")
    if judged["unseen"] is not None:
        print(f"    the style's next file (real, not taught from) as if generated: {words(judged['unseen'])}")
    print("    clip minus kept motion, in σ of all references: "
          + ", ".join(f"{n} {what} {d:+.1f}" for n, what, d in judged["gap"]))
    for i, (c, j) in enumerate(zip(taught.candidates, judged["candidates"])):
        mark = (" <- kept by finetune" if i == judged["chosen_index"] else "") + (
            " <- nearest the clip (first half)" if i == judged["by_frechet"] else "")
        print(f"    {c.get('label') or 'λ=%g' % c['prior_weight']}: {words(j)}; to the clip on the first half "
              f"{j['clip_distance_first_half']:.0f}{mark}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", type=Path, default=DATA / "released-lpn")
    ap.add_argument("--styles", nargs="*", default=["feminine", "elderly", "exhausted", "active"])
    ap.add_argument("--files", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--judge-seconds", type=float, default=20.0, help="rollout judged by classifier and Fréchet "
                                                                       "rank (0: skip)")
    ap.add_argument("--rollout-rounds", type=int, default=0,
                    help="also refit the kept vector at the states it visits, this many rounds "
                         "(minifilm/pipeline/rollout_refit.py); each round's vector is judged too")
    ap.add_argument("--probes", type=int, default=0,
                    help="also judge this many vectors near the released styles (blends of those nearest the "
                         "kept vector, moves along their principal directions and past them): does any make "
                         "motion taken for the clip? (a ceiling for teaching there)")
    ap.add_argument("--seeds", type=int, default=3, help="classifier seeds (the minimum recognition counts)")
    ap.add_argument("--motion", default="", help="settings of the refinement by motion other than finetune's, e.g. "
                                                 "'population=32,elite=8' (RefitSettings' fields)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--out", type=Path, help="folder for <style>_clip.bvh (retargeted), <style>_taught.bvh and "
                                             "the pictures <style>.gif / .png, the clip beside the result "
                                             "(default: a new temporary folder)")
    args = ap.parse_args()
    args.out = args.out or Path(tempfile.mkdtemp(prefix="teach-real-clips-"))
    rel = load_released(args.params)
    layout = FeatureLayout.for_skeleton(STYLE100)
    names, parents = list(layout.joint_names), layout.parents
    rows = []
    for style in args.styles:
        files = sorted((DATA / "bandai2").glob(f"dataset-2_walk_{style}_*.bvh"))[:args.files]
        read = [read_clip(f, log=lambda m: None) for f in files]
        motions = [m for m, _ in read]
        t0 = time.perf_counter()
        taught = teach(rel, layout, style, motions, files, align=True, motion=refit_settings(args.motion),
                       adapter=AdapterPlan("off"), log=lambda m: None)    # the FiLM route alone: teach_adapter.py
        seconds = time.perf_counter() - t0
        clip = []
        for m in motions:
            lab = label(m, STYLE100, style)
            world = m.world()[0][:, STYLE100.joint_indices(m)]
            clip.append(figures(world, lab.contacts, world[:, 0, [0, 2]], 60.0, names, parents))
        clip = {k: float(np.mean([c[k] for c in clip])) for k in clip[0]}
        r, _ = candidate_rollouts(rel.network, layout, taught.film[None], taught.clip.speed, args.seconds + 1)
        k0 = 60
        result = figures(r.positions[0, k0:], r.contacts[0, k0:], r.root_positions[0, k0:], 60.0, names, parents,
                         r.network_positions[0, k0:])
        row = dict(style=style, files=[f.name for f in files], clip_seconds=taught.clip.seconds,
                   teach_seconds=seconds, share_beyond=taught.distance.share_beyond,
                   share_as_retargeted=taught.distance.share_as_read, start_loss=taught.distance.start_loss,
                   own_loss=taught.distance.known_losses[0], loss=taught.loss, nearest=taught.nearest,
                   best_known=taught.best_known, clip=clip, result=result, words=taught.check.words())
        rows.append(row)
        args.out.mkdir(parents=True, exist_ok=True)
        skeleton = rest_motion()
        clip_bvh, taught_bvh = args.out / f"{style}_clip.bvh", args.out / f"{style}_taught.bvh"
        write_bvh(motions[0], clip_bvh, scale=STYLE100.bvh_scale)
        write_bvh(r.to_motion(skeleton, root_joint_indices(layout, skeleton)).slice(k0, r.positions.shape[1]),
                  taught_bvh, scale=STYLE100.bvh_scale)
        pictures = clip_and_result(clip_bvh, taught_bvh, args.out, style, (f"{style} clip", f"{style} taught"))
        print(f"{style}: {len(files)} files, {taught.clip.seconds:.1f} s, taught in {seconds:.1f} s; beyond 5 σ "
              f"{taught.distance.share_as_read:.1%} as retargeted -> {taught.distance.share_beyond:.1%} aligned; loss "
              f"{taught.distance.start_loss:.3f} ({taught.best_known}) -> {taught.loss:.3f} (own {row['own_loss']:.3f})",
              flush=True)
        for key in clip:
            print(f"    {key:13s} clip {clip[key]:7.3f}   result {result[key]:7.3f}")
        print(f"    check: {taught.check.words()}; pictures: {', '.join(str(p) for p in pictures) or 'none'}",
              flush=True)
        if args.rollout_rounds > 0:
            add_rollout_rounds(rel, layout, taught, args.rollout_rounds, row)
        first_probe = len(taught.candidates)
        if args.probes > 0:
            add_probes(rel, taught, args.probes)
        if args.judge_seconds > 0:
            row["judged"] = judged = judge_taught(rel, layout, taught, args.judge_seconds, seeds=range(args.seeds),
                                                  unseen=unseen_summaries(rel, layout, style, args.files))
            if args.probes > 0:
                row["ceiling"] = print_ceiling(taught, judged, first_probe)
                judged["candidates"] = judged["candidates"][:first_probe]       # the fit's own, printed below
                taught.candidates = taught.candidates[:first_probe]
            print_judged(style, taught, judged)
    print(f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
