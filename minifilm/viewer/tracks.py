"""What the viewer draws: ``Track``, one character's joint positions over time, and its builders.

A ``Track`` is deliberately plain (world positions + a drawing hierarchy + a frame rate), so that
anything that can produce joint positions can be shown: a ``Motion``, a BVH file, or a network's
output. Every renderer (GIF, MP4, HTML) takes a list of tracks.

Axes are those of the BVH forward kinematics: metres, y up.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import List, Optional, Sequence, Union

import numpy as np

from minifilm.body.read import read_in_metres
from minifilm.motion.bvh import read_bvh
from minifilm.motion.motion import Motion
from minifilm.viewer.body import body_plan

__all__ = ["Track", "track_from_motion", "track_from_bvh", "as_tracks"]

JointRef = Union[int, str]


@dataclass
class Track:
    """One character to draw.

    Attributes:
        name:           shown above the character.
        positions:      (F, J, 3) world joint positions, metres, y up, F >= 1.
        parents:        (J,) int: a bone is drawn from joint j to ``parents[j]``; -1 draws no bone.
                        ``parents[j] < j`` (parents come first, as in a BVH file).
        fps:            frames per second of ``positions``.
        contacts:       optional (F, C) contact values in [0, 1]; a joint counts as in contact at 0.5
                        and above.
        contact_joints: (C,) indices of the joints ``contacts`` refers to (required with contacts).
        trail:          optional (F, 3) path drawn on the floor; default: ``root`` projected to y = 0.
        root:           joint the camera follows and the trail defaults to; default: the first joint
                        that moves (Bandai files have a ``joint_Root`` fixed at the origin and the
                        walking ``Hips`` below it), joint 0 for a motionless track.
        joint_names:    optional (J,) names, for labels and error messages.
        body:           optional body plan for the shaded body (minifilm/viewer/body.py: which bone
                        is torso, neck, head, arm or leg); default: found from the positions when
                        the page is made.

    Arrays are converted to float64 / int64 copies and checked; a problem raises one ``ValueError``
    naming the track, the field and, for bad values, the frame and joint.
    """

    name: str
    positions: np.ndarray
    parents: np.ndarray
    fps: float
    contacts: Optional[np.ndarray] = None
    contact_joints: Optional[np.ndarray] = None
    trail: Optional[np.ndarray] = None
    root: Optional[int] = None
    joint_names: Optional[List[str]] = None
    body: Optional[dict] = None

    def __post_init__(self) -> None:
        self.name = str(self.name)
        self.positions = np.array(self.positions, dtype=np.float64)
        self.parents = np.array(self.parents, dtype=np.int64).reshape(-1)
        P = self.positions
        if P.ndim != 3 or P.shape[2] != 3:
            self._fail(f"positions has shape {P.shape}, expected (frames, joints, 3)")
        F, J = P.shape[:2]
        if F == 0:
            self._fail("positions has no frames (an empty motion cannot be shown)")
        if J == 0:
            self._fail("positions has no joints")
        self._check_finite("positions", P)
        if self.parents.shape != (J,):
            self._fail(f"parents has shape {self.parents.shape}, expected ({J},) for {J} joints")
        bad = np.nonzero((self.parents < -1) | (self.parents >= np.arange(J)))[0]
        if len(bad):
            j = int(bad[0])
            self._fail(f"parents[{j}] = {self.parents[j]} ({self._joint(j)}): must be -1 or a joint before it")
        if not (np.isfinite(self.fps) and self.fps > 0):
            self._fail(f"fps must be positive, got {self.fps}")
        self.fps = float(self.fps)
        if self.joint_names is not None:
            self.joint_names = [str(n) for n in self.joint_names]
            if len(self.joint_names) != J:
                self._fail(f"{len(self.joint_names)} joint_names for {J} joints")
        self._check_contacts(F, J)
        if self.root is None:
            self.root = _first_moving_joint(P)
        if not 0 <= int(self.root) < J:
            self._fail(f"root = {self.root} is not a joint index in [0, {J})")
        self.root = int(self.root)
        if self.trail is None:
            self.trail = P[:, self.root] * np.array([1.0, 0.0, 1.0])
        self.trail = np.array(self.trail, dtype=np.float64)
        if self.trail.shape != (F, 3):
            self._fail(f"trail has shape {self.trail.shape}, expected ({F}, 3)")
        self._check_finite("trail", self.trail[:, None])

    # -- derived quantities ---------------------------------------------------------------------

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_joints(self) -> int:
        return int(self.positions.shape[1])

    @property
    def duration(self) -> float:
        """Seconds shown: frames / fps (each frame lasts 1 / fps)."""
        return self.n_frames / self.fps

    @property
    def bones(self) -> np.ndarray:
        """(B, 2) int pairs (joint, parent) of the bones to draw."""
        j = np.nonzero(self.parents >= 0)[0]
        return np.stack([j, self.parents[j]], axis=1)

    def body_size(self) -> float:
        """A length that scales the view, metres: the largest extent of the pose about its root.

        The 95th percentile over frames of the largest per-axis extent, so a stray frame does not
        zoom the camera out; at least 1 mm so a degenerate (single-point) track still gets a view.
        """
        extent = self.positions.max(axis=1) - self.positions.min(axis=1)  # (F, 3)
        return float(max(np.percentile(extent.max(axis=1), 95), 1e-3))

    def in_contact(self) -> np.ndarray:
        """(F, C) bool: contact value >= 0.5; (F, 0) without contacts."""
        if self.contacts is None:
            return np.zeros((self.n_frames, 0), dtype=bool)
        return self.contacts >= 0.5

    # -- checks ----------------------------------------------------------------------------------

    def _fail(self, message: str) -> None:
        raise ValueError(f"Track {self.name!r}: {message}")

    def _joint(self, j: int) -> str:
        return self.joint_names[j] if self.joint_names is not None and j < len(self.joint_names) else f"joint {j}"

    def _check_finite(self, what: str, values: np.ndarray) -> None:
        """``values``: (F, J, ...) array; names the first non-finite frame and joint."""
        bad = ~np.isfinite(values).reshape(values.shape[0], values.shape[1], -1).all(axis=2)
        if bad.any():
            f, j = (int(i[0]) for i in np.nonzero(bad))
            where = self._joint(j) if what == "positions" else "root trail"
            self._fail(f"{what} are not finite (NaN or inf) at frame {f}, {where}")

    def _check_contacts(self, F: int, J: int) -> None:
        if self.contacts is None:
            if self.contact_joints is not None and len(self.contact_joints):
                self._fail("contact_joints given without contacts")
            self.contact_joints = np.zeros(0, dtype=np.int64)
            return
        self.contacts = np.array(self.contacts, dtype=np.float64)
        if self.contact_joints is None:
            self._fail("contacts given without contact_joints (the joints they refer to)")
        self.contact_joints = np.array(self.contact_joints, dtype=np.int64).reshape(-1)
        C = len(self.contact_joints)
        if self.contacts.shape != (F, C):
            self._fail(f"contacts has shape {self.contacts.shape}, expected ({F}, {C}) "
                       f"for {F} frames and {C} contact joints")
        bad = np.nonzero((self.contact_joints < 0) | (self.contact_joints >= J))[0]
        if len(bad):
            self._fail(f"contact_joints[{bad[0]}] = {self.contact_joints[bad[0]]} is not a joint index in [0, {J})")
        outside = ~((self.contacts >= 0) & (self.contacts <= 1))  # also catches NaN
        if outside.any():
            f, c = (int(i[0]) for i in np.nonzero(outside))
            self._fail(f"contacts must lie in [0, 1]; frame {f}, contact {c} "
                       f"({self._joint(int(self.contact_joints[c]))}) is {self.contacts[f, c]}")


def _first_moving_joint(positions: np.ndarray) -> int:
    """Index of the first joint whose position changes over the clip (0 if none does)."""
    moving = np.nonzero(np.ptp(positions, axis=0).max(axis=1) > 1e-9)[0]
    return int(moving[0]) if len(moving) else 0


# ----------------------------------------------------------------------------------------------
# Builders
# ----------------------------------------------------------------------------------------------

def track_from_motion(motion: Motion, name: Optional[str] = None,
                      joints: Optional[Sequence[JointRef]] = None,
                      contacts: Optional[np.ndarray] = None,
                      contact_joints: Optional[Sequence[JointRef]] = None,
                      trail: Optional[np.ndarray] = None, humanoid=None) -> Track:
    """A ``Track`` of ``motion`` drawn with the file's own hierarchy.

    Args:
        motion:         the motion; its forward kinematics gives the positions.
        name:           label; default: the file name without extension (``motion.source``).
        joints:         joints to draw (names or indices). Default: all joints except those that
                        sit on their parent in every frame: zero-length End Sites (Bandai, Xia) and
                        zero-offset helper joints (Xia's ``LHipJoint``) would only draw
                        zero-length bones. End Sites with a length are kept because they are the
                        ends of the last bones: without them the head and the toes vanish.
        contacts:       optional (F, C) contact values in [0, 1] (e.g. from the contacts module).
        contact_joints: (C,) joints (names or indices of ``motion``) that ``contacts`` refers to. A
                        dropped zero-length joint maps to the joint it coincides with.
        trail:          optional (F, 3) floor path; default: the followed root on the floor.
        humanoid:       its humanoid parts as its reader found them (minifilm/body/read.py), for the
                        shaded body; None: found for the page (:func:`minifilm.viewer.body.body_plan`).

    A link from a hierarchy root to a child with a changing local translation is that child's
    translation, not a bone (Bandai's ``joint_Root`` on the floor, static or moving, above the
    walking ``Hips``): it is not drawn, and a joint left with no bone at all is dropped, so no
    line stretches from the floor to the character.
    """
    source = getattr(motion, "source", "<memory>")
    if name is None:
        name = Path(source).stem if source and not source.startswith("<") else "motion"
    if motion.n_frames == 0:
        raise ValueError(f"{source}: the motion has no frames (an empty motion cannot be shown)")
    P, _ = motion.world()  # (F, J, 3)
    P = np.asarray(P, dtype=np.float64)
    parents = np.asarray(motion.parents, dtype=np.int64)
    names = list(motion.names)
    if joints is None:
        keep, merged_into = _drop_coincident(P, parents)
    else:
        keep = sorted({_index(motion, j, "joints") for j in joints})
        merged_into = {}
    link_parent = _kept_parents(parents, keep)
    kept_parent = _cut_root_translations(motion, keep, link_parent)
    if joints is None:
        keep, kept_parent = _drop_isolated(keep, kept_parent)
    position_in_track = {j: i for i, j in enumerate(keep)}
    track_parents = [position_in_track[p] if p >= 0 else -1 for p in kept_parent]

    c_idx = None
    if contact_joints is not None:
        c_idx = []
        for ref in contact_joints:
            j = _index(motion, ref, "contact_joints")
            j = merged_into.get(j, j)
            if j not in position_in_track:
                raise ValueError(f"{source}: contact joint {names[j]!r} is not among the drawn joints")
            c_idx.append(position_in_track[j])
    return Track(name=name, positions=P[:, keep], parents=np.array(track_parents, dtype=np.int64),
                 fps=motion.fps, contacts=contacts, contact_joints=c_idx, trail=trail,
                 joint_names=[names[j] for j in keep], body=body_plan(motion, keep, humanoid))


def track_from_bvh(path: Union[str, os.PathLike], name: Optional[str] = None, scale: Optional[float] = None,
                   **kwargs) -> Track:
    """Read a BVH file in metres and build its ``Track``.

    ``scale``: metres per file unit; default: the skeleton's or the body's own
    (minifilm/body/units.py: a humanoid is drawn at its true size; other rigs in centimetres).

    ``kwargs`` go to ``track_from_motion`` (``joints``, ``contacts``, ``contact_joints``, ``trail``).
    Raises OSError when the file cannot be read and ``BVHError`` (a ValueError naming the file and
    line) when it is not a valid BVH file.
    """
    if scale is not None:
        return track_from_motion(read_bvh(path, scale=scale), name=name, **kwargs)
    motion, humanoid, _ = read_in_metres(path)
    return track_from_motion(motion, name=name, humanoid=humanoid, **kwargs)


def as_tracks(items) -> List[Track]:
    """A list of tracks from a ``Track``, ``Motion`` or BVH path, or a sequence of them."""
    if isinstance(items, (Track, Motion, str, os.PathLike)):
        items = [items]
    out = []
    for item in items:
        if isinstance(item, Track):
            out.append(item)
        elif isinstance(item, Motion):
            out.append(track_from_motion(item))
        elif isinstance(item, (str, os.PathLike)):
            out.append(track_from_bvh(item))
        elif hasattr(item, "root_positions") and hasattr(item, "positions"):  # a runtime Rollout
            raise TypeError("cannot draw a Rollout directly: it carries no skeleton; "
                            "minifilm.viewer.tracks_from_rollout(rollout, parents, names) makes its tracks")
        else:
            raise TypeError(f"cannot draw a {type(item).__name__}: give Track, Motion or BVH paths")
    if not out:
        raise ValueError("nothing to draw: no tracks given")
    return out


def _index(motion: Motion, ref: JointRef, what: str) -> int:
    if isinstance(ref, (int, np.integer)):
        if not 0 <= int(ref) < motion.n_joints:
            raise ValueError(f"{motion.source}: {what} index {ref} is not in [0, {motion.n_joints})")
        return int(ref)
    if str(ref) not in motion.names:
        raise ValueError(f"{motion.source}: {what} names {ref!r}, which is not a joint; "
                         f"joints are {list(motion.names)}")
    return motion.names.index(str(ref))


def _link_lengths(P: np.ndarray, j: int, p: int) -> np.ndarray:
    return np.linalg.norm(P[:, j] - P[:, p], axis=1)  # (F,)


def _drop_coincident(P: np.ndarray, parents: np.ndarray):
    """Joints to keep (ascending) and {dropped joint: the kept joint it sits on}."""
    scale = max(float(np.ptp(P[0], axis=0).max()), 1e-6)
    keep, merged_into = [], {}
    for j, p in enumerate(parents):
        if p >= 0 and _link_lengths(P, j, p).max() <= 1e-6 * scale:
            merged_into[j] = merged_into.get(int(p), int(p))
        else:
            keep.append(j)
    return keep, merged_into


def _kept_parents(parents: np.ndarray, keep: List[int]) -> List[int]:
    """For each kept joint, its nearest kept ancestor (-1 if none)."""
    kept = set(keep)
    out = []
    for j in keep:
        p = int(parents[j])
        while p >= 0 and p not in kept:
            p = int(parents[p])
        out.append(p)
    return out


def _cut_root_translations(motion: Motion, keep: List[int], link_parent: List[int]) -> List[int]:
    """``link_parent`` with the links that are translations, not bones, set to -1.

    A link from a hierarchy root (a joint without parent) to a child whose local translation
    changes over the clip is the child's translation: Bandai's ``joint_Root`` (static at the
    origin, or moving on the floor) above the walking ``Hips``. Links anywhere else are always
    drawn, even if their length changes, so a non-rigid generated skeleton shows as one.
    ``keep`` and ``link_parent`` are aligned lists of kept joints and their kept parents.
    """
    T = np.asarray(motion.translations, dtype=np.float64)  # (F, J, 3) local translations
    parents = motion.parents
    scale = max(float(np.ptp(T[0], axis=0).max()), 1e-6)
    out = []
    for j, p in zip(keep, link_parent):
        if p >= 0 and parents[p] < 0:
            chain, k = [], j  # j and its dropped ancestors below p
            while k != p:
                chain.append(k)
                k = int(parents[k])
            if np.ptp(T[:, chain], axis=0).max() > 1e-6 * scale:
                p = -1
        out.append(p)
    return out


def _drop_isolated(keep: List[int], kept_parent: List[int]):
    """Drop joints with no bone (no parent and no child), unless that would leave nothing."""
    has_child = {p for p in kept_parent if p >= 0}
    pairs = [(j, p) for j, p in zip(keep, kept_parent) if p >= 0 or j in has_child]
    if not pairs:
        return keep, kept_parent
    return [j for j, _ in pairs], [p for _, p in pairs]
