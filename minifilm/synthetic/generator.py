"""Procedural stylised locomotion on the 100STYLE skeleton: the data minifilm makes for itself.

``generate_style(style, gait, seconds, rng)`` returns a ``SyntheticClip``: a ``Motion`` exactly like
the one ``read_bvh`` gives for a 100STYLE file (28 joints incl. End Sites, metres, radians, local
rotation matrices, translations = offsets except the root), plus the ground truth the pipeline
tries to recover: the phase of each limb and the foot contacts.

How a clip is made (everything vectorised over frames):

1. Gait timeline and root path (``trajectories.py``): speed, travel direction, stride frequency,
   walk/run timing per frame; a turning path on the floor; the stride phase θ(t) = ∫ f dt.
2. Feet. Foot ``i`` has phase φ_i = θ + offset_i. Cycle k is centred on mid-stance φ_i = k + 0.25
   (the paper's convention: a sinusoid fitted to the contact signal peaks at φ = 0.25, i.e. at
   mid-stance, docs/original-code.md §4.7). The stance covers |φ_i − k − 0.25| <= d/2 with duty
   factor d. During stance k the toe tip (``<Side>ToeSite``, the contact sensor) is planted at a
   target on the floor y = 0, placed where the hip will be at mid-stance; between stances it swings
   to the next target along a smooth arc. Late in stance the heel rises by rotating the foot about
   the toe, which keeps the toe tip planted. A lifted foot (hopping styles) instead oscillates
   forward and back in the hips' frame and never comes near the floor.
3. Hips: the root path plus sway, with a height that bobs and is then lowered (soft minimum)
   just enough for both legs to reach their feet.
4. Legs by analytic two-bone IK (hip -> knee -> ankle), the knee bending towards the foot's
   forward direction; spine, head and arms by per-limb oscillators with the style's parameters.

Ground truth, for measuring phase extraction (circular error) and contact detection:

- ``true_phase`` (F, 4), order [left hand, right hand, left foot, right foot], cycles in [0, 1):
  * feet that step: φ = 0.25 at mid-stance and 0.75 at mid-swing, advancing with the stride phase
    θ = ∫ f dt (uniformly in time while the stride frequency f is constant);
  * a lifted foot (hop styles) and the hands: φ = 0.25 when the limb is at the *forward* extreme
    of its swing, 0.75 at the backward extreme. Each such limb swings along one path driven by
    angle = centre + amplitude · sin 2πφ (the upper arm's forward swing; the foot's forward offset),
    so in the hips' frame its largest-variance direction, turned to point forwards (+z) as the
    original's PCA source does (§3.4), is maximal at φ = 0.25, the same convention as the feet.
- ``phase_active`` (F, 4): where the limb really oscillates, and has for half a second either side
  (a foot that stands still while idle, or an arm whose swing is under 7°, has no meaningful phase).
- ``true_contacts`` (F, 2), order [right, left], 1.0 during designed stance, and also during a
  "swing" so small (< 1 cm lift, < 5 mm travel, as when standing still) that the foot never
  actually leaves the floor.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, List, Optional, Sequence, Union

import numpy as np
from scipy.ndimage import minimum_filter1d

from minifilm.files import atomic_savez
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.motion import Motion
from minifilm.synthetic.body import (JOINT_INDEX, JOINT_NAMES, OFFSETS, REACH, STANDING_HIPS_HEIGHT, Foot,
                                     apply, arms, lifted_foot, rot, skeleton_100style, smoothstep, soft_min,
                                     stepping_foot, two_bone_ik, upper_body)
from minifilm.synthetic.styles import DUTY_HOP, DUTY_RUN, DUTY_WALK, GAITS, STYLE_PARAMS, STYLES, StyleParams
from minifilm.synthetic.trajectories import GaitTimeline, RootPath, gait_timeline, root_path, smooth_noise

__all__ = ["SyntheticClip", "generate_style", "default_dataset", "write_dataset", "STYLES", "GAITS",
           "DEFAULT_GAITS", "skeleton_100style", "JOINT_NAMES", "rest_motion"]

#: Gaits of the default data set (every style gets each of them).
DEFAULT_GAITS = ("FW", "BW", "FR", "SW", "ID", "TR")

# ----------------------------------------------------------------------------------------------
# The clip
# ----------------------------------------------------------------------------------------------

@dataclass
class SyntheticClip:
    """One generated clip and its ground truth.

    motion:        Motion on the 100STYLE skeleton (28 joints incl. End Sites), F frames.
    true_phase:    (F, 4) phases in [0, 1), [left hand, right hand, left foot, right foot].
    true_contacts: (F, 2) 0.0/1.0 foot contacts, [right, left].
    style, gait:   names, e.g. "Neutral", "FW".
    phase_active:  (F, 4) bool, where the limb oscillates so its phase is meaningful.
    frame_gaits:   (F,) gait code of each frame (differs from ``gait`` only in TR clips).
    """

    motion: Motion
    true_phase: np.ndarray
    true_contacts: np.ndarray
    style: str
    gait: str
    phase_active: np.ndarray
    frame_gaits: np.ndarray


def generate_style(style: str, gait: str, seconds: float, rng, fps: float = 60) -> SyntheticClip:
    """Generate ``seconds`` of locomotion of ``style`` (one of ``STYLES``) and ``gait`` (one of
    ``GAITS``: FW, BW, FR, SW, ID, TR) at ``fps`` frames per second.

    rng: an ``np.random.Generator`` (or a seed); the same rng state gives the same clip.
    """
    if style not in STYLE_PARAMS:
        raise ValueError(f"generate_style: unknown style {style!r}; expected one of {STYLES}")
    if gait not in GAITS:
        raise ValueError(f"generate_style: unknown gait {gait!r}; expected one of {GAITS}")
    if not (seconds > 0 and fps > 0):
        raise ValueError(f"generate_style: seconds and fps must be positive, got {seconds}, {fps}")
    rng = np.random.default_rng(rng)
    sp = STYLE_PARAMS[style]
    F = int(round(seconds * fps))
    pad = int(round(2.5 * fps))            # margin so every stance target has a time on the path
    n = F + 2 * pad
    t = np.arange(n) / fps

    timeline = gait_timeline(gait, n, fps, rng, sp)
    path = root_path(timeline, fps, rng, noise=sp.noise)
    theta = float(rng.uniform(0, 1)) + np.cumsum(timeline.stride_freq) / fps

    # Stepping activity: 0 when standing still (unless the style steps in place, e.g. hopping).
    active = np.ones(n) if sp.idle_steps else smoothstep(timeline.speed, 0.02, 0.35)
    duty_base = DUTY_HOP if sp.lifted_foot else DUTY_WALK
    duty_gait = duty_base * (1 - timeline.run) + DUTY_RUN * timeline.run
    lift = timeline.swing_height * active
    if sp.idle_steps:
        lift = np.maximum(lift, 0.05)
    feet: List[Optional[Foot]] = [None, None]                  # [right, left]
    for leg, side in ((0, -1), (1, +1)):
        if sp.lifted_foot == ("right", "left")[leg]:
            continue
        duty = np.clip(duty_gait + sp.duty_delta[leg], 0.2, 0.95)
        # Standing still: the stance fills (almost) the whole cycle. Keep every swing at least
        # 3 frames long, so a foot never jumps between two stance targets from one frame to the next.
        duty = np.minimum(1.0 - (1.0 - duty) * active, 1.0 - 3.0 * timeline.stride_freq / fps)
        feet[leg] = stepping_foot(side, theta, sp.foot_phase_offset[leg], duty, lift,
                                  timeline.heel_off, active, timeline.stride_freq,
                                  timeline.velocity_local[:, 0], t, path, sp, leg, rng)

    # Hips: the path plus sway over the stance foot, pelvis rotations, then the height.
    phi_r = theta + sp.foot_phase_offset[0]                     # the right foot's phase
    hips, R_hips, pelvis_yaw, pelvis_pitch = _hips(sp, timeline, path, theta, phi_r, active, feet, fps, rng)
    hip_offsets = [apply(R_hips, OFFSETS[JOINT_INDEX[name]]) for name in ("RightHip", "LeftHip")]
    hip_joints = [hips + hip_offsets[0], hips + hip_offsets[1]]
    for leg in (0, 1):
        if feet[leg] is None:
            psi = theta + sp.foot_phase_offset[leg]
            feet[leg] = lifted_foot((-1, 1)[leg], psi, hip_joints[leg], R_hips)

    # Local rotations, all joints: (N, 28, 3, 3), identity for End Sites.
    R = np.broadcast_to(np.eye(3), (n, len(JOINT_NAMES), 3, 3)).copy()
    R[:, 0] = R_hips
    for leg, prefix in ((0, "Right"), (1, "Left")):
        foot = feet[leg]
        thigh, shin = two_bone_ik(hip_joints[leg], foot.ankle, foot.forward)
        R[:, JOINT_INDEX[prefix + "Hip"]] = np.swapaxes(R_hips, 1, 2) @ thigh
        R[:, JOINT_INDEX[prefix + "Knee"]] = np.swapaxes(thigh, 1, 2) @ shin
        R[:, JOINT_INDEX[prefix + "Ankle"]] = np.swapaxes(shin, 1, 2) @ foot.rotation
        R[:, JOINT_INDEX[prefix + "Toe"]] = foot.toe_local
    upper_body(R, sp, timeline, theta, phi_r, pelvis_yaw, pelvis_pitch, active, fps, rng)
    arm_phase, arm_active = arms(R, sp, timeline, theta, fps, rng)

    keep = slice(pad, pad + F)
    translations = np.broadcast_to(OFFSETS, (F, len(JOINT_NAMES), 3)).copy()
    translations[:, 0] = hips[keep] - np.array([hips[pad, 0], 0.0, hips[pad, 2]])
    names, parents, offsets, channels = skeleton_100style()
    motion = Motion(names, parents, offsets, channels, R[keep], translations, 1.0 / fps,
                    source=f"synthetic:{style}_{gait}")
    phase = np.stack([arm_phase[0], arm_phase[1], feet[1].phase, feet[0].phase], axis=1)[keep]
    # A phase is only meaningful where the limb has been oscillating for a while around the frame
    # (the pipeline fits windows of about half a second): erode the masks by half a second.
    oscillating = np.stack([arm_active[0], arm_active[1], feet[1].active, feet[0].active], axis=1)
    phase_active = minimum_filter1d(oscillating.astype(np.uint8), int(fps) | 1, axis=0, mode="nearest")
    phase_active = phase_active[keep].astype(bool)
    contacts = np.stack([feet[0].contact, feet[1].contact], axis=1)[keep].astype(np.float64)
    return SyntheticClip(motion=motion, true_phase=np.mod(phase, 1.0), true_contacts=contacts,
                         style=style, gait=gait, phase_active=phase_active,
                         frame_gaits=timeline.gait[keep].astype(str))


def _hips(sp: StyleParams, timeline: GaitTimeline, path: RootPath, theta: np.ndarray, phi_r: np.ndarray,
          active: np.ndarray, feet: List[Optional[Foot]], fps: float, rng: np.random.Generator):
    """Hips world position (N, 3) and rotation (N, 3, 3), plus the pelvis yaw and pitch (N,).

    Horizontally the path plus a sway over the stance foot; the rotation is the path's yaw plus
    the pelvis oscillation. The height bobs with the stride (highest at mid-stance when walking,
    lowest when running or hopping) and is then lowered, by a smooth minimum, just enough that each
    stepping leg reaches its ankle target: |ankle - hip joint| <= REACH.
    """
    n = theta.size
    sway = -sp.hips_sway * np.sin(2 * np.pi * phi_r) * active
    if sp.lifted_foot == "right":
        sway = np.full(n, 0.04)                                # over the left (hopping) foot
    sway = sway + 0.05 * sp.noise * smooth_noise(rng, n, fps, 0.8)
    pelvis_yaw = sp.pelvis_yaw * np.cos(2 * np.pi * phi_r) * active
    pelvis_pitch = sp.pelvis_pitch + 0.08 * timeline.run
    pelvis_roll = 0.07 * sp.noise * smooth_noise(rng, n, fps, 0.7)
    R_hips = rot(1, path.yaw + pelvis_yaw) @ rot(0, pelvis_pitch) @ rot(2, pelvis_roll)
    hips = path.position + np.stack([np.cos(path.yaw) * sway, np.zeros(n), -np.sin(path.yaw) * sway], 1)

    if sp.lifted_foot:
        stance_phi = theta + sp.foot_phase_offset[1 if sp.lifted_foot == "right" else 0]
        bob = -0.035 * np.cos(2 * np.pi * (stance_phi - 0.25))
    else:
        walk_bob = 0.012 * np.cos(4 * np.pi * (phi_r - 0.25))   # highest at mid-stance
        run_bob = -0.03 * np.cos(4 * np.pi * (phi_r - 0.25))    # lowest at mid-stance
        bob = ((1 - timeline.run) * walk_bob + timeline.run * run_bob) * active
    # Knees slightly bent when standing, more when walking (the stance leg is never locked straight).
    desired = (STANDING_HIPS_HEIGHT - 0.005 - 0.02 * active - 0.04 * timeline.run + sp.hips_height
               + sp.hips_bob_scale * bob)
    hip_offsets = [apply(R_hips, OFFSETS[JOINT_INDEX[name]]) for name in ("RightHip", "LeftHip")]
    bounds = [desired]
    for leg, foot in enumerate(feet):
        if foot is None:
            continue
        horizontal = foot.ankle[:, [0, 2]] - (hips[:, [0, 2]] + hip_offsets[leg][:, [0, 2]])
        reach = np.sqrt(np.maximum(REACH ** 2 - np.sum(horizontal ** 2, axis=1), 1e-4))
        bounds.append(foot.ankle[:, 1] - hip_offsets[leg][:, 1] + reach)
    hips[:, 1] = soft_min(bounds, 0.01)
    return hips, R_hips, pelvis_yaw, pelvis_pitch


# ----------------------------------------------------------------------------------------------
# Data sets
# ----------------------------------------------------------------------------------------------

def rest_motion() -> Motion:
    """The 100STYLE skeleton standing at rest (one frame, metres): a skeleton to write the released
    network's motion on when no BVH of the real one is at hand (its offsets are the real header's)."""
    names, parents, offsets, channels = skeleton_100style()
    rotations = np.broadcast_to(np.eye(3), (1, len(names), 3, 3)).copy()
    translations = offsets[None].copy()
    translations[0, 0] = (0.0, STANDING_HIPS_HEIGHT, 0.0)
    return Motion(names, parents, offsets, channels, rotations, translations, 1.0 / 60.0, "100STYLE rest pose")


def default_dataset(seed: int = 0, seconds: float = 6.0, styles: Optional[Iterable[str]] = None,
                    gaits: Optional[Iterable[str]] = None, fps: float = 60) -> List[SyntheticClip]:
    """Every style × gait (default: all ``STYLES`` × ``DEFAULT_GAITS``), ``seconds`` each.

    Each clip draws from its own generator seeded by (seed, style index, gait index), so a clip
    does not change when the lists of styles or gaits are shortened.
    """
    styles = list(STYLES if styles is None else styles)
    gaits = list(DEFAULT_GAITS if gaits is None else gaits)
    unknown = [s for s in styles if s not in STYLE_PARAMS] + [g for g in gaits if g not in GAITS]
    if unknown:
        raise ValueError(f"default_dataset: unknown styles or gaits {unknown}; styles are {STYLES}, "
                         f"gaits {list(GAITS)}")
    clips = []
    for style in styles:
        for gait in gaits:
            key = [int(seed), list(STYLE_PARAMS).index(style), GAITS.index(gait)]
            clips.append(generate_style(style, gait, seconds, np.random.default_rng(key), fps))
    return clips


def write_dataset(directory: Union[str, Path], clips: Optional[Sequence[SyntheticClip]] = None,
                  truth: bool = True, **dataset_options) -> List[Path]:
    """Write clips (default: ``default_dataset(**dataset_options)``) as ``<Style>_<Gait>.bvh``.

    With ``truth``, also ``<Style>_<Gait>.truth.npz`` holding true_phase, true_contacts,
    phase_active (plain arrays, loadable with allow_pickle=False). Returns the BVH paths.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    if clips is None:
        clips = default_dataset(**dataset_options)
    elif dataset_options:
        raise ValueError(f"write_dataset: options {sorted(dataset_options)} only apply when clips is None")
    paths = []
    for clip in clips:
        path = directory / f"{clip.style}_{clip.gait}.bvh"
        write_bvh(clip.motion, path)
        if truth:
            atomic_savez(directory / f"{clip.style}_{clip.gait}.truth.npz",
                         dict(true_phase=clip.true_phase, true_contacts=clip.true_contacts,
                              phase_active=clip.phase_active))
        paths.append(path)
    return paths
