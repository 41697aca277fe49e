"""A retargeted clip's joint frames turned to the released network's convention.

The network reads every joint's forward and up axes (docs/features.md). Retargeting puts a clip's
joints where they belong, but each joint's frame is the target skeleton's rest frame carried along,
not the frame the 100STYLE capture's joints had: on a retargeted Bandai-Namco clip the spine's,
collars', shoulders' and one leg's axes differ from the network's by 60-180°, one constant
rotation per joint (docs/teaching-released.md). :func:`align_axes` finds and removes it.
"""
from __future__ import annotations

import numpy as np

from minifilm.features.layout import FeatureLayout

def align_axes(x: np.ndarray, z: np.ndarray, layout: FeatureLayout, stats) -> tuple:
    """Turn each joint's forward/up axes by one constant rotation so their mean over the clip
    matches the network's mean (its input statistics): a retargeted skeleton's joint frames are
    not the 100STYLE capture's, and differ from them by a fixed rotation per joint.

    x (N, x_dim), z (N, z_dim) raw rows -> (x, z) copies with the axes turned, and the rotation
    angle per joint (degrees, (J,)). Positions and velocities are untouched. For joint j with
    root-space frames A(t) (columns: up x forward, up, forward), the rotation O maximises
    Σ_t Σ_c  (A(t) O e_c) · b_c  for the network's mean axes b_c (orthogonal Procrustes)."""
    x, z = np.array(x, np.float64), np.array(z, np.float64)
    angles = np.zeros(layout.n_joints)
    fx, ux = layout.joint_columns("x", "forward"), layout.joint_columns("x", "up")
    fz, uz = layout.joint_columns("z", "forward"), layout.joint_columns("z", "up")
    mean = stats.x_mean
    for j in range(layout.n_joints):
        b_up, b_fwd = mean[ux[j]], mean[fx[j]]
        O = _procrustes(_frames(x[:, fx[j]], x[:, ux[j]]), b_up, b_fwd)
        angles[j] = np.degrees(np.arccos(np.clip((np.trace(O) - 1) / 2, -1, 1)))
        for rows, fc, uc in ((x, fx[j], ux[j]), (z, fz[j], uz[j])):
            turned = _frames(rows[:, fc], rows[:, uc]) @ O
            rows[:, uc], rows[:, fc] = turned[:, :, 1], turned[:, :, 2]
    return x, z, angles


def _frames(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(N, 3) forward and up axes -> (N, 3, 3) orthonormal frames [up x forward, up, forward]."""
    f = forward / np.linalg.norm(forward, axis=1, keepdims=True)
    u = up - np.sum(up * f, axis=1, keepdims=True) * f
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return np.stack([np.cross(u, f), u, f], axis=2)


def _procrustes(A: np.ndarray, b_up: np.ndarray, b_fwd: np.ndarray) -> np.ndarray:
    """The rotation O (3, 3) that best maps e_up, e_fwd through A(t) O onto b_up, b_fwd."""
    M = np.einsum("nki,k->i", A, b_up)[:, None] * np.array([0.0, 1.0, 0.0])[None] \
        + np.einsum("nki,k->i", A, b_fwd)[:, None] * np.array([0.0, 0.0, 1.0])[None]
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    return U @ np.diag([1.0, 1.0, d]) @ Vt

