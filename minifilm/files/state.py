"""The files minifilm keeps for itself, which no output option may replace.

A trained run, a data set made by minifilm and the caches are *state*: what a later command
reads back. An output named by a user (``--out``, ``--gif``, ``--html``, ``--png``, ``--record``,
``--animation``, ``--markdown``, the files a ``--out`` folder receives) never replaces one of
them, whatever its name says: ``generate --run R --out R/styles.npz`` would leave BVH text where
the style library was. Only the code that owns a state file writes it, and it says so by writing
inside :func:`owned_writes`. The state files are:

* in a **run folder** (a folder holding ``run.json``): ``run.json``, ``model.npz``,
  ``styles.npz``, ``starts.npz``, ``skeleton.bvh``, ``loss_curve.png``, every fine-tuned
  checkpoint ``model-<NAME>.npz`` and everything under ``data/``, ``cache/`` and ``generated/``
  (``minifilm train`` writes them; ``minifilm finetune`` adds a style to ``styles.npz`` and
  ``starts.npz`` and writes its ``model-<NAME>.npz``);
* in a **data set folder made by minifilm** (a folder holding ``dataset.json``): ``dataset.json``,
  ``manifest.csv`` and its BVH files (``minifilm dataset --from-released``);
* anywhere, a **data set cache** ``dataset-<hash>.npz`` and a **speed calibration cache**
  ``calibration-<hash>.json`` (the data set builder and the demo write them).

A folder exchanged whole (:func:`minifilm.files.atomic.atomic_directory`) follows the same rule:
``train --out R/data`` would replace a run's training data with a run. Names are compared
case-folded, as macOS and Windows compare them, so ``R/STYLES.NPZ`` is the style library there
and is refused everywhere.

Like the inputs of :mod:`minifilm.files.output_targets`, the rule holds while a command runs (inside
``command_inputs()``); a Python user may still rewrite a run's files on purpose.
"""
from __future__ import annotations

import contextlib
import os
import re
import threading
from pathlib import Path
from typing import Iterator, Optional

#: the marker of a run folder: ``minifilm train`` writes it last, after every other file
RUN_MARKER = "run.json"
#: a run folder's own files and folders -> (what it is, the command that writes it)
RUN_STATE = {
    "run.json": ("the run's description", "minifilm train"),
    "model.npz": ("the run's checkpoint", "minifilm train"),
    "styles.npz": ("the run's style library", "minifilm train and minifilm finetune"),
    "starts.npz": ("the run's start frames", "minifilm train and minifilm finetune"),
    "adapters.npz": ("the run's style adapters", "minifilm finetune"),
    "adapters.json": ("the run's style adapters' description", "minifilm finetune"),
    "skeleton.bvh": ("the run's skeleton", "minifilm train"),
    "loss_curve.png": ("the run's loss curve", "minifilm train"),
    "data": ("the run's training data", "minifilm train"),
    "cache": ("the run's data set cache", "minifilm train"),
    "generated": ("the run's generated motion", "minifilm train"),
}
#: what a fine-tuned style's checkpoint is called in a run folder
CHECKPOINT = re.compile(r"^model-.*\.npz$", re.IGNORECASE | re.DOTALL)
#: the marker of a data set folder made by ``minifilm dataset --from-released``
DATASET_MARKER = "dataset.json"
#: caches, wherever they are
CACHES = ((re.compile(r"^dataset-[0-9a-f]{20}\.npz$", re.IGNORECASE), "a data set cache",
           "minifilm train and minifilm dataset"),
          (re.compile(r"^calibration-[0-9a-f]+\.json$", re.IGNORECASE), "a speed calibration cache",
           "minifilm demo"))

_lock = threading.Lock()
_owned: dict = {}          # real path -> how many open owned_writes() blocks name it


def is_run_entry(name: str) -> bool:
    """Whether ``name`` is something a run folder holds (RUN_STATE or a ``model-<NAME>.npz``)."""
    return name.casefold() in RUN_STATE or bool(CHECKPOINT.match(name))


def _run_entry(name: str):
    """(what, owner) of the run folder entry ``name``, or None."""
    folded = name.casefold()
    if folded in RUN_STATE:
        return RUN_STATE[folded]
    if CHECKPOINT.match(name):
        return "a fine-tuned style's checkpoint", "minifilm finetune"
    return None


def state_of(path) -> Optional[str]:
    """Why ``path`` is one of minifilm's state files (see the module docstring), as "the run's
    style library in the run folder R (written by minifilm train and minifilm finetune as part of
    that run)", or None when it is not one. ``path`` is looked at as given and where its links lead."""
    seen = set()
    for p in (Path(os.path.abspath(path)), Path(os.path.realpath(path))):
        if p in seen:
            continue
        seen.add(p)
        why = _state_of(p)
        if why:
            return why
    return None


def _state_of(path: Path) -> Optional[str]:
    for pattern, what, owner in CACHES:
        if pattern.match(path.name):
            return f"{what} (only {owner} write{'' if ' and ' in owner else 's'} one)"
    below = path
    for folder in path.parents:          # R/generated/x.bvh belongs to the run folder R
        entry = below.name
        if _exists(folder / RUN_MARKER):
            found = _run_entry(entry)
            if found:
                what, owner = found
                inside = "" if below == path else f" (under {entry}/)"
                return f"{what}{inside} in the run folder {folder} (written by {owner} as part of that run)"
            return None
        if folder == path.parent and _exists(folder / DATASET_MARKER) and \
                (entry.casefold() in (DATASET_MARKER, "manifest.csv") or entry.lower().endswith(".bvh")):
            return f"a file of the data set folder {folder} (written by minifilm dataset --from-released as a whole)"
        below = folder
    return None


def _exists(path: Path) -> bool:
    try:
        return os.path.isfile(path)
    except (OSError, ValueError):
        return False


def is_owned(path) -> bool:
    """Whether the running code has said it writes ``path`` as the owner of that state file."""
    with _lock:
        return bool(_owned) and os.path.realpath(path) in _owned


@contextlib.contextmanager
def owned_writes(*paths) -> Iterator[None]:
    """While open, the state files ``paths`` may be written: the code in the block is their owner
    (``finetune`` writing ``styles.npz``, the data set builder its cache)."""
    reals = [os.path.realpath(p) for p in paths]
    with _lock:
        for r in reals:
            _owned[r] = _owned.get(r, 0) + 1
    try:
        yield
    finally:
        with _lock:
            for r in reals:
                _owned[r] -= 1
                if not _owned[r]:
                    del _owned[r]
