"""The paper's comparisons from the command line (issue 8, Sec. 5).

    python -m minifilm.evaluate table2 [--markdown PATH] [--runs 5] [--frames 200]
        Table 2: parameter counts (A.S.N., S.M.N., P.S.R.) of the seven variants in the paper's
        configuration, paper vs ours, and the batch-1 time per frame measured here.
    python -m minifilm.evaluate compare ...
        Figure 10 and the style metrics (minifilm/evaluation/compare.py; see its --help).

Each subcommand lives in its own module, imported only when asked for.
"""
from __future__ import annotations

import sys

SUBCOMMANDS = {
    "table2": ("minifilm.evaluation.table2", "Table 2: parameter counts and run time of the seven variants"),
    "compare": ("minifilm.evaluation.compare", "Figure 10 and style metrics (train and compare the variants)"),
}


def usage() -> str:
    lines = ["usage: python -m minifilm.evaluate {" + "|".join(SUBCOMMANDS) + "} [options]", ""]
    lines += [f"  {name:8s} {text}" for name, (_, text) in SUBCOMMANDS.items()]
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(usage())
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in SUBCOMMANDS:
        print(f"minifilm.evaluate: unknown subcommand {name!r}\n\n{usage()}", file=sys.stderr)
        return 2
    if name == "table2" and "numpy" not in sys.modules:
        # Batch-1 timing on one BLAS thread, like a game loop: a matrix-vector product gains
        # nothing from threads, and on a busy machine threaded BLAS made it ~20x slower here.
        # Must be set before NumPy is first imported; setdefault keeps a user's own choice.
        import os
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
        os.environ.setdefault("OMP_NUM_THREADS", "1")
    import importlib
    module = importlib.import_module(SUBCOMMANDS[name][0])
    return module.main(rest) or 0


if __name__ == "__main__":
    sys.exit(main())
