"""The column layout of the input frame x, the output frame z, the phases p and the style clip y.

This is THE one place that says what every number means (paper Sec. 3.2; docs/original-code.md
§5-§7 and §9). The network's bone-length loss, the runtime, the dataset builder and the docs all
read column indices from a :class:`FeatureLayout`; nobody else hard-codes an offset.

For J exported joints (J = 25 for 100STYLE):

x (48 + 12 J = 348)
    0 .. 47        12 trajectory samples, point-major, each ``[pos_x, pos_z, dir_x, dir_z]`` of the
                   root at that sample time, relative to the CURRENT root.  Sample times
                   ``TRAJECTORY_SECONDS``: -1 s .. -1/6 s every 1/6 s, 0, +0.2 s .. +1.0 s every
                   0.2 s.  Sample 6 is the current root itself, always ``[0, 0, 0, 1]``.
    48 .. 48+12J   per exported joint, interleaved ``[p(3), fwd(3), up(3), v(3)]`` relative to the
                   current root: position (m), forward axis = 3rd column of the world rotation,
                   up axis = 2nd column, backward-difference world velocity (m/s).
p (8)
    ``[s0, c0, s1, c1, s2, c2, s3, c3]`` = amplitude * (sin 2 pi phi, cos 2 pi phi) for the phase
    slots [left hand, right hand, left foot, right foot] (Eq. 1) of the current frame; the gating
    network's input, kept outside x.
z (24 + 12 J + 8 + 8 + 2 = 342)
    0 .. 23        trajectory samples 6..11 of the NEXT frame, relative to the CURRENT root; the
                   first four numbers are the root delta (where the next root is, which way it faces).
    24 .. 24+12J   joints of the next frame, same interleave as x, relative to the CURRENT root.
    then 8         phases of the next frame (same order as p).
    then 8         phase updates, next minus current (vector difference).
    then 2         foot contacts of the next frame, ``[right, left]``, 0/1.
clip y (T, 12 J)
    per frame the joint block of x, each frame relative to its OWN root (no trajectory, no phases).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, NamedTuple, Tuple

import numpy as np

#: Trajectory sample times in seconds relative to the current frame (docs/original-code.md §5).
#: The past is spaced 1/6 s, the future 0.2 s: deliberately not uniform.
#: PAPER: "every 10 frames for 1 second in the future and past" (Sec. 3.2), i.e. 1/6 s at 60 fps on
#: both sides; the original code spaces the future 12 frames apart, and the released network was
#: trained so.
TRAJECTORY_SECONDS: Tuple[float, ...] = (-1.0, -5 / 6, -4 / 6, -3 / 6, -2 / 6, -1 / 6,
                                         0.0, 0.2, 0.4, 0.6, 0.8, 1.0)
#: Index of the current frame among the trajectory samples.
CURRENT_SAMPLE = 6
#: The four numbers stored per trajectory sample.
TRAJECTORY_FIELDS = ("position x", "position z", "direction x", "direction z")
#: The four 3-vectors stored per joint, in order; each takes 3 columns.
JOINT_FIELDS = ("position", "forward", "up", "velocity")
#: Phase slot order of p (docs/original-code.md §3.1).
PHASE_SLOTS = ("left hand", "right hand", "left foot", "right foot")
#: Order of the two contact numbers at the end of z.
CONTACT_ORDER = ("right foot", "left foot")

_JOINT_FIELD_TEXT = {
    "position": ("position", "m"),
    "forward": ("forward axis (3rd column of the world rotation)", "unit vector"),
    "up": ("up axis (2nd column of the world rotation)", "unit vector"),
    "velocity": ("velocity (backward difference of world positions)", "m/s"),
}


class Column(NamedTuple):
    """One row of :meth:`FeatureLayout.describe`."""
    index: int
    joint: str
    quantity: str
    frame: str
    units: str


@dataclass(frozen=True)
class FeatureLayout:
    """Column layout of x, z, p and the clip for a skeleton with ``n_joints`` exported joints.

    Args:
        n_joints:    J, the number of exported joints.
        parents:     (J,) parent export index of each joint, -1 for the root (used by the
                     bone-length loss together with :meth:`joint_columns`).
        joint_names: (J,) names, for :meth:`describe` and error messages.
        trajectory_seconds: the 12 sample times (seconds), default ``TRAJECTORY_SECONDS``.
    """

    n_joints: int
    parents: Tuple[int, ...]
    joint_names: Tuple[str, ...]
    trajectory_seconds: Tuple[float, ...] = field(default=TRAJECTORY_SECONDS)

    def __post_init__(self) -> None:
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))
        object.__setattr__(self, "joint_names", tuple(str(n) for n in self.joint_names))
        object.__setattr__(self, "trajectory_seconds", tuple(float(t) for t in self.trajectory_seconds))
        J = int(self.n_joints)
        if J < 1:
            raise ValueError(f"FeatureLayout: n_joints must be >= 1, got {J}")
        if len(self.parents) != J or len(self.joint_names) != J:
            raise ValueError(f"FeatureLayout: {J} joints but {len(self.parents)} parents and "
                             f"{len(self.joint_names)} names")
        for j, p in enumerate(self.parents):
            if not (-1 <= p < j):
                raise ValueError(f"FeatureLayout: joint {j} ({self.joint_names[j]}) has parent {p}; "
                                 f"parents must come before their children")
        ts = self.trajectory_seconds
        if len(ts) != 12 or ts[CURRENT_SAMPLE] != 0.0 or not all(a < b for a, b in zip(ts, ts[1:])):
            raise ValueError(f"FeatureLayout: trajectory_seconds must be 12 increasing times with "
                             f"sample {CURRENT_SAMPLE} at 0, got {ts}")

    # ----------------------------------------------------------------- construction
    @classmethod
    def for_skeleton(cls, skeleton) -> "FeatureLayout":
        """The layout for a :class:`minifilm.motion.skeletons.Skeleton` (its exported joints)."""
        return cls(len(skeleton.joints), tuple(skeleton.parents), tuple(skeleton.joints))

    @classmethod
    def generic(cls, n_joints: int) -> "FeatureLayout":
        """A layout for J joints named ``joint0 ..`` in a chain: for code that needs only the
        column positions (they depend on J alone)."""
        return cls(n_joints, (-1,) + tuple(range(n_joints - 1)), tuple(f"joint{j}" for j in range(n_joints)))

    def to_dict(self) -> dict:
        """JSON-ready description, saved next to a model so the runtime rebuilds the same layout."""
        return {"n_joints": self.n_joints, "parents": list(self.parents),
                "joint_names": list(self.joint_names),
                "trajectory_seconds": list(self.trajectory_seconds)}

    @classmethod
    def from_dict(cls, d: dict) -> "FeatureLayout":
        return cls(int(d["n_joints"]), tuple(d["parents"]), tuple(d["joint_names"]),
                   tuple(d.get("trajectory_seconds", TRAJECTORY_SECONDS)))

    # ----------------------------------------------------------------- sizes
    n_trajectory_samples = len(TRAJECTORY_SECONDS)          # 12
    n_future_samples = len(TRAJECTORY_SECONDS) - CURRENT_SAMPLE  # 6: samples 6..11 go into z
    phase_dim = 8
    contact_dim = 2

    @property
    def joint_dim(self) -> int:
        """12 J: the joint block of x, z and every clip frame."""
        return 12 * self.n_joints

    @property
    def x_dim(self) -> int:
        return 4 * self.n_trajectory_samples + self.joint_dim

    @property
    def z_dim(self) -> int:
        return 4 * self.n_future_samples + self.joint_dim + 2 * self.phase_dim + self.contact_dim

    @property
    def clip_dim(self) -> int:
        return self.joint_dim

    # ----------------------------------------------------------------- slices of x
    @property
    def x_trajectory(self) -> slice:
        return slice(0, 4 * self.n_trajectory_samples)

    @property
    def x_joints(self) -> slice:
        a = 4 * self.n_trajectory_samples
        return slice(a, a + self.joint_dim)

    # ----------------------------------------------------------------- slices of z
    @property
    def z_trajectory(self) -> slice:
        return slice(0, 4 * self.n_future_samples)

    @property
    def z_root_delta(self) -> slice:
        """``[pos_x, pos_z, dir_x, dir_z]`` of the next root in the current root's frame."""
        return slice(0, 4)

    @property
    def z_joints(self) -> slice:
        a = 4 * self.n_future_samples
        return slice(a, a + self.joint_dim)

    @property
    def z_phases(self) -> slice:
        a = self.z_joints.stop
        return slice(a, a + self.phase_dim)

    @property
    def z_phase_updates(self) -> slice:
        a = self.z_phases.stop
        return slice(a, a + self.phase_dim)

    @property
    def z_contacts(self) -> slice:
        a = self.z_phase_updates.stop
        return slice(a, a + self.contact_dim)

    # ----------------------------------------------------------------- joint columns
    def joint_columns(self, which: str, field: str) -> np.ndarray:
        """(J, 3) int column indices of one per-joint 3-vector.

        Args:
            which: 'x', 'z' or 'clip'.
            field: 'position', 'forward', 'up' or 'velocity'.
        Example: the bone-length loss reads ``z[:, layout.joint_columns('z', 'position')]``.
        """
        base = {"x": self.x_joints.start, "z": self.z_joints.start, "clip": 0}
        if which not in base:
            raise ValueError(f"joint_columns: which must be 'x', 'z' or 'clip', got {which!r}")
        if field not in JOINT_FIELDS:
            raise ValueError(f"joint_columns: field must be one of {JOINT_FIELDS}, got {field!r}")
        j = np.arange(self.n_joints)[:, None]
        return base[which] + 12 * j + 3 * JOINT_FIELDS.index(field) + np.arange(3)[None, :]

    def trajectory_columns(self, which: str, sample: int) -> np.ndarray:
        """(4,) columns ``[pos_x, pos_z, dir_x, dir_z]`` of trajectory sample ``sample`` (0..11).

        In z only samples 6..11 exist (of the next frame).
        """
        if which == "x":
            first = 0
        elif which == "z":
            first = CURRENT_SAMPLE
        else:
            raise ValueError(f"trajectory_columns: which must be 'x' or 'z', got {which!r}")
        if not (first <= sample < self.n_trajectory_samples):
            raise ValueError(f"trajectory_columns: {which} has samples {first}..11, got {sample}")
        return 4 * (sample - first) + np.arange(4)

    # ----------------------------------------------------------------- description
    def describe(self, which: str) -> List[Column]:
        """Every column of 'x', 'z', 'p' or 'clip' as ``(index, joint, quantity, frame, units)``."""
        if which == "x":
            cols = self._trajectory_columns(range(self.n_trajectory_samples), "current frame",
                                            "root of the current frame")
            cols += self._joint_block("current frame", "root of the current frame")
        elif which == "z":
            cols = self._trajectory_columns(range(CURRENT_SAMPLE, self.n_trajectory_samples),
                                            "next frame", "root of the current frame")
            cols += self._joint_block("next frame", "root of the current frame")
            cols += self._phase_block("phase vector of the next frame", "none (amplitude-scaled)")
            cols += self._phase_block("phase update (next minus current)", "per frame")
            cols += [("root", f"{side} contact of the next frame", "none", "0/1")
                     for side in CONTACT_ORDER]
        elif which == "p":
            cols = self._phase_block("phase vector of the current frame", "none (amplitude-scaled)")
        elif which == "clip":
            cols = self._joint_block("clip frame t", "root of clip frame t (each frame its own)")
        else:
            raise ValueError(f"describe: which must be 'x', 'z', 'p' or 'clip', got {which!r}")
        return [Column(i, *c) for i, c in enumerate(cols)]

    def _trajectory_columns(self, samples, whose: str, frame: str) -> list:
        out = []
        for s in samples:
            t = self.trajectory_seconds[s]
            for f in TRAJECTORY_FIELDS:
                units = "m" if f.startswith("position") else "unit vector"
                out.append(("root", f"trajectory sample {s} ({t:+.3f} s from the {whose}) {f}",
                            frame, units))
        return out

    def _joint_block(self, whose: str, frame: str) -> list:
        out = []
        for name in self.joint_names:
            for f in JOINT_FIELDS:
                text, units = _JOINT_FIELD_TEXT[f]
                for axis in "xyz":
                    out.append((name, f"{text} {axis}, {whose}", frame, units))
        return out

    def _phase_block(self, what: str, units: str) -> list:
        out = []
        for slot in PHASE_SLOTS:
            out.append((slot, f"{what}: amplitude * sin(2 pi phase)", "none", units))
            out.append((slot, f"{what}: amplitude * cos(2 pi phase)", "none", units))
        return out

