"""Errors that describe a user's input, shared by every layer (this module imports nothing).

Every error minifilm raises about bad input names the file (and line or field), the argument or
the array, says what was found and what was expected, and is one of:

* :class:`InputError` (a ValueError): a malformed or implausible file, array, argument or message.
  Its subclasses say which kind of input: ``BVHError`` (minifilm/motion/bvh.py), ``CheckpointError``
  (minifilm/train/checkpoint.py), ``ReleasedFormatError`` (minifilm/runtime/released.py),
  ``RunFolderError`` (minifilm/pipeline/run_folder.py), ``UnknownStyleError``
  (minifilm/runtime/style_library.py), :class:`DataError` below;
* :class:`OutputPathError` (an OSError): an output path that cannot be written;
* FileNotFoundError / PermissionError from the operating system for a missing or unreadable file;
* :class:`MissingDependencyError` (an ImportError): an optional package (an extra such as
  ``minifilm[viz]``) or program (ffmpeg) that the asked-for output needs is not installed.

The `minifilm` command prints any of them as one line, ``error: ...``, and exits with code 2.
"""

#: Frame rates minifilm accepts, frames per second (motion capture runs at 24-240; far outside
#: this range a file is broken, and its arrays would be absurdly large or small).
MIN_FPS, MAX_FPS = 1.0, 1000.0


class InputError(ValueError):
    """Bad input (file, array, argument, message); the message names it and what was expected."""


class DataError(InputError):
    """Motion data that cannot be trained on or run: non-finite or absurd numbers, too few frames,
    a style without rows; the message names the file (and column, frame) or the style."""


class OutputPathError(OSError):
    """An output path cannot be written (a missing or read-only folder, a folder given as a file
    name); the message names the path and says why."""


class MissingDependencyError(ImportError):
    """An optional package or program needed for what was asked is missing; the message names it
    and how to install it (or what to use instead)."""


def check_fps(fps: float, where: str) -> float:
    """``fps`` if it is a finite rate within [MIN_FPS, MAX_FPS]; InputError naming ``where`` otherwise
    (also for True and False, which Python would count as 1 and 0)."""
    if isinstance(fps, bool):
        raise InputError(f"{where}: frame rate {fps!r} is not a number")
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise InputError(f"{where}: frame rate {fps!r} is not a number") from None
    if not (MIN_FPS <= value <= MAX_FPS):       # also refuses nan
        raise InputError(f"{where}: {value:g} frames per second is outside {MIN_FPS:g}-{MAX_FPS:g}")
    return value
