"""CharacterState: everything the controller remembers between two frames, for B characters.

All arrays are in the world frame (metres, y up; 2-D vectors are floor (x, z) pairs). The
controller replaces arrays rather than writing into them, so a frame handed out by
:meth:`~minifilm.runtime.controller.Controller.frame` stays valid until the next step.
"""
from __future__ import annotations

from dataclasses import dataclass

from typing import Optional

import numpy as np


@dataclass
class CharacterState:
    """The state of B characters.

    root, facing (B, 2)            the root on the floor and its unit facing direction
    history_pos, history_dir (B, N, 2)  the root's last N frames; [:, -n] is n frames ago
    future_pos, future_dir (B, S, 2)    the future trajectory samples; sample 0 is the root
    joint_pos, joint_fwd, joint_up, joint_vel (B, J, 3)
                                   the pose the next input frame is built from (positions, forward
                                   and up axes of each joint's rotation, velocities in m/s)
    phases (B, 8)                  the running local phases p (Eq. 1)
    contacts (B, 2)                the predicted foot contacts [right, left]
    network_pos (B, J, 3)          the joints exactly as the network last predicted them
    out_pos, out_fwd, out_up (B, J, 3)  the pose shown to the user (after the skeleton fit and
                                   foot locking, when on)
    """

    root: np.ndarray
    facing: np.ndarray
    history_pos: np.ndarray
    history_dir: np.ndarray
    future_pos: np.ndarray
    future_dir: np.ndarray
    joint_pos: np.ndarray
    joint_fwd: np.ndarray
    joint_up: np.ndarray
    joint_vel: np.ndarray
    phases: np.ndarray
    contacts: np.ndarray
    network_pos: np.ndarray
    out_pos: np.ndarray
    out_fwd: np.ndarray
    out_up: np.ndarray
    idle_seconds: Optional[np.ndarray] = None    # (B,) how long nothing has been asked (standing.py)
    target_facing: Optional[np.ndarray] = None   # (B, 2) the last frame's target facing (standing.py)
    quiet_seconds: Optional[np.ndarray] = None   # (B,) how long idle: still, the target not turned (standing.py)
    rest_seconds: Optional[np.ndarray] = None    # (B,) how long at rest: idle, the turn finished (standing.py)
    feet_weight: Optional[np.ndarray] = None     # (B,) how firmly the feet are held (standing.py)
    feet: Optional[np.ndarray] = None            # (B, 2, 2, 3) held [right, left] (ankle, toe) (standing.py)
    lowering: Optional[np.ndarray] = None        # (B, 2) held feet on their way down to the floor (standing.py)
    held_rows: Optional[np.ndarray] = None       # (B,) the characters whose feet were held last frame (standing.py)

    @property
    def batch(self) -> int:
        return len(self.root)


@dataclass
class Prediction:
    """The network's output frame z (Sec. 3.2) read into the world, for B characters: what the
    controller makes its next frame from.

    trajectory_pos, trajectory_dir (B, S, 2)  the predicted future samples; [:, 0] is the next root
    joint_pos, joint_fwd, joint_up, joint_vel (B, J, 3)  the predicted joints of the next frame
    contacts (B, 2)                the predicted foot contacts [right, left]
    """

    trajectory_pos: np.ndarray
    trajectory_dir: np.ndarray
    joint_pos: np.ndarray
    joint_fwd: np.ndarray
    joint_up: np.ndarray
    joint_vel: np.ndarray
    contacts: np.ndarray
