"""Helpers of the viewer tests: a small synthetic walker, test-only foot contacts.

The synthetic ``Motion`` is built here from rotations and translations (not by any minifilm
generator), so the tests depend only on ``Motion`` and the BVH reader. (A module with its own
name rather than ``conftest``: ``tests/conftest.py`` is also called ``conftest``.)
"""
from __future__ import annotations

import numpy as np

from minifilm.motion.motion import Motion

# name, parent, offset (metres); "Site" joints are End Sites (no channels).
SKELETON = [
    ("Hips", -1, (0.0, 0.0, 0.0)),
    ("Spine", 0, (0.0, 0.25, 0.0)),
    ("Head", 1, (0.0, 0.35, 0.0)),
    ("HeadSite", 2, (0.0, 0.18, 0.0)),
    ("LeftUpLeg", 0, (0.1, -0.05, 0.0)),
    ("LeftLeg", 4, (0.0, -0.42, 0.0)),
    ("LeftFoot", 5, (0.0, -0.42, 0.0)),
    ("LeftFootSite", 6, (0.0, -0.06, 0.12)),
    ("RightUpLeg", 0, (-0.1, -0.05, 0.0)),
    ("RightLeg", 8, (0.0, -0.42, 0.0)),
    ("RightFoot", 9, (0.0, -0.42, 0.0)),
    ("RightFootSite", 10, (0.0, -0.06, 0.12)),
    ("LeftArm", 1, (0.2, 0.3, 0.0)),
    ("LeftForeArm", 12, (0.0, -0.25, 0.0)),
    ("LeftHand", 13, (0.0, -0.25, 0.0)),
    ("RightArm", 1, (-0.2, 0.3, 0.0)),
    ("RightForeArm", 15, (0.0, -0.25, 0.0)),
    ("RightHand", 16, (0.0, -0.25, 0.0)),
]
SWING = {"LeftUpLeg": 0.5, "RightUpLeg": -0.5, "LeftLeg": 0.3, "RightLeg": -0.3,
         "LeftArm": -0.4, "RightArm": 0.4}


def _rx(angle: np.ndarray) -> np.ndarray:
    """(F, 3, 3) rotations about x by ``angle`` (F,) radians."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(angle.shape + (3, 3))
    R[:, 0, 0] = 1
    R[:, 1, 1], R[:, 1, 2], R[:, 2, 1], R[:, 2, 2] = c, -s, s, c
    return R


def synthetic_walker(n_frames: int = 36, fps: float = 30.0, speed: float = 1.2, turn: float = 0.0) -> Motion:
    """An 18-joint stick figure (a humanoid: the mannequin draws it) walking along +z (``speed`` m/s), legs and arms swinging at 1 Hz.

    ``turn`` rad/s turns the root about y, so the path curves.
    """
    names = [n for n, _, _ in SKELETON]
    parents = np.array([p for _, p, _ in SKELETON])
    offsets = np.array([o for _, _, o in SKELETON], dtype=np.float64)
    t = np.arange(n_frames) / fps
    F, J = n_frames, len(names)
    rotations = np.tile(np.eye(3), (F, J, 1, 1))
    translations = np.tile(offsets, (F, 1, 1))
    yaw = turn * t
    c, s = np.cos(yaw), np.sin(yaw)
    rotations[:, 0] = np.stack([np.stack([c, 0 * c, s], -1), np.stack([0 * c, 1 + 0 * c, 0 * c], -1),
                                np.stack([-s, 0 * c, c], -1)], axis=1)
    translations[:, 0] = np.stack([0.1 * np.sin(2 * np.pi * t), 0.95 + 0.02 * np.cos(4 * np.pi * t),
                                   speed * t], axis=1)
    for name, amplitude in SWING.items():
        rotations[:, names.index(name)] = _rx(amplitude * np.sin(2 * np.pi * t))
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")]
    channels += [() if n.endswith("Site") else ("Zrotation", "Xrotation", "Yrotation") for n in names[1:]]
    return Motion(names, parents, offsets, channels, rotations, translations, 1.0 / fps, source="synthetic.bvh")


def foot_contacts(positions: np.ndarray, fps: float, feet) -> np.ndarray:
    """(F, len(feet)) 0/1 contacts: foot low and slow (a test-only stand-in for the contacts module)."""
    P = positions[:, list(feet)]  # (F, C, 3)
    speed = np.linalg.norm(np.gradient(P, axis=0), axis=2) * fps
    return ((P[:, :, 1] < np.percentile(P[:, :, 1], 40, axis=0)) & (speed < np.median(speed, axis=0))).astype(float)
