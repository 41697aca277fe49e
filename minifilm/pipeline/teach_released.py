"""Teach the authors' released network a new style from a user's clip (docs/teaching-released.md).

    clip(s) of any humanoid rig -> 100STYLE rig, 60 fps -> labels -> x, p, z rows (normalised with
    the network's statistics) -> how far they lie from the network's data (warnings) -> a FiLM
    vector fitted through the frozen Ω and Φ under a prior from the network's own styles
    (minifilm/train/film_fit.py) -> the candidate vectors rolled out, the one whose motion is
    closest to the clip kept -> that vector moved until the network's own walk in it looks like
    the clip (minifilm/pipeline/motion_refit.py), or, when the clip lies outside the style space,
    an adapter of the style's own fitted beside it instead (minifilm/pipeline/teach_adapter.py)
    -> a style pack (minifilm/runtime/style_pack.py)

The released network is never written: the new style lives in the pack folder, which
``minifilm generate / demo --params NET --styles PACK`` read beside the network's own styles.
"""
from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, List, Optional, Sequence

import numpy as np

from minifilm.errors import InputError
from minifilm.features.compute import frame_features
from minifilm.features.layout import FeatureLayout
from minifilm.files import check_name, folder_lock
from minifilm.motion.bvh import read_bvh
from minifilm.motion.editing import resample
from minifilm.motion.motion import Motion
from minifilm.motion.skeletons import STYLE100
from minifilm.phases.label import label
from minifilm.body.read import Body, read_source
from minifilm.body.retarget_clip import retarget_motion
from minifilm.body.target import load_rig
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.released import load_released
from minifilm.runtime.style_pack import load_pack_or_empty
from minifilm.runtime.walk_checks import count_strikes, walk_report
from minifilm.pipeline.joint_axes import align_axes
from minifilm.pipeline.motion_refit import RefitSettings, refine_by_motion
from minifilm.parallel import executor, map_in_order, worker_count
from minifilm.pipeline.teach_adapter import (AdapterPlan, adapted_check, adapter_kind, fit_style_adapter,
                                             released_controller)
from minifilm.pipeline.walks import (CHECK_SECONDS, FPS, WALK_WORKERS, FaultCheck, candidate_rollouts,  # noqa: F401
                                     clip_summaries, straight_path, walk)     # (WALK_WORKERS: for the command's help)
from minifilm.synthetic.generator import rest_motion
from minifilm.train.film_fit import FitSettings, FrozenRows, StylePrior, fit_film

RECOMMENDED_SECONDS = 10.0        # shorter clips are taught, with a warning
SIGMA = 5.0                       # a normalised feature beyond this many σ of the network's data is "far"
FAR_SHARE = 0.01                  # ... and a clip with more than this share of such numbers
PRIOR_WEIGHTS = (0.3, 1.0, 3.0)   # λ of the fit: the candidates the rollouts choose between


class ClipError(InputError):
    """A clip that cannot teach a style (no steps, too short for a single row, not a humanoid)."""


@dataclass
class ClipRows:
    """The clip as the network sees it: raw and normalised rows, and plain figures of the motion."""
    x: np.ndarray
    p: np.ndarray
    z: np.ndarray
    seconds: float
    steps_per_s: float
    hips: float                   # median hip height, m
    speed: float                  # mean root speed, m/s
    sources: List[dict] = field(default_factory=list)


def read_clip(path, log: Callable[[str], None] = print):
    """One BVH file on the 100STYLE skeleton at 60 fps: -> (Motion, retargeted). Another rig is
    retargeted, another frame rate resampled, another unit than the skeleton's usual one read as
    such (:meth:`~minifilm.body.read.Body.on_skeleton`), and each is said."""
    body = Body(read_bvh(path, scale=1.0))
    if body.motion.n_frames < 2:
        raise ClipError(f"{path}: {body.motion.n_frames} frame: too short to teach a style")
    missing = [n for n in FeatureLayout.for_skeleton(STYLE100).joint_names if n not in body.motion.names]
    if not missing:
        motion, unit = body.on_skeleton(STYLE100)
        if unit is not None:
            log(f"    {Path(path).name}: {unit.how}")
    else:
        source, roles = read_source(path)
        motion = retarget_motion(source, load_rig("100style"), roles)
        log(f"    {Path(path).name}: not on the 100STYLE skeleton ({len(source.names)} joints, hips {roles.hips!r}); "
            "retargeted onto it")
    if abs(motion.fps - FPS) > 1e-3 * FPS:
        log(f"    {Path(path).name}: {motion.fps:g} fps resampled to the network's {FPS:g} fps")
        motion = resample(motion, FPS)
    return motion, bool(missing)


def clip_rows(motions: Sequence[Motion], files: Sequence, name: str, require_steps: bool = True) -> ClipRows:
    """Rows of every file (labelled with minifilm's contacts and local phases), concatenated, and
    plain figures of the clip (steps per second, hip height, root speed)."""
    xs, ps, zs, sources, strikes, hips, speeds = [], [], [], [], 0, [], []
    for motion, path in zip(motions, files):
        lab = label(motion, STYLE100, name)
        rows = frame_features(motion, STYLE100, lab.vectors, lab.contacts, fps=FPS)
        xs.append(rows.x), ps.append(rows.p), zs.append(rows.z)
        strikes += count_strikes(lab.contacts)
        world = motion.world()[0][:, STYLE100.joint_indices(motion)]       # (F, J, 3)
        hips.append(world[:, 0, 1])
        speeds.append(np.linalg.norm(np.diff(world[:, 0, [0, 2]], axis=0), axis=1) * FPS)
        sources.append({"file": Path(path).name, "frames": int(motion.n_frames), "fps": FPS})
    seconds = sum(m.n_frames for m in motions) / FPS
    if sum(len(x) for x in xs) < 10:
        raise ClipError(f"{files[0]}: too short to teach a style ({seconds:.2f} s)")
    if strikes < 2 and require_steps:
        raise ClipError(f"{', '.join(str(f) for f in files)}: fewer than two foot steps in {seconds:.1f} s (a style "
                        "is learnt from locomotion: walk or run in it for a few steps)")
    return ClipRows(np.concatenate(xs), np.concatenate(ps), np.concatenate(zs), seconds, strikes / seconds,
                    float(np.median(np.concatenate(hips))), float(np.mean(np.concatenate(speeds))), sources)


@dataclass
class Distance:
    """How far the clip's inputs lie from the network's data, in the network's own σ units."""
    share_beyond: float           # share of (row, input feature) values beyond SIGMA σ
    worst: List[tuple]            # [(feature name, share of rows beyond SIGMA σ)] worst first
    start_loss: float             # loss of the clip's rows at the nearest known style's vector
    known_losses: List[float]     # the known styles' own loss on their own motion, for comparison
    share_as_read: Optional[float] = None   # share beyond SIGMA before the joint axes were aligned
    axis_turns: Optional[np.ndarray] = None  # degrees per joint (align_axes), None: not aligned

    def far(self) -> bool:
        """Far outside: more than FAR_SHARE of the input numbers beyond SIGMA, or a start loss over 3x
        the known style's own."""
        own = self.known_losses[0] if self.known_losses else None
        return self.share_beyond > FAR_SHARE or (own is not None and self.start_loss > 3 * own)

    def words(self) -> str:
        worst = ", ".join(f"{n} ({s:.0%} of frames)" for n, s in self.worst if s > 0) or "none"
        text = (f"{self.share_beyond:.1%} of the clip's normalised input numbers lie beyond {SIGMA:g} σ of the "
                f"network's data (worst: {worst})")
        if self.axis_turns is not None:
            text += (f"; {self.share_as_read:.1%} as retargeted, before each joint's axes were turned to the "
                     f"network's convention (median {np.median(self.axis_turns):.0f}°, up to "
                     f"{np.max(self.axis_turns):.0f}°)")
        return text


def input_distance(x_norm: np.ndarray, layout: FeatureLayout, top: int = 3) -> tuple:
    """(share of values beyond SIGMA, [(name, share of rows)] of the ``top`` worst input features)."""
    far = np.abs(x_norm) > SIGMA
    per_feature = far.mean(axis=0)
    names = [f"{c.joint} {c.quantity}" if c.joint else c.quantity for c in layout.describe("x")]
    order = np.argsort(-per_feature)[:top]
    return float(far.mean()), [(names[i], float(per_feature[i])) for i in order]


@dataclass
class TaughtStyle:
    name: str
    film: np.ndarray
    seconds: float                # teaching time (fit and rollouts), wall clock
    clip: ClipRows
    distance: Distance
    loss: float                   # at the chosen vector, all rows
    nearest: str                  # nearest known style in FiLM space
    best_known: str               # known style with the lowest loss on the clip
    check: object                 # WalkReport of the chosen vector's rollout
    candidates: List[dict] = field(default_factory=list)
    candidate_films: Optional[np.ndarray] = None   # (len(candidates), 2048): every fitted vector
    adapter: object = None        # the style's StyleAdapter (teach_adapter.py), or None
    adapter_info: Optional[dict] = None

    def pack_info(self) -> dict:
        return {"taught_from": self.clip.sources,
                "clip": {"seconds": self.clip.seconds, "steps_per_s": self.clip.steps_per_s,
                         "hips": self.clip.hips, "speed": self.clip.speed},
                "fit": {"loss": self.loss, "start_loss": self.distance.start_loss, "seconds": self.seconds,
                        "nearest_style": self.nearest, "lowest_loss_style": self.best_known,
                        "share_beyond_5_sigma": self.distance.share_beyond,
                        "share_beyond_5_sigma_as_retargeted": self.distance.share_as_read,
                        "axis_turns_degrees": None if self.distance.axis_turns is None
                        else [round(float(a), 1) for a in self.distance.axis_turns],
                        "worst_features": [list(w) for w in self.distance.worst], "candidates": self.candidates},
                "checks": self.check.to_dict(), "adapter": self.adapter_info}


def normalised(stats, clip: ClipRows):
    return stats.normalize_x(clip.x), stats.normalize_p(clip.p), stats.normalize_z(clip.z)


def own_loss(rel, rollout, character: int, film: np.ndarray, name: str) -> float:
    """The loss of a known style's vector on its own generated motion, labelled as a clip is."""
    skeleton = rest_motion()
    from_layout = FeatureLayout.for_skeleton(STYLE100)
    motion = rollout.to_motion(skeleton, root_joint_indices(from_layout, skeleton), character=character)
    motion = motion.slice(int(FPS), motion.n_frames)              # after the start from the mean pose
    own = clip_rows([motion], [f"{name} (generated)"], name, require_steps=False)   # it may not step
    x, p, z = normalised(rel.stats, own)
    return FrozenRows(rel.model, x, p, z).loss(film)


def rollout_score(report, clip: ClipRows) -> float:
    """Lower is closer to the clip: steps per second (log ratio), hip height (relative), feet on
    the floor. The loss is not used: a vector can fit the rows and not walk."""
    steps = abs(np.log(max(report.steps_per_s, 0.05) / max(clip.steps_per_s, 0.05)))
    return steps + 5 * abs(report.hips / clip.hips - 1) + (1 - report.toe_on_floor)


def teach(rel, layout: FeatureLayout, name: str, motions: Sequence[Motion], files: Sequence,
          known: Optional[dict] = None, settings: FitSettings = FitSettings(),
          prior_weights: Sequence[float] = PRIOR_WEIGHTS, choose_by_rollout: bool = True,
          align: bool = False, require_steps: bool = True, motion: Optional[RefitSettings] = RefitSettings(),
          workers: Optional[int] = None, adapter: AdapterPlan = AdapterPlan(),
          log: Callable[[str], None] = print) -> TaughtStyle:
    """Fit ``name`` to the clip(s) on the loaded released network ``rel``; ``known``: the styles
    the prior is made of (default all of the network's); ``align``: turn the joint axes to the
    network's convention (:func:`align_axes`; for retargeted clips); ``motion``: how the kept vector
    is then refined by the motion it makes (:func:`refine_by_motion`; None or 0 rounds: not at
    all); ``workers``: processes that share the teacher-forced fits and the refinement's walks
    (minifilm/parallel.py; default: every usable core, at most WALK_WORKERS; 1: all in this
    process; one when not refining); ``adapter``: whether and how the style gets an adapter of its
    own (teach_adapter.py; with one, the vector is not refined by motion). Nothing is written."""
    clip = clip_rows(motions, files, name, require_steps)
    refining = motion is not None and motion.rounds > 0
    n = worker_count(workers, WALK_WORKERS) if refining else 1
    with executor(n, n) as pool:
        return _teach(rel, layout, name, clip, known, settings, prior_weights, choose_by_rollout, align,
                      motion if refining else None, pool, n, adapter, log)


def _teach(rel, layout, name, clip, known, settings, prior_weights, choose_by_rollout, align, motion, pool, shares,
           plan, log):
    """:func:`teach` with the clip's rows made and the pool of ``shares`` workers open (None: this
    process alone; ``motion``: None when not refining)."""
    known = dict(rel.styles if known is None else known)
    names = list(known)
    V = np.stack([known[n] for n in names]).astype(np.float64)
    share_as_read, turns = None, None
    if align:
        share_as_read = input_distance(rel.stats.normalize_x(clip.x), layout)[0]
        clip.x, clip.z, turns = align_axes(clip.x, clip.z, layout, rel.stats)
    windows = clip_summaries(clip, rel.stats, layout)       # the clip's windows, as taught (axes turned)
    motion = motion if len(windows) >= 2 else None          # too short to measure a walk against: no refining
    walks = functools.partial(walk, rel.network, layout, rel.stats, pool=pool, shares=shares)
    x, p, z = normalised(rel.stats, clip)
    share, worst = input_distance(x, layout)
    if adapter_kind(plan, share > FAR_SHARE, 0.0, 0.0) is not None:
        motion = None          # an adapter whatever the fit gives (step 7): no refinement, no known walks
    t0 = time.perf_counter()
    rows = FrozenRows(rel.model, x, p, z)
    sub = np.arange(0, len(rows), max(1, len(rows) // 600))
    losses = np.array([rows.loss(v, sub) for v in V])
    best_known = names[int(np.argmin(losses))]
    distance = Distance(share, worst, float(losses.min()), [], share_as_read, turns)
    prior = StylePrior.from_vectors(V)
    # one candidate per prior weight, each fit in a worker (the same fit wherever it runs)
    fits = [FitSettings(**{**settings.__dict__, "prior_weight": lam}) for lam in prior_weights]
    start = V[int(np.argmin(losses))]
    fitted = map_in_order(functools.partial(fit_film, rows, prior, start), fits, 1 if pool is None else pool,
                          doing="fitting", name=lambda f: f"the vector of prior weight {f.prior_weight:g}")
    candidates, films = [], []
    for lam, fit in zip(prior_weights, fitted):
        candidates.append({"prior_weight": lam, "loss": fit.loss, "holdout_loss": fit.holdout_loss,
                           "steps": fit.steps})
        films.append(fit.film)
    # one batch: every candidate, and the closest known style (its own loss on its own motion is
    # the yardstick the clip's loss is printed beside)
    ref = start
    r, path = candidate_rollouts(rel.network, layout, np.stack(films + [ref]).astype(np.float32), clip.speed)
    toes = [list(layout.joint_names).index(t) for t in ("RightToe", "LeftToe")]
    reports = [walk_report(r, b, toes, path, clip_steps_per_s=clip.steps_per_s, clip_hips=clip.hips)
               for b in range(len(films))]
    scores = [rollout_score(rep, clip) for rep in reports]
    for c, rep, s in zip(candidates, reports, scores):
        c.update(rollout_score=float(s), steps_per_s=rep.steps_per_s, hips=rep.hips, toe_on_floor=rep.toe_on_floor)
    chosen = int(np.argmin(scores)) if choose_by_rollout else int(np.argmin([c["holdout_loss"] for c in candidates]))
    film, check = films[chosen], reports[chosen]
    candidates[chosen]["chosen"] = True
    distance.known_losses = [own_loss(rel, r, len(films), ref, best_known)]
    kind = adapter_kind(plan, distance.far(), rows.loss(film), distance.known_losses[0])
    adapter = adapter_info = None
    if kind is not None:
        log(f"the clip lies outside the style space: a {kind} adapter of its own beside the vector (which is "
            "not refined by motion)")
        adapter, adapter_info = fit_style_adapter(rel.model, rel.network, lambda n: released_controller(n, layout),
                                                  (x, p, z), film, known, clip.speed, plan, kind, log)
        check = adapted_check(rel.network, layout, film, adapter, clip, toes, candidate_rollouts)
        adapter_info.update(steps_per_s=check.steps_per_s, hips=check.hips, toe_on_floor=check.toe_on_floor)
        motion = None
    if motion is not None:
        log(f"refining by motion: {motion.rounds} rounds of {motion.population} walks"
            + (f" in {shares} worker processes" if pool is not None else "") + " ...")
        faults = FaultCheck(toes, straight_path(clip.speed, motion.seconds + 1), clip.steps_per_s, clip.hips)
        refit = refine_by_motion(rel.network, layout, rel.stats, film, known, windows, clip.speed, motion,
                                 problems=faults, walks=walks)
        r, path = candidate_rollouts(rel.network, layout, refit.film[None], clip.speed)
        check = walk_report(r, 0, toes, path, clip_steps_per_s=clip.steps_per_s, clip_hips=clip.hips)
        candidates[chosen]["chosen"] = False
        candidates.append({"label": "refined by motion", "from_candidate": chosen, "rounds": motion.rounds,
                           "motion_distance_start": refit.start_distance, "motion_distance": refit.distance,
                           "motion_ratio_start": refit.start_score, "motion_ratio": refit.score,
                           "loss": rows.loss(refit.film), "rollout_score": float(rollout_score(check, clip)),
                           "steps_per_s": check.steps_per_s, "hips": check.hips,
                           "toe_on_floor": check.toe_on_floor, "chosen": True})
        film = refit.film.astype(np.float64)
        films.append(film)
        log(f"refined by motion: distance to the clip's windows {refit.start_distance:.0f} -> {refit.distance:.0f}"
            + (f"; {refit.start_score:.2f} -> {refit.score:.2f} times that to the nearest known style's"
               if motion.contrast else ""))
    seconds = time.perf_counter() - t0
    d = np.linalg.norm(V - film, axis=1)
    return TaughtStyle(name, film.astype(np.float32), seconds, clip, distance, rows.loss(film), names[int(np.argmin(d))],
                       best_known, check, candidates, np.stack(films).astype(np.float32), adapter, adapter_info)


def teach_released(params, name: str, files: Sequence, out, replace: bool = False,
                   settings: FitSettings = FitSettings(), motion: Optional[RefitSettings] = RefitSettings(),
                   workers: Optional[int] = None, adapter: AdapterPlan = AdapterPlan(),
                   log: Callable[[str], None] = print) -> TaughtStyle:
    """``minifilm finetune --params NET --name NAME --out PACK CLIP...``: read and check everything,
    teach, then write PACK (the old pack's styles kept) in one step. The network folder is only read."""
    check_name(name, "--name")
    files = [Path(f) for f in files]
    if not files:
        raise InputError("no clip given: name one or more BVH files of the new style")
    rel = load_released(params)
    if name in rel.styles:
        raise InputError(f"--name {name!r}: the released network already has a style of that name; pick another")
    shape = dict(film_dim=4 * rel.model.config.hidden, reserved=rel.styles, network=rel.network)
    load_pack_or_empty(out, **shape)            # a pack, before a lock beside it
    # one writer of a pack from reading it to writing it: a second teaching into it is refused,
    # naming this one, rather than both succeeding and one style being lost (minifilm/files/lock.py)
    with folder_lock(out, "style pack folder"):
        pack = load_pack_or_empty(out, **shape)
        if name in pack.info and not replace:
            raise InputError(f"--name {name!r}: the pack {out} already has a style of that name (--replace to "
                             "overwrite it)")
        if replace and name not in pack.info:
            raise InputError(f"--replace: the pack {out} has no style {name!r} to replace "
                             f"(it holds: {', '.join(pack.names) or 'none'}); leave out --replace to add a new style")
        log(f"[finetune] teaching the released network {Path(params).name} the style {name!r} from {len(files)} "
            "file(s)")
        read = [read_clip(f, log) for f in files]
        layout = FeatureLayout.for_skeleton(STYLE100)
        align = any(retargeted for _, retargeted in read)
        taught = teach(rel, layout, name, [m for m, _ in read], files, settings=settings, align=align, motion=motion,
                       workers=workers, adapter=adapter, log=log)
        pack.with_style(name, taught.film, taught.pack_info(), replace=replace, adapter=taught.adapter).save(out)
    return taught


def report_lines(r: TaughtStyle) -> List[str]:
    """What ``finetune --params`` prints: the fit, how far the clip lies from the network's data,
    and whether the new style walks, with a WARNING line for each thing that will not work."""
    c, k = r.clip, r.check
    own = r.distance.known_losses[0] if r.distance.known_losses else float("nan")
    lines = [f"[finetune] {r.name}: FiLM vector fitted through the frozen network"
             + (" and an adapter beside it" if r.adapter_info else "") + f" in {r.seconds:.1f} s "
             f"from {c.seconds:.1f} s of motion ({len(c.x)} frames)"]
    if c.seconds < RECOMMENDED_SECONDS:
        lines.append(f"    WARNING: the clip lasts {c.seconds:.1f} s; {RECOMMENDED_SECONDS:g}-30 s of walking in the "
                     "style is recommended (a short clip shows few steps)")
    lines.append(f"    distance from the network's data: {r.distance.words()}")
    lines.append(f"    loss on the clip: {r.distance.start_loss:.4f} at the closest of the network's styles "
                 f"({r.best_known}) -> {r.loss:.4f} fitted; {r.best_known} on its own generated motion: {own:.4f}")
    if r.distance.far():
        lines.append("    WARNING: the clip lies far outside the motion the network was trained on; "
                     "the new style may not walk like it")
    refined = [x for x in r.candidates if x.get("label") == "refined by motion"]
    if refined:
        m = refined[0]
        lines.append(f"    refined by the motion it makes ({m['rounds']} rounds): distance of its walk's windows to the "
                     f"clip's {m['motion_distance_start']:.0f} -> {m['motion_distance']:.0f}"
                     + (f", {m['motion_ratio_start']:.2f} -> {m['motion_ratio']:.2f} times that to the nearest "
                        "known style's (below 1: nearer the clip than any)" if "motion_ratio" in m else ""))
    if r.adapter_info:
        a = r.adapter_info
        lines.append(f"    an adapter of its own ({a['kind']}" + (f", rank {a['rank']}" if a["rank"] else "")
                     + f", {a['replay']:.0%} of each minibatch replaying the network's own motion): loss on the "
                     f"clip's held-out rows {a['holdout_loss_film_alone']:.4f} with the vector alone -> "
                     f"{a['holdout_loss']:.4f}; on the network's own motion with it on {a['replay_loss']:.4f} "
                     f"({a['seconds']:.1f} s)")
    lines.append(f"    nearest of the network's styles in FiLM space: {r.nearest}")
    lines.append(f"    rolled out {CHECK_SECONDS:g} s: {k.steps_per_s:.2f} steps/s (clip {c.steps_per_s:.2f}), hips "
                 f"{k.hips:.2f} m (clip {c.hips:.2f}), lowest toe on the floor in {k.toe_on_floor:.0%} of frames, "
                 f"{k.path_mean:.2f} m from the path: {k.words()}")
    return lines

