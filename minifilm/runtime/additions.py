"""What the runtime adds to the paper's loop (Sec. 4.4), at the points where the controller calls it.

PAPER: none of this is in the paper's loop. :meth:`~minifilm.runtime.controller.Controller.step`
runs the paper's steps and calls :class:`RuntimeAdditions` once at each of four named points (a
method each); an addition switched off does nothing there, and with ``stand=None``,
``heading_follow=None`` and ``velocity_blend=1.0`` none of them changes anything.

- ``before_input``: standing still: a still character's future pinned to its root, the clocks
  of being still, idle and at rest counted (:mod:`~minifilm.runtime.standing`);
- ``correct`` (the predicted frame): standing's root held (its drift faded out, its turn once
  idle); the heading follow's turn (:mod:`~minifilm.runtime.heading`); the demo's velocity blend
  (docs/original-code.md §10.3); the held feet planted;
- ``refit`` (inside the skeleton fit): the fitted legs put back on the held feet;
- ``after_frame``: the phases of idle characters decayed (held: a slow idle cycle); a held body's
  own velocities and contacts fed back.

The run feed (the demo's Shift) changes only the trajectory input: see
:mod:`~minifilm.runtime.run_feed`.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from minifilm.features.layout import FeatureLayout
from minifilm.runtime.heading import HeadingFollow
from minifilm.runtime.held_body import leg_chains
from minifilm.runtime.standing import StandStill
from minifilm.runtime.state import CharacterState, Prediction


class RuntimeAdditions:
    """The optional behaviours of the runtime, one method per point of the controller's step.

    stand: :class:`StandStill` or None; heading_follow: :class:`HeadingFollow` or None;
    velocity_blend: weight of the predicted joint positions against ``previous + velocity / fps``
    (1.0: the predicted positions as they are); layout: for the legs standing holds; fps.
    """

    def __init__(self, stand: Optional[StandStill], heading_follow: Optional[HeadingFollow],
                 velocity_blend: float, layout: FeatureLayout, fps: float):
        self.stand, self.heading_follow = stand, heading_follow
        self.velocity_blend, self.fps = float(velocity_blend), float(fps)
        self.legs = leg_chains(layout.joint_names, layout.parents)     # (2, 4) or None: no legs to hold

    def before_input(self, st: CharacterState, facing: np.ndarray, velocity: np.ndarray) -> None:
        """Before x is built, with the command (B, 2) of this frame (:meth:`StandStill.begin_frame`)."""
        if self.stand is not None:
            self.stand.begin_frame(st, velocity, facing, 1.0 / self.fps)

    def correct(self, st: CharacterState, prediction: Prediction, target) -> Prediction:
        """The predicted frame changed, in this order: standing's root held (the body moved back
        with it), the heading follow's turn while moving, the velocity blend, the held feet
        planted (``st.feet``; None when no feet are held this frame). ``target``: the command
        (facing, velocity) or None (no command: no heading to follow)."""
        p, dt = prediction, 1.0 / self.fps
        vectors = (p.joint_fwd, p.joint_up, p.joint_vel)
        if self.stand is not None:
            p.trajectory_pos, p.trajectory_dir, p.joint_pos, vectors = self.stand.hold_prediction(
                st, p.trajectory_pos, p.trajectory_dir, p.joint_pos, vectors)
        if self.heading_follow is not None and target is not None:
            facing, velocity = target
            moving = np.linalg.norm(velocity, axis=-1) > 1e-6
            p.trajectory_pos, p.trajectory_dir, p.joint_pos, vectors = self.heading_follow.apply(
                facing, moving, p.trajectory_pos, p.trajectory_dir, p.joint_pos, vectors, dt)
        p.joint_fwd, p.joint_up, p.joint_vel = vectors
        if self.velocity_blend < 1.0:
            integrated = st.joint_pos + p.joint_vel / self.fps
            p.joint_pos = self.velocity_blend * p.joint_pos + (1 - self.velocity_blend) * integrated
        if self.stand is not None and self.stand.holds_feet(st, self.legs):
            p.joint_pos = self.stand.plant(st, p.joint_pos, self.legs, dt)
        else:
            st.feet = None
        return p

    def refit(self, st: CharacterState, fit, positions: np.ndarray, rotations: np.ndarray):
        """The skeleton fit's output (B, J, 3), (B, J, 3, 3) with its legs back on the held feet
        (:meth:`StandStill.refit`); unchanged when no feet are held."""
        if st.feet is None:
            return positions, rotations
        return self.stand.refit(st, fit, positions, rotations, self.legs)

    def after_frame(self, st: CharacterState, previous: np.ndarray) -> None:
        """Once the frame is made: idle characters' phase amplitudes decay towards a still body's
        and, held, ease into a slow idle cycle; a held body feeds back the velocities its pose
        really has (``previous`` (B, J, 3): the pose the frame was made from) and the contacts of
        its held feet (:meth:`StandStill.settle_feedback`)."""
        if self.stand is None:
            return
        dt = 1.0 / self.fps
        idle = st.quiet_seconds > 0             # counted up this frame exactly where idle
        st.phases = st.phases * self.stand.phase_factor(idle, dt)[:, None]
        st.phases = self.stand.idle_phases(st.phases, st.rest_seconds)
        self.stand.settle_feedback(st, previous, self.fps)
