"""A nearest-centroid style classifier: the plainest independent judge of whose style a motion is.

Each style is the centroid of its reference windows; a window is given the style of the nearest
centroid. Windows are read as the project's other style measures read them (style_judge.py: the
mean and spread over 0.75 s of every joint's normalised clip features), standardised by the
references' spread per number and projected on their ``dims`` leading principal directions, so
that the few hundred numbers that move together count once. No training, no seed: nothing in
teaching reads it (teaching measures motion with style_judge.py's Fréchet distance), so what it
says about a taught style is a second opinion.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Mapping

import numpy as np


@dataclass
class NearestCentroid:
    names: List[str]
    mean: np.ndarray             # (2C,) of all reference windows
    scale: np.ndarray            # (2C,) their spread per number
    directions: np.ndarray       # (dims, 2C) leading principal directions of the standardised references
    centroids: np.ndarray        # (S, dims)

    @classmethod
    def fit(cls, references: Mapping[str, np.ndarray], dims: int = 16) -> "NearestCentroid":
        """references: style -> (M >= 1, 2C) window summaries."""
        names = list(references)
        if len(names) < 2 or any(len(references[n]) < 1 for n in names):
            raise ValueError("NearestCentroid.fit: need two or more styles with a window each")
        X = np.concatenate([np.asarray(references[n], np.float64) for n in names])
        mean, scale = X.mean(axis=0), X.std(axis=0) + 1e-9
        Z = (X - mean) / scale
        _, _, Vt = np.linalg.svd(Z - Z.mean(axis=0), full_matrices=False)
        out = cls(names, mean, scale, Vt[:dims], np.zeros((0, 0)))
        out.centroids = np.stack([out.project(references[n]).mean(axis=0) for n in names])
        return out

    def project(self, summaries: np.ndarray) -> np.ndarray:
        return ((np.asarray(summaries, np.float64) - self.mean) / self.scale) @ self.directions.T

    def classify(self, summaries: np.ndarray) -> np.ndarray:
        """(M, 2C) windows -> (M,) style names."""
        d = ((self.project(summaries)[:, None, :] - self.centroids[None]) ** 2).sum(axis=-1)
        return np.asarray(self.names)[np.argmin(d, axis=1)]

    def shares(self, summaries: np.ndarray) -> Dict[str, float]:
        """style -> share of the windows given to it (every style, most first)."""
        picked = self.classify(summaries)
        out = {n: float(np.mean(picked == n)) for n in self.names}
        return dict(sorted(out.items(), key=lambda kv: -kv[1]))
