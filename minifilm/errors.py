"""Errors that describe a user's input, shared by every layer (this module imports nothing).

Every error minifilm raises about bad input names the file (and line or field) or the argument,
what was found and what was expected. Most are ValueErrors (a BVHError, a CheckpointError, ...);
an output path that cannot be written is an OutputPathError. The `minifilm` command prints any
of them as one line, ``error: ...``, and exits with code 2.
"""


class OutputPathError(OSError):
    """An output path cannot be written (a missing or read-only folder, a folder given as a file
    name); the message names the path and says why."""
