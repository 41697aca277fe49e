"""Root-relative frames on the floor, per character: the per-frame arithmetic of the runtime.

A root at (x, z) facing f = (f_x, f_z) (unit, on the floor) has the rotation R = LookRotation(f)
about the vertical axis; "local" vectors are R^T v, "world" vectors R v (docs/original-code.md §0.3).
These are written out component by component into preallocated arrays because they run for every
character on every frame, where ``np.stack`` and general rotation matrices cost more than the
arithmetic itself.
"""
from __future__ import annotations

import numpy as np


def to_local2(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """World (x, z) vectors (..., 2) into the frame of a root facing f (..., 2): R^T v."""
    out = np.empty(np.broadcast_shapes(v.shape, f.shape))   # filled in place: np.stack costs more per frame
    out[..., 0] = f[..., 1] * v[..., 0] - f[..., 0] * v[..., 1]
    out[..., 1] = f[..., 0] * v[..., 0] + f[..., 1] * v[..., 1]
    return out


def to_world2(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_local2`: R v for R = LookRotation(f)."""
    out = np.empty(np.broadcast_shapes(v.shape, f.shape))
    out[..., 0] = f[..., 1] * v[..., 0] + f[..., 0] * v[..., 1]
    out[..., 1] = -f[..., 0] * v[..., 0] + f[..., 1] * v[..., 1]
    return out


def to_local3(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """World 3-vectors (B, J, 3) into root frames facing f (B, 2): R^T v (y unchanged)."""
    fx, fz = f[:, 0, None], f[:, 1, None]
    out = np.empty(np.broadcast_shapes(v.shape, (len(f), 1, 3)))
    out[..., 0] = fz * v[..., 0] - fx * v[..., 2]
    out[..., 1] = v[..., 1]
    out[..., 2] = fx * v[..., 0] + fz * v[..., 2]
    return out


def to_world3(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_local3`."""
    fx, fz = f[:, 0, None], f[:, 1, None]
    out = np.empty(np.broadcast_shapes(v.shape, (len(f), 1, 3)))
    out[..., 0] = fz * v[..., 0] + fx * v[..., 2]
    out[..., 1] = v[..., 1]
    out[..., 2] = -fx * v[..., 0] + fz * v[..., 2]
    return out


def unit2(v: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 1e-8, v / np.maximum(n, 1e-8), fallback)


def floor_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees in [0, 180] between floor directions a and b (..., 2); 90 where either is zero-length."""
    cos = np.sum(a * b, axis=-1) / np.maximum(np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1), 1e-9)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
