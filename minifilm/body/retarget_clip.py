"""Retarget a clip from one humanoid rig onto another (docs/retargeting.md).

    from minifilm.body import load_rig, read_source, retarget_motion
    from minifilm.motion.bvh_write import write_bvh

    target = load_rig("100style")
    motion, roles = read_source("walk_bandai.bvh")     # minifilm/body/read.py: read once, roles found once
    write_bvh(retarget_motion(motion, target, roles), "walk_100style.bvh", scale=target.bvh_scale)

The steps, on the roles of both rigs as given (minifilm/body/roles.py): the pose transfer on world bone
directions from canonical rest poses (:mod:`~minifilm.body.pose`), the root's path
scaled by the ratio of leg lengths, then the floor and the planted feet
(:mod:`~minifilm.body.feet`) and the toes kept out of the floor in swing
(:mod:`~minifilm.body.clearance`). The result is a Motion on the target's hierarchy with its
channels (so ``write_bvh`` writes it in the target's channel order; pass the rig's ``bvh_scale``
for its units), at the source's frame rate.
"""
from __future__ import annotations

import os
from typing import Optional, Union

import numpy as np

from minifilm.body.read import read_source
from minifilm.motion.bvh_write import write_bvh
from minifilm.body.roles import RigError, Roles, sensor_positions
from minifilm.body.proportions import foot_shape_of, leg_length
from minifilm.motion.motion import Motion
from minifilm.motion.retarget import world_to_local
from minifilm.body.clearance import FLOOR_SLACK, clear_floor_keeping_contacts
from minifilm.body.feet import floor_height, plant_feet
from minifilm.body.pose import canonical_pose, match_chords, place_feet, rest_positions, transfer_rotations
from minifilm.body.target import Rig
from minifilm.phases.contacts import DEFAULT_FILTER_SECONDS, foot_contacts

__all__ = ["retarget_motion", "retarget_file"]


def retarget_motion(source: Motion, target: Rig, source_roles: Roles, plant: bool = True,
                    blend_seconds: float = 0.1, contact_filter_seconds: float = DEFAULT_FILTER_SECONDS) -> Motion:
    """``source`` (metres) on the ``target`` rig (see the module doc).

    Args:
        source:        a Motion of any humanoid rig, metres.
        target:        the rig to put it on (:func:`minifilm.body.target.load_rig`).
        source_roles:  the source's roles, found once by its reader (``read_source``).
        plant:         pin the feet during the source's contacts (off: only the floor is fixed).
        blend_seconds: how long a pin fades in and out.
    Returns:
        a Motion on the target's hierarchy, channels and frame rate of the source, with the floor at y = 0.
    """
    s_roles = source_roles.check(source)
    t_roles = target.roles.check(target.template)
    tm = target.template
    F, J = source.n_frames, tm.n_joints
    if F < 1:
        raise RigError(f"{source.source}: no frames to retarget")
    Ps, Rs = source.world()
    t_shape = target.foot_shape if target.foot_shape is not None else foot_shape_of(tm, t_roles)
    s_shape = foot_shape_of(source, s_roles)
    world = transfer_rotations(Rs, source, s_roles, canonical_pose(source, s_roles, s_shape[0]),
                               tm, t_roles, canonical_pose(tm, t_roles, t_shape[0]))
    world = place_feet(world, tm, t_roles, t_shape, source, s_roles, s_shape)
    # the spine's and the neck's chords point as the source's (chains of other lengths bend otherwise)
    si, ti = source.names.index, tm.names.index
    world = match_chords(world, tm, [[ti(n) for n in (t_roles.hips,) + t_roles.spine],
                                     [ti(n) for n in (t_roles.chest,) + t_roles.neck]],
                         [Ps[:, si(s_roles.chest)] - Ps[:, si(s_roles.hips)],
                          Ps[:, si(s_roles.head)] - Ps[:, si(s_roles.chest)]])
    # the root's path: the source's hips above its floor, scaled by the ratio of leg lengths
    scale = leg_length(tm, t_roles, t_shape[0]) / leg_length(source, s_roles, s_shape[0])
    s_floor = floor_height(sensor_positions(Ps, source, s_roles), source.fps)
    s_hips = source.names.index(s_roles.hips)
    hips_path = (Ps[:, s_hips] - np.array([0.0, s_floor, 0.0])) * scale
    P = _positions(tm, world, tm.names.index(t_roles.hips), hips_path)
    # the floor: the target's toe tips rest on y = 0 where the source's rest on its floor
    contacts = foot_contacts(sensor_positions(Ps, source, s_roles), source.fps, floor_height=s_floor,
                             filter_seconds=contact_filter_seconds)
    P[..., 1] -= _floor_offset(sensor_positions(P, tm, t_roles), contacts, source.fps)
    if plant:
        legs = [[tm.names.index(n) for n in (limb.upleg, limb.knee, limb.ankle, limb.sensor)]
                for limb in (t_roles.right, t_roles.left)]
        hips = tm.names.index(t_roles.hips)
        body = [hips] + [j for j in range(J) if hips in _ancestor_list(tm, j)]
        # unscaled: near a contact the tip moves at the source tip's own speed, so that a touch-down
        # just under the contact speed threshold stays under it on a longer-legged target
        guides = sensor_positions(Ps, source, s_roles) - np.array([0.0, s_floor, 0.0])
        P, world = plant_feet(P, world, tm.parents, legs, contacts, guides, source.fps, body, blend_seconds)
        # the toes out of the floor in swing, where this foot reaches further than the source's
        # (clearance.py): no lower than the source's tip, nor than 0.7 cm under the floor
        if _foot_reach(tm, t_roles, t_shape[0]) > _foot_reach(source, s_roles, s_shape[0]):
            feet = [[tm.names.index(limb.ankle), tm.names.index(limb.toe) if limb.toe else None,
                     tm.names.index(limb.sensor)] for limb in (t_roles.right, t_roles.left)]
            bound = np.minimum(guides[..., 1], 0.0) - FLOOR_SLACK
            # the contact test estimates its floor, as minifilm phases and the benchmark do
            def test(Q):
                return foot_contacts(sensor_positions(Q, tm, t_roles), source.fps,
                                     filter_seconds=contact_filter_seconds)
            P, world = clear_floor_keeping_contacts(P, world, tm.parents, feet, bound, source.fps, contacts, test)
    return _to_motion(tm, world, P, tm.names.index(t_roles.hips), source.frame_time,
                      f"{source.source} on {target.name}")


def _foot_reach(motion: Motion, roles: Roles, foot_pitch: float) -> float:
    """How far the toe tip reaches from the ankle at rest, in leg lengths (the mean of both feet)."""
    P0 = rest_positions(motion)
    i = motion.names.index
    reach = [np.linalg.norm(P0[i(l.sensor)] - P0[i(l.ankle)]) for l in (roles.left, roles.right)]
    return float(np.mean(reach)) / leg_length(motion, roles, foot_pitch)


def _ancestor_list(motion: Motion, j: int) -> list:
    out, a = [], int(motion.parents[j])
    while a >= 0:
        out.append(a)
        a = int(motion.parents[a])
    return out


def _floor_offset(sensors: np.ndarray, contacts: np.ndarray, fps: float) -> float:
    """The height to take off the target so its toe tips are on y = 0 on average while the source's
    feet are in contact ((F, 2, 3) sensors, (F, 2) contacts); without contacts, the lower toe tip's
    5th percentile height (a foot touches the floor at least now and then)."""
    on = contacts > 0.5
    if np.any(on):
        return float(np.median(sensors[..., 1][on]))
    return float(np.percentile(sensors[..., 1].min(axis=1), 5))


def _positions(tm: Motion, world: np.ndarray, hips: int, hips_path: np.ndarray) -> np.ndarray:
    """(F, J, 3) world positions: the hips on their path, the rest by the target's offsets; joints
    above the hips (a floor marker) at rest."""
    F, J = world.shape[:2]
    P = np.empty((F, J, 3))
    rest = rest_positions(tm)
    above = set()
    a = int(tm.parents[hips])
    while a >= 0:
        above.add(a)
        a = int(tm.parents[a])
    for j in range(J):
        p = int(tm.parents[j])
        if j in above:
            P[:, j] = rest[j]
        elif j == hips:
            P[:, j] = hips_path
        else:
            P[:, j] = P[:, p] + (world[:, p] @ tm.offsets[j][:, None])[..., 0]
    return P


def _to_motion(tm: Motion, world: np.ndarray, P: np.ndarray, hips: int, frame_time: float, source: str) -> Motion:
    """Local rotations and translations from world ones: every joint at its rest offset except the
    hips, whose translation puts them at P[:, hips]."""
    F, J = world.shape[:2]
    local = world_to_local(world, tm.parents)
    translations = np.broadcast_to(tm.offsets, (F, J, 3)).copy()
    p = int(tm.parents[hips])
    if p >= 0:
        translations[:, hips] = (np.swapaxes(world[:, p], -1, -2) @ (P[:, hips] - P[:, p])[..., None])[..., 0]
    else:
        translations[:, hips] = P[:, hips]
    has_position = any(c.endswith("position") for c in tm.channels[hips])
    if not has_position:
        raise RigError(f"{tm.source}: the hips ({tm.names[hips]}) have no position channels, so the "
                       "body could not move")
    return Motion(list(tm.names), tm.parents.copy(), tm.offsets.copy(), list(tm.channels), local, translations,
                  frame_time, source)


def retarget_file(path: Union[str, os.PathLike], target: Rig, out: Union[str, os.PathLike], map_path=None,
                  scale: Optional[float] = None, plant: bool = True) -> Motion:
    """Read a BVH of any humanoid rig, retarget it onto ``target`` and write it to ``out`` (atomically,
    in the target's units). Returns the retargeted Motion (metres)."""
    motion, roles = read_source(path, map_path, scale)
    result = retarget_motion(motion, target, roles, plant=plant)
    write_bvh(result, out, scale=target.bvh_scale)
    return result
