"""Compact encoding of tracks for the HTML player: JSON with base64 little-endian arrays.

Per character, joint positions are stored as the followed root joint's position per frame
(float32, (F, 3)) plus every joint's offset from it quantised to int16 with one step per
character: ``position = root + rel * step``. ``step = max|rel| / 32767``; the offsets are taken
from the float32-rounded root, so the rounding of the root cancels and the only error is the
quantisation, at most ``step / 2`` (about 25 micrometres for a 1.7 m person), while the data
shrinks to about half of float32:
8 characters x 10 s x 60 fps x 21 joints take about 1 MB of base64.
"""
from __future__ import annotations

import base64
from typing import List, Sequence

import numpy as np

from minifilm.viewer.body import body_plan_of_positions
from minifilm.viewer.tracks import Track

__all__ = ["encode_track", "encode_tracks", "quantise", "decode_positions", "INT16_MAX"]

INT16_MAX = 32767


def _b64(a: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode("ascii")


def quantise(track: Track):
    """(root (F, 3) float32, rel (F, J, 3) int16, step metres) for ``track``'s positions."""
    P = track.positions
    root = P[:, track.root].astype(np.float32)  # (F, 3)
    rel = P - root.astype(np.float64)[:, None]  # offsets from the stored (rounded) root
    step = max(float(np.abs(rel).max()) / INT16_MAX, 1e-9)
    q = np.clip(np.round(rel / step), -INT16_MAX, INT16_MAX).astype(np.int16)
    return root, q, step


def decode_positions(root: np.ndarray, rel: np.ndarray, step: float) -> np.ndarray:
    """(F, J, 3) positions as the page computes them (float64 arithmetic, like JavaScript)."""
    return root.astype(np.float64)[:, None] + rel.astype(np.float64) * step


def encode_track(track: Track, offset: Sequence[float]) -> dict:
    """JSON-ready dict for one character; ``offset`` (3,) is added in the page to place it."""
    root, rel, step = quantise(track)
    out = {
        "name": track.name,
        "fps": track.fps,
        "nFrames": track.n_frames,
        "nJoints": track.n_joints,
        "parents": [int(p) for p in track.parents],
        "jointNames": track.joint_names or [f"joint {j}" for j in range(track.n_joints)],
        "rootJoint": track.root,
        "root": _b64(root, "<f4"),
        "rel": _b64(rel, "<i2"),
        "step": step,
        "trail": _b64(track.trail, "<f4"),
        "offset": [float(v) for v in offset],
        "contactJoints": [int(j) for j in track.contact_joints],
        "body": track.body if track.body is not None else body_plan_of_positions(track.positions, track.parents,
                                                                                 track.joint_names),
        # Contacts only switch a highlight at 0.5: one byte per value is plenty.
        "contacts": _b64(np.round(track.contacts * 255), "u1") if track.contacts is not None else None,
    }
    return out


def encode_tracks(tracks: List[Track], offsets: np.ndarray) -> List[dict]:
    return [encode_track(t, o) for t, o in zip(tracks, offsets)]
