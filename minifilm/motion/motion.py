"""The in-memory motion container shared by the BVH reader, the synthetic generator and the runtime.

Everything is in metres, seconds and radians (BVH centimetres and degrees are converted at the
edge, in ``bvh.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional, Tuple

import numpy as np

from minifilm.motion.kinematics import forward_kinematics


@dataclass
class Motion:
    """A skeletal animation: a joint hierarchy plus per-frame local transforms.

    Joints are listed in BVH file order, End Sites included (an End Site is named after its parent
    with ``"Site"`` appended, e.g. ``LeftWristSite``, as the original pipeline does).

    Attributes:
        names:        (J,) joint names.
        parents:      (J,) int array, parent index of each joint, -1 for the root. Parents always come
                      before their children.
        offsets:      (J, 3) rest offsets from the parent, metres.
        channels:     (J,) tuple of channel names per joint as in the BVH file, e.g.
                      ``("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")``;
                      ``()`` for End Sites. Used to write the motion back in its own channel order.
        rotations:    (F, J, 3, 3) local rotation matrices (identity for End Sites).
        translations: (F, J, 3) local translations, metres: the position channels where a joint has
                      them, otherwise its offset.
        frame_time:   seconds per frame (1 / fps).
        source:       where the motion came from (file name), for error messages.
    """

    names: List[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: List[Tuple[str, ...]]
    rotations: np.ndarray
    translations: np.ndarray
    frame_time: float
    source: str = "<memory>"
    _fk_cache: Optional[Tuple[np.ndarray, np.ndarray]] = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.parents = np.asarray(self.parents, dtype=np.int64)
        self.offsets = np.asarray(self.offsets, dtype=np.float64)
        J = len(self.names)
        F = self.rotations.shape[0] if self.rotations.ndim == 4 else -1
        expected = {
            "parents": ((J,), self.parents.shape),
            "offsets": ((J, 3), self.offsets.shape),
            "rotations": ((F, J, 3, 3), self.rotations.shape),
            "translations": ((F, J, 3), self.translations.shape),
        }
        for what, (want, got) in expected.items():
            if tuple(want) != tuple(got):
                raise ValueError(f"Motion({self.source}): {what} has shape {got}, expected {want}")
        if len(self.channels) != J:
            raise ValueError(f"Motion({self.source}): {len(self.channels)} channel lists for {J} joints")
        if not (self.frame_time > 0 and np.isfinite(self.frame_time)):
            raise ValueError(f"Motion({self.source}): frame_time must be positive, got {self.frame_time}")
        for j, p in enumerate(self.parents):
            if p >= j:
                raise ValueError(f"Motion({self.source}): joint {self.names[j]} has parent {p} not before it")

    @property
    def n_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def n_joints(self) -> int:
        return len(self.names)

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def index(self, name: str) -> int:
        """Index of the joint called ``name``; a clear KeyError naming the known joints otherwise."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"{self.source}: no joint named {name!r}; joints are {self.names}") from None

    def world(self) -> Tuple[np.ndarray, np.ndarray]:
        """World transforms by forward kinematics: (positions (F, J, 3), rotations (F, J, 3, 3)).

        Cached: treat the returned arrays as read-only and build a new Motion to change the motion.
        """
        if self._fk_cache is None:
            self._fk_cache = forward_kinematics(self.rotations, self.translations, self.parents)
        return self._fk_cache

    def slice(self, start: int, stop: int) -> "Motion":
        """Frames ``start:stop`` as a new Motion (arrays are copied)."""
        return Motion(list(self.names), self.parents.copy(), self.offsets.copy(), list(self.channels),
                      self.rotations[start:stop].copy(), self.translations[start:stop].copy(),
                      self.frame_time, self.source)
