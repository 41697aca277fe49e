"""Teach a network a new style from a short clip: fine-tune Ψ alone (Sec. 5.3.2, Figure 11), or,
for the authors' released network (which ships without Ψ), fit the style's FiLM vector itself.

    minifilm finetune --run runs/train_small --name Proud proud_walk.bvh [more.bvh ...]
    minifilm finetune --params ../shared/data/released-lpn --name Strut --out my-styles strut.bvh

With --params the network folder is only read: the new style goes into the style pack folder
--out (made, or extended when it exists), which ``minifilm generate / demo --params NET --styles
PACK`` read beside the network's own styles (docs/teaching-released.md).

The clips (10-30 s of walking or running in the new style, on the run's skeleton or on any other
humanoid rig, which is retargeted onto it and said so (docs/retargeting.md); another frame rate
is resampled) are labelled (contacts, local phases), featurised, and Ψ is fine-tuned on them
with Ω and Φ frozen. NAME joins the run's style library: ``minifilm generate --run RUN --style
NAME`` then uses it like any other style, and blends work. Existing styles keep their stored FiLM
vectors exactly; the fine-tuned checkpoint is saved as RUN/model-NAME.npz, never over model.npz.
With --motion-rounds N the new style's vector is then moved until the run's own walk in it looks
like the clip, as a style taught to the released network is (pipeline/run_motion_refit.py; off
by default for a run: Ψ alone, as the paper).

When the clip lies outside the style space (the distance test finetune prints), the new style also
gets an adapter of its own (--adapter auto, the default; off, residual or lowrank to choose):
a small change of Φ fitted on the clip's frames, with a share of every minibatch replaying the
network's own motion, that acts only while that style is on (pipeline/teach_adapter.py,
docs/teaching-released.md). The network's files are never written.
"""
from __future__ import annotations

from pathlib import Path

from minifilm.cli.args import in_range, input_path, output_folder, positive
from minifilm.errors import InputError
from minifilm.pipeline.new_style import teach_style
from minifilm.pipeline.self_fed import SelfFed
from minifilm.pipeline.motion_refit import RefitSettings
from minifilm.pipeline.teach_adapter import MODES, AdapterPlan
from minifilm.pipeline.teach_released import RECOMMENDED_SECONDS, SIGMA, WALK_WORKERS, report_lines, teach_released
from minifilm.train.adapter_fit import AdapterSettings
from minifilm.train.film_fit import FitSettings

HELP = "teach a trained run a new style from a short clip (Ψ only)"
ROLLOUT_ROUNDS = 0     # teacher forcing alone (the paper); benchmarks/README.md has the comparison


def add_arguments(ap) -> None:
    ap.add_argument("files", nargs="+", type=input_path, help="BVH file(s) of the new style")
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--run", type=Path, help="a run folder written by minifilm train")
    src.add_argument("--params", type=input_path, help="the released network's parameter folder (only read)")
    ap.add_argument("--out", type=output_folder, help="with --params: the style pack folder to write or extend")
    ap.add_argument("--name", required=True, help="the new style's name")
    ap.add_argument("--replace", action="store_true", help="replace a style of the same name")
    ap.add_argument("--steps", type=in_range(1, 100_000, int), default=400, help="fine-tuning steps (default 400)")
    ap.add_argument("--lr", type=positive(float, 1.0), default=5e-4, help="learning rate (default 5e-4)")
    ap.add_argument("--seed", type=in_range(0, 2**32 - 1, int), default=0)
    ap.add_argument("--motion-rounds", type=in_range(0, 200, int), default=None,
                    help="rounds of moving the taught vector until the network's own walk in it looks like the "
                         f"clip (pipeline/motion_refit.py; about 3 s each on two cores; 0: not at all). Default: "
                         f"{RefitSettings.rounds} with --params, 0 with --run (Ψ alone, the paper)")
    ap.add_argument("--workers", type=in_range(1, 64, int), default=None,
                    help="worker processes that share the walks of --motion-rounds (with --params also the "
                         f"teacher-forced fits); default: every usable core, at most {WALK_WORKERS}; 1: all in "
                         "this process")
    ap.add_argument("--adapter", choices=MODES, default="auto",
                    help="an adapter of the new style's own beside its FiLM vector: auto (default: when the clip "
                         "lies outside the style space), off, residual (on Φ's hidden layers) or lowrank (low-rank "
                         "updates of the expert weights)")
    ap.add_argument("--adapter-rank", type=in_range(1, 64, int), default=AdapterSettings.rank,
                    help=f"rank of the low-rank updates (default {AdapterSettings.rank})")
    ap.add_argument("--adapter-steps", type=in_range(1, 20_000, int), default=AdapterSettings.steps,
                    help=f"Adam steps of the adapter's fit at most (default {AdapterSettings.steps})")
    ap.add_argument("--adapter-noise", type=in_range(0.0, 10.0), default=AdapterSettings.noise,
                    help="σ of the noise on the clip's normalised inputs the adapter is fitted on (their targets "
                         f"kept: it learns to come back to the clip; default {AdapterSettings.noise:g}, 0: none)")
    ap.add_argument("--replay", type=in_range(0.0, 0.9), default=AdapterSettings.replay,
                    help="share of each minibatch of the adapter's fit that replays the network's own motion in "
                         f"its own styles (default {AdapterSettings.replay:g})")
    ap.add_argument("--rollout-rounds", type=in_range(0, 100, int), default=ROLLOUT_ROUNDS,
                    help="rounds of training on the model's own rollouts along the clip after the "
                         f"teacher-forced steps (pipeline/self_fed.py; default {ROLLOUT_ROUNDS}: teacher forcing "
                         f"alone, the paper; {SelfFed.rounds} is the studied setting)")


def run(args) -> int:
    if args.params is not None:
        return run_released(args)
    if args.out is not None:
        raise InputError("--out is for --params (a style pack); a run folder keeps its styles itself")
    if args.workers not in (None, 1) and not args.motion_rounds:     # (1, all in this process: as it is)
        raise InputError(f"--workers {args.workers} is for the walks of --motion-rounds; without them "
                         "fine-tuning Ψ runs in this one process")
    motion = RefitSettings(rounds=args.motion_rounds, seed=args.seed) if args.motion_rounds else None
    r = teach_style(args.run, args.name, args.files, steps=args.steps, lr=args.lr, seed=args.seed,
                    replace=args.replace,
                    self_fed=SelfFed(rounds=args.rollout_rounds) if args.rollout_rounds else None,
                    motion=motion, workers=args.workers, adapter=adapter_plan(args))
    print(f"[finetune] {r.name}: Ψ fine-tuned for {r.steps} steps on {r.frames} frames ({r.clips} style clips) "
          f"in {r.seconds:.1f} s")
    print(f"    loss on the clip (MSE + BLL): {r.loss_before:.4f} with Ψ as trained -> {r.loss_after:.4f}")
    if r.rollout_errors:
        print("    rollouts along the clip, mean joint error per round: "
              + " -> ".join(f"{e * 100:.1f} cm" for e in r.rollout_errors) + f" (kept {min(r.rollout_errors) * 100:.1f})")
    if r.refit is not None:
        f = r.refit
        print(f"    refined by motion: distance to the clip's windows {f.start_distance:.0f} -> {f.distance:.0f}; "
              f"{f.start_score:.2f} -> {f.score:.2f} times that to the nearest trained style's")
    if r.adapter_info:
        a = r.adapter_info
        print(f"    an adapter of its own ({a['kind']}" + (f", rank {a['rank']}" if a["rank"] else "")
              + f"): loss on the clip's held-out rows {a['holdout_loss_film_alone']:.4f} with the vector alone -> "
              f"{a['holdout_loss']:.4f} ({a['seconds']:.1f} s); kept in {args.run / 'adapters.npz'}")
    if r.nearest:
        print(f"    nearest trained style in FiLM space: {r.nearest}")
    for line in run_warnings(r):
        print(line)
    print(f"    added to {args.run / 'styles.npz'}; fine-tuned checkpoint {r.checkpoint}")
    print(f"    try: minifilm generate --run {args.run} --style {r.name!r} --out {r.name}.bvh")
    return 0


def adapter_plan(args) -> AdapterPlan:
    """The adapter options as an AdapterPlan."""
    return AdapterPlan(args.adapter, AdapterSettings(rank=args.adapter_rank, steps=args.adapter_steps,
                                                     replay=args.replay, noise=args.adapter_noise, seed=args.seed))


def run_warnings(r) -> list:
    """The lines that say how far the clip lies from the run's data and whether the style walks."""
    worst = ", ".join(f"{n} ({s:.0%} of frames)" for n, s in r.worst if s > 0) or "none"
    lines = [f"    distance from the run's data: {r.share_beyond:.1%} of the clip's normalised input numbers beyond "
             f"{SIGMA:g} σ (worst: {worst})"]
    if r.clip_seconds < RECOMMENDED_SECONDS:
        lines.append(f"    WARNING: the clip lasts {r.clip_seconds:.1f} s; {RECOMMENDED_SECONDS:g}-30 s of walking in the "
                     "style is recommended (a short clip shows few steps)")
    if r.share_beyond > 0.01:
        lines.append("    WARNING: the clip lies far outside the motion the run was trained on; the new style may not walk")
    if r.check is not None:
        k = r.check
        lines.append(f"    rolled out 6 s: {k.steps_per_s:.2f} steps/s (clip {k.clip_steps_per_s:.2f}), hips {k.hips:.2f} m "
                     f"(clip {k.clip_hips:.2f}), lowest toe on the floor in {k.toe_on_floor:.0%} of frames: {k.words()}")
    return lines


def run_released(args) -> int:
    if args.out is None:
        raise InputError("--params needs --out PACK: the style pack folder the new style is written into "
                         "(the network folder is never written)")
    settings = FitSettings(steps=min(args.steps, 1000), seed=args.seed)
    r = teach_released(args.params, args.name, args.files, args.out, replace=args.replace, settings=settings,
                       motion=RefitSettings(rounds=RefitSettings.rounds if args.motion_rounds is None
                                            else args.motion_rounds, seed=args.seed),
                       workers=args.workers, adapter=adapter_plan(args))
    for line in report_lines(r):
        print(line)
    print(f"    written to the style pack {args.out}")
    print(f"    try: minifilm generate --params {args.params} --styles {args.out} --style {r.name!r} --out {r.name}.bvh")
    return 0
