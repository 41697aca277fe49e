"""The body of the synthetic generator: the 100STYLE skeleton, feet, two-bone leg IK, spine and arms.

``generator.py`` decides *when* things happen (gait timeline, root path, stride phase); this module
turns those per-frame drivers into joint rotations. Everything is vectorised over frames (N).
Conventions as in the 100STYLE data: metres, radians, y up, the hips' local +z is the character's
front, right-side joints have negative x.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Sequence, Tuple

import numpy as np

from minifilm.synthetic.styles import StyleParams
from minifilm.synthetic.trajectories import GaitTimeline, RootPath, smooth_noise

__all__ = ["JOINT_NAMES", "JOINT_INDEX", "OFFSETS", "skeleton_100style", "STANDING_HIPS_HEIGHT", "REACH",
           "rot", "apply", "smoothstep", "soft_min", "Foot", "stepping_foot", "lifted_foot", "two_bone_ik",
           "upper_body", "arms"]

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
OFFSETS = np.array([o for _, _, o in _SKELETON_CM], dtype=np.float64) * 0.01
_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Yrotation", "Xrotation", "Zrotation")
_JOINT_CHANNELS = ("Yrotation", "Xrotation", "Zrotation")
JOINT_INDEX = {name: i for i, name in enumerate(JOINT_NAMES)}


def skeleton_100style() -> Tuple[List[str], np.ndarray, np.ndarray, List[Tuple[str, ...]]]:
    """(names (28,), parents (28,), offsets (28, 3) metres, channels (28,)) of the 100STYLE skeleton."""
    channels = [() if n.endswith("Site") else (_ROOT_CHANNELS if p < 0 else _JOINT_CHANNELS)
                for n, p, _ in _SKELETON_CM]
    return list(JOINT_NAMES), _PARENTS.copy(), OFFSETS.copy(), channels


# Leg geometry. The standing hips height puts the toe tip on the floor with every joint at rest.
_THIGH, _SHIN = OFFSETS[JOINT_INDEX["RightKnee"]], OFFSETS[JOINT_INDEX["RightAnkle"]]
_FOOT, _TOE = OFFSETS[JOINT_INDEX["RightToe"]], OFFSETS[JOINT_INDEX["RightToeSite"]]
_L1, _L2 = float(np.linalg.norm(_THIGH)), float(np.linalg.norm(_SHIN))
REACH = 0.997 * (_L1 + _L2)        # keep the knee a little bent even at full stretch
STANDING_HIPS_HEIGHT = -float((OFFSETS[JOINT_INDEX["RightHip"]] + _THIGH + _SHIN + _FOOT + _TOE)[1])
#: Forward distance from the path point under the hip to the planted toe tip at mid-stance, m:
#: the ankle then sits about 4 cm behind the hip (the toe tip is 24 cm ahead of the ankle).
_TOE_AHEAD = 0.20


# ----------------------------------------------------------------------------------------------
# Small vectorised helpers
# ----------------------------------------------------------------------------------------------

def rot(axis: int, angle) -> np.ndarray:
    """(N,) angles -> (N, 3, 3) right-handed rotations about x (0), y (1) or z (2)."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i], R[..., j, j] = c, c
    R[..., i, j], R[..., j, i] = -s, s
    return R


def apply(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 3, 3) @ (N, 3) or (3,) -> (N, 3)."""
    return np.einsum("nij,...j->ni", R, v) if v.ndim == 1 else np.einsum("nij,nj->ni", R, v)


def smoothstep(x, lo: float = 0.0, hi: float = 1.0) -> np.ndarray:
    """0 below ``lo``, 1 above ``hi``, 3u² − 2u³ between (zero slope at both ends)."""
    u = np.clip((np.asarray(x, dtype=np.float64) - lo) / (hi - lo), 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _normalize(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def soft_min(values: Sequence[np.ndarray], k: float) -> np.ndarray:
    """Smooth minimum −k log Σ exp(−v/k): never above the true minimum, at most k·log(n) below."""
    v = np.stack(values)
    m = v.min(axis=0)
    return m - k * np.log(np.exp(-(v - m) / k).sum(axis=0))


# ----------------------------------------------------------------------------------------------
# Feet
# ----------------------------------------------------------------------------------------------

@dataclass
class Foot:
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
    R_foot = rot(1, yaw) @ rot(0, pitch)
    toe_local = rot(0, toe_bend)
    R_toe = R_foot @ toe_local
    toe_joint = tip - apply(R_toe, _TOE)
    ankle = toe_joint - apply(R_foot, _FOOT)
    return ankle, R_foot, toe_local


def stepping_foot(side: int, theta: np.ndarray, offset: float, duty: np.ndarray, lift: np.ndarray,
                   heel_off: np.ndarray, activity: np.ndarray, freq: np.ndarray, velocity_x: np.ndarray,
                   t: np.ndarray, path: RootPath, style: StyleParams, leg: int,
                   rng: np.random.Generator) -> Foot:
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
    w = smoothstep(sigma)
    tip = targets[a] + (targets[b] - targets[a]) * w[:, None]
    arc = np.sin(np.pi * sigma)
    height = lift * style.swing_height_scale[leg]
    tip[:, 1] = height * arc
    out = side * style.circumduction[leg] * activity * arc      # swing the foot outwards (limp)
    tip[:, 0] += np.cos(path.yaw) * out
    tip[:, 2] -= np.sin(path.yaw) * out
    yaw = foot_yaw[a] + (foot_yaw[b] - foot_yaw[a]) * w

    beta_max = heel_off * style.heel_off_scale[leg]
    pitch = np.where(stance, beta_max * smoothstep(progress, 0.5, 1.0),
                     beta_max * (1.0 - smoothstep(sigma, 0.0, 0.6)))
    toe_bend = np.where(stance, -pitch, -beta_max * (1.0 - smoothstep(sigma, 0.0, 0.35)))
    ankle, R_foot, toe_local = _foot_from_toe_tip(tip, yaw, pitch, toe_bend)

    travel = np.linalg.norm((targets[b] - targets[a])[:, [0, 2]], axis=1)
    # A "swing" (at least 3 frames long) that stays within 1 cm of the floor and moves the foot by
    # under 5 mm never exceeds the contact speed of 0.15 m/s: the foot never leaves the floor.
    shuffle = (height < 0.01) & (travel < 0.005)
    forward = np.stack([np.sin(yaw), np.zeros_like(yaw), np.cos(yaw)], axis=1)
    return Foot(tip, ankle, R_foot, toe_local, forward, stance | shuffle, phi, duty < 0.9)


def lifted_foot(side: int, psi: np.ndarray, hip: np.ndarray, R_hips: np.ndarray) -> Foot:
    """A foot held up (the free foot when hopping): the ankle swings forward and back in the hips'
    frame, forward-most at ψ = 0.25, and stays far above the floor."""
    two_pi = 2 * np.pi * psi
    rel = np.stack([np.full_like(psi, side * 0.03), -0.50 + 0.03 * np.cos(two_pi),
                    -0.20 + 0.10 * np.sin(two_pi)], axis=1)
    ankle = hip + apply(R_hips, rel)
    R_foot = R_hips @ rot(0, np.full_like(psi, 0.6))
    toe_local = rot(0, np.full_like(psi, -0.2))
    tip = ankle + apply(R_foot, _FOOT) + apply(R_foot @ toe_local, _TOE)
    forward = _normalize(R_hips[:, :, 2] * np.array([1.0, 0.0, 1.0]))
    n = psi.size
    return Foot(tip, ankle, R_foot, toe_local, forward, np.zeros(n, bool), psi, np.ones(n, bool))


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


def two_bone_ik(hip: np.ndarray, ankle: np.ndarray, pole: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
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
# Spine and arms
# ----------------------------------------------------------------------------------------------

def upper_body(R: np.ndarray, sp: StyleParams, tl: GaitTimeline, theta: np.ndarray, phi_r: np.ndarray,
                pelvis_yaw: np.ndarray, pelvis_pitch: np.ndarray, active: np.ndarray, fps: float,
                rng: np.random.Generator) -> None:
    """Spine, neck and head local rotations (in place): lean, counter-rotation, sideways sway."""
    n = theta.size
    lean = sp.spine_lean + 0.1 * tl.run
    counter = -pelvis_yaw                                  # shoulders turn against the pelvis
    roll = sp.stance_lean * np.sin(2 * np.pi * phi_r) * active
    roll = roll + 0.12 * sp.noise * smooth_noise(rng, n, fps, 0.9)
    for name in ("Chest", "Chest2", "Chest3", "Chest4"):
        R[:, JOINT_INDEX[name]] = rot(1, counter / 4) @ rot(0, np.full(n, lean / 4)) @ rot(2, roll / 4)
    # Neck and head bring the gaze back towards level (partly) and add the style's head pitch.
    head_pitch = (sp.head_pitch - 0.6 * (lean + pelvis_pitch)) / 2
    head_roll = -0.5 * roll + 0.15 * sp.noise * smooth_noise(rng, n, fps, 0.6)
    for name in ("Neck", "Head"):
        R[:, JOINT_INDEX[name]] = rot(0, np.broadcast_to(head_pitch, (n,))) @ rot(2, head_roll / 2)


def arms(R: np.ndarray, sp: StyleParams, tl: GaitTimeline, theta: np.ndarray, fps: float,
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
        R[:, JOINT_INDEX[prefix + "Collar"]] = rot(2, np.full(n, side * sp.collar_raise))
        down = rot(2, np.full(n, -side * sp.arm_down))
        R[:, JOINT_INDEX[prefix + "Shoulder"]] = rot(0, -forwards * swing) @ down
        R[:, JOINT_INDEX[prefix + "Elbow"]] = rot(1, -side * flex)
        phases.append(psi)
        actives.append(amp >= 7 * np.pi / 180)
    return phases, actives
