"""The gradient-check suite: every backward pass of the kit and the networks against numerical
gradients, printed as a table (what each row checks and why the numbers are what they are:
minifilm/evaluation/gradcheck_table.py and docs/backprop.md).

    minifilm gradcheck [--seeds 5] [--only TEXT]

The exit code is 1 when any check fails, 0 when all pass.
"""
from minifilm.cli.args import in_range
from minifilm.evaluation.gradcheck_table import run as run_suite

HELP = "check every backward pass against numerical gradients and print the table"


def add_arguments(ap) -> None:
    ap.add_argument("--seeds", type=in_range(1, 100, int), default=5,
                    help="check every row on seeds 0 .. N-1 (default 5)")
    ap.add_argument("--only", metavar="TEXT", help="only the rows whose name contains TEXT (e.g. 'layer norm', 'LPN')")


def run(args) -> int:
    return run_suite(range(args.seeds), args.only)
