"""A run's files belong together: each says which run it is of, and a stranger is named as one.

A run folder's files are made together by one ``minifilm train`` (and grown together by
``minifilm finetune``); a file copied in from another run of the same shape would load without a
word and drive the network with a style library, start frames or settings that are not its own.
So ``train`` gives the run an id (random, :func:`new_run_id`) and writes it into

    run.json      ``run_id``, and ``checkpoint``: a fingerprint of model.npz's configuration and
                  training state (:func:`checkpoint_fingerprint`)
    styles.npz    a ``run_id`` member (kept by every rewrite: finetune adds a style)
    starts.npz    a ``run_id`` member

and the readers of the folder compare them (:func:`foreign_files`). The file that disagrees with
the others is named; where two files are all there is to compare, both are. Runs written before
the ids existed still load: a file without an id agrees with any. Two checks need no id, so they
hold for such runs too: run.json's layout must fit the checkpoint's network, and at least one
style of styles.npz must have a start frame in starts.npz (``train`` writes one for each style,
``finetune`` one for each style it adds).
"""
from __future__ import annotations

import hashlib
import json
import secrets
from collections import Counter
from typing import Dict, List, Optional

#: run.json's keys
RUN_ID, CHECKPOINT = "run_id", "checkpoint"


def new_run_id() -> str:
    """A fresh run's id: 16 hex digits, random (two trainings never share one)."""
    return secrets.token_hex(8)


def checkpoint_fingerprint(meta: dict) -> str:
    """A fingerprint of a checkpoint: its configuration and training state (step, optimiser
    settings, random state), which differ between any two trainings; read from the small
    meta.json member, so checking it costs nothing beside loading the checkpoint."""
    text = json.dumps(meta, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def foreign_files(ids: Dict[str, Optional[str]]) -> List[str]:
    """The files whose run id is not the one most of the others hold, from file name -> its run id
    (None: the file carries none and agrees with any). Empty when all agree; every file with an
    id when no id has a majority (two files, two runs)."""
    known = {f: i for f, i in ids.items() if i is not None}
    if len(set(known.values())) <= 1:
        return []
    counts = Counter(known.values()).most_common()
    if counts[0][1] == counts[1][1]:
        return sorted(known)
    return [f for f, i in known.items() if i != counts[0][0]]


def describe_foreign(folder, foreign: List[str], ids: Dict[str, Optional[str]]) -> str:
    """One message: which files of the run folder are of another run, and how that was told."""
    groups: Dict[str, List[str]] = {}
    for f, i in ids.items():
        if i is not None:
            groups.setdefault(i, []).append(f)
    shown = "; ".join(f"{' and '.join(files)} of run {i}" for i, files in groups.items())
    if len(foreign) == 1:
        return (f"run folder {folder}: {foreign[0]} is another run's {_WHAT[foreign[0]]} ({shown}); a run's "
                "files are made together by minifilm train: put back this run's own copy, or use the folder "
                f"it came from")
    return (f"run folder {folder}: its files are of different runs ({shown}{_model(foreign, ids)}); a run's files "
            "are made together by minifilm train: put back the run's own copies")


def _model(foreign: List[str], ids: Dict[str, Optional[str]]) -> str:
    return "; model.npz is not the checkpoint run.json recorded" if "model.npz" in foreign and \
        ids.get("model.npz") is None else ""


_WHAT = {"run.json": "description", "model.npz": "checkpoint", "styles.npz": "style library",
         "starts.npz": "start frames"}
