"""``python -m minifilm``: the same as the ``minifilm`` command."""
from minifilm.cli import main

main()
