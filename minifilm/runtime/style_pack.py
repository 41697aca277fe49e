"""Style packs: styles taught to a network that ships without Ψ, kept beside it (never inside it).

A pack is a folder of two files:

    styles.npz   ``names`` (S,) and ``films`` (S, D): the StyleLibrary format (style_library.py)
    pack.json    {"format": "minifilm style pack", "version": 1, "film_dim": D,
                  "styles": [{"name", "taught_from": [{"file", "frames", "fps", ...}], "fit": {...},
                              "checks": {...}}, ...]}
    adapters.npz, adapters.json   only when a style was taught with an adapter of its own
                  (adapter_file.py; applied only while that style is on: adapted.py)

``minifilm finetune --params NET --out PACK`` writes one (the whole folder at once, atomically:
a reader sees the old pack or the new one; it holds the pack's lock from reading the pack to
writing it, so a second teaching into the same pack is refused rather than losing a style),
``minifilm generate / demo --params NET --styles PACK``
read it: the pack's styles join the network's own, so every name can be used and blended. A
pack style may not take the name of one of the network's styles.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Dict, List, Mapping, Optional

import numpy as np

from minifilm.errors import InputError
from minifilm.files import atomic_directory, read_json
from minifilm.runtime import adapter_file
from minifilm.runtime.style_library import StyleLibrary, StyleLibraryError

PACK_FORMAT = "minifilm style pack"
PACK_VERSION = 1
FILES = ("styles.npz", "pack.json")
ALL_FILES = FILES + adapter_file.FILES


class StylePackError(InputError):
    """A style pack folder that cannot be used: missing, broken, or not made for this network."""


class StylePack:
    """styles: StyleLibrary of the pack's vectors; info: name -> that style's pack.json entry;
    adapters: name -> StyleAdapter of the styles taught with one (minifilm/model/adapters.py)."""

    def __init__(self, styles: StyleLibrary, info: Mapping[str, dict], adapters: Optional[Mapping] = None):
        self.styles, self.info, self.adapters = styles, dict(info), dict(adapters or {})

    @property
    def names(self) -> List[str]:
        return self.styles.names

    @classmethod
    def empty(cls) -> "StylePack":
        return cls(StyleLibrary(), {})

    def with_style(self, name: str, film: np.ndarray, info: dict, replace: bool = False,
                   adapter=None) -> "StylePack":
        """A new pack with ``name`` added (or replaced when ``replace``), with its ``adapter`` (None:
        the style has none); the old pack is unchanged."""
        if name in self.info and not replace:
            raise StylePackError(f"the pack already has a style {name!r} (--replace to overwrite it)")
        if replace and name not in self.info:
            raise StylePackError(f"--replace: the pack has no style {name!r} to replace "
                                 f"(it holds: {', '.join(self.names) or 'none'}); leave out --replace to add it")
        library = StyleLibrary({n: self.styles[n] for n in self.names})
        library.add(name, film)
        infos = dict(self.info)
        infos[name] = {**info, "name": name}
        adapters = {n: a for n, a in self.adapters.items() if n != name}
        if adapter is not None:
            adapters[name] = adapter
        return StylePack(library, infos, adapters)

    def save(self, folder) -> Path:
        """Write the pack as ``folder`` (atomically, see the module docstring)."""
        if not self.names:
            raise StylePackError("a style pack needs at least one style")
        doc = {"format": PACK_FORMAT, "version": PACK_VERSION, "film_dim": self.styles.dim,
               "styles": [self.info[n] for n in self.names]}
        text = json.dumps(doc, indent=1, allow_nan=False)
        with atomic_directory(folder, "style pack folder", replaceable=lambda n: n in ALL_FILES) as tmp:
            self.styles.save(tmp / "styles.npz")
            (tmp / "pack.json").write_text(text + "\n", encoding="utf-8")
            adapter_file.write_adapters(tmp, {n: self.adapters[n] for n in self.names if n in self.adapters})
        return Path(folder)


def load_pack(folder, film_dim: Optional[int] = None, reserved: Mapping = (), network=None) -> StylePack:
    """Read a pack written by :meth:`StylePack.save`. ``film_dim``: the network's 4H; ``reserved``:
    the network's own style names, which a pack style may not take; ``network``: the
    RuntimeNetwork the pack's adapters must fit (needed when the pack has adapters). StylePackError
    naming the folder and what is wrong, for anything that is not such a pack."""
    d = Path(os.fspath(folder))
    where = f"style pack {d}"
    if not d.is_dir():
        raise StylePackError(f"{where}: not a folder (a style pack is the folder `minifilm finetune --params "
                             "... --out PACK` writes)")
    for f in FILES:
        if not (d / f).is_file():
            raise StylePackError(f"{where}: no {f} (not a style pack written by minifilm finetune --params)")
    doc = read_json(d / "pack.json", "style pack description", StylePackError)
    if not isinstance(doc, dict) or doc.get("format") != PACK_FORMAT:
        raise StylePackError(f"{where}: pack.json is not a style pack description (its 'format' is not "
                             f"{PACK_FORMAT!r})")
    if doc.get("version") != PACK_VERSION:
        raise StylePackError(f"{where}: pack version {doc.get('version')!r}; this minifilm reads version {PACK_VERSION}")
    try:
        styles = StyleLibrary.load(d / "styles.npz", dim=film_dim)
    except StyleLibraryError as e:
        raise StylePackError(f"{where}: {e}") from None
    entries = doc.get("styles")
    if not isinstance(entries, list) or not all(isinstance(e, dict) and isinstance(e.get("name"), str)
                                                for e in entries):
        raise StylePackError(f"{where}: pack.json 'styles' must be a list of objects with a 'name'")
    info: Dict[str, dict] = {e["name"]: e for e in entries}
    if [e["name"] for e in entries] != styles.names:
        raise StylePackError(f"{where}: pack.json lists the styles {[e['name'] for e in entries][:10]} but "
                             f"styles.npz holds {styles.names[:10]}: the two files do not belong together")
    film_dim = doc.get("film_dim")
    if isinstance(film_dim, bool) or not isinstance(film_dim, int):
        raise StylePackError(f"{where}: pack.json's 'film_dim' is {film_dim!r}, not a whole number (the length "
                             f"of a FiLM vector: styles.npz holds {styles.dim})")
    if film_dim != styles.dim:
        raise StylePackError(f"{where}: pack.json says FiLM vectors of {film_dim} numbers, "
                             f"styles.npz holds {styles.dim}")
    clash = [n for n in styles.names if n in reserved]
    if clash:
        raise StylePackError(f"{where}: the style name(s) {clash[:5]} are already the network's own styles")
    return StylePack(styles, info, _adapters(d, styles.names, network))


def _adapters(folder: Path, names, network) -> dict:
    """The pack's adapters, checked against ``network`` (adapter_file.py)."""
    if not (folder / "adapters.json").exists() and not (folder / "adapters.npz").exists():
        return {}
    if network is None or network.film_dim is None:
        raise StylePackError(f"style pack {folder}: holds style adapters, which need the network they were "
                             "taught to")
    H = network.hidden.hidden
    return adapter_file.read_adapters(folder, names, [network.x_dim, H, H, network.z_dim], network.n_experts,
                                      StylePackError)


def load_pack_or_empty(folder, film_dim: Optional[int] = None, reserved: Mapping = (), network=None) -> StylePack:
    """The pack at ``folder``, or an empty one when nothing is there yet (a first ``finetune --out``)."""
    if not os.path.lexists(folder):
        return StylePack.empty()
    return load_pack(folder, film_dim, reserved, network)


def with_pack(styles: Mapping[str, np.ndarray], pack: Optional[StylePack]) -> StyleLibrary:
    """A StyleLibrary of the network's styles followed by the pack's (blends work across both)."""
    films = dict(styles)
    if pack is not None:
        films.update({n: pack.styles[n] for n in pack.names})
    return StyleLibrary(films)
