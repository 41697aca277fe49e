"""Foot locking from predicted contacts with a two-bone leg IK (Sec. 4.4; docs/original-code.md §10.3 step 8).

While a foot is predicted to be in contact its toe is pinned where it was; the leg is bent to
reach (hip fixed, thigh and shin lengths kept, knee staying in the leg's current bending plane),
and the foot (ankle -> toe) moves rigidly with the ankle. The contact weight follows the original
demo: ``c = SmoothStep(contact, power 2, threshold 0.2)`` and the pin is updated as
``target <- lerp(target, toe_now, 1 - c)``, so at c = 0 the foot is free and at c = 1 it stays put.

Works on world joint positions only; rotations are refitted afterwards by
:func:`minifilm.motion.retarget.retarget` (``fit_positions=True``).
"""
from __future__ import annotations

from typing import Sequence, Tuple

import numpy as np

__all__ = ["two_bone_ik", "contact_weight", "FootLocker"]


def _unit(v, eps=1e-9):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), eps)


def two_bone_ik(a: np.ndarray, b: np.ndarray, c: np.ndarray, target: np.ndarray,
                margin: float = 1e-4) -> Tuple[np.ndarray, np.ndarray]:
    """Move the middle and end joints of a chain a -> b -> c so that c reaches ``target``.

    a (root, fixed), b (middle), c (end), target: (..., 3). Bone lengths |b-a| and |c-b| are kept;
    the middle joint stays on the side it was bent to (the plane of a, b and the target). A target
    out of reach is approached along the line from a (the leg straightens, minus ``margin``).
    Returns (b', c').
    """
    l1 = np.linalg.norm(b - a, axis=-1)
    l2 = np.linalg.norm(c - b, axis=-1)
    to_t = target - a
    d = np.clip(np.linalg.norm(to_t, axis=-1), np.abs(l1 - l2) + margin, l1 + l2 - margin)
    axis = _unit(to_t)
    bend = (b - a) - np.sum((b - a) * axis, axis=-1, keepdims=True) * axis   # knee direction, ⟂ axis
    fallback = (c - b) - np.sum((c - b) * axis, axis=-1, keepdims=True) * axis
    bend = np.where(np.linalg.norm(bend, axis=-1, keepdims=True) > 1e-6, bend, -fallback)
    bend = _unit(bend)
    x = (l1 ** 2 - l2 ** 2 + d ** 2) / (2 * d)                 # law of cosines, along the axis
    h = np.sqrt(np.maximum(l1 ** 2 - x ** 2, 0.0))
    b_new = a + x[..., None] * axis + h[..., None] * bend
    c_new = a + d[..., None] * axis
    return b_new, c_new


def contact_weight(contact: np.ndarray, threshold: float = 0.2) -> np.ndarray:
    """The demo's SmoothStep(x, power 2, threshold): biased towards 1, then a smooth S-curve."""
    x = np.clip(np.asarray(contact, dtype=np.float64), 0.0, 1.0)
    if threshold < 0.5:
        x = 1.0 - (1.0 - x) ** (0.5 / threshold)
    elif threshold > 0.5:
        x = x ** (0.5 / (1.0 - threshold))
    return np.where(x < 0.5, 0.5 * (2 * x) ** 2, 1.0 - 0.5 * (2 - 2 * x) ** 2)


class FootLocker:
    """Online foot locking for a batch of characters.

    Args:
        chains: per foot, in the order of the contact columns ([right, left] in minifilm), the
            exported-joint indices (hip, knee, ankle, toe).
        threshold: SmoothStep threshold of the contact weight (demo: 0.2).
    """

    def __init__(self, chains: Sequence[Sequence[int]], threshold: float = 0.2):
        self.chains = np.asarray(chains, dtype=np.int64)
        if self.chains.ndim != 2 or self.chains.shape[1] != 4:
            raise ValueError(f"FootLocker: chains must be (feet, 4) joint indices (hip, knee, ankle, toe), "
                             f"got shape {self.chains.shape}")
        self.threshold = threshold
        self.targets = None

    def reset(self, batch: int = None) -> None:
        self.targets = None

    def apply(self, positions: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """positions (B, J, 3) world, contacts (B, feet) predicted in [0, 1] -> new positions."""
        P = np.array(positions, dtype=np.float64)
        hip, knee, ankle, toe = (self.chains[:, i] for i in range(4))
        toe_now = P[:, toe]                                              # (B, feet, 3)
        c = contact_weight(contacts, self.threshold)[..., None]          # (B, feet, 1)
        if self.targets is None or self.targets.shape != toe_now.shape:
            self.targets = toe_now.copy()
        self.targets = c * self.targets + (1 - c) * toe_now              # lerp(target, toe, 1 - c)
        shift = self.targets - toe_now
        want_ankle = P[:, ankle] + shift
        new_knee, new_ankle = two_bone_ik(P[:, hip], P[:, knee], P[:, ankle], want_ankle)
        P[:, toe] = new_ankle + (P[:, toe] - P[:, ankle])               # foot moves rigidly
        P[:, knee], P[:, ankle] = new_knee, new_ankle
        return P
