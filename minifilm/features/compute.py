"""Input frame x, output frame z and style clip y (paper Sec. 3.2; docs/original-code.md §5-§9).

The column meaning lives in :class:`~minifilm.features.layout.FeatureLayout`; this file does the
arithmetic. The core functions work on plain arrays so they can be read (and tested) without BVH
files:

    positions  (F, J, 3)     world positions of the exported joints, metres
    rotations  (F, J, 3, 3)  world rotations; forward axis = column 2, up axis = column 1
    velocities (F, J, 3)     world velocities, m/s (backward difference, kinematics.velocities)
    root_pos   (F, 3)        the root: hips projected onto the floor y = 0
    root_rot   (F, 3, 3)     LookRotation(flattened facing); its column 2 is the facing direction

"Relative to a root (R, r)" means ``R^T (x - r)`` for points and ``R^T d`` for directions
(docs/original-code.md §0.3).

Segments. Every function takes a frame range ``[start, stop)`` and never reads a frame outside it:
a trajectory sample that falls outside is point-reflected about the segment's first / last frame
(docs/original-code.md §5), and the current frames are ``start+1 .. stop-2`` (the first and last frame
of a segment are never current, as in the original exporter §8.3: the first frame's velocity would
need the frame before, the last has no next frame). So a validation segment's rows contain no
training frame, and short clips still give rows.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from minifilm.features.layout import CURRENT_SAMPLE, TRAJECTORY_SECONDS, FeatureLayout
from minifilm.motion.kinematics import velocities as _velocities
from minifilm.motion.skeletons import root_transforms

__all__ = ["FeatureLayout", "FrameFeatures", "seconds_to_frames", "trajectory_offsets",
           "trajectory_sample_frames", "trajectory_features", "joint_features",
           "frame_features_from_arrays", "clip_features_from_arrays", "frame_features",
           "clip_features", "decode_joints", "decode_trajectory", "motion_arrays"]


@dataclass
class FrameFeatures:
    """Training pairs of one motion segment.

    x (N, x_dim), p (N, 8), z (N, z_dim); frames (N,) the current frame index of each row (z is
    built from frame ``frames + 1``).
    """
    x: np.ndarray
    p: np.ndarray
    z: np.ndarray
    frames: np.ndarray

    def __len__(self) -> int:
        return int(self.x.shape[0])


# --------------------------------------------------------------------------- time -> frames
def seconds_to_frames(seconds, fps: float) -> np.ndarray:
    """Nearest whole frame of ``seconds * fps``; halves round away from zero so that past and
    future offsets of the same size are mirror images. Returns int64 of the input's shape."""
    v = np.asarray(seconds, dtype=np.float64) * float(fps)
    # + 1e-9: a product that float error leaves just below a half still rounds away from zero
    return (np.sign(v) * np.floor(np.abs(v) + 0.5 + 1e-9)).astype(np.int64)


def trajectory_offsets(fps: float, seconds=TRAJECTORY_SECONDS) -> np.ndarray:
    """(12,) int frame offsets of the trajectory samples, e.g. at 60 fps
    ``[-60,-50,-40,-30,-20,-10, 0, 12,24,36,48,60]``; at 30 fps half of that."""
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"trajectory_offsets: fps must be positive, got {fps}")
    return seconds_to_frames(seconds, fps)


# --------------------------------------------------------------------------- trajectory
def trajectory_sample_frames(current: np.ndarray, offsets: np.ndarray, start: int,
                             stop: int) -> Tuple[np.ndarray, np.ndarray]:
    """Which frame each trajectory sample reads, and about which frame it is reflected.

    For a target ``t = current + offset`` inside ``[start, stop)`` the sample is frame t itself.
    Outside, docs/original-code.md §5 reflects it: past ``t < start`` reads ``ref = 2 start - t`` and
    the position becomes ``2 P(start) - P(ref)``; future ``t > last`` (last = stop-1) reads
    ``ref = 2 last - t`` and becomes ``2 P(last) - P(ref)``. The direction is ``ref``'s, not
    reflected. When the segment is shorter than the window, ``ref`` is clamped into the segment.

    Args:
        current: (N,) current frame indices, inside [start, stop).
        offsets: (S,) frame offsets.
    Returns:
        ref (N, S) the frame read; pivot (N, S) the reflection centre, or -1 where not reflected.
    """
    last = stop - 1
    t = np.asarray(current, dtype=np.int64)[:, None] + np.asarray(offsets, dtype=np.int64)[None, :]
    pivot = np.full(t.shape, -1, dtype=np.int64)
    ref = t.copy()
    before, after = t < start, t > last
    pivot[before], ref[before] = start, 2 * start - t[before]
    pivot[after], ref[after] = last, 2 * last - t[after]
    np.clip(ref, start, last, out=ref)
    return ref, pivot


def trajectory_features(root_pos: np.ndarray, root_rot: np.ndarray, current: np.ndarray,
                        reference: np.ndarray, offsets: np.ndarray, start: int = 0,
                        stop: Optional[int] = None) -> np.ndarray:
    """Trajectory samples ``[pos_x, pos_z, dir_x, dir_z]`` around frames ``current``, expressed
    relative to the roots of frames ``reference`` (docs/original-code.md §5, §6.1, §7).

    x uses ``reference = current`` and all 12 offsets; z uses ``current = k+1``,
    ``reference = k`` and offsets 6..11.

    Args:
        root_pos (F, 3), root_rot (F, 3, 3): the root of every frame.
        current (N,), reference (N,): frame indices; offsets (S,) frame offsets.
        start, stop: the segment the samples may read (default: the whole motion).
    Returns:
        (N, 4 S), point-major.
    """
    stop = root_pos.shape[0] if stop is None else stop
    ref, pivot = trajectory_sample_frames(current, offsets, start, stop)
    pos = root_pos[ref]                                        # (N, S, 3)
    reflected = pivot >= 0
    pos[reflected] = 2.0 * root_pos[pivot[reflected]] - pos[reflected]
    direction = root_rot[ref][..., :, 2]                       # (N, S, 3) facing column
    R = root_rot[np.asarray(reference)]                        # (N, 3, 3)
    r = root_pos[np.asarray(reference)]                        # (N, 3)
    # R^T v for row vectors v is v @ R: one batched matmul, much faster than einsum
    local_pos = (pos - r[:, None, :]) @ R                      # (N, S, 3)
    local_dir = direction @ R
    out = np.stack([local_pos[..., 0], local_pos[..., 2], local_dir[..., 0], local_dir[..., 2]],
                   axis=-1)                                    # (N, S, 4)
    return out.reshape(out.shape[0], -1)


# --------------------------------------------------------------------------- joints
def joint_features(positions: np.ndarray, rotations: np.ndarray, velocities: np.ndarray,
                   root_pos: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    """Per joint ``[p, fwd, up, v]`` relative to a root, interleaved (docs/original-code.md §6.1).

    Args:
        positions (N, J, 3), rotations (N, J, 3, 3), velocities (N, J, 3): world quantities of N
        frames; root_pos (N, 3), root_rot (N, 3, 3): the root each frame is expressed in.
    Returns:
        (N, 12 J): joint j occupies columns 12 j .. 12 j + 11.
    """
    N, J = positions.shape[:2]
    world = np.empty((N, J, 4, 3))
    world[:, :, 0] = positions - root_pos[:, None, :]
    world[:, :, 1] = rotations[..., :, 2]
    world[:, :, 2] = rotations[..., :, 1]
    world[:, :, 3] = velocities
    local = world.reshape(N, 4 * J, 3) @ root_rot              # row vectors: v @ R = (R^T v)^T
    return local.reshape(N, 12 * J)


# --------------------------------------------------------------------------- x, p, z
def _check_arrays(positions, rotations, velocities, root_pos, root_rot, phases=None,
                  contacts=None, where="features") -> int:
    F, J = positions.shape[:2]
    want = {"positions": ((F, J, 3), positions), "rotations": ((F, J, 3, 3), rotations),
            "velocities": ((F, J, 3), velocities), "root_pos": ((F, 3), root_pos),
            "root_rot": ((F, 3, 3), root_rot)}
    if phases is not None:
        want["phases"] = ((F, 8), phases)
    if contacts is not None:
        want["contacts"] = ((F, 2), contacts)
    for name, (shape, a) in want.items():
        if tuple(np.shape(a)) != shape:
            raise ValueError(f"{where}: {name} has shape {np.shape(a)}, expected {shape} "
                             f"(F={F} frames, J={J} joints)")
    return F


def _segment(start: int, stop: Optional[int], F: int, where: str) -> Tuple[int, int]:
    stop = F if stop is None else int(stop)
    start = int(start)
    if not (0 <= start <= stop <= F):
        raise ValueError(f"{where}: segment [{start}, {stop}) is not inside [0, {F})")
    return start, stop


def frame_features_from_arrays(positions, rotations, velocities, root_pos, root_rot, phases,
                               contacts, fps: float, start: int = 0, stop: Optional[int] = None,
                               dtype=np.float32, layout: Optional[FeatureLayout] = None) -> FrameFeatures:
    """x, p, z for every current frame ``k = start+1 .. stop-2`` of a segment (Sec. 3.2).

    Shapes as in the module docstring; phases (F, 8) from ``LocalPhases.vectors()``, contacts
    (F, 2) ``[right, left]``. Rows whose samples would leave ``[start, stop)`` are reflected (see
    :func:`trajectory_sample_frames`). A segment shorter than 3 frames gives 0 rows. The columns
    are those of ``layout`` (default: :meth:`FeatureLayout.generic` for J joints).
    """
    F = _check_arrays(positions, rotations, velocities, root_pos, root_rot, phases, contacts,
                      "frame_features")
    start, stop = _segment(start, stop, F, "frame_features")
    L = _layout(layout, positions.shape[1])
    k = np.arange(start + 1, stop - 1)                         # current frames
    offsets = trajectory_offsets(fps, L.trajectory_seconds)
    phases = np.asarray(phases, dtype=np.float64)
    contacts = np.asarray(contacts, dtype=np.float64)
    x = np.empty((k.size, L.x_dim), dtype=dtype)
    z = np.empty((k.size, L.z_dim), dtype=dtype)
    if k.size:
        x[:, L.x_trajectory] = trajectory_features(root_pos, root_rot, k, k, offsets, start, stop)
        x[:, L.x_joints] = joint_features(positions[k], rotations[k], velocities[k], root_pos[k], root_rot[k])
        # z: the next frame (k + 1) seen from the CURRENT root (k)
        z[:, L.z_trajectory] = trajectory_features(root_pos, root_rot, k + 1, k,
                                                   offsets[CURRENT_SAMPLE:], start, stop)
        z[:, L.z_joints] = joint_features(positions[k + 1], rotations[k + 1], velocities[k + 1],
                                          root_pos[k], root_rot[k])
        z[:, L.z_phases] = phases[k + 1]
        z[:, L.z_phase_updates] = phases[k + 1] - phases[k]
        z[:, L.z_contacts] = contacts[k + 1]
    return FrameFeatures(x=x, p=phases[k].astype(dtype), z=z, frames=k)


def _layout(layout: Optional[FeatureLayout], J: int) -> FeatureLayout:
    if layout is None:
        return FeatureLayout.generic(J)
    if layout.n_joints != J:
        raise ValueError(f"features: the layout has {layout.n_joints} joints, the arrays {J}")
    return layout


def clip_features_from_arrays(positions, rotations, velocities, root_pos, root_rot, fps: float,
                              clip_seconds: float = 4.0, stride_seconds: float = 2.0,
                              start: int = 0, stop: Optional[int] = None,
                              dtype=np.float32) -> np.ndarray:
    """Style clips y: (M, T, 12 J), T = clip_seconds * fps frames, windows every stride_seconds.

    Each clip frame holds the joint block of x relative to that frame's OWN root (Sec. 3.2,
    docs/original-code.md §9). Windows start at ``start + 1`` (so every velocity comes from inside the
    segment) and must end by ``stop``; a segment needs T + 1 frames for one clip, as in the
    original.
    """
    F = _check_arrays(positions, rotations, velocities, root_pos, root_rot, where="clip_features")
    start, stop = _segment(start, stop, F, "clip_features")
    T = int(seconds_to_frames(clip_seconds, fps))
    stride = int(seconds_to_frames(stride_seconds, fps))
    if T < 1 or stride < 1:
        raise ValueError(f"clip_features: clip {clip_seconds} s and stride {stride_seconds} s give "
                         f"{T} and {stride} frames at {fps} fps; both must be >= 1")
    firsts = np.arange(start + 1, stop - T + 1, stride)
    J = positions.shape[1]
    if firsts.size == 0:
        return np.empty((0, T, 12 * J), dtype=dtype)
    a, b = firsts[0], firsts[-1] + T                           # frames any clip uses
    block = joint_features(positions[a:b], rotations[a:b], velocities[a:b], root_pos[a:b],
                           root_rot[a:b]).astype(dtype, copy=False)   # each frame once
    return block[(firsts - a)[:, None] + np.arange(T)[None, :]]       # (M, T, 12 J)


# --------------------------------------------------------------------------- decoding
def decode_joints(block: np.ndarray, root_pos: np.ndarray, root_rot: np.ndarray):
    """Inverse of :func:`joint_features`: world quantities from a (N, 12 J) joint block.

    Returns positions (N, J, 3), forward (N, J, 3), up (N, J, 3), velocities (N, J, 3) in world
    space (``R x + r`` for points, ``R d`` for directions). Used by the runtime and the tests.
    """
    N = block.shape[0]
    q = np.asarray(block, dtype=np.float64).reshape(N, -1, 4, 3)
    R = np.asarray(root_rot, dtype=np.float64)
    world = np.einsum("nab,njfb->njfa", R, q)                  # R d for all four fields
    pos = world[:, :, 0] + np.asarray(root_pos, dtype=np.float64)[:, None, :]
    return pos, world[:, :, 1], world[:, :, 2], world[:, :, 3]


def decode_trajectory(block: np.ndarray, root_pos: np.ndarray, root_rot: np.ndarray):
    """World positions (N, S, 3) on the floor and facing directions (N, S, 3) of a (N, 4 S)
    trajectory block expressed relative to roots (root_pos (N, 3), root_rot (N, 3, 3))."""
    N = block.shape[0]
    q = np.asarray(block, dtype=np.float64).reshape(N, -1, 4)
    zeros = np.zeros(q.shape[:2])
    lp = np.stack([q[..., 0], zeros, q[..., 1]], axis=-1)
    ld = np.stack([q[..., 2], zeros, q[..., 3]], axis=-1)
    R = np.asarray(root_rot, dtype=np.float64)
    pos = np.einsum("nab,nsb->nsa", R, lp) + np.asarray(root_pos, dtype=np.float64)[:, None, :]
    return pos, np.einsum("nab,nsb->nsa", R, ld)


# --------------------------------------------------------------------------- Motion wrappers
def motion_arrays(motion, skeleton, fps: Optional[float] = None):
    """World arrays of the exported joints of ``motion``: positions (F, J, 3), rotations
    (F, J, 3, 3), velocities (F, J, 3) (m/s at ``fps``, default the motion's), root_pos (F, 3),
    root_rot (F, 3, 3)."""
    fps = motion.fps if fps is None else float(fps)
    idx = skeleton.joint_indices(motion)
    wp, wr = motion.world()
    positions, rotations = wp[:, idx], wr[:, idx]
    vel = _velocities(positions, fps)
    root_pos, root_rot = root_transforms(motion, skeleton)
    return positions, rotations, vel, root_pos, root_rot


def frame_features(motion, skeleton, phases: np.ndarray, contacts: np.ndarray,
                   fps: Optional[float] = None, start: int = 0, stop: Optional[int] = None,
                   dtype=np.float32) -> FrameFeatures:
    """x, p, z of a :class:`~minifilm.motion.motion.Motion` on ``skeleton``'s exported joints (Sec. 3.2).

    phases (F, 8) from ``LocalPhases.vectors()``; contacts (F, 2) ``[right, left]``.
    fps defaults to the motion's; it sets the trajectory window and the velocity scale.
    """
    fps = motion.fps if fps is None else float(fps)
    arrays = motion_arrays(motion, skeleton, fps)
    return frame_features_from_arrays(*arrays, phases, contacts, fps, start, stop, dtype,
                                      FeatureLayout.for_skeleton(skeleton))


def clip_features(motion, skeleton, clip_seconds: float = 4.0, stride_seconds: float = 2.0,
                  fps: Optional[float] = None, start: int = 0, stop: Optional[int] = None,
                  dtype=np.float32) -> np.ndarray:
    """Style clips (M, T, 12 J) of a :class:`~minifilm.motion.motion.Motion`; see :func:`clip_features_from_arrays`."""
    fps = motion.fps if fps is None else float(fps)
    arrays = motion_arrays(motion, skeleton, fps)
    return clip_features_from_arrays(*arrays, fps, clip_seconds, stride_seconds, start, stop, dtype)
