"""The files of taught styles' adapters (minifilm/model/adapters.py), beside a style pack's styles
(style_pack.py) or a run's (minifilm/pipeline/run_folder.py):

    adapters.json   {"format": "minifilm style adapters", "version": 1,
                     "adapters": [{"style", "kind", "rank", "sizes", "experts", "dtype",
                                   "arrays": {name: shape}}, ...]}
    adapters.npz    the arrays, named "<i>.<name>" for the i-th adapter of adapters.json

Nothing is pickled. Reading checks the description against the network first (its layer sizes
and expert count) and works out every array's shape from it; the archive is then read with
exactly those arrays' bytes as its budget, so each member's header is checked against it before
any data is read (minifilm/files/reading.py), and every array's name, shape, dtype and values
are checked before an adapter is made of them.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Dict, Mapping, Sequence, Type

import numpy as np

from minifilm.errors import InputError
from minifilm.files import atomic_savez, atomic_write_text, read_json, read_npz
from minifilm.model.adapters import KINDS, RANKS, StyleAdapter, adapter_shapes

FORMAT, VERSION = "minifilm style adapters", 1
FILES = ("adapters.npz", "adapters.json")
DTYPES = ("float32", "float64")


def write_adapters(folder, adapters: Mapping[str, StyleAdapter]) -> None:
    """Write ``adapters`` (style name -> adapter) into ``folder`` as the two files above, each
    atomically. Nothing is written for no adapters."""
    if not adapters:
        return
    folder = Path(folder)
    entries, arrays = [], {}
    for i, (style, a) in enumerate(adapters.items()):
        entries.append({"style": style, **a.description(),
                        "arrays": {k: list(v.shape) for k, v in a.params.params.items()}})
        arrays.update({f"{i}.{k}": v for k, v in a.params.params.items()})
    atomic_savez(folder / "adapters.npz", arrays, "style adapters")
    doc = {"format": FORMAT, "version": VERSION, "adapters": entries}
    atomic_write_text(folder / "adapters.json", json.dumps(doc, indent=1, allow_nan=False) + "\n")


def read_adapters(folder, styles: Sequence[str], sizes: Sequence[int], n_experts: int,
                  error: Type[InputError] = InputError) -> Dict[str, StyleAdapter]:
    """The adapters in ``folder`` (style name -> adapter; {} when it has no adapters.json), for a
    network with layer sizes ``sizes`` [x_dim, H, H, z_dim] and ``n_experts``, whose styles are
    ``styles``. ``error`` naming the folder and what is wrong, for anything else."""
    folder = Path(folder)
    where = f"{folder}/adapters.json"
    if not (folder / "adapters.json").exists():
        if (folder / "adapters.npz").exists():
            raise error(f"{folder}: adapters.npz without adapters.json (a damaged folder)")
        return {}
    doc = read_json(folder / "adapters.json", "style adapters", error)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or doc.get("version") != VERSION:
        raise error(f"{where}: not a description of style adapters (format {FORMAT!r}, version {VERSION})")
    entries = doc.get("adapters")
    if not isinstance(entries, list) or not entries:
        raise error(f"{where}: 'adapters' must be a non-empty list")
    shapes, seen = [], set()
    for i, e in enumerate(entries):
        shapes.append(_entry_shapes(e, i, where, styles, sizes, n_experts, seen, error))
    total = sum(math.prod(s) * np.dtype(e["dtype"]).itemsize for e, sh in zip(entries, shapes) for s in sh.values())
    arrays = read_npz(folder / "adapters.npz", "style adapters", error, max_bytes=total)
    expected = {f"{i}.{k}": (s, entries[i]["dtype"]) for i, sh in enumerate(shapes) for k, s in sh.items()}
    if set(arrays) != set(expected):
        raise error(f"{folder}/adapters.npz: holds the arrays {sorted(arrays)[:8]}, adapters.json describes "
                    f"{sorted(expected)[:8]}: the two files do not belong together")
    for name, (shape, dtype) in expected.items():
        a = arrays[name]
        if a.shape != tuple(shape) or a.dtype != np.dtype(dtype) or not np.all(np.isfinite(a)):
            raise error(f"{folder}/adapters.npz: array {name!r} is {a.dtype} {a.shape}, expected finite {dtype} "
                        f"{tuple(shape)}")
    return {e["style"]: StyleAdapter.from_arrays(e, {k: arrays[f"{i}.{k}"] for k in shapes[i]})
            for i, e in enumerate(entries)}


def _entry_shapes(e, i, where, styles, sizes, n_experts, seen, error) -> dict:
    """The array shapes adapter ``i``'s entry must have, after checking the entry."""
    at = f"{where}: adapter {i}"
    if not isinstance(e, dict):
        raise error(f"{at}: not an object")
    style = e.get("style")
    if style not in styles or style in seen:
        raise error(f"{at}: its style {style!r} is " + ("given twice" if style in seen else "not one of the folder's styles"))
    seen.add(style)
    kind, rank = e.get("kind"), e.get("rank")
    if kind not in KINDS:
        raise error(f"{at} ({style}): kind {kind!r}, expected one of {', '.join(KINDS)}")
    if not isinstance(rank, int) or (kind == "lowrank" and not RANKS[0] <= rank <= RANKS[1]) \
            or (kind == "residual" and rank != 0):
        raise error(f"{at} ({style}): rank {rank!r} is not possible for a {kind} adapter")
    if e.get("sizes") != list(sizes) or e.get("experts") != n_experts:
        raise error(f"{at} ({style}): made for layers {e.get('sizes')!r} and {e.get('experts')!r} experts; the "
                    f"network has {list(sizes)} and {n_experts}")
    if e.get("dtype") not in DTYPES:
        raise error(f"{at} ({style}): dtype {e.get('dtype')!r}, expected one of {', '.join(DTYPES)}")
    shapes = adapter_shapes(kind, sizes, n_experts, rank)
    if e.get("arrays") != {k: list(s) for k, s in shapes.items()}:
        raise error(f"{at} ({style}): its arrays {e.get('arrays')!r} are not those of a {kind} adapter of this "
                    f"network ({ {k: list(s) for k, s in shapes.items()} })")
    return shapes
