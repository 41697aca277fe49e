"""Teach a trained run a new style from a short clip: fine-tune Ψ alone (Sec. 5.3.2, Figure 11).

    minifilm finetune --run runs/train_small --name Proud proud_walk.bvh [more.bvh ...]

The clips (10-30 s of walking or running in the new style, on the run's skeleton or on any other
humanoid rig, which is retargeted onto it and said so (docs/retargeting.md); another frame rate
is resampled) are labelled (contacts, local phases), featurised, and Ψ is fine-tuned on them
with Ω and Φ frozen. NAME joins the run's style library: ``minifilm generate --run RUN --style
NAME`` then uses it like any other style, and blends work. Existing styles keep their stored FiLM
vectors exactly; the fine-tuned checkpoint is saved as RUN/model-NAME.npz, never over model.npz.
"""
from __future__ import annotations

from pathlib import Path

from minifilm.cli.args import in_range, input_path, positive
from minifilm.pipeline.new_style import teach_style
from minifilm.pipeline.self_fed import SelfFed

HELP = "teach a trained run a new style from a short clip (Ψ only)"
ROLLOUT_ROUNDS = 0     # teacher forcing alone (the paper); benchmarks/README.md has the comparison


def add_arguments(ap) -> None:
    ap.add_argument("files", nargs="+", type=input_path, help="BVH file(s) of the new style")
    ap.add_argument("--run", type=Path, required=True, help="a run folder written by minifilm train")
    ap.add_argument("--name", required=True, help="the new style's name")
    ap.add_argument("--replace", action="store_true", help="replace a style of the same name")
    ap.add_argument("--steps", type=in_range(1, 100_000, int), default=400, help="fine-tuning steps (default 400)")
    ap.add_argument("--lr", type=positive(float, 1.0), default=5e-4, help="learning rate (default 5e-4)")
    ap.add_argument("--seed", type=in_range(0, 2**32 - 1, int), default=0)
    ap.add_argument("--rollout-rounds", type=in_range(0, 100, int), default=ROLLOUT_ROUNDS,
                    help="rounds of training on the model's own rollouts along the clip after the "
                         f"teacher-forced steps (pipeline/self_fed.py; default {ROLLOUT_ROUNDS}: teacher forcing "
                         f"alone, the paper; {SelfFed.rounds} is the studied setting)")


def run(args) -> int:
    r = teach_style(args.run, args.name, args.files, steps=args.steps, lr=args.lr, seed=args.seed,
                    replace=args.replace,
                    self_fed=SelfFed(rounds=args.rollout_rounds) if args.rollout_rounds else None)
    print(f"[finetune] {r.name}: Ψ fine-tuned for {r.steps} steps on {r.frames} frames ({r.clips} style clips) "
          f"in {r.seconds:.1f} s")
    print(f"    loss on the clip (MSE + BLL): {r.loss_before:.4f} with Ψ as trained -> {r.loss_after:.4f}")
    if r.rollout_errors:
        print("    rollouts along the clip, mean joint error per round: "
              + " -> ".join(f"{e * 100:.1f} cm" for e in r.rollout_errors) + f" (kept {min(r.rollout_errors) * 100:.1f})")
    if r.nearest:
        print(f"    nearest trained style in FiLM space: {r.nearest}")
    print(f"    added to {args.run / 'styles.npz'}; fine-tuned checkpoint {r.checkpoint}")
    print(f"    try: minifilm generate --run {args.run} --style {r.name!r} --out {r.name}.bvh")
    return 0
