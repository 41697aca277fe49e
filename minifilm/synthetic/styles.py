"""Style and gait parameters of the synthetic locomotion generator (``generator.py``).

A *style* is a handful of numbers that change how the oscillators drive the body: how the feet
are timed (duty factors, phase offsets, a lifted foot), how high the hips are, how the spine
leans, how the arms swing (amplitude, centre, phase relative to the legs, frequency ratio) and how
much randomness there is. A *gait* (100STYLE's codes FW, BW, FR, SW, ID, TR) sets the speed, the
direction of travel relative to the facing, the stride frequency and walk/run timing.

The eight styles reproduce the hard cases of Mason et al. 2022 (Sec. 1, 4.1, Fig. 5-6):

==============  ==============================================================================
Neutral         ordinary walking: arms swing in opposition to the legs.
PendulumHands   both arms swing forward and back *together*: hands and feet share no single
                global phase (why the paper uses local phases).
LeftHop         hops on the left foot only; the right foot is held up and never touches the
                floor, so its phase must come from the contact-free (PCA) source.
Limp            asymmetric: the right leg has a short stance, low stiff swing with
                circumduction, the left a long stance; uneven step timing and a lean.
HandsAbove      both arms held up above the head the whole time, with a small sway.
Crouched        hips low, knees bent, trunk leaning forward, short steps.
Swimming        the arms cycle in large strokes at 1.5x the stride frequency, out of step
                with the legs (like 100STYLE's Swimming).
Drunk           stochastic: irregular step timing and step placement, swaying trunk and head,
                wandering path, loose arms (like 100STYLE's Drunk).
==============  ==============================================================================

Angles are radians, lengths metres, frequencies Hz (cycles per second of one foot's stride).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Dict, Optional, Tuple

import numpy as np

__all__ = ["StyleParams", "GaitParams", "STYLE_PARAMS", "GAIT_PARAMS", "STYLES", "GAITS"]

_DEG = np.pi / 180.0


@dataclass(frozen=True)
class StyleParams:
    """How one style drives the oscillators. Pairs are (right, left) for legs, (left, right) for arms
    (the orders of ``true_contacts`` and of the hand slots of ``true_phase`` respectively)."""

    name: str
    speed_scale: float = 1.0            # multiplies the gait's speed
    stride_freq_scale: float = 1.0      # multiplies the gait's stride frequency
    # --- legs (right, left) ---
    foot_phase_offset: Tuple[float, float] = (0.0, 0.5)   # cycles added to the stride phase
    duty_delta: Tuple[float, float] = (0.0, 0.0)          # added to the gait's duty factor
    lifted_foot: Optional[str] = None   # "right": that foot never steps (hopping on the other)
    idle_steps: bool = False            # keep stepping (hopping) in place when the gait is idle
    step_width: float = 0.11            # lateral distance of each toe tip from the path, m
    swing_height_scale: Tuple[float, float] = (1.0, 1.0)
    circumduction: Tuple[float, float] = (0.0, 0.0)       # outward arc of the swing foot, m
    heel_off_scale: Tuple[float, float] = (1.0, 1.0)      # how much the heel rises before toe-off
    toe_out: float = 8 * _DEG           # feet turned outwards
    # --- pelvis and spine ---
    hips_height: float = 0.0            # added to the standing hips height, m
    hips_bob_scale: float = 1.0
    hips_sway: float = 0.02             # side-to-side over the stance foot, m
    pelvis_yaw: float = 5 * _DEG        # pelvis rotation with the stride
    pelvis_pitch: float = 0.0           # forward tilt of the hips
    spine_lean: float = 3 * _DEG        # forward lean spread over the four chest joints
    stance_lean: float = 0.0            # sideways lean over the right stance foot (limp)
    head_pitch: float = 0.0             # added to the neck + head (negative: look up)
    # --- arms (left, right) ---
    arm_down: float = 82 * _DEG         # 90°: arms hanging; 0: T-pose; negative: raised
    arm_swing_center: float = 2 * _DEG  # mean forward swing of the upper arm
    arm_swing_amp: float = 18 * _DEG    # forward/back swing amplitude
    arm_phase: Tuple[float, float] = (0.25, 0.75)  # arm phase = ratio * stride phase + this
    arm_freq_ratio: float = 1.0         # arm cycles per stride
    elbow_flex: float = 15 * _DEG
    elbow_flex_amp: float = 10 * _DEG   # more flexed when the arm is forward
    collar_raise: float = 0.0
    run_elbow_scale: float = 1.0        # share of the gait's extra elbow flexion (running) taken
    # --- randomness ---
    noise: float = 0.0                  # 0: regular; 1: Drunk-like irregular timing and placement


@dataclass(frozen=True)
class GaitParams:
    """A 100STYLE gait code and its locomotion numbers."""

    code: str
    speed: float                        # m/s
    direction: Tuple[float, float]      # travel direction (x, z) in the facing frame (+x: left, +z: front)
    stride_freq: float                  # Hz, cycles of one foot
    run: float                          # 0 walk timing (double support), 1 run timing (flight)
    swing_height: float                 # toe-tip clearance at mid-swing, m
    heel_off: float                     # foot pitch at toe-off, rad
    arm_scale: float                    # multiplies the arm swing amplitude
    elbow_extra: float = 0.0            # added elbow flexion (running)


GAIT_PARAMS: Dict[str, GaitParams] = {
    "FW": GaitParams("FW", 1.20, (0.0, 1.0), 1.00, 0.0, 0.07, 28 * _DEG, 1.0),
    "BW": GaitParams("BW", 0.80, (0.0, -1.0), 0.90, 0.0, 0.06, 8 * _DEG, 0.7),
    "FR": GaitParams("FR", 2.80, (0.0, 1.0), 1.35, 1.0, 0.12, 35 * _DEG, 1.6, 60 * _DEG),
    "SW": GaitParams("SW", 0.50, (1.0, 0.0), 0.95, 0.0, 0.05, 8 * _DEG, 0.4),   # sign flips in time
    "ID": GaitParams("ID", 0.00, (0.0, 1.0), 0.55, 0.0, 0.00, 0.0, 0.35),
}
#: Gait codes of the generator; "TR" strings the others together with smooth transitions.
GAITS = ("FW", "BW", "FR", "SW", "ID", "TR")

#: Duty factors (stance fraction of a cycle) for walk and run timing, before style deltas.
DUTY_WALK, DUTY_RUN, DUTY_HOP = 0.62, 0.36, 0.45

_NEUTRAL = StyleParams(name="Neutral")

STYLE_PARAMS: Dict[str, StyleParams] = {
    "Neutral": _NEUTRAL,
    "PendulumHands": replace(
        _NEUTRAL, name="PendulumHands", arm_phase=(0.25, 0.25), arm_swing_amp=38 * _DEG,
        arm_swing_center=8 * _DEG, elbow_flex=5 * _DEG, elbow_flex_amp=4 * _DEG, pelvis_yaw=2 * _DEG),
    "LeftHop": replace(
        _NEUTRAL, name="LeftHop", lifted_foot="right", idle_steps=True, foot_phase_offset=(0.0, 0.0),
        stride_freq_scale=1.75, speed_scale=0.75, step_width=0.06, hips_sway=0.0, pelvis_yaw=2 * _DEG,
        arm_down=70 * _DEG, arm_swing_amp=12 * _DEG, arm_phase=(0.25, 0.25), elbow_flex=35 * _DEG),
    "Limp": replace(
        _NEUTRAL, name="Limp", speed_scale=0.7, foot_phase_offset=(0.0, 0.58), duty_delta=(-0.12, 0.1),
        swing_height_scale=(0.45, 1.0), circumduction=(0.07, 0.0), heel_off_scale=(0.25, 1.0),
        stance_lean=9 * _DEG, hips_sway=0.04, arm_swing_amp=12 * _DEG),
    "HandsAbove": replace(
        _NEUTRAL, name="HandsAbove", arm_down=-78 * _DEG, arm_swing_center=-3 * _DEG,
        arm_swing_amp=12 * _DEG, elbow_flex=20 * _DEG, elbow_flex_amp=8 * _DEG, collar_raise=10 * _DEG,
        run_elbow_scale=0.0, pelvis_yaw=3 * _DEG),
    "Crouched": replace(
        _NEUTRAL, name="Crouched", hips_height=-0.24, pelvis_pitch=18 * _DEG, spine_lean=28 * _DEG,
        head_pitch=-35 * _DEG, speed_scale=0.75, stride_freq_scale=1.1, step_width=0.14,
        swing_height_scale=(0.8, 0.8), hips_bob_scale=0.5, arm_swing_amp=14 * _DEG,
        elbow_flex=45 * _DEG),
    "Swimming": replace(
        _NEUTRAL, name="Swimming", arm_freq_ratio=1.5, arm_phase=(0.0, 0.5), arm_down=78 * _DEG,
        arm_swing_center=50 * _DEG, arm_swing_amp=80 * _DEG, elbow_flex=10 * _DEG,
        elbow_flex_amp=15 * _DEG, run_elbow_scale=0.3, speed_scale=0.8, pelvis_yaw=3 * _DEG),
    "Drunk": replace(
        _NEUTRAL, name="Drunk", noise=1.0, step_width=0.14, hips_sway=0.05, speed_scale=0.8,
        arm_down=75 * _DEG, arm_swing_amp=22 * _DEG, elbow_flex=20 * _DEG, spine_lean=8 * _DEG,
        head_pitch=10 * _DEG),
}

#: Style names, CamelCase as in 100STYLE.
STYLES = list(STYLE_PARAMS)
