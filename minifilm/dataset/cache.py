"""The dataset cache key: which files, settings and code a cached dataset was built from.

A dataset has one cache file, named by a hash of *what* it is (file paths and labels, settings,
custom skeleton); the key stored inside adds a hash of every file's bytes and of the code that
computes the arrays, and must match for the cache to be used. So a changed file, setting or code
rebuilds the dataset, and never serves stale arrays: also a file changed in place with its size and
modification time kept (as ``cp -p`` and ``rsync -t`` leave it), which a key of sizes and times
would miss. Hashing the bytes costs far less than labelling them (about 1 s per GB).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Optional, Sequence, Tuple

from minifilm.dataset.manifest import MotionFile
from minifilm.dataset.settings import DatasetSettings
from minifilm.files import MAX_JSON_BYTES, Member, open_regular, read_npz_member
from minifilm.files.reading import JSON_NUMBERS

#: Bump when the meaning of the cached arrays changes without any source file changing.
CACHE_FORMAT = 1


def source_fingerprint() -> str:
    """Hash of the code that computes the cached arrays: a code change invalidates old caches.

    That code is every module of the packages that read (with the body's unit), label and
    featurise motion."""
    h = hashlib.sha256()
    package = Path(__file__).resolve().parents[1]
    for folder in ("motion", "body", "phases", "features", "dataset"):
        for p in sorted((package / folder).glob("*.py")):
            h.update(f"{folder}/{p.name}".encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def dataset_cache_key(files: Sequence[MotionFile], settings: DatasetSettings, skeleton=None) -> Tuple[str, str]:
    """(name, key): ``name`` hashes what the dataset is (file paths and labels, settings, custom
    skeleton) and names the cache file, so a dataset has one cache file; ``key`` adds a hash of every
    file's bytes and the code, and must match the stored one for the cache to be used."""
    what, state = [], []
    for f in files:
        what.append([str(Path(f.path).resolve()), f.style, f.gait, f.start, f.end, f.mirror])
        state.append(content_hash(f.path))
    name = json.dumps({"files": what, "settings": settings.to_dict(),
                       "skeleton": None if skeleton is None else repr(skeleton)}, sort_keys=True)
    key = json.dumps({"name": name, "state": state, "format": CACHE_FORMAT,
                      "code": source_fingerprint()}, sort_keys=True)
    return hashlib.sha256(name.encode()).hexdigest()[:20], hashlib.sha256(key.encode()).hexdigest()


def content_hash(path) -> str:
    """SHA-256 of the bytes of the regular file ``path`` (read in pieces: a file of any size)."""
    h = hashlib.sha256()
    with open_regular(path, "BVH file") as f:
        for piece in iter(lambda: f.read(1 << 20), b""):
            h.update(piece)
    return h.hexdigest()


def cached_key(path: Path) -> Optional[str]:
    """The key stored in a cache file (reads only its small 'meta' entry, checked from its header
    first); None if unreadable: a broken cache (or something else under its name) is rebuilt."""
    try:
        meta = read_npz_member(path, "meta", "dataset cache", member=Member("U", ()), max_bytes=4 * MAX_JSON_BYTES)
        key = None if meta is None else json.loads(str(meta), **JSON_NUMBERS).get("cache_key")
        return key if isinstance(key, str) else None
    except (OSError, ValueError, AttributeError, RecursionError):     # InputError is a ValueError
        return None
