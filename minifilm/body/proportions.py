"""A rig's proportions that retargeting needs: how its foot lies flat, and how long its legs are.

The foot's shape on the floor differs between rigs (100STYLE's ankle -> toe bone points 27 degrees
down when the foot is flat, CMU's 10, Bandai's 40) and is read from the rest pose when that is a
standing pose, else measured on the motion's contact frames (:func:`foot_shape_of`). The legs'
length, as the hips' height standing straight, scales the root's path (:func:`leg_length`).
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from minifilm.body.rig import builtin_skeleton_of
from minifilm.body.roles import SIDES, RigError, Roles, sensor_positions
from minifilm.motion.motion import Motion
from minifilm.phases.contacts import foot_contacts
from minifilm.body.builtin_rigs import BANDAI_FOOT_SHAPE
from minifilm.body.pose import canonical_pose, foot_and_toe_directions, pitch_below_horizontal, rest_positions

__all__ = ["foot_shape_of", "foot_pitch_of", "leg_length", "rest_foot_pitch", "motion_foot_pitch", "rest_toe_bend",
           "motion_toe_bend", "DEFAULT_FOOT_PITCH"]


def rest_foot_pitch(motion: Motion, roles: Roles) -> Optional[float]:
    """The angle (radians) by which the feet point down at rest, when the zero pose is a standing
    pose (both legs within 30 degrees of straight down from the hips, taking the hips -> chest
    direction as up); None when it is not (the Bandai rig's zero pose has its legs along x)."""
    P0 = rest_positions(motion)
    idx = {n: i for i, n in enumerate(motion.names)}
    up = P0[idx[roles.chest]] - P0[idx[roles.hips]]
    up = up / max(np.linalg.norm(up), 1e-12)
    pitches = []
    for side in SIDES:
        limb = roles.limb(side)
        leg = P0[idx[limb.ankle]] - P0[idx[limb.upleg]]
        if np.dot(leg, -up) < np.cos(np.radians(30.0)) * np.linalg.norm(leg):
            return None
        end = limb.toe or limb.toe_end
        if end is None:
            return 0.0
        foot = P0[idx[end]] - P0[idx[limb.ankle]]
        if np.linalg.norm(foot) < 1e-9:
            return 0.0
        pitches.append(np.arcsin(np.clip(-np.dot(foot, up) / np.linalg.norm(foot), -1.0, 1.0)))
    return float(np.mean(pitches))


def motion_foot_pitch(motion: Motion, roles: Roles, contacts: np.ndarray) -> Optional[float]:
    """The feet's pitch (radians) when flat on the floor, from a motion: the 10th percentile, over
    the frames a foot is in contact ((F, 2) contacts, [right, left]), of the angle by which the
    ankle -> toe bone points below the horizontal (a toe in contact with its heel raised points
    further down, so a low percentile). None without contacts or a foot bone."""
    P, _ = motion.world()
    out = []
    for k, side in enumerate(("right", "left")):
        limb = roles.limb(side)
        end = limb.toe or limb.toe_end
        on = contacts[:, k] > 0.5
        if end is None or not np.any(on):
            continue
        d = P[on, motion.names.index(end)] - P[on, motion.names.index(limb.ankle)]
        out.append(np.arctan2(-d[:, 1], np.hypot(d[:, 0], d[:, 2])))
    return float(np.percentile(np.concatenate(out), 10)) if out else None


#: the flat-foot pitch assumed for a rig whose zero pose is not a standing pose and whose motion
#: shows no contacts (between CMU's 10 and Bandai's 40 degrees)
DEFAULT_FOOT_PITCH = float(np.radians(25.0))


def foot_pitch_of(motion: Motion, roles: Roles) -> float:
    """The flat-foot pitch of a rig (radians): :func:`foot_shape_of`'s first value."""
    return foot_shape_of(motion, roles)[0]


def foot_shape_of(motion: Motion, roles: Roles) -> Tuple[float, float]:
    """(pitch, toe bend) of a rig's foot flat on the floor, radians: from its rest pose when that is
    a standing pose; the measured constant of the built-in Bandai rig (builtin_rigs.BANDAI_FOOT_SHAPE) on its
    files; else measured on the motion's flattest contact frames
    (:func:`motion_foot_pitch`, :func:`motion_toe_bend`); else DEFAULT_FOOT_PITCH and no bend."""
    pitch = rest_foot_pitch(motion, roles)
    if pitch is not None:
        return pitch, rest_toe_bend(motion, roles)
    skeleton = builtin_skeleton_of(motion)
    if skeleton is not None and skeleton.name == "bandai":     # the same value for every Bandai clip
        return BANDAI_FOOT_SHAPE
    if motion.n_frames > 1:
        P, _ = motion.world()
        contacts = foot_contacts(sensor_positions(P, motion, roles), motion.fps)
        pitch = motion_foot_pitch(motion, roles, contacts)
        if pitch is not None:
            return pitch, motion_toe_bend(motion, roles, contacts, pitch)
    return DEFAULT_FOOT_PITCH, 0.0


def motion_toe_bend(motion: Motion, roles: Roles, contacts: np.ndarray, flat_pitch: float) -> float:
    """How much less the toe points down than the foot (radians) on the contact frames whose foot
    pitch is within 3 degrees of the flat-foot pitch; 0 without such frames or a toe joint."""
    bends = []
    for k, side in enumerate(("right", "left")):
        limb = roles.limb(side)
        if limb.toe is None:
            continue
        fs, ts = foot_and_toe_directions(motion, limb)
        keep = (contacts[:, k] > 0.5) & (np.abs(pitch_below_horizontal(fs) - flat_pitch) < np.radians(3.0))
        bends.append(pitch_below_horizontal(fs[keep]) - pitch_below_horizontal(ts[keep]))
    bends = np.concatenate(bends) if bends else np.zeros(0)
    return float(np.median(bends)) if len(bends) else 0.0


def rest_toe_bend(motion: Motion, roles: Roles) -> float:
    """How much (radians) the toe bone points less far down than the foot bone at rest (100STYLE:
    its toe tip is pitched 15 degrees, its foot 27: 0.21); 0 for a rig without a toe bone. Taken
    from the zero pose when it is a standing pose, else the unsigned angle between the two bones."""
    P0 = rest_positions(motion)
    idx = {n: i for i, n in enumerate(motion.names)}
    bends = []
    for side in SIDES:
        limb = roles.limb(side)
        if not (limb.toe and limb.toe_end):
            return 0.0
        foot = P0[idx[limb.toe]] - P0[idx[limb.ankle]]
        toe = P0[idx[limb.toe_end]] - P0[idx[limb.toe]]
        if np.linalg.norm(toe) < 1e-9 or np.linalg.norm(foot) < 1e-9:
            return 0.0
        if rest_foot_pitch(motion, roles) is not None:
            bends.append(pitch_below_horizontal(foot) - pitch_below_horizontal(toe))
        else:
            bends.append(np.arccos(np.clip(foot @ toe / np.linalg.norm(foot) / np.linalg.norm(toe), -1, 1)))
    return float(np.mean(bends))


def leg_length(motion: Motion, roles: Roles, foot_pitch: Optional[float] = None) -> float:
    """The legs' length as the hips' height above the floor standing straight (metres): the rig in
    its canonical pose (legs straight down, feet flat at ``foot_pitch``, default the rig's own),
    from the hips down to the lowest point of either foot. Thigh + shin alone would leave out the
    pelvis and the ankle's height, which differ between rigs (the Bandai ankle stands 7 cm above
    the floor, 100STYLE's 11 cm) and would put one character's feet through the floor."""
    pitch = foot_shape_of(motion, roles)[0] if foot_pitch is None else foot_pitch
    C = canonical_pose(motion, roles, pitch)
    P = np.zeros((motion.n_joints, 3))
    for j in range(motion.n_joints):
        p = int(motion.parents[j])
        if p >= 0:
            P[j] = P[p] + C[p] @ motion.offsets[j]
    idx = {n: i for i, n in enumerate(motion.names)}
    feet = [idx[n] for side in SIDES for n in roles.limb(side).leg()]
    length = float(P[idx[roles.hips], 1] - P[feet, 1].min())
    if not length > 1e-6:
        raise RigError(f"{motion.source}: its legs have no length at rest")
    return length
