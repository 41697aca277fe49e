"""The style a character moves in: a mix of the library's styles, changed smoothly (Sec. 4.4).

Styles are mixed linearly in FiLM space (:meth:`StyleLibrary.blend`: a picked style is the
one-hot mix, the blend triangle three weights). A change goes from the mix of the moment to the
new one along a smoothstep over ``seconds`` (:func:`minifilm.runtime.style_library.smoothstep`,
as :meth:`StyleLibrary.schedule` switches styles in a scripted rollout), so a change in the middle
of another starts where that one had got to. When a change ends, the FiLM vector is the target's
own array, so a one-hot mix is exactly that style's vector.
"""
from __future__ import annotations

import hashlib
from typing import Dict, Mapping, Tuple

import numpy as np

from minifilm.runtime.style_library import StyleLibrary, smoothstep


def film_digest(film: np.ndarray) -> str:
    """A short fingerprint of a FiLM vector's exact bits: a page (or a test) can tell which vector
    drove a frame, e.g. that the blend triangle at a corner is bit for bit that style."""
    return hashlib.blake2b(np.ascontiguousarray(film).tobytes(), digest_size=8).hexdigest()


class StyleMix:
    """The current FiLM vector (D,) of one character and the mix of styles it stands for."""

    def __init__(self, library: StyleLibrary, weights: Mapping[str, float]):
        self.library = library
        self._target_w = dict(weights)
        self._target = library.blend(self._target_w)
        self._from_w, self._from = self._target_w, self._target
        self.film = self._target
        self._u, self._seconds = 1.0, 0.0
        self._digest, self._digest_of = "", None

    def change(self, weights: Mapping[str, float], seconds: float) -> None:
        """Start moving to ``weights`` (names -> w >= 0 summing to 1) over ``seconds``."""
        target_w = dict(weights)
        target = self.library.blend(target_w)       # checks the names and the sum first
        self._from_w, self._from = self.weights, self.film
        self._target_w, self._target = target_w, target
        self._u, self._seconds = 0.0, float(seconds)
        if self._seconds <= 0.0:
            self._finish()

    def advance(self, dt: float) -> np.ndarray:
        """The FiLM vector (D,) for the next frame, ``dt`` seconds on."""
        if self._u < 1.0:
            self._u = min(1.0, self._u + dt / self._seconds)
            if self._u >= 1.0:
                self._finish()
            else:
                s = float(smoothstep(self._u))
                self.film = ((1.0 - s) * self._from + s * self._target).astype(self._target.dtype)
        return self.film

    def _finish(self) -> None:
        self._u = 1.0
        self._from_w, self._from = self._target_w, self._target
        self.film = self._target

    @property
    def digest(self) -> str:
        """:func:`film_digest` of the current FiLM vector (computed again only when it changes)."""
        if self._digest_of is not self.film:
            self._digest, self._digest_of = film_digest(self.film), self.film
        return self._digest

    @property
    def changing(self) -> bool:
        return self._u < 1.0

    @property
    def weights(self) -> Dict[str, float]:
        """The mix of the moment: name -> weight (> 0), summing to 1."""
        if self._u >= 1.0:
            return dict(self._target_w)
        s = float(smoothstep(self._u))
        out: Dict[str, float] = {}
        for w, part in ((1.0 - s, self._from_w), (s, self._target_w)):
            for name, v in part.items():
                out[name] = out.get(name, 0.0) + w * v
        return {n: v for n, v in out.items() if v > 0.0}

    @property
    def target(self) -> Dict[str, float]:
        return dict(self._target_w)

    def dominant(self) -> Tuple[str, float]:
        """The style of the largest weight now, and its weight."""
        name, w = max(self.weights.items(), key=lambda kv: kv[1])
        return name, w
