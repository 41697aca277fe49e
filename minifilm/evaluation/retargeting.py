"""How faithful a retargeted clip is to its source (the retargeting checks; benchmarks/retarget.py prints them).

* :func:`bone_direction_errors`: the angle between each mapped bone's world direction in source
  and target, per frame. Mapped bones run between role joints both rigs have (thigh, shin, foot,
  upper arm, forearm, ...), plus the spine (hips -> chest) and neck (chest -> head) as chords;
  a bone of zero length in either rig is left out.
* :func:`contact_agreement`: the fraction of frames (both feet pooled) on which the foot contacts
  of source and target (:func:`minifilm.phases.contacts.foot_contacts`, each on its own floor)
  agree.
* :func:`skating`: the mean horizontal speed (m/s) of the toe-tip sensors over the frames they
  are in contact: how much a planted foot slides.
* :func:`standing_height`: the median over frames of the highest joint above the floor.
* :func:`round_trip_errors`: per mapped joint, the distance between a clip and the same clip
  taken to another rig and back (both on their floor), metres.
"""
from __future__ import annotations

from typing import Dict, List, Tuple

import numpy as np

from minifilm.body.roles import SIDES, Roles, sensor_positions
from minifilm.motion.motion import Motion
from minifilm.body.feet import floor_height
from minifilm.body.pose import rest_positions
from minifilm.phases.contacts import foot_contacts

__all__ = ["mapped_bones", "mapped_joints", "bone_direction_errors", "contact_agreement", "skating",
           "standing_height", "round_trip_errors"]


def mapped_joints(a: Roles, b: Roles) -> List[Tuple[str, str, str]]:
    """(label, joint in a, joint in b) for every role both rigs have a joint for."""
    out = [("hips", a.hips, b.hips), ("chest", a.chest, b.chest), ("head", a.head, b.head)]
    for side in SIDES:
        la, lb = a.limb(side), b.limb(side)
        for part in ("collar", "shoulder", "elbow", "wrist", "upleg", "knee", "ankle", "toe"):
            ja, jb = getattr(la, part), getattr(lb, part)
            if ja and jb:
                out.append((f"{side} {part}", ja, jb))
    return out


def mapped_bones(a: Roles, b: Roles) -> List[Tuple[str, Tuple[str, str], Tuple[str, str]]]:
    """(label, (from, to) in a, (from, to) in b) of the bones between consecutive mapped joints."""
    out = [("spine", (a.hips, a.chest), (b.hips, b.chest)), ("neck", (a.chest, a.head), (b.chest, b.head))]
    for side in SIDES:
        la, lb = a.limb(side), b.limb(side)
        chain = [p for p in ("collar", "shoulder", "elbow", "wrist") if getattr(la, p) and getattr(lb, p)]
        chain += [p for p in ("upleg", "knee", "ankle", "toe") if getattr(la, p) and getattr(lb, p)]
        for p, q in zip(chain[:-1], chain[1:]):
            if (p, q) == ("wrist", "upleg"):
                continue
            out.append((f"{side} {p}-{q}", (getattr(la, p), getattr(la, q)), (getattr(lb, p), getattr(lb, q))))
    return out


def bone_direction_errors(source: Motion, source_roles: Roles, target: Motion, target_roles: Roles
                          ) -> Dict[str, np.ndarray]:
    """label -> (F,) angle in degrees between the bone's world direction in source and target."""
    Ps, _ = source.world()
    Pt, _ = target.world()
    rs, rt = rest_positions(source), rest_positions(target)
    si = {n: i for i, n in enumerate(source.names)}
    ti = {n: i for i, n in enumerate(target.names)}
    out = {}
    for label, (sa, sb), (ta, tb) in mapped_bones(source_roles, target_roles):
        if np.linalg.norm(rs[si[sb]] - rs[si[sa]]) < 1e-6 or np.linalg.norm(rt[ti[tb]] - rt[ti[ta]]) < 1e-6:
            continue
        u = Ps[:, si[sb]] - Ps[:, si[sa]]
        v = Pt[:, ti[tb]] - Pt[:, ti[ta]]
        cos = np.sum(u * v, -1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1) + 1e-12)
        out[label] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def _contacts(motion: Motion, roles: Roles) -> np.ndarray:
    P, _ = motion.world()
    return foot_contacts(sensor_positions(P, motion, roles), motion.fps)


def contact_agreement(source: Motion, source_roles: Roles, target: Motion, target_roles: Roles) -> float:
    """Fraction of (frame, foot) pairs where source and target contacts agree."""
    return float(np.mean(_contacts(source, source_roles) == _contacts(target, target_roles)))


def skating(motion: Motion, roles: Roles) -> float:
    """Mean horizontal toe-tip speed (m/s) over the frames each foot is in contact; 0 without contacts."""
    P, _ = motion.world()
    s = sensor_positions(P, motion, roles)
    v = np.zeros(s.shape[:2])
    if len(s) >= 2:
        v[1:] = np.linalg.norm((s[1:] - s[:-1])[..., [0, 2]], axis=-1) * motion.fps
        v[0] = v[1]
    c = _contacts(motion, roles) > 0.5
    return float(v[c].mean()) if np.any(c) else 0.0


def standing_height(motion: Motion, roles: Roles) -> float:
    """Median over frames of the highest joint's height above the floor (metres)."""
    P, _ = motion.world()
    floor = floor_height(sensor_positions(P, motion, roles), motion.fps)
    return float(np.median(P[..., 1].max(axis=1) - floor))


def round_trip_errors(original: Motion, original_roles: Roles, back: Motion, back_roles: Roles
                      ) -> Dict[str, np.ndarray]:
    """label -> (F,) distance (metres) of each mapped joint between a clip and its round trip,
    both with their floor at y = 0."""
    Po, _ = original.world()
    Pb, _ = back.world()
    Po = Po - np.array([0.0, floor_height(sensor_positions(Po, original, original_roles), original.fps), 0.0])
    Pb = Pb - np.array([0.0, floor_height(sensor_positions(Pb, back, back_roles), back.fps), 0.0])
    oi = {n: i for i, n in enumerate(original.names)}
    bi = {n: i for i, n in enumerate(back.names)}
    return {label: np.linalg.norm(Po[:, oi[a]] - Pb[:, bi[b]], axis=-1)
            for label, a, b in mapped_joints(original_roles, back_roles)}
