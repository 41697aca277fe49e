"""Figure 10 and the style metrics of Sec. 5: train the seven comparison models with one budget on
one data set and compare them (test errors, style recognition of generated motion, foot sliding,
bone-length variation, interpolation smoothness, FiLM-code separation after fine-tuning Ψ), with
every run's validation curve and a verdict for each claim of the paper's Sec. 5 (docs/compare_claims.md).

    minifilm compare                                   # synthetic data (generated here)
    minifilm compare --data DIR --split-files --holdout NAME
    minifilm compare --tiny --budget-steps 5           # a smoke run in seconds
    minifilm compare --data DATA --styles 10 --until-flat --max-steps 40000   # DATA made by --from-released

Writes a markdown report with plots (--out, default reports/); see minifilm/evaluation/compare.py.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from minifilm.cli.args import in_range, input_path, output_folder, positive
from minifilm.errors import InputError
from minifilm.evaluation.compare import MODEL, SYNTH_HOLDOUT, TINY_MODEL
from minifilm.evaluation.compare import run as run_compare

HELP = "Figure 10 and style metrics: train and compare the seven models"


def add_arguments(p) -> None:
    p.add_argument("--data", default="synthetic", help="'synthetic' (default) or a folder of BVH files")
    p.add_argument("--budget-steps", type=in_range(1, 10**7, int), default=2500,
                   help="training steps per variant, rounded up to whole epochs (default 2500)")
    p.add_argument("--until-flat", action="store_true",
                   help="after the budget, keep training each variant and seed in whole epochs while its "
                   "validation loss still falls (the last 20 %% of its steps improved it by 3 %% or more), up to "
                   "--max-steps; the report gives each run's steps and curve")
    p.add_argument("--max-steps", type=in_range(1, 10**8, int),
                   help="with --until-flat: most steps per run, rounded up to whole epochs (default 4 x the budget)")
    p.add_argument("--finetune-steps", type=in_range(0, 10**7, int), default=300, help="Ψ fine-tuning steps (default 300)")
    p.add_argument("--out", type=output_folder, default=Path("reports"), help="folder of the markdown report and PNGs")
    p.add_argument("--work", type=output_folder, default=Path("runs/compare"),
                   help="folder for generated data and caches")
    p.add_argument("--variants", help="comma-separated subset of the seven variants (default: all)")
    p.add_argument("--holdout", help="style held out of training and taught afterwards by fine-tuning Ψ alone, or "
                   f"several, comma-separated (default: {SYNTH_HOLDOUT} on synthetic data, else the last style)")
    p.add_argument("--interpolate", help="two seen styles A,B for the interpolation test, or several pairs 'A,B;C,D' "
                   "(default: BentForward,LeanBack when both are seen, else the first two)")
    p.add_argument("--fps", type=in_range(1.0, 1000.0), default=30.0, help="resample the data to this rate (default 30)")
    p.add_argument("--clip-seconds", type=positive(float, 60.0), default=2.0)
    p.add_argument("--seconds", type=positive(float, 3600.0), default=10.0, help="synthetic seconds per style and gait")
    p.add_argument("--styles", help="comma-separated styles of the data, or a number N: N styles spread "
                   "evenly over the sorted names, keeping --holdout and --interpolate (default: all)")
    p.add_argument("--gaits", help="comma-separated synthetic gaits (default: all)")
    p.add_argument("--split-files", action="store_true",
                   help="whole files per split (for many short files, e.g. Bandai's ~5 s files)")
    p.add_argument("--rollout-seconds", type=positive(float, 3600.0), default=10.0)
    p.add_argument("--batch-size", type=in_range(1, 65536, int), default=32)
    p.add_argument("--lr", type=positive(float, 10.0), default=1e-3,
                   help="Adam's learning rate (default 1e-3, the rate of the 8- and 5-style reports; at 100 "
                   "styles 1e-3 collapsed PFNN FiLM's style input and 5e-4 did not: reports/compare_100styles.md)")
    p.add_argument("--seed", type=in_range(0, 2**32 - 1, int), default=0, help="data, split, classifier and first model seed")
    p.add_argument("--extra-seeds", default="1",
                   help="comma-separated further model seeds for the test errors (default '1'; '' for none)")
    p.add_argument("--released", type=input_path, metavar="DIR",
                   help="the authors' released network's folder: its rollouts along the same paths become one more "
                   "row of the rollout table (default: the one a --from-released data set was made by, if present)")
    p.add_argument("--workers", type=in_range(1, 256, int),
                   help="processes training the variants and seeds at once, one BLAS thread each (default: the "
                   "cores this process may use); the results are those of one process but for float round-off")
    p.add_argument("--tiny", action="store_true", help="a tiny model (tests and smoke runs)")


def finish(a):
    """Turn the comma-separated options into lists and pick the model sizes."""
    try:
        a.extra_seeds = [int(x) for x in a.extra_seeds.split(",") if x.strip()]
    except ValueError:
        raise InputError(f"--extra-seeds {a.extra_seeds!r}: give comma-separated whole numbers, e.g. '1,2'") from None
    if any(not 0 <= x < 2**32 for x in a.extra_seeds):
        raise InputError(f"--extra-seeds {a.extra_seeds}: seeds are whole numbers from 0 to 2**32 - 1")
    if a.interpolate is not None:
        pairs = [[x.strip() for x in part.split(",")] for part in a.interpolate.split(";")]
        for pair in pairs:
            if len(pair) != 2 or not all(pair) or pair[0] == pair[1]:
                raise InputError(f"--interpolate {a.interpolate!r}: give two different styles, 'A,B' "
                                 "(or several pairs, 'A,B;C,D')")
        a.interpolate = ";".join(",".join(p) for p in pairs)
    a.styles = a.styles.split(",") if a.styles else None
    a.gaits = a.gaits.split(",") if a.gaits else None
    a.model = TINY_MODEL if a.tiny else MODEL
    return a


def parse_args(argv):
    """The options of ``minifilm compare`` as ``run`` reads them (for tests and scripts)."""
    parser = argparse.ArgumentParser(prog="minifilm compare")
    add_arguments(parser)
    return finish(parser.parse_args(argv))


def run(args) -> int:
    run_compare(finish(args))
    return 0
