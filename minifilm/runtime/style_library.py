"""Precomputed styles: name -> FiLM vector {γ1, β1, γ2, β2} (Eq. 2), and ways to mix them (Sec. 4.4).

At run time the FiLM generator Ψ is not needed: each style is one vector of 4*hidden numbers
(2048 in the paper), computed offline from one clip or averaged over many clips of the style
(Sec. 4.4 / 5.2). Styles are mixed linearly in FiLM space:

* :meth:`StyleLibrary.blend` -- any weights summing to 1 (2-way ``(1-w) a + w b``);
* :meth:`StyleLibrary.barycentric` -- three styles at a point of the triangle (the demo's UI);
* :meth:`StyleLibrary.schedule` -- per-frame vectors that switch style over time with a smooth
  (smoothstep) transition.

Stored as ``.npz`` with two arrays, ``names`` (S,) unicode and ``films`` (S, D); loaded with
``allow_pickle=False``.
"""
from __future__ import annotations

import os
from collections import Counter
from typing import Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from minifilm.errors import InputError
from minifilm.files import Member, atomic_savez, check_name, read_npz

__all__ = ["StyleLibrary", "StyleLibraryError", "UnknownStyleError", "blend_film", "smoothstep"]


#: the most a style library file may ask for when read: 10,000 styles of the paper's 2048 numbers in
#: float64 take 164 MB (100STYLE's 100 styles in float32 take 0.8 MB)
MAX_LIBRARY_BYTES = 256 << 20


class UnknownStyleError(KeyError, InputError):
    """A style name the library does not hold. A KeyError for dict-like use and an InputError so
    command-line tools report it as bad input (:func:`minifilm.cli.report_errors`) instead of a traceback."""

    def __str__(self) -> str:      # KeyError would print the message in quotes
        return str(self.args[0]) if self.args else ""


class StyleLibraryError(InputError):
    """A style library file that cannot be used; the message names the file and what is wrong."""


def smoothstep(u: np.ndarray) -> np.ndarray:
    """3u^2 - 2u^3 on [0, 1], clamped: 0 -> 0 and 1 -> 1 exactly, zero slope at both ends."""
    u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def blend_film(films: np.ndarray, weights: Sequence[float]) -> np.ndarray:
    """Blend the FiLM vectors of several styles (Sec. 4.4): Σ_s w_s film_s.

    films (S, D), weights (S,) summing to 1 -> (D,) in the films' dtype. Weights (0, .., 1, .., 0)
    return that style's vector exactly (the others are multiplied by 0).
    """
    films = np.asarray(films)
    weights = np.asarray(weights, dtype=np.float64)
    if films.ndim != 2 or weights.shape != (films.shape[0],):
        raise ValueError(f"blend_film: need films (S, D) and weights (S,), got {films.shape} and {weights.shape}")
    if not np.all(np.isfinite(weights)) or not np.isclose(weights.sum(), 1.0, atol=1e-6):
        raise ValueError(f"blend_film: weights must be finite and sum to 1, got {weights.tolist()}")
    return weights.astype(films.dtype) @ films


class StyleLibrary:
    """An ordered mapping style name -> FiLM vector (D,), all of the same length D = 4*hidden."""

    def __init__(self, films: Optional[Mapping[str, np.ndarray]] = None, dtype=np.float32):
        self.dtype = np.dtype(dtype)
        #: the run this library belongs to (its run.json's run_id), or None (a library of its own)
        self.run_id: Optional[str] = None
        self._films: Dict[str, np.ndarray] = {}
        for name, film in (films or {}).items():
            self.add(name, film)

    # ------------------------------------------------------------------ container
    @property
    def names(self) -> list:
        return list(self._films)

    @property
    def dim(self) -> int:
        if not self._films:
            raise ValueError("StyleLibrary is empty: no FiLM dimension yet")
        return len(next(iter(self._films.values())))

    def __len__(self) -> int:
        return len(self._films)

    def __contains__(self, name: str) -> bool:
        return name in self._films

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._films[name]
        except KeyError:
            known = ", ".join(self.names[:20]) + (f" and {len(self) - 20} more" if len(self) > 20 else "")
            raise UnknownStyleError(f"style {name!r} is not in the library; known styles: {known}") from None

    def add(self, name: str, film: np.ndarray) -> None:
        """Add or replace one style's FiLM vector (D,)."""
        check_name(name, "StyleLibrary.add")
        v = np.asarray(film, dtype=self.dtype)
        if v.ndim != 1:
            raise ValueError(f"StyleLibrary.add({name!r}): FiLM vector must be 1-D (D,), got shape {v.shape}")
        if self._films and name not in self._films and len(v) != self.dim:
            raise ValueError(f"StyleLibrary.add({name!r}): length {len(v)} differs from the library's {self.dim}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"StyleLibrary.add({name!r}): FiLM vector has non-finite values")
        self._films[str(name)] = v.copy()

    def add_from_clips(self, name: str, model, clips: np.ndarray, batch: int = 16) -> np.ndarray:
        """Style vector = mean of Ψ(clip) over the given normalised clips (M, T, C) (M = 1: one clip).

        ``model`` is anything with ``film_parameters(clips (B, T, C)) -> (B, D)`` (a StyleModel).
        """
        clips = np.asarray(clips)
        if clips.ndim != 3 or len(clips) == 0:
            raise ValueError(f"add_from_clips({name!r}): clips must be (M>=1, T, C), got {clips.shape}")
        total = 0.0
        for a in range(0, len(clips), batch):
            total = total + np.asarray(model.film_parameters(clips[a:a + batch]), dtype=np.float64).sum(axis=0)
        film = total / len(clips)
        self.add(name, film)
        return self[name]

    # ------------------------------------------------------------------ files
    def save(self, path: Union[str, os.PathLike]) -> None:
        """Write ``names`` and ``films`` to an .npz (atomically: temporary file, then rename), and
        ``run_id``, the run the library belongs to, when it has one (minifilm/pipeline/run_identity.py)."""
        films = np.stack([self._films[n] for n in self.names]) if self._films else np.zeros((0, 0))
        arrays = {"names": np.array(self.names, dtype=str), "films": films}
        if self.run_id is not None:
            arrays["run_id"] = np.array(self.run_id)
        atomic_savez(path, arrays)

    @classmethod
    def load(cls, path: Union[str, os.PathLike], dim: Optional[int] = None) -> "StyleLibrary":
        """Read a library written by :meth:`save`. ``dim``: the FiLM width the library must have
        (its network's 4*hidden). StyleLibraryError naming the file for anything else: a broken
        archive, names that are not unique non-empty strings, non-finite or non-float vectors."""
        where = f"style library {path}"
        # S names and S vectors of the network's length, checked from the headers before reading
        members = {"names": Member("U", ("S",)), "films": Member("f", ("S", dim), why=f"the network needs {dim} numbers per style"),
                   "run_id": Member("U", (), optional=True)}
        arrays = read_npz(path, "style library", StyleLibraryError, MAX_LIBRARY_BYTES, members)
        names, films = arrays["names"], arrays["films"]
        listed = names.tolist()
        if not listed:
            raise StyleLibraryError(f"{where}: the library holds no styles")
        for i, n in enumerate(listed):          # names from a file: never printed raw
            check_name(n, f"{where}: style {i}", StyleLibraryError)
        repeated = sorted(n for n, k in Counter(listed).items() if k > 1)
        if repeated:
            raise StyleLibraryError(f"{where}: styles named more than once: {repeated[:10]}"
                                    + (f" and {len(repeated) - 10} more" if len(repeated) > 10 else ""))
        bad = [n for n, v in zip(listed, films) if not np.all(np.isfinite(v))]
        if bad:
            raise StyleLibraryError(f"{where}: non-finite FiLM values in {bad[:5]}")
        library = cls(dict(zip(listed, films)), dtype=films.dtype)
        run_id = arrays.get("run_id")
        if run_id is not None:
            if not str(run_id).isalnum():
                raise StyleLibraryError(f"{where}: 'run_id' must be one word of letters and digits")
            library.run_id = str(run_id)
        return library

    # ------------------------------------------------------------------ mixing
    def blend(self, weights: Union[Mapping[str, float], Sequence[Tuple[str, float]]]) -> np.ndarray:
        """Σ_s w_s film_s for weights summing to 1 (Sec. 4.4); see :func:`blend_film`. ``weights``
        is name -> w or a sequence of (name, w) pairs, in which a style named twice gets the sum
        of its weights (a blend of a style with itself is that style)."""
        pairs = list(weights.items()) if isinstance(weights, Mapping) else [tuple(p) for p in weights]
        if not pairs:
            raise ValueError("blend: no styles given")
        total: Dict[str, float] = {}
        for name, w in pairs:
            total[name] = total.get(name, 0.0) + float(w)
        films = np.stack([self[name] for name in total])
        return blend_film(films, list(total.values()))

    def barycentric(self, styles: Sequence[str], coords: Sequence[float]) -> np.ndarray:
        """Three styles blended at barycentric coordinates (w1, w2, w3) >= 0, summing to 1."""
        if len(styles) != 3 or len(coords) != 3:
            raise ValueError(f"barycentric: need 3 styles and 3 coordinates, got {len(styles)} and {len(coords)}")
        if min(coords) < -1e-9:
            raise ValueError(f"barycentric: coordinates must be >= 0 (inside the triangle), got {list(coords)}")
        return self.blend(list(zip(styles, coords)))

    def schedule(self, keys: Sequence[Tuple[float, Union[str, Mapping[str, float]]]], n_frames: int,
                 fps: float = 60.0, transition_seconds: float = 1.0) -> np.ndarray:
        """Per-frame FiLM vectors (n_frames, D) switching style over time.

        ``keys`` = [(time s, style name or {name: weight}), ...] in time order: the style set at a
        key is held until the next key, and each change is a smoothstep transition of
        ``transition_seconds`` starting at the key's time.
        """
        if not keys:
            raise ValueError("schedule: no keys")
        times = [float(t) for t, _ in keys]
        if times != sorted(times):
            raise ValueError(f"schedule: key times must increase, got {times}")
        targets = [self.blend({s: 1.0}) if isinstance(s, str) else self.blend(s) for _, s in keys]
        t = np.arange(n_frames) / fps
        out = np.empty((n_frames, self.dim), dtype=self.dtype)
        out[:] = targets[0]
        for k in range(1, len(keys)):
            w = smoothstep((t - times[k]) / max(transition_seconds, 1e-9)).astype(self.dtype)[:, None]
            start = t >= times[k]
            out[start] = (1 - w[start]) * out[start] + w[start] * targets[k]
        return out
