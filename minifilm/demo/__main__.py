"""``python -m minifilm.demo ARGS`` is ``minifilm demo ARGS`` (the options are in minifilm/cli/demo.py)."""
import sys

from minifilm.cli import main

main(["demo"] + sys.argv[1:])
