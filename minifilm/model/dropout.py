"""The dropout of one forward pass, with named sites and replayable keep-masks.

The paper regularises "with a dropout rate of 0.3 everywhere" (Sec. 4.3). Here, as in the
original code, Ω and Φ drop before each of their layers and Ψ before its last dense layer only
(marked PAPER: in minifilm/model/film_generator.py).
A gradient check needs the *same* masks on every evaluation of the loss, so each dropout site has
a name ("gating0", "motion2", "film_dense", ...) and a forward pass can be given the masks to use
(``masks={name: bool array}``); the masks a pass actually used are kept in ``used``, so a caller
can replay them. Masks are drawn from an explicit ``np.random.Generator`` when not given.
"""
from __future__ import annotations

from typing import Dict, Optional

import numpy as np

from minifilm.nn.functional import dropout_backward, dropout_forward


class Dropout:
    """Inverted dropout with rate ``p`` for one forward pass of a network.

    train=False or p == 0: every site is the identity (no mask is drawn). Otherwise each site
    uses ``masks[name]`` when given, else draws a keep-mask from ``rng`` (keep with
    probability 1 - p), and records it in ``used[name]``.
    """

    def __init__(self, p: float, train: bool = False, rng: Optional[np.random.Generator] = None,
                 masks: Optional[Dict[str, np.ndarray]] = None):
        self.p, self.train, self.rng, self.masks = p, train, rng, masks
        self.used: Dict[str, np.ndarray] = {}

    def forward(self, x: np.ndarray, site: str):
        """x (B, ...) -> (out, cache) at the named site; see :func:`dropout_backward`."""
        if not self.train or self.p == 0.0:
            return dropout_forward(x, self.p, train=False)
        mask = None if self.masks is None else self.masks.get(site)
        if mask is None:
            if self.rng is None:
                raise ValueError(f"dropout site '{site}': training needs an rng or a fixed mask")
            mask = self.rng.random(x.shape) >= self.p
        elif mask.shape != x.shape:
            raise ValueError(f"dropout site '{site}': mask shape {mask.shape} != activation shape {x.shape}")
        self.used[site] = mask
        return dropout_forward(x, self.p, mask=mask, train=True)

    backward = staticmethod(dropout_backward)
