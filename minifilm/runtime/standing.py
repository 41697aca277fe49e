"""Standing still when nothing is asked: what the runtime adds to the paper's loop at zero command.

Measured on the released network (``benchmarks/standing.py``): with a zero command after
walking, the character kept going (Neutral at 0.37 m/s), stepping, for as long as it ran. Three
things keep it going, each found by switching it off:

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

Pinning the future, fading the root's drift out and decaying the phases stopped the root in all
100 styles, but in 34 the body went on stepping on the spot (43 counting the feet's own motion,
a toe faster than 0.15 m/s: the contact labeller's "slow"). Three more causes, each measured on
the 100 styles:

4. **The fed-back joint velocities.** The input's velocities are the network's own predicted
   ones, while in the data they are the pose's backward differences. A shuffling style predicts
   moving feet, is told its feet are moving, and goes on: feeding back zero velocities once idle
   alone made 92 of 100 stand (contacts and feet).
5. **The facing** is never held: SpinClock turned 414 degrees in 5 s of "standing", Drunk 269,
   SpinAntiClock 54, and 30 styles more than 5 degrees. Turning on the spot is stepping.
6. **No standing pose to settle into.** Even told it is still, some styles keep their feet busy
   (Drunk's flail at 2.6 m/s, hops, kicks), and the still feet of others get contacts hovering
   about 0.5 (Followed 0.54 / 0.50) that flip with the slightest sway.

So while the commanded velocity is zero, :class:`StandStill`:

- pins every future sample to the root (the stop the user asked for, at once);
- fades the network's remaining root displacement out over ``settle`` seconds (smoothstep), moving
  the predicted body with it, so the root history becomes still and the network sees a still past;
- while the target facing is not being turned either (turning on the spot is stepping, not
  standing), decays the phase amplitudes with time constant ``phase_tau`` seconds, towards the
  standing phases of the data (judged by the target, not by the facing reached);
- and once at rest (idle, and no longer turning towards the target: a turn on the spot is
  finished by the network's own steps first, for at most ``turn_wait`` seconds) holds the body
  as a game character settles, over ``settle`` seconds (``hold``, :mod:`~minifilm.runtime.held_body`):
  the network's turning is faded out like its drift; the feet are kept where they come to rest
  (the foot locker's rule with the hold as the contact; the legs bent by two-bone IK, the pelvis
  lowered when the network lifts it out of the legs' reach; a foot left in the air, over
  ``contact_height``, put down to the other); the held pose is fed back with the velocities it
  really has; and the reported contacts are the held feet's (toe under ``contact_height``; the
  network's own flip with still feet in 3 styles: LawnMower, Swimming, 098).

What was tried and left (figures from ``benchmarks/standing.py``, 100 styles): phases forced to
zero instead of decayed, 73 stand (by the contacts); hysteresis on the predicted contacts alone,
78; feet planted without lowering the pelvis, 87 (a bouncing pelvis drags held feet along); the
held feet fed back with the network's own velocities: all stand, but the start after idling is
slower (``--go``: 11 styles more than 3 frames later than without the held body, mean 7.96
frames to 0.3 m/s, against 6 and 6.50 with the pose's own velocities); feet put down whenever
over 4 cm (not only over 8 cm), about a frame more on average (the network then has to lift a
foot it would have stepped with); the facing and velocities without the feet held: 88 stand by
the contacts, but only 55 keep their toes under 0.1 m/s.

None of this happens while anything is held: the paper's loop is unchanged then, bit for bit
(``tests/runtime/test_standing.py``), except that held feet are let go over ``release`` seconds
after a command (a foot the network holds up would otherwise jump there in one frame).
``StandStill(hold=False)`` is the stand-still without the held body; ``Controller(...,
stand=None)`` turns it all off (the runtime as the authors' demo had it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from minifilm.runtime.root_frames import floor_angle
from minifilm.runtime.held_body import hold_root, plant_feet, refit_on_feet

#: below this commanded speed (m/s) the command is "stand"
STILL_SPEED = 1e-6
#: a target facing that moved more than this (degrees) since the last frame is being turned by the
#: user: the character turns on the spot (stepping), it does not stand
TURNING_DEG = 0.05
#: an idle character whose facing is within REACHED_DEG of the target, or came closer to it by
#: less than TURN_RATE (degrees per second) over the last TURN_WINDOW seconds, has finished turning
REACHED_DEG = 3.0
TURN_RATE = 20.0
TURN_WINDOW = 0.25



@dataclass(frozen=True)
class StandStill:
    """How the runtime stands still at a zero command (see the module docstring).

    settle: seconds over which the network's own root displacement is faded out once still, and
        over which the lower body is taken over once idle (``hold``).
    phase_tau: seconds, the time constant of the phase amplitudes' decay while idle.
    hold: once idle, hold the body: its facing kept, the feet kept where they come to rest (the
        legs bent to reach them), the velocities fed back the held pose's own, the contacts reported
        the held feet's. False: the stand-still of before (root, phases), whose feet may keep stepping.
    contact_height: metres; a held foot whose toe is lower is on the floor (reported in contact);
        a higher one is put down at ``lower_speed`` m/s (the released network's toes are 1-6 cm high
        where it predicts a contact).
    release: seconds over which held feet are let go once something is asked (instead of jumping
        to where the network has them in one frame).
    turn_wait: seconds an idle character may go on turning towards the target facing (see
        ``TURN_RATE``) before it is held all the same.
    idle_amplitude, idle_hz: once held, the phases are eased (with the hold) into a slow cycle of
        this amplitude (the data's walking phases have amplitudes near 2) and frequency, the left
        and right limbs half a cycle apart (:meth:`idle_phases`): the network's experts keep
        blending and the held body sways and breathes instead of freezing (0: the still phases of
        before, a statue). Measured in ``benchmarks/idle.py``.
    """

    settle: float = 0.5
    phase_tau: float = 0.05
    hold: bool = True
    contact_height: float = 0.08
    lower_speed: float = 0.5
    release: float = 0.15
    turn_wait: float = 1.0
    idle_amplitude: float = 0.3
    idle_hz: float = 0.3

    def __post_init__(self):
        for name in ("settle", "phase_tau", "contact_height", "lower_speed", "release", "turn_wait"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0 and np.isfinite(v)):
                raise ValueError(f"StandStill: {name} must be a positive finite number, got {v!r}")
        for name in ("idle_amplitude", "idle_hz"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v >= 0 and np.isfinite(v)):
                raise ValueError(f"StandStill: {name} must be a finite number >= 0, got {v!r}")

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

    def idle_phases(self, phases: np.ndarray, rest_seconds: np.ndarray) -> np.ndarray:
        """The phases (B, 8) of held characters eased into the idle cycle.

        Still phases give the gating network a still input: the network (never trained on the
        idle clips) then settles into one fixed pose, and no joint moves by even 0.1 mm. So once
        the body is held the phases are blended, by the hold weight, into
        ``a (sin phi_k, cos phi_k)`` with ``phi_k = 2 pi f t + offset_k``: amplitude
        ``idle_amplitude``, frequency ``idle_hz``, t the seconds at rest, the offsets 0, pi, 0,
        pi for the left hand, right hand, left foot, right foot (the phase vector's order). The
        feet and the root stay held; the rest of the body follows the network. Rows not held
        are returned unchanged, bit for bit.
        """
        h = self.hold_weight(rest_seconds)
        if self.idle_amplitude <= 0 or not np.any(h > 0):
            return phases
        t = np.asarray(rest_seconds, dtype=np.float64)[:, None]
        phi = 2 * np.pi * self.idle_hz * t + np.array([0.0, np.pi, 0.0, np.pi])      # (B, 4)
        cycle = self.idle_amplitude * np.stack([np.sin(phi), np.cos(phi)], axis=-1).reshape(len(t), 8)
        blended = (1.0 - h)[:, None] * phases + h[:, None] * cycle
        return np.where((h > 0)[:, None], blended, phases)

    # ------------------------------------------------------------------ the controller's hooks
    def begin_frame(self, st, target_velocity: np.ndarray, target_facing: np.ndarray, dt: float) -> np.ndarray:
        """Before the input is built: pin the future of still characters to their roots and count
        the time still (``idle_seconds``), idle (``quiet_seconds``), at rest (idle with the turn
        finished: ``rest_seconds``) and the feet's hold. st: the
        :class:`~minifilm.runtime.state.CharacterState`. Returns idle (B,)."""
        still = self.still(target_velocity)
        st.future_pos = self.pin_future(st.future_pos, still)
        previous = st.target_facing if st.target_facing is not None else target_facing
        idle = self.idle(target_velocity, target_facing, previous)
        st.target_facing = np.array(target_facing, dtype=np.float64)
        zeros = np.zeros(len(still))
        st.idle_seconds = np.where(still, (zeros if st.idle_seconds is None else st.idle_seconds) + dt, 0.0)
        st.quiet_seconds = np.where(idle, (zeros if st.quiet_seconds is None else st.quiet_seconds) + dt, 0.0)
        rest = zeros if st.rest_seconds is None else st.rest_seconds
        # the hold waits while the network is still turning towards the target facing (a turn on
        # the spot is finished by its own steps), at most ``turn_wait`` seconds
        lag = max(1, int(round(TURN_WINDOW / dt)))
        if st.history_dir.shape[1] >= lag:
            now, then = floor_angle(st.facing, st.target_facing), floor_angle(st.history_dir[:, -lag], st.target_facing)
            turning = (now > REACHED_DEG) & (then - now > TURN_RATE * lag * dt)
        else:
            turning = np.zeros(len(idle), dtype=bool)
        at_rest = idle & ((rest > 0) | ~turning | (st.quiet_seconds > self.turn_wait))
        st.rest_seconds = np.where(at_rest, rest + dt, 0.0)
        st.feet_weight = self.feet_weight(st.feet_weight, st.rest_seconds, idle, dt)
        return idle

    def hold_prediction(self, st, new_pos, new_dir, joints, vectors):
        """The network's root step faded out while still, its turn while idle, the predicted body
        moved and turned back with it (:func:`~minifilm.runtime.held_body.hold_root`)."""
        return hold_root(st.root, st.facing, new_pos, new_dir, joints, vectors,
                         self.root_weight(st.idle_seconds), 1.0 - self.hold_weight(st.rest_seconds))

    def holds_feet(self, st, legs) -> bool:
        """True when some character's feet are held this frame (and there are legs to hold)."""
        return legs is not None and st.feet_weight is not None and bool(np.any(st.feet_weight > 0))

    def plant(self, st, positions: np.ndarray, legs: np.ndarray, dt: float) -> np.ndarray:
        """The pose (B, J, 3) with held feet (:func:`~minifilm.runtime.held_body.plant_feet`);
        the held feet are kept in ``st.feet``. Characters not held are returned unchanged."""
        w = st.feet_weight
        if st.feet is None:
            st.lowering = st.held_rows = None
        fresh = None if st.held_rows is None else ~st.held_rows       # their hold begins now
        planted, st.feet, st.lowering = plant_feet(positions, st.feet, w, legs, w * self.lower_speed * dt,
                                                   self.contact_height, st.lowering, fresh)
        st.held_rows = w > 0
        return np.where((w > 0)[:, None, None], planted, positions)

    def refit(self, st, fit, positions, rotations, legs):
        """The skeleton fit's output with its legs back on the held feet (:func:`refit_on_feet`)."""
        return refit_on_feet(fit, positions, rotations, st.feet, st.feet_weight > 0, legs)

    def settle_feedback(self, st, previous: np.ndarray, fps: float) -> None:
        """After the pose to feed back is chosen: held characters feed back the velocities their
        pose really has (the data's are backward differences; the network's own prediction keeps a
        shuffle going) and report the contacts of their held feet (toe below ``contact_height``)."""
        if st.feet_weight is None or not np.any(st.feet_weight > 0):
            return
        h = st.feet_weight[:, None, None]
        own = (st.joint_pos - previous) * fps
        st.joint_vel = np.where(h > 0, (1.0 - h) * st.joint_vel + h * own, st.joint_vel)
        if st.feet is not None:
            grounded = (st.feet[:, :, 1, 1] < self.contact_height).astype(np.float64)     # (B, 2) toes
            h = h[..., 0]
            st.contacts = np.where(h > 0, (1.0 - h) * st.contacts + h * grounded, st.contacts)
