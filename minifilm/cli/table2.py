"""Table 2 of the paper (Sec. 5.2.1): storage and run time of the seven comparison models.

    minifilm table2 [--no-timing] [--markdown PATH] [--runs 5] [--frames 200] [--styles 95]

Parameter counts come from the architectures in the paper's configuration; run times are measured
here, batch 1 through the one inference path (see minifilm/evaluation/table2.py).
"""

from minifilm.cli.args import in_range, markdown_path
from minifilm.evaluation.table2 import report

HELP = "Table 2: parameter counts and run time of the seven models"


def add_arguments(ap) -> None:
    ap.add_argument("--markdown", type=markdown_path, help="also write the table as markdown to this path")
    ap.add_argument("--runs", type=in_range(1, 1000, int), default=5, help="timing runs (mean ± std over runs); default 5")
    ap.add_argument("--frames", type=in_range(1, 100_000, int), default=200, help="frames per timing run; default 200")
    ap.add_argument("--styles", type=in_range(1, 100_000, int), default=95, help="training styles (the paper: 95)")
    ap.add_argument("--no-timing", action="store_true", help="parameter counts only")


def run(args) -> int:
    return report(args.markdown, args.runs, args.frames, args.styles, timing=not args.no_timing)
