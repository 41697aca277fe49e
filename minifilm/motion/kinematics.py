"""Rotations and kinematics: Euler angles, quaternions, forward kinematics, root-relative frames.

Conventions (docs/original-code.md §0.3): right-handed, Y up, column vectors, so a point ``x`` in a
joint's frame is ``R @ x + p`` in its parent's frame. Angles are radians. Rotation matrices act on
the last two axes, so every function works on any stack of leading axes, e.g. (F, J, 3, 3).

Euler angles follow the BVH reading (docs/original-code.md §1.1): the channel order ``"YXZ"`` means
``R = Ry(a0) @ Rx(a1) @ Rz(a2)``, i.e. *intrinsic* rotations in the listed order (which is the same
matrix as *extrinsic* rotations in the reversed order). In SciPy's naming that is
``Rotation.from_euler("YXZ", a)`` with capital letters.

Quaternions are stored ``(w, x, y, z)``.

Mirroring and resampling, which build new ``Motion`` objects, live in ``editing.py``.
"""
from __future__ import annotations

from typing import Sequence, Tuple

import numpy as np

AXES = "XYZ"
ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


# ----------------------------------------------------------------------------------------------
# Single-axis rotations and Euler angles
# ----------------------------------------------------------------------------------------------

def axis_rotation(axis: str, angle: np.ndarray) -> np.ndarray:
    """Rotation about one coordinate axis. ``angle`` (...,) radians -> (..., 3, 3).

    ``Rx(t) = [[1,0,0],[0,c,-s],[0,s,c]]`` and cyclically for y and z (right-handed).
    """
    i = _axis_index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(angle.shape + (3, 3))
    R[..., i, i] = 1.0
    R[..., j, j] = c
    R[..., k, k] = c
    R[..., j, k] = -s
    R[..., k, j] = s
    return R


def euler_to_matrix(angles: np.ndarray, order: str) -> np.ndarray:
    """Euler angles (..., 3) in radians -> rotation matrices (..., 3, 3).

    ``R = R_order[0](angles[..., 0]) @ R_order[1](angles[..., 1]) @ R_order[2](angles[..., 2])``,
    exactly how a BVH joint with rotation channels listed in ``order`` is read.
    """
    order = _check_order(order)
    angles = np.asarray(angles, dtype=np.float64)
    if angles.shape[-1:] != (3,):
        raise ValueError(f"euler_to_matrix: angles must end in 3, got shape {angles.shape}")
    R = axis_rotation(order[0], angles[..., 0])
    R = R @ axis_rotation(order[1], angles[..., 1])
    return R @ axis_rotation(order[2], angles[..., 2])


def matrix_to_euler(R: np.ndarray, order: str) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> Euler angles (..., 3) with ``euler_to_matrix(a, order) == R``.

    For intrinsic axes (i, j, k) with parity ``s`` (+1 for the cyclic orders XYZ, YZX, ZXY, -1 for
    the others), ``R[i, k] = s sin(a1)``, ``tan(a0) = -s R[j, k] / R[k, k]`` and
    ``tan(a2) = -s R[i, j] / R[i, i]``. The middle angle is in [-pi/2, pi/2]. At gimbal lock
    (cos a1 ~ 0) only a0 +- a2 is defined: we set a2 = 0 and read a0 from column j.
    """
    order = _check_order(order)
    R = np.asarray(R, dtype=np.float64)
    i, j, k = (_axis_index(a) for a in order)
    s = 1.0 if (j - i) % 3 == 1 else -1.0
    sin_b = np.clip(s * R[..., i, k], -1.0, 1.0)
    cos_b = np.hypot(R[..., i, i], R[..., i, j])
    b = np.arctan2(sin_b, cos_b)
    a = np.arctan2(-s * R[..., j, k], R[..., k, k])
    c = np.arctan2(-s * R[..., i, j], R[..., i, i])
    locked = cos_b < 1e-9
    if np.any(locked):
        # With a2 = 0, column j of R is R_i(a0) e_j: (R[k, j], R[j, j]) = (s sin a0, cos a0).
        a = np.where(locked, np.arctan2(s * R[..., k, j], R[..., j, j]), a)
        c = np.where(locked, 0.0, c)
    return np.stack([a, b, c], axis=-1)


def _axis_index(axis: str) -> int:
    idx = AXES.find(axis.upper()) if isinstance(axis, str) and len(axis) == 1 else -1
    if idx < 0:
        raise ValueError(f"unknown rotation axis {axis!r}; expected one of X, Y, Z")
    return idx


def _check_order(order: str) -> str:
    up = order.upper() if isinstance(order, str) else ""
    if up not in ORDERS:
        raise ValueError(f"unknown Euler order {order!r}; expected one of {', '.join(ORDERS)}")
    return up


# ----------------------------------------------------------------------------------------------
# Quaternions (w, x, y, z)
# ----------------------------------------------------------------------------------------------

def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) ``(w, x, y, z)`` -> rotation matrices (..., 3, 3). ``q`` is normalised first."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> unit quaternions (..., 4) ``(w, x, y, z)`` with w >= 0.

    Shepperd's method: solve for the largest of |w|, |x|, |y|, |z| first, which keeps the division
    well conditioned for every rotation (including 180 degrees).
    """
    R = np.asarray(R, dtype=np.float64)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    trace = m00 + m11 + m22
    # 4 * (w^2, x^2, y^2, z^2) from the diagonal
    cand = np.stack([1 + trace, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    best = np.argmax(cand, axis=-1)
    r = np.sqrt(np.maximum(np.take_along_axis(cand, best[..., None], -1)[..., 0], 1e-300))
    a21, a12 = R[..., 2, 1], R[..., 1, 2]
    a02, a20 = R[..., 0, 2], R[..., 2, 0]
    a10, a01 = R[..., 1, 0], R[..., 0, 1]
    # Rows: the quaternion computed assuming w, x, y or z is the largest component (times 2r).
    options = np.stack([
        np.stack([r * r, a21 - a12, a02 - a20, a10 - a01], -1),
        np.stack([a21 - a12, r * r, a01 + a10, a02 + a20], -1),
        np.stack([a02 - a20, a01 + a10, r * r, a12 + a21], -1),
        np.stack([a10 - a01, a02 + a20, a12 + a21, r * r], -1),
    ], -2)
    q = np.take_along_axis(options, best[..., None, None], -2)[..., 0, :] / (2 * r[..., None])
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of quaternions (..., 4); rotation by b, then by a."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions (..., 4) at ``t`` (broadcast to (...,)).

    Takes the short way round (flips q1 when q0 . q1 < 0); falls back to normalised linear
    interpolation when the two are nearly equal (sin of the angle ~ 0). Returns unit quaternions.
    """
    q0 = np.asarray(q0, dtype=np.float64)
    q1 = np.asarray(q1, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.clip(np.abs(dot), -1.0, 1.0)
    theta = np.arccos(dot)
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-6
    safe = np.where(small, 1.0, sin_theta)
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(small, t, np.sin(t * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# ----------------------------------------------------------------------------------------------
# Forward kinematics, axes, velocities
# ----------------------------------------------------------------------------------------------

def forward_kinematics(rotations: np.ndarray, translations: np.ndarray,
                       parents: Sequence[int]) -> Tuple[np.ndarray, np.ndarray]:
    """World transforms from local ones (docs/original-code.md §1.1).

    ``World_j = World_parent(j) @ [R_j | t_j]``; a root's world transform is its local one.

    Args:
        rotations:    (F, J, 3, 3) local rotations.
        translations: (F, J, 3) local translations (offset or position channels).
        parents:      (J,) parent index, -1 for roots; parents come before children.
    Returns:
        positions (F, J, 3) and rotations (F, J, 3, 3) in world space. Vectorised over frames;
        the Python loop runs over joints only.
    """
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    parents = np.asarray(parents, dtype=np.int64)
    F, J = rotations.shape[:2]
    if rotations.shape != (F, J, 3, 3) or translations.shape != (F, J, 3) or parents.shape != (J,):
        raise ValueError(f"forward_kinematics: shapes rotations {rotations.shape}, translations "
                         f"{translations.shape}, parents {parents.shape} do not agree as (F,J,3,3), (F,J,3), (J,)")
    world_R = np.empty_like(rotations)
    world_p = np.empty_like(translations)
    for j in range(J):
        p = parents[j]
        if p < 0:
            world_R[:, j] = rotations[:, j]
            world_p[:, j] = translations[:, j]
        elif p >= j:
            raise ValueError(f"forward_kinematics: joint {j} has parent {p}, which does not come before it")
        else:
            world_R[:, j] = world_R[:, p] @ rotations[:, j]
            world_p[:, j] = (world_R[:, p] @ translations[:, j, :, None])[..., 0] + world_p[:, p]
    return world_p, world_R


def forward_axis(R: np.ndarray) -> np.ndarray:
    """The local +Z axis in the parent/world frame: third column, (..., 3, 3) -> (..., 3)."""
    return np.asarray(R)[..., :, 2]


def up_axis(R: np.ndarray) -> np.ndarray:
    """The local +Y axis in the parent/world frame: second column, (..., 3, 3) -> (..., 3)."""
    return np.asarray(R)[..., :, 1]


def right_axis(R: np.ndarray) -> np.ndarray:
    """The local +X axis in the parent/world frame: first column, (..., 3, 3) -> (..., 3)."""
    return np.asarray(R)[..., :, 0]


def velocities(positions: np.ndarray, fps: float) -> np.ndarray:
    """Backward-difference velocities (docs/original-code.md §1.4): ``v[k] = (x[k] - x[k-1]) * fps``.

    ``positions`` (F, ..., 3) -> (F, ..., 3) in units per second. Frame 0 has no predecessor and
    copies frame 1's value; a single frame gets zero velocity.
    """
    x = np.asarray(positions, dtype=np.float64)
    v = np.zeros_like(x)
    if x.shape[0] >= 2:
        v[1:] = (x[1:] - x[:-1]) * fps
        v[0] = v[1]
    return v


def look_rotation(forward: np.ndarray) -> np.ndarray:
    """Unity's ``LookRotation(f, up=+Y)`` for horizontal directions (docs/original-code.md §0.3).

    ``forward`` (..., 3) is flattened (y dropped) and normalised, then
    ``R = [[fz, 0, fx], [0, 1, 0], [-fx, 0, fz]]`` (columns: right, up, forward). A direction with no
    horizontal part (straight up/down) gives the identity (facing +Z).
    """
    f = np.asarray(forward, dtype=np.float64)
    fx, fz = f[..., 0], f[..., 2]
    n = np.hypot(fx, fz)
    degenerate = n < 1e-12
    n = np.where(degenerate, 1.0, n)
    fx = np.where(degenerate, 0.0, fx / n)
    fz = np.where(degenerate, 1.0, fz / n)
    R = np.zeros(f.shape[:-1] + (3, 3))
    R[..., 0, 0] = fz
    R[..., 0, 2] = fx
    R[..., 1, 1] = 1.0
    R[..., 2, 0] = -fx
    R[..., 2, 2] = fz
    return R


# ----------------------------------------------------------------------------------------------
# Root-relative coordinates (docs/original-code.md §0.3, "relative to")
# ----------------------------------------------------------------------------------------------

def _expand(root: np.ndarray, target_ndim: int, tail: int) -> np.ndarray:
    """Insert singleton axes before the last ``tail`` axes so ``root`` broadcasts against points."""
    extra = target_ndim - (root.ndim - tail + 1)
    if extra < 0:
        raise ValueError(f"root transform with shape {root.shape} has more leading axes than the points")
    return root.reshape(root.shape[:root.ndim - tail] + (1,) * extra + root.shape[root.ndim - tail:])


def to_local(points: np.ndarray, root_pos: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    """World points -> root frame: ``R^T (x - p)``.

    Shapes: ``root_pos`` (..., 3), ``root_rot`` (..., 3, 3), ``points`` (..., [N, ...,] 3): any extra
    axes of ``points`` between the leading ones and the last are broadcast over, e.g. points
    (F, J, 3) with a per-frame root (F, 3), (F, 3, 3).
    """
    points = np.asarray(points, dtype=np.float64)
    p = _expand(np.asarray(root_pos, dtype=np.float64), points.ndim, 1)
    R = _expand(np.asarray(root_rot, dtype=np.float64), points.ndim, 2)
    return (np.swapaxes(R, -1, -2) @ (points - p)[..., None])[..., 0]


def from_local(points: np.ndarray, root_pos: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    """Root-frame points -> world: ``R x + p`` (inverse of ``to_local``; same shapes)."""
    points = np.asarray(points, dtype=np.float64)
    p = _expand(np.asarray(root_pos, dtype=np.float64), points.ndim, 1)
    R = _expand(np.asarray(root_rot, dtype=np.float64), points.ndim, 2)
    return (R @ points[..., None])[..., 0] + p


def directions_to_local(directions: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    """World directions or velocities -> root frame: ``R^T d`` (shapes as in ``to_local``)."""
    d = np.asarray(directions, dtype=np.float64)
    R = _expand(np.asarray(root_rot, dtype=np.float64), d.ndim, 2)
    return (np.swapaxes(R, -1, -2) @ d[..., None])[..., 0]


def directions_from_local(directions: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    """Root-frame directions -> world: ``R d`` (inverse of ``directions_to_local``)."""
    d = np.asarray(directions, dtype=np.float64)
    R = _expand(np.asarray(root_rot, dtype=np.float64), d.ndim, 2)
    return (R @ d[..., None])[..., 0]
