"""The dataset cache key: which files, settings and code a cached dataset was built from.

A dataset has one cache file, named by a hash of *what* it is (file paths and labels, settings,
custom skeleton); the key stored inside adds every file's size and modification time and a hash of
the code that computes the arrays, and must match for the cache to be used. So a changed file,
setting or code rebuilds the dataset, and never serves stale arrays.
"""
from __future__ import annotations

import hashlib
import json
import zipfile
import zlib
from pathlib import Path
from typing import Optional, Sequence, Tuple

import numpy as np

from minifilm.dataset.manifest import MotionFile
from minifilm.dataset.settings import DatasetSettings
from minifilm.files import open_regular
from minifilm.files.reading import JSON_NUMBERS

#: Bump when the meaning of the cached arrays changes without any source file changing.
CACHE_FORMAT = 1


def source_fingerprint() -> str:
    """Hash of the code that computes the cached arrays: a code change invalidates old caches.

    That code is every module of the packages that read, label and featurise motion."""
    h = hashlib.sha256()
    package = Path(__file__).resolve().parents[1]
    for folder in ("motion", "phases", "features", "dataset"):
        for p in sorted((package / folder).glob("*.py")):
            h.update(f"{folder}/{p.name}".encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def dataset_cache_key(files: Sequence[MotionFile], settings: DatasetSettings, skeleton=None) -> Tuple[str, str]:
    """(name, key): ``name`` hashes what the dataset is (file paths and labels, settings, custom
    skeleton) and names the cache file, so a dataset has one cache file; ``key`` adds every file's
    size and mtime and the code, and must match the stored one for the cache to be used."""
    what, state = [], []
    for f in files:
        st = Path(f.path).stat()
        what.append([str(Path(f.path).resolve()), f.style, f.gait, f.start, f.end, f.mirror])
        state.append([st.st_size, st.st_mtime_ns])
    name = json.dumps({"files": what, "settings": settings.to_dict(),
                       "skeleton": None if skeleton is None else repr(skeleton)}, sort_keys=True)
    key = json.dumps({"name": name, "state": state, "format": CACHE_FORMAT,
                      "code": source_fingerprint()}, sort_keys=True)
    return hashlib.sha256(name.encode()).hexdigest()[:20], hashlib.sha256(key.encode()).hexdigest()


def cached_key(path: Path) -> Optional[str]:
    """The key stored in a cache file (reads only its small 'meta' entry); None if unreadable."""
    try:
        with open_regular(path, "dataset cache") as f, np.load(f, allow_pickle=False) as d:
            if len(set(d.files)) != len(d.files):    # two members of one name: rebuilt, never guessed
                return None
            key = json.loads(str(d["meta"]), **JSON_NUMBERS).get("cache_key")
        return key if isinstance(key, str) else None
    except (OSError, ValueError, KeyError, AttributeError, EOFError, MemoryError, RecursionError,
            zipfile.BadZipFile, zlib.error):
        return None         # a broken cache (or something else under its name) is rebuilt
