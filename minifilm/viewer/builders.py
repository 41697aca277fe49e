"""Tracks from the rest of minifilm: a runtime rollout, or a BVH file with its foot contacts.

``tracks.py`` knows only joint positions and a hierarchy; these builders add what the viewer can
show beyond them: the names of generated characters, and foot contacts (highlighted toes) from
the network's predicted contacts or, for a humanoid BVH file, from its toe tips (Sec. 4.1.2).
"""
from __future__ import annotations

import os
from typing import List, Optional, Sequence, Tuple, Union

from minifilm.body.read import read_in_metres
from minifilm.body.units import BodyUnit
from minifilm.phases.contacts import humanoid_contacts
from minifilm.runtime.rollout import Rollout
from minifilm.viewer.tracks import Track, track_from_motion

__all__ = ["tracks_from_rollout", "track_with_contacts", "track_and_unit"]


def tracks_from_rollout(rollout: Rollout, parents: Sequence[int], names: Optional[Sequence[str]] = None,
                        joint_names: Optional[Sequence[str]] = None,
                        toes: Optional[Sequence[int]] = None, start: int = 0) -> List[Track]:
    """One Track per character of ``rollout`` (output positions, after any skeleton fit).

    parents (J,): the layout's parents (``layout.parents``); names: one label per character;
    toes: the joint indices of the predicted contact columns [right, left] (their marks light up
    while the network predicts contact); joint_names: for labels; start: the first frame shown
    (e.g. after the first second, which starts from the data's mean pose).
    """
    B, F = rollout.positions.shape[:2]
    if not 0 <= start < F:
        raise ValueError(f"tracks_from_rollout: start frame {start} is not in [0, {F})")
    k = slice(start, None)
    names = list(names) if names is not None else [f"character {b}" for b in range(B)]
    if len(names) != B:
        raise ValueError(f"tracks_from_rollout: {len(names)} names for {B} characters")
    out = []
    for b in range(B):
        root = rollout.root_positions[b, k]                                # (F, 2) on the floor
        trail = root[:, [0, 0, 1]] * [1.0, 0.0, 1.0]
        out.append(Track(name=names[b], positions=rollout.positions[b, k], parents=parents, fps=rollout.fps,
                         contacts=None if toes is None else rollout.contacts[b, k].clip(0.0, 1.0),
                         contact_joints=None if toes is None else list(toes), trail=trail, root=0,
                         joint_names=None if joint_names is None else list(joint_names)))
    return out


def track_with_contacts(path: Union[str, os.PathLike], name: Optional[str] = None) -> Track:
    """A BVH file as a Track at its true size, with its foot contacts marked.

    The unit comes from the skeleton or the body's height, and the feet from the joint names or
    the hierarchy, found once by its reader (minifilm/body/read.py); a skeleton that is not a humanoid
    is drawn in centimetres without contacts."""
    return track_and_unit(path, name)[0]


def track_and_unit(path: Union[str, os.PathLike], name: Optional[str] = None) -> Tuple[Track, BodyUnit]:
    """``track_with_contacts(path, name)`` and the unit it was read in (``BodyUnit.how`` says why)."""
    motion, humanoid, unit = read_in_metres(path)
    if humanoid is None or motion.n_frames < 2:
        return track_from_motion(motion, name=name, humanoid=humanoid), unit
    contacts, sensors = humanoid_contacts(motion, humanoid)
    return track_from_motion(motion, name=name, contacts=contacts, contact_joints=list(sensors),
                             humanoid=humanoid), unit
