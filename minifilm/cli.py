"""One way for the example scripts to report bad input: a one-line message, not a traceback.

Errors that describe the user's input (a missing file, a malformed BVH, a corrupt checkpoint, a
wrong released-network folder) already say what was wrong and where; a traceback would only bury
that sentence. Anything else is a bug and keeps its traceback.
"""
from __future__ import annotations

import sys
from typing import Callable, Optional


def run(main: Callable[[], Optional[int]]) -> None:
    """Call ``main()``; exit with its return code, or print ``error: <message>`` and exit 2 when it
    raises one of the input errors (FileNotFoundError, NotADirectoryError, ValueError and its
    subclasses BVHError, CheckpointError, ReleasedFormatError)."""
    try:
        code = main()
    except (FileNotFoundError, NotADirectoryError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
    sys.exit(code if isinstance(code, int) else 0)
