"""Standing still when nothing is asked: what the runtime adds to the paper's loop at zero command.

Measured on the released network (Neutral, ``benchmarks/standing.py``): with a zero command after
walking, the character kept going at 0.37 m/s, stepping, for as long as it ran. Three things keep
it going, each found by switching it off:

1. **The trajectory blend** (Sec. 4.4, ``blend_future_trajectory``) keeps 85 % of the network's
   own predicted step for the nearest future sample and 68 % for the next: at a zero command the
   future the network is shown still moves, so it keeps moving. With the near samples pinned to
   the root, the stepping stopped but the root still slid at 0.2 m/s.
2. **The past trajectory** is the root's own history: once it slides, the past says "moving",
   which the network continues. Nothing in the loop ever damps this.
3. **The phases** (``p <- 0.5 p_pred + 0.5 (p + dp_pred)``, docs/original-code.md §10.2 step 7)
   keep their amplitude: the gating network keeps blending the experts of a gait cycle. In the
   data a standing body has amplitude near zero (its contacts do not oscillate). The released
   network was never trained on the idle clips (the authors' exporter skipped them), only on the
   stops inside the transition clips, so it does not find its own way there.

So while the commanded velocity is zero, :class:`StandStill`:

- pins every future sample to the root (the stop the user asked for, at once);
- fades the network's remaining root displacement out over ``settle`` seconds (smoothstep), moving
  the predicted body with it, so the root history becomes still and the network sees a still past
  (turning on the spot needs no travel either);
- and, while the target facing is not being turned either (turning on the spot is stepping, not
  standing), decays the phase amplitudes with time constant ``phase_tau`` seconds, towards the
  standing phases of the data. (Judged by the target, not by the facing reached: some styles
  drift their facing while standing, and would otherwise never count as idle.)

None of this happens while anything is held; the paper's loop is unchanged then. ``Controller(...,
stand=None)`` turns it off (the runtime as the authors' demo had it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from minifilm.motion.foot_ik import two_bone_ik
from minifilm.runtime.frames import to_local2, to_local3, to_world2, to_world3, unit2

#: below this commanded speed (m/s) the command is "stand"
STILL_SPEED = 1e-6
#: a target facing that moved more than this (degrees) since the last frame is being turned by the
#: user: the character turns on the spot (stepping), it does not stand
TURNING_DEG = 0.05
#: the toe joints' names tried, [right, left] (the contact columns' order), for the held legs
#: metres: a held ankle is reached this much short of the straight leg (the knee keeps a bend)
REACH_MARGIN = 0.005
TOE_NAMES = (("RightToe", "LeftToe"), ("RightToeBase", "LeftToeBase"), ("RightFoot", "LeftFoot"))


@dataclass(frozen=True)
class StandStill:
    """How the runtime stands still at a zero command (see the module docstring).

    settle: seconds over which the network's own root displacement is faded out once idle, and
        over which the lower body is taken over once idle and not turned (``hold``).
    phase_tau: seconds, the time constant of the phase amplitudes' decay while idle.
    contact_height: metres; a held foot whose toe is lower than this is reported in contact (the
        released network's toes are 1-6 cm high in its predicted contacts).
    lower_speed: m/s at which a held foot that is off the floor is put down (``plant_feet``).
    release: seconds over which held feet are let go once something is asked.
    hold: once idle, hold the lower body: feet planted where they come to rest (legs bent to
        reach them), the velocities fed back the pose's own, the reported contacts the planted feet's.
    """

    settle: float = 0.5
    phase_tau: float = 0.05
    hold: bool = True
    contact_height: float = 0.08
    lower_speed: float = 0.5
    release: float = 0.15

    def __post_init__(self):
        if not (self.settle > 0 and np.isfinite(self.settle)):
            raise ValueError(f"StandStill: settle must be a positive number of seconds, got {self.settle}")
        if not (self.phase_tau > 0 and np.isfinite(self.phase_tau)):
            raise ValueError(f"StandStill: phase_tau must be a positive number of seconds, got {self.phase_tau}")

    @staticmethod
    def still(target_velocity: np.ndarray) -> np.ndarray:
        """(B,) True where the command asks for no movement."""
        return np.linalg.norm(np.asarray(target_velocity, dtype=np.float64), axis=-1) < STILL_SPEED

    @staticmethod
    def idle(target_velocity: np.ndarray, target_facing: np.ndarray, previous_target: np.ndarray) -> np.ndarray:
        """(B,) True where nothing is asked: no movement, and the target facing where it was last
        frame (within ``TURNING_DEG``: the user is not turning the character on the spot)."""
        tf = np.asarray(target_facing, dtype=np.float64)
        f = np.asarray(previous_target, dtype=np.float64)
        cos = np.sum(tf * f, axis=-1) / np.maximum(np.linalg.norm(tf, axis=-1) * np.linalg.norm(f, axis=-1), 1e-9)
        return StandStill.still(target_velocity) & (cos >= np.cos(np.radians(TURNING_DEG)))

    @staticmethod
    def pin_future(future_pos: np.ndarray, still: np.ndarray) -> np.ndarray:
        """Future positions (B, S, 2) with every sample of the ``still`` rows at the root (sample 0)."""
        out = future_pos.copy()
        out[still, 1:] = out[still, :1]
        return out

    def root_weight(self, idle_seconds: np.ndarray) -> np.ndarray:
        """(B,) how much of the network's root displacement is kept: 1 while moving, a smoothstep
        down to 0 over ``settle`` seconds of idling."""
        u = np.clip(np.asarray(idle_seconds, dtype=np.float64) / self.settle, 0.0, 1.0)
        return 1.0 - u * u * (3.0 - 2.0 * u)

    def hold_weight(self, rest_seconds: np.ndarray) -> np.ndarray:
        """(B,) how firmly the lower body is held: 0 while anything is asked (the paper's loop), a
        smoothstep up to 1 over ``settle`` seconds of idling without turning; always 0 without ``hold``."""
        if not self.hold:
            return np.zeros(np.shape(rest_seconds))
        return 1.0 - self.root_weight(rest_seconds)

    def feet_weight(self, previous: Optional[np.ndarray], rest_seconds: np.ndarray, idle: np.ndarray,
                    dt: float) -> np.ndarray:
        """(B,) how firmly the feet are held this frame: the hold weight while idle, and from a
        command on falling linearly to 0 over ``release`` seconds (the feet are let go, not dropped:
        a held foot would otherwise jump to where the network has it in one frame)."""
        falling = np.zeros(len(idle)) if previous is None else np.maximum(previous - dt / self.release, 0.0)
        return np.where(idle, np.maximum(self.hold_weight(rest_seconds), falling), falling)

    def phase_factor(self, idle: np.ndarray, dt: float) -> np.ndarray:
        """(B,) the factor the phases (amplitude times (sin, cos)) are multiplied by this frame."""
        return np.where(idle, np.exp(-dt / self.phase_tau), 1.0)


def leg_chains(joint_names: Sequence[str], parents: Sequence[int]) -> Optional[np.ndarray]:
    """(2, 4) exported-joint indices (hip, knee, ankle, toe) of the [right, left] legs: the toes by
    name (``TOE_NAMES``), the rest their parents; None when no pair of toes is found."""
    names = list(joint_names)
    for pair in TOE_NAMES:
        if all(n in names for n in pair):
            chains = []
            for toe in (names.index(n) for n in pair):
                ankle = parents[toe]
                knee = parents[ankle] if ankle >= 0 else -1
                hip = parents[knee] if knee >= 0 else -1
                if hip < 0:
                    return None
                chains.append([hip, knee, ankle, toe])
            return np.array(chains, dtype=np.int64)
    return None


def plant_feet(positions: np.ndarray, held: Optional[np.ndarray], weight: np.ndarray,
               chains: np.ndarray, lower: Optional[np.ndarray] = None,
               floor: float = 0.08) -> Tuple[np.ndarray, np.ndarray]:
    """Hold the feet where they come to rest: the lower body of a settled character.

    positions (B, J, 3) world joints; held (B, 2, 2, 3) the [right, left] feet's held ankle and toe
    positions (None: start from these positions); weight (B,) in [0, 1] (:meth:`StandStill.hold_weight`).
    Each frame the held feet move towards the current ones by ``1 - weight`` (free at 0, still at
    1: the foot locker's rule with the hold weight as the contact), the legs bend to put the ankles
    there (two-bone IK, hips fixed, bone lengths kept) and the toes sit at theirs (the foot keeps
    its length). A foot held with its toe higher than ``floor`` (m) and than the other toe (a
    knee up, a hop, a kick when the stop came) is put down by up to ``lower`` (B,) metres this
    frame: a standing body stands on both feet. Returns the new positions (B, J, 3) and held
    feet (B, 2, 2, 3).
    """
    P = np.array(positions, dtype=np.float64)
    hip, knee, ankle, toe = (chains[:, i] for i in range(4))
    now = np.stack([P[:, ankle], P[:, toe]], axis=2)                    # (B, 2 feet, 2 joints, 3)
    w = np.asarray(weight, dtype=np.float64)[:, None, None, None]
    held = now if held is None else w * held + (1.0 - w) * now
    if lower is not None:
        toe_y = held[:, :, 1, 1]                                        # (B, 2)
        down = np.minimum(toe_y[:, ::-1], floor / 2)                   # the other toe, or half-way
        step = np.where(toe_y > floor, np.clip(toe_y - down, 0.0, np.asarray(lower, dtype=np.float64)[:, None]), 0.0)
        held = held.copy()
        held[..., 1] -= step[:, :, None]
    # a held foot out of the leg's reach (the network lifts its hips: a bounce, a hop) lowers the
    # whole body until both are reached, as a game's pelvis adjustment does: the feet stay put
    reach = (np.linalg.norm(P[:, knee] - P[:, hip], axis=-1)
             + np.linalg.norm(P[:, ankle] - P[:, knee], axis=-1) - REACH_MARGIN)          # (B, 2)
    to_foot = held[:, :, 0] - P[:, hip]
    across = np.hypot(to_foot[..., 0], to_foot[..., 2])
    above = -to_foot[..., 1]                                     # hip height over the held ankle
    drop = np.where(across < reach, above - np.sqrt(np.maximum(reach ** 2 - across ** 2, 0.0)), 0.0)
    P[..., 1] -= np.maximum(drop.max(axis=1), 0.0)[:, None]
    new_knee, new_ankle = two_bone_ik(P[:, hip], P[:, knee], P[:, ankle], held[:, :, 0])
    foot = held[:, :, 1] - held[:, :, 0]
    # the foot's own length (held toe - held ankle drifts from it only while the hold is partial)
    length = np.linalg.norm(P[:, toe] - P[:, ankle], axis=-1, keepdims=True)
    P[:, knee], P[:, ankle] = new_knee, new_ankle
    P[:, toe] = new_ankle + foot * (length / np.maximum(np.linalg.norm(foot, axis=-1, keepdims=True), 1e-9))
    return P, held


def hold_root(root: np.ndarray, facing: np.ndarray, new_pos: np.ndarray, new_dir: np.ndarray,
              joints: np.ndarray, vectors: Sequence[np.ndarray], move: np.ndarray, turn: np.ndarray):
    """Keep only part of the network's root step, moving its predicted body with the root.

    root, facing (B, 2): the current root; new_pos, new_dir (B, S, 2): the predicted trajectory,
    sample 0 the next root; joints (B, J, 3) predicted world positions; vectors: world 3-vectors
    (B, J, 3) to turn with the body (axes, velocities); move, turn (B,): the fraction of the
    predicted displacement and of the predicted change of facing that is kept (1: all, the
    paper's loop, those rows returned unchanged). The body and the trajectory are moved back and
    turned back about the next root, so the body stays where its root is and faces its way.
    Returns new_pos, new_dir, joints, [vectors].
    """
    rows = (move < 1.0) | (turn < 1.0)
    if not np.any(rows):
        return new_pos, new_dir, joints, list(vectors)
    shift = (1.0 - move)[:, None] * (new_pos[:, 0] - root)                     # (B, 2)
    pos = new_pos - shift[:, None]
    centre = pos[:, 0]
    before = np.arctan2(facing[:, 0], facing[:, 1])
    turned = np.arctan2(new_dir[:, 0, 0], new_dir[:, 0, 1])
    kept = before + turn * (np.mod(turned - before + np.pi, 2 * np.pi) - np.pi)
    g_new, g_kept = new_dir[:, :1], np.stack([np.sin(kept), np.cos(kept)], axis=-1)[:, None]
    pos = to_world2(to_local2(pos - centre[:, None], g_new), g_kept) + centre[:, None]
    direction = unit2(to_world2(to_local2(new_dir, g_new), g_kept), new_dir)
    rel = joints.copy()                         # moved back with the root, about the next root
    rel[..., 0] -= (shift[:, 0] + centre[:, 0])[:, None]
    rel[..., 2] -= (shift[:, 1] + centre[:, 1])[:, None]
    body = to_world3(to_local3(rel, g_new[:, 0]), g_kept[:, 0])
    body[..., 0] += centre[:, 0, None]
    body[..., 2] += centre[:, 1, None]
    turned_vectors = [to_world3(to_local3(v, g_new[:, 0]), g_kept[:, 0]) for v in vectors]
    r2, r3 = rows[:, None, None], rows[:, None, None]
    return (np.where(r2, pos, new_pos), np.where(r2, direction, new_dir), np.where(r3, body, joints),
            [np.where(r3, t, v) for t, v in zip(turned_vectors, vectors)])
