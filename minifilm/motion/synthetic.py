"""Procedural stylised locomotion on the 100STYLE skeleton: the data minifilm makes for itself.

``generate_style(style, gait, seconds, rng)`` returns a ``SyntheticClip``: a ``Motion`` exactly like
the one ``read_bvh`` gives for a 100STYLE file (28 joints incl. End Sites, metres, radians, local
rotation matrices, translations = offsets except the root), plus the ground truth the pipeline
tries to recover: the phase of each limb and the foot contacts.

How a clip is made (everything vectorised over frames):

1. Gait timeline and root path (``trajectories.py``): speed, travel direction, stride frequency,
   walk/run timing per frame; a turning path on the floor; the stride phase θ(t) = ∫ f dt.
2. Feet. Foot ``i`` has phase φ_i = θ + offset_i. Cycle k is centred on mid-stance φ_i = k + 0.25
   (the paper's convention: a sinusoid fitted to the contact signal peaks at φ = 0.25, i.e. at
   mid-stance, original-pipeline.md §4.7). The stance covers |φ_i − k − 0.25| <= d/2 with duty
   factor d. During stance k the toe tip (``<Side>ToeSite``, the contact sensor) is planted at a
   target on the floor y = 0, placed where the hip will be at mid-stance; between stances it swings
   to the next target along a smooth arc. Late in stance the heel rises by rotating the foot about
   the toe, which keeps the toe tip planted. A lifted foot (hopping styles) instead oscillates
   forward and back in the hips' frame and never comes near the floor.
3. Hips: the root path plus sway, with a height that bobs and is then lowered (soft minimum)
   just enough for both legs to reach their feet.
4. Legs by analytic two-bone IK (hip -> knee -> ankle), the knee bending towards the foot's
   forward direction; spine, head and arms by per-limb oscillators with the style's parameters.

Ground truth, for measuring phase extraction (circular error) and contact detection:

- ``true_phase`` (F, 4), order [left hand, right hand, left foot, right foot], cycles in [0, 1):
  * feet that step: φ = 0.25 at mid-stance, increasing linearly in time between mid-stances;
  * a lifted foot (hop styles) and the hands: φ = 0.25 when the limb is at the *forward* extreme
    of its swing, 0.75 at the backward extreme. Each such limb swings along one path driven by
    angle = centre + amplitude · sin 2πφ (the upper arm's forward swing; the foot's forward offset),
    so in the hips' frame its largest-variance direction, turned to point forwards (+z) as the
    original's PCA source does (§3.4), is maximal at φ = 0.25, the same convention as the feet.
- ``phase_active`` (F, 4): where the limb really oscillates, and has for half a second either side
  (a foot that stands still while idle, or an arm whose swing is under 7°, has no meaningful phase).
- ``true_contacts`` (F, 2), order [right, left], 1.0 during designed stance, and also during a
  "swing" so small (< 1 cm lift, < 5 mm travel, as when standing still) that the foot never
  actually leaves the floor.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np
from scipy.ndimage import minimum_filter1d

from .motion import Motion
from .synthetic_styles import (DUTY_HOP, DUTY_RUN, DUTY_WALK, GAITS, STYLE_PARAMS, STYLES,
                               StyleParams)
from .trajectories import GaitTimeline, RootPath, gait_timeline, root_path, smooth_noise

__all__ = ["SyntheticClip", "generate_style", "default_dataset", "write_dataset", "STYLES", "GAITS",
           "DEFAULT_GAITS", "skeleton_100style", "JOINT_NAMES"]

# ----------------------------------------------------------------------------------------------
# The 100STYLE skeleton (Neutral_FR.bvh header, centimetres), 28 bones incl. the 5 End Sites.
# Right-side joints have negative x, y is up, the hips' local +z is the character's front.
# ----------------------------------------------------------------------------------------------

_SKELETON_CM = (
    ("Hips", -1, (0.0, 0.0, 0.0)),
    ("Chest", 0, (0.0, 12.953391, -0.028419)),
    ("Chest2", 1, (0.0, 10.280254, 0.051622)),
    ("Chest3", 2, (0.0, 9.287180, 0.0)),
    ("Chest4", 3, (0.0, 9.287180, 0.0)),
    ("Neck", 4, (0.0, 13.296264, 0.0)),
    ("Head", 5, (0.0, 8.959264, 0.099003)),
    ("HeadSite", 6, (0.0, 17.121337, 0.039303)),
    ("RightCollar", 4, (-3.193511, 7.451388, 0.0)),
    ("RightShoulder", 8, (-15.792092, 0.0, 0.0)),
    ("RightElbow", 9, (-31.151839, 0.0, 0.0)),
    ("RightWrist", 10, (-25.536298, 0.0, 0.002321)),
    ("RightWristSite", 11, (-19.133213, 0.0, 0.0)),
    ("LeftCollar", 4, (3.193511, 7.451388, 0.0)),
    ("LeftShoulder", 13, (15.792092, 0.0, 0.0)),
    ("LeftElbow", 14, (31.151839, 0.0, 0.0)),
    ("LeftWrist", 15, (25.536298, 0.0, 0.002321)),
    ("LeftWristSite", 16, (19.133213, 0.0, 0.0)),
    ("RightHip", 0, (-10.745749, 0.139252, 0.014209)),
    ("RightKnee", 18, (0.0, -43.743899, -0.006071)),
    ("RightAnkle", 19, (0.0, -43.214199, 0.089931)),
    ("RightToe", 20, (0.0, -9.699830, 19.151588)),
    ("RightToeSite", 21, (0.0, -1.292898, 4.893873)),
    ("LeftHip", 0, (10.745749, 0.139252, 0.014209)),
    ("LeftKnee", 23, (0.0, -43.743899, -0.006071)),
    ("LeftAnkle", 24, (0.0, -43.214199, 0.089931)),
    ("LeftToe", 25, (0.0, -9.699830, 19.151588)),
    ("LeftToeSite", 26, (0.0, -1.292898, 4.893873)),
)
JOINT_NAMES = tuple(name for name, _, _ in _SKELETON_CM)
_PARENTS = np.array([p for _, p, _ in _SKELETON_CM], dtype=np.int64)
_OFFSETS = np.array([o for _, _, o in _SKELETON_CM], dtype=np.float64) * 0.01
_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Yrotation", "Xrotation", "Zrotation")
_JOINT_CHANNELS = ("Yrotation", "Xrotation", "Zrotation")
_J = {name: i for i, name in enumerate(JOINT_NAMES)}

#: Gaits of the default data set (every style gets each of them).
DEFAULT_GAITS = ("FW", "BW", "FR", "SW", "ID", "TR")


def skeleton_100style() -> Tuple[List[str], np.ndarray, np.ndarray, List[Tuple[str, ...]]]:
    """(names (28,), parents (28,), offsets (28, 3) metres, channels (28,)) of the 100STYLE skeleton."""
    channels = [() if n.endswith("Site") else (_ROOT_CHANNELS if p < 0 else _JOINT_CHANNELS)
                for n, p, _ in _SKELETON_CM]
    return list(JOINT_NAMES), _PARENTS.copy(), _OFFSETS.copy(), channels


# Leg geometry. The standing hips height puts the toe tip on the floor with every joint at rest.
_THIGH, _SHIN = _OFFSETS[_J["RightKnee"]], _OFFSETS[_J["RightAnkle"]]
_FOOT, _TOE = _OFFSETS[_J["RightToe"]], _OFFSETS[_J["RightToeSite"]]
_L1, _L2 = float(np.linalg.norm(_THIGH)), float(np.linalg.norm(_SHIN))
_REACH = 0.997 * (_L1 + _L2)        # keep the knee a little bent even at full stretch
STANDING_HIPS_HEIGHT = -float((_OFFSETS[_J["RightHip"]] + _THIGH + _SHIN + _FOOT + _TOE)[1])
#: Forward distance from the path point under the hip to the planted toe tip at mid-stance, m:
#: the ankle then sits about 4 cm behind the hip (the toe tip is 24 cm ahead of the ankle).
_TOE_AHEAD = 0.20


# ----------------------------------------------------------------------------------------------
# Small vectorised helpers
# ----------------------------------------------------------------------------------------------

def _rot(axis: int, angle) -> np.ndarray:
    """(N,) angles -> (N, 3, 3) right-handed rotations about x (0), y (1) or z (2)."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i], R[..., j, j] = c, c
    R[..., i, j], R[..., j, i] = -s, s
    return R


def _apply(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 3, 3) @ (N, 3) or (3,) -> (N, 3)."""
    return np.einsum("nij,...j->ni", R, v) if v.ndim == 1 else np.einsum("nij,nj->ni", R, v)


def _smoothstep(x, lo: float = 0.0, hi: float = 1.0) -> np.ndarray:
    """0 below ``lo``, 1 above ``hi``, 3u² − 2u³ between (zero slope at both ends)."""
    u = np.clip((np.asarray(x, dtype=np.float64) - lo) / (hi - lo), 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _normalize(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _soft_min(values: Sequence[np.ndarray], k: float) -> np.ndarray:
    """Smooth minimum −k log Σ exp(−v/k): never above the true minimum, at most k·log(n) below."""
    v = np.stack(values)
    m = v.min(axis=0)
    return m - k * np.log(np.exp(-(v - m) / k).sum(axis=0))


# ----------------------------------------------------------------------------------------------
# Feet
# ----------------------------------------------------------------------------------------------

@dataclass
class _Foot:
    """Per-frame world description of one foot, all (N, ...)."""

    toe_tip: np.ndarray      # (N, 3) planned ToeSite position
    ankle: np.ndarray        # (N, 3) ankle position that realises it
    rotation: np.ndarray     # (N, 3, 3) world rotation of the Ankle joint (the foot)
    toe_local: np.ndarray    # (N, 3, 3) local rotation of the Toe joint
    forward: np.ndarray      # (N, 3) horizontal forward direction of the foot (the knee's pole)
    contact: np.ndarray      # (N,) bool ground-truth contact
    phase: np.ndarray        # (N,) continuous phase (cycles)
    active: np.ndarray       # (N,) bool: the phase is meaningful


def _foot_from_toe_tip(tip: np.ndarray, yaw: np.ndarray, pitch: np.ndarray, toe_bend: np.ndarray):
    """Ankle position and foot/toe rotations that put the toe tip at ``tip``.

    The foot (ankle -> toe) is pitched by ``pitch`` about its x axis (positive lifts the heel), the
    toe segment by ``toe_bend`` more; with ``toe_bend = -pitch`` the toe lies flat and the heel
    rises about the planted toe, as at heel-off.
    """
    R_foot = _rot(1, yaw) @ _rot(0, pitch)
    toe_local = _rot(0, toe_bend)
    R_toe = R_foot @ toe_local
    toe_joint = tip - _apply(R_toe, _TOE)
    ankle = toe_joint - _apply(R_foot, _FOOT)
    return ankle, R_foot, toe_local


def _stepping_foot(side: int, theta: np.ndarray, offset: float, duty: np.ndarray, lift: np.ndarray,
                   heel_off: np.ndarray, activity: np.ndarray, freq: np.ndarray, velocity_x: np.ndarray,
                   t: np.ndarray, path: RootPath, style: StyleParams, leg: int,
                   rng: np.random.Generator) -> _Foot:
    """A foot that alternates stance (toe tip planted on y = 0) and swing.

    side: -1 right, +1 left (the x side of the body); leg: 0 right, 1 left (index into the style's
    (right, left) pairs). theta: (N,) stride phase; duty, lift, heel_off: (N,) per frame;
    activity: (N,) 1 while walking, 0 when standing still (fades out the sideways swing arc);
    freq: (N,) stride frequency, Hz; velocity_x: (N,) sideways velocity in the facing frame, m/s.
    """
    phi = theta + offset
    # Cycle k spans φ in [k − 0.25, k + 0.75) and has its mid-stance at φ = k + 0.25.
    k = np.floor(phi + 0.25).astype(np.int64)
    q = phi - k
    half = duty / 2
    before = q < 0.25 - half                         # swinging from stance k − 1 to stance k
    after = q > 0.25 + half                          # swinging from stance k to stance k + 1
    stance = ~(before | after)
    sigma = np.where(before, (q - (half - 0.75)) / (1 - duty), (q - 0.25 - half) / (1 - duty))
    sigma = np.where(stance, 0.0, np.clip(sigma, 0.0, 1.0))
    progress = np.clip((q - (0.25 - half)) / duty, 0.0, 1.0)    # through the stance

    # One target per stance: where the hip's path point is at mid-stance, turned by the toe-out.
    ks = np.arange(k.min() - 1, k.max() + 2)
    t_mid = np.interp(ks + 0.25 - offset, theta, t)
    yaw_k = np.interp(t_mid, t, path.yaw)
    px, pz = np.interp(t_mid, t, path.position[:, 0]), np.interp(t_mid, t, path.position[:, 2])
    # Moving sideways, a foot travels ±v·d/(2f) sideways under the body during its stance; widen
    # the stance by most of that so the feet come together at the closest but never cross.
    sideways = np.abs(np.interp(t_mid, t, velocity_x)) * np.interp(t_mid, t, duty / (2 * freq))
    lateral = side * (style.step_width + 0.8 * sideways) + 0.05 * style.noise * rng.standard_normal(ks.size)
    ahead = _TOE_AHEAD + 0.04 * style.noise * rng.standard_normal(ks.size)
    s, c = np.sin(yaw_k), np.cos(yaw_k)
    targets = np.stack([px + c * lateral + s * ahead, np.zeros_like(px), pz - s * lateral + c * ahead], 1)
    foot_yaw = yaw_k + side * style.toe_out + 0.1 * style.noise * rng.standard_normal(ks.size)

    a = (k - before) - ks[0]
    b = (k + after) - ks[0]
    w = _smoothstep(sigma)
    tip = targets[a] + (targets[b] - targets[a]) * w[:, None]
    arc = np.sin(np.pi * sigma)
    height = lift * style.swing_height_scale[leg]
    tip[:, 1] = height * arc
    out = side * style.circumduction[leg] * activity * arc      # swing the foot outwards (limp)
    tip[:, 0] += np.cos(path.yaw) * out
    tip[:, 2] -= np.sin(path.yaw) * out
    yaw = foot_yaw[a] + (foot_yaw[b] - foot_yaw[a]) * w

    beta_max = heel_off * style.heel_off_scale[leg]
    pitch = np.where(stance, beta_max * _smoothstep(progress, 0.5, 1.0),
                     beta_max * (1.0 - _smoothstep(sigma, 0.0, 0.6)))
    toe_bend = np.where(stance, -pitch, -beta_max * (1.0 - _smoothstep(sigma, 0.0, 0.35)))
    ankle, R_foot, toe_local = _foot_from_toe_tip(tip, yaw, pitch, toe_bend)

    travel = np.linalg.norm((targets[b] - targets[a])[:, [0, 2]], axis=1)
    # A "swing" (at least 3 frames long) that stays within 1 cm of the floor and moves the foot by
    # under 5 mm never exceeds the contact speed of 0.15 m/s: the foot never leaves the floor.
    shuffle = (height < 0.01) & (travel < 0.005)
    forward = np.stack([np.sin(yaw), np.zeros_like(yaw), np.cos(yaw)], axis=1)
    return _Foot(tip, ankle, R_foot, toe_local, forward, stance | shuffle, phi, duty < 0.9)


def _lifted_foot(side: int, psi: np.ndarray, hip: np.ndarray, R_hips: np.ndarray) -> _Foot:
    """A foot held up (the free foot when hopping): the ankle swings forward and back in the hips'
    frame, forward-most at ψ = 0.25, and stays far above the floor."""
    two_pi = 2 * np.pi * psi
    rel = np.stack([np.full_like(psi, side * 0.03), -0.50 + 0.03 * np.cos(two_pi),
                    -0.20 + 0.10 * np.sin(two_pi)], axis=1)
    ankle = hip + _apply(R_hips, rel)
    R_foot = R_hips @ _rot(0, np.full_like(psi, 0.6))
    toe_local = _rot(0, np.full_like(psi, -0.2))
    tip = ankle + _apply(R_foot, _FOOT) + _apply(R_foot @ toe_local, _TOE)
    forward = _normalize(R_hips[:, :, 2] * np.array([1.0, 0.0, 1.0]))
    n = psi.size
    return _Foot(tip, ankle, R_foot, toe_local, forward, np.zeros(n, bool), psi, np.ones(n, bool))


# ----------------------------------------------------------------------------------------------
# Two-bone IK
# ----------------------------------------------------------------------------------------------

def _bone_frame(bone: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(…, 3, 3) orthonormal frame with columns [normal, bone, normal × bone] (bone ⟂ normal)."""
    return np.stack([normal, bone, np.cross(normal, bone)], axis=-1)


# In the rest pose the leg hangs straight down and bends about −x (knee forward).
_REST_NORMAL = np.array([-1.0, 0.0, 0.0])
_REST_THIGH = _bone_frame(_THIGH / _L1, _REST_NORMAL)
_REST_SHIN = _bone_frame(_SHIN / _L2, _REST_NORMAL)


def _two_bone_ik(hip: np.ndarray, ankle: np.ndarray, pole: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """World rotations (N, 3, 3) of the thigh and shin that bring the ankle to ``ankle``.

    The knee lies in the plane of the hip, the ankle and the ``pole`` direction, on the pole's side
    (law of cosines). A target out of reach is approached along the hip-ankle line.
    """
    d_vec = ankle - hip
    d = np.clip(np.linalg.norm(d_vec, axis=1), abs(_L1 - _L2) + 1e-6, _L1 + _L2 - 1e-9)
    u = _normalize(d_vec)
    a = (_L1 ** 2 - _L2 ** 2 + d ** 2) / (2 * d)
    r = np.sqrt(np.maximum(_L1 ** 2 - a ** 2, 0.0))
    w = _normalize(pole - np.sum(pole * u, axis=1, keepdims=True) * u)
    knee = hip + a[:, None] * u + r[:, None] * w
    normal = _normalize(np.cross(u, w))
    thigh = _bone_frame(_normalize(knee - hip), normal) @ _REST_THIGH.T
    shin_dir = _normalize(hip + d[:, None] * u - knee)
    shin = _bone_frame(shin_dir, normal) @ _REST_SHIN.T
    return thigh, shin


# ----------------------------------------------------------------------------------------------
# The clip
# ----------------------------------------------------------------------------------------------

@dataclass
class SyntheticClip:
    """One generated clip and its ground truth.

    motion:        Motion on the 100STYLE skeleton (28 joints incl. End Sites), F frames.
    true_phase:    (F, 4) phases in [0, 1), [left hand, right hand, left foot, right foot].
    true_contacts: (F, 2) 0.0/1.0 foot contacts, [right, left].
    style, gait:   names, e.g. "Neutral", "FW".
    phase_active:  (F, 4) bool, where the limb oscillates so its phase is meaningful.
    frame_gaits:   (F,) gait code of each frame (differs from ``gait`` only in TR clips).
    """

    motion: Motion
    true_phase: np.ndarray
    true_contacts: np.ndarray
    style: str
    gait: str
    phase_active: np.ndarray
    frame_gaits: np.ndarray


def generate_style(style: str, gait: str, seconds: float, rng, fps: float = 60) -> SyntheticClip:
    """Generate ``seconds`` of locomotion of ``style`` (one of ``STYLES``) and ``gait`` (one of
    ``GAITS``: FW, BW, FR, SW, ID, TR) at ``fps`` frames per second.

    rng: an ``np.random.Generator`` (or a seed); the same rng state gives the same clip.
    """
    if style not in STYLE_PARAMS:
        raise ValueError(f"generate_style: unknown style {style!r}; expected one of {STYLES}")
    if gait not in GAITS:
        raise ValueError(f"generate_style: unknown gait {gait!r}; expected one of {GAITS}")
    if not (seconds > 0 and fps > 0):
        raise ValueError(f"generate_style: seconds and fps must be positive, got {seconds}, {fps}")
    rng = np.random.default_rng(rng)
    sp = STYLE_PARAMS[style]
    F = int(round(seconds * fps))
    pad = int(round(2.5 * fps))            # margin so every stance target has a time on the path
    n = F + 2 * pad
    t = np.arange(n) / fps

    timeline = gait_timeline(gait, n, fps, rng, sp)
    path = root_path(timeline, fps, rng, noise=sp.noise)
    theta = float(rng.uniform(0, 1)) + np.cumsum(timeline.stride_freq) / fps

    # Stepping activity: 0 when standing still (unless the style steps in place, e.g. hopping).
    active = np.ones(n) if sp.idle_steps else _smoothstep(timeline.speed, 0.02, 0.35)
    duty_base = DUTY_HOP if sp.lifted_foot else DUTY_WALK
    duty_gait = duty_base * (1 - timeline.run) + DUTY_RUN * timeline.run
    lift = timeline.swing_height * active
    if sp.idle_steps:
        lift = np.maximum(lift, 0.05)
    feet: List[Optional[_Foot]] = [None, None]                  # [right, left]
    for leg, side in ((0, -1), (1, +1)):
        if sp.lifted_foot == ("right", "left")[leg]:
            continue
        duty = np.clip(duty_gait + sp.duty_delta[leg], 0.2, 0.95)
        # Standing still: the stance fills (almost) the whole cycle. Keep every swing at least
        # 3 frames long, so a foot never jumps between two stance targets from one frame to the next.
        duty = np.minimum(1.0 - (1.0 - duty) * active, 1.0 - 3.0 * timeline.stride_freq / fps)
        feet[leg] = _stepping_foot(side, theta, sp.foot_phase_offset[leg], duty, lift,
                                   timeline.heel_off, active, timeline.stride_freq,
                                   timeline.velocity_local[:, 0], t, path, sp, leg, rng)

    # Hips: the path plus sway over the stance foot, pelvis rotations, then the height.
    phi_r = theta + sp.foot_phase_offset[0]
    sway = -sp.hips_sway * np.sin(2 * np.pi * phi_r) * active
    if sp.lifted_foot == "right":
        sway = np.full(n, 0.04)                                # over the left (hopping) foot
    sway = sway + 0.05 * sp.noise * smooth_noise(rng, n, fps, 0.8)
    pelvis_yaw = sp.pelvis_yaw * np.cos(2 * np.pi * phi_r) * active
    pelvis_pitch = sp.pelvis_pitch + 0.08 * timeline.run
    pelvis_roll = 0.07 * sp.noise * smooth_noise(rng, n, fps, 0.7)
    R_hips = _rot(1, path.yaw + pelvis_yaw) @ _rot(0, pelvis_pitch) @ _rot(2, pelvis_roll)
    hips = path.position + np.stack([np.cos(path.yaw) * sway, np.zeros(n), -np.sin(path.yaw) * sway], 1)

    if sp.lifted_foot:
        stance_phi = theta + sp.foot_phase_offset[1 if sp.lifted_foot == "right" else 0]
        bob = -0.035 * np.cos(2 * np.pi * (stance_phi - 0.25))
    else:
        walk_bob = 0.012 * np.cos(4 * np.pi * (phi_r - 0.25))   # highest at mid-stance
        run_bob = -0.03 * np.cos(4 * np.pi * (phi_r - 0.25))    # lowest at mid-stance
        bob = ((1 - timeline.run) * walk_bob + timeline.run * run_bob) * active
    # Knees slightly bent when standing, more when walking (the stance leg is never locked straight).
    desired = (STANDING_HIPS_HEIGHT - 0.005 - 0.02 * active - 0.04 * timeline.run + sp.hips_height
               + sp.hips_bob_scale * bob)
    hip_offsets = {0: _apply(R_hips, _OFFSETS[_J["RightHip"]]), 1: _apply(R_hips, _OFFSETS[_J["LeftHip"]])}
    bounds = [desired]
    for leg, foot in enumerate(feet):
        if foot is None:
            continue
        horizontal = foot.ankle[:, [0, 2]] - (hips[:, [0, 2]] + hip_offsets[leg][:, [0, 2]])
        reach = np.sqrt(np.maximum(_REACH ** 2 - np.sum(horizontal ** 2, axis=1), 1e-4))
        bounds.append(foot.ankle[:, 1] - hip_offsets[leg][:, 1] + reach)
    hips[:, 1] = _soft_min(bounds, 0.01)
    hip_joints = [hips + hip_offsets[0], hips + hip_offsets[1]]
    for leg in (0, 1):
        if feet[leg] is None:
            psi = theta + sp.foot_phase_offset[leg]
            feet[leg] = _lifted_foot((-1, 1)[leg], psi, hip_joints[leg], R_hips)

    # Local rotations, all joints: (N, 28, 3, 3), identity for End Sites.
    R = np.broadcast_to(np.eye(3), (n, len(JOINT_NAMES), 3, 3)).copy()
    R[:, 0] = R_hips
    for leg, prefix in ((0, "Right"), (1, "Left")):
        foot = feet[leg]
        thigh, shin = _two_bone_ik(hip_joints[leg], foot.ankle, foot.forward)
        R[:, _J[prefix + "Hip"]] = np.swapaxes(R_hips, 1, 2) @ thigh
        R[:, _J[prefix + "Knee"]] = np.swapaxes(thigh, 1, 2) @ shin
        R[:, _J[prefix + "Ankle"]] = np.swapaxes(shin, 1, 2) @ foot.rotation
        R[:, _J[prefix + "Toe"]] = foot.toe_local
    _upper_body(R, sp, timeline, theta, phi_r, pelvis_yaw, pelvis_pitch, active, fps, rng)
    arm_phase, arm_active = _arms(R, sp, timeline, theta, fps, rng)

    keep = slice(pad, pad + F)
    translations = np.broadcast_to(_OFFSETS, (F, len(JOINT_NAMES), 3)).copy()
    translations[:, 0] = hips[keep] - np.array([hips[pad, 0], 0.0, hips[pad, 2]])
    names, parents, offsets, channels = skeleton_100style()
    motion = Motion(names, parents, offsets, channels, R[keep], translations, 1.0 / fps,
                    source=f"synthetic:{style}_{gait}")
    phase = np.stack([arm_phase[0], arm_phase[1], feet[1].phase, feet[0].phase], axis=1)[keep]
    # A phase is only meaningful where the limb has been oscillating for a while around the frame
    # (the pipeline fits windows of about half a second): erode the masks by half a second.
    active = np.stack([arm_active[0], arm_active[1], feet[1].active, feet[0].active], axis=1)
    phase_active = minimum_filter1d(active.astype(np.uint8), int(fps) | 1, axis=0, mode="nearest")
    phase_active = phase_active[keep].astype(bool)
    contacts = np.stack([feet[0].contact, feet[1].contact], axis=1)[keep].astype(np.float64)
    return SyntheticClip(motion=motion, true_phase=np.mod(phase, 1.0), true_contacts=contacts,
                         style=style, gait=gait, phase_active=phase_active,
                         frame_gaits=timeline.gait[keep].astype(str))


def _upper_body(R: np.ndarray, sp: StyleParams, tl: GaitTimeline, theta: np.ndarray, phi_r: np.ndarray,
                pelvis_yaw: np.ndarray, pelvis_pitch: np.ndarray, active: np.ndarray, fps: float,
                rng: np.random.Generator) -> None:
    """Spine, neck and head local rotations (in place): lean, counter-rotation, sideways sway."""
    n = theta.size
    lean = sp.spine_lean + 0.1 * tl.run
    counter = -pelvis_yaw                                  # shoulders turn against the pelvis
    roll = sp.stance_lean * np.sin(2 * np.pi * phi_r) * active
    roll = roll + 0.12 * sp.noise * smooth_noise(rng, n, fps, 0.9)
    for name in ("Chest", "Chest2", "Chest3", "Chest4"):
        R[:, _J[name]] = _rot(1, counter / 4) @ _rot(0, np.full(n, lean / 4)) @ _rot(2, roll / 4)
    # Neck and head bring the gaze back towards level (partly) and add the style's head pitch.
    head_pitch = (sp.head_pitch - 0.6 * (lean + pelvis_pitch)) / 2
    head_roll = -0.5 * roll + 0.15 * sp.noise * smooth_noise(rng, n, fps, 0.6)
    for name in ("Neck", "Head"):
        R[:, _J[name]] = _rot(0, np.broadcast_to(head_pitch, (n,))) @ _rot(2, head_roll / 2)


def _arms(R: np.ndarray, sp: StyleParams, tl: GaitTimeline, theta: np.ndarray, fps: float,
          rng: np.random.Generator) -> Tuple[List[np.ndarray], List[np.ndarray]]:
    """Arm local rotations (in place) from one oscillator per arm; returns the arms' continuous
    phases [left, right] (forward-most swing at 0.25) and where they are active."""
    n = theta.size
    phases, actives = [], []
    for i, (prefix, side) in enumerate((("Left", 1), ("Right", -1))):
        psi = sp.arm_freq_ratio * theta + sp.arm_phase[i]
        if sp.noise:
            psi = psi + 0.06 * sp.noise * smooth_noise(rng, n, fps, 0.5)
        wave = np.sin(2 * np.pi * psi)
        amp = np.minimum(sp.arm_swing_amp * tl.arm_scale, 85 * np.pi / 180)
        amp = amp * (1.0 + 0.3 * sp.noise * smooth_noise(rng, n, fps, 1.0))
        swing = sp.arm_swing_center + amp * wave
        flex = (sp.elbow_flex + sp.run_elbow_scale * tl.elbow_extra
                + sp.elbow_flex_amp * tl.arm_scale * (1 + wave) / 2)   # most flexed when forward
        # Right arm rests along −x, left along +x: Rz(±down) brings it down (up when down < 0),
        # then Rx(∓swing) turns it about the shoulders' axis so that the *hand* moves forwards.
        forwards = 1.0 if np.sin(sp.arm_down) >= 0 else -1.0
        R[:, _J[prefix + "Collar"]] = _rot(2, np.full(n, side * sp.collar_raise))
        R[:, _J[prefix + "Shoulder"]] = _rot(0, -forwards * swing) @ _rot(2, np.full(n, -side * sp.arm_down))
        R[:, _J[prefix + "Elbow"]] = _rot(1, -side * flex)
        phases.append(psi)
        actives.append(amp >= 7 * np.pi / 180)
    return phases, actives


# ----------------------------------------------------------------------------------------------
# Data sets
# ----------------------------------------------------------------------------------------------

def default_dataset(seed: int = 0, seconds: float = 6.0, styles: Optional[Iterable[str]] = None,
                    gaits: Optional[Iterable[str]] = None, fps: float = 60) -> List[SyntheticClip]:
    """Every style × gait (default: all ``STYLES`` × ``DEFAULT_GAITS``), ``seconds`` each.

    Each clip draws from its own generator seeded by (seed, style index, gait index), so a clip
    does not change when the lists of styles or gaits are shortened.
    """
    styles = list(STYLES if styles is None else styles)
    gaits = list(DEFAULT_GAITS if gaits is None else gaits)
    clips = []
    for style in styles:
        for gait in gaits:
            key = [int(seed), STYLES.index(style) if style in STYLES else -1,
                   GAITS.index(gait) if gait in GAITS else -1]
            clips.append(generate_style(style, gait, seconds, np.random.default_rng(key), fps))
    return clips


def write_dataset(directory: Union[str, Path], clips: Optional[Sequence[SyntheticClip]] = None,
                  truth: bool = True, **dataset_options) -> List[Path]:
    """Write clips (default: ``default_dataset(**dataset_options)``) as ``<Style>_<Gait>.bvh``.

    With ``truth``, also ``<Style>_<Gait>.truth.npz`` holding true_phase, true_contacts,
    phase_active (plain arrays, loadable with allow_pickle=False). Returns the BVH paths.
    """
    from .bvh import write_bvh

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    if clips is None:
        clips = default_dataset(**dataset_options)
    paths = []
    for clip in clips:
        path = directory / f"{clip.style}_{clip.gait}.bvh"
        write_bvh(clip.motion, path)
        if truth:
            np.savez(directory / f"{clip.style}_{clip.gait}.truth.npz", true_phase=clip.true_phase,
                     true_contacts=clip.true_contacts, phase_active=clip.phase_active)
        paths.append(path)
    return paths
