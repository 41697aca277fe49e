"""The field's standard locomotion metrics, so minifilm's figures can be read beside other papers'.

Definitions and where they come from are in ``docs/metrics.md``. All inputs are world positions in
metres with y up, ``fps`` frames per second; nothing here knows about networks.

- :func:`foot_sliding` — how far a foot moves horizontally while it is on the floor, judged by
  height alone (as the diffusion controller CAMDM, Chen et al. 2024, evaluates it), so it does not
  depend on any model's own contact labels;
- :func:`body_facing` — the body's facing angle from the shoulders and hips;
- :func:`trajectory_errors` — how well the root follows a commanded path: position, direction of
  travel and facing;
- :func:`fid_like` — a Fréchet distance between all generated and all real windows, the role FID
  plays in image and motion generation, in minifilm's style-feature space.
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from minifilm.evaluation.style_measures import frechet_distance, gaussian

CM_PER_M = 100.0


def _wrap_degrees(angle: np.ndarray) -> np.ndarray:
    """Angles in degrees wrapped to [-180, 180): the difference 350° - 10° is -20°, not 340°."""
    return (np.asarray(angle, np.float64) + 180.0) % 360.0 - 180.0


def foot_sliding(positions: np.ndarray, feet: Sequence[int], fps: float, height: float = 0.01,
                 floor: Optional[float] = None) -> dict:
    """Horizontal motion of the feet while they touch the floor, judged by height.

    positions (F, J, 3) world joint positions in metres, y up; feet: joint indices of the foot joints
    to judge (the toes, as CAMDM's evaluation uses); ``height`` (m): a foot sample counts as on the
    floor when its height above the floor is below it (CAMDM: 1 cm); ``floor`` (m): the floor's height,
    or None for the lowest height any of the feet reaches in the clip (CAMDM first moves the clip so
    its lowest toe is at 0, so a model that floats or sinks evenly is not punished twice).

    Returns, over every (frame, foot) sample on the floor (the step from frame k to k+1 belongs to k):
      speed_cm_s:   mean horizontal speed, cm/s (a foot sliding 1 cm per frame at 60 fps reads 60);
      per_frame_cm: mean horizontal distance per frame, cm;
      relative:     per_frame_cm over the root's mean horizontal distance per frame (CAMDM's
                    reported number: sliding as a share of how far the body travels; the root
                    distance counts as 1 when the body does not move);
      contact_share: share of samples on the floor (0 means nothing was judged: the others read 0).
    """
    P = np.asarray(positions, np.float64)
    if P.ndim != 3 or P.shape[2] != 3 or P.shape[0] < 2:
        raise ValueError(f"foot_sliding: positions must be (F >= 2, J, 3), got {P.shape}")
    feet = [int(j) for j in feet]
    if not feet or min(feet) < 0 or max(feet) >= P.shape[1]:
        raise ValueError(f"foot_sliding: foot joints {feet} are not joints of a {P.shape[1]}-joint skeleton")
    if not fps > 0:
        raise ValueError(f"foot_sliding: fps must be positive, got {fps}")
    foot = P[:, feet]                                               # (F, feet, 3)
    ground = foot[..., 1].min() if floor is None else float(floor)
    on_floor = (foot[:-1, :, 1] - ground) < height                  # (F-1, feet)
    step = np.linalg.norm(np.diff(foot[..., [0, 2]], axis=0), axis=-1)   # (F-1, feet) metres
    root_step = float(np.linalg.norm(np.diff(P[:, 0, [0, 2]], axis=0), axis=-1).mean())
    if not on_floor.any():
        return dict(speed_cm_s=0.0, per_frame_cm=0.0, relative=0.0, contact_share=0.0)
    per_frame = float(step[on_floor].mean())
    return dict(speed_cm_s=per_frame * fps * CM_PER_M, per_frame_cm=per_frame * CM_PER_M,
                relative=per_frame / (root_step if root_step > 0 else 1.0),
                contact_share=float(on_floor.mean()))


def body_facing(positions: np.ndarray, left_shoulder: int, right_shoulder: int, left_hip: int,
                right_hip: int) -> np.ndarray:
    """The body's facing on the floor, degrees, per frame: (F,).

    The across-the-body direction is the mean of the unit shoulder line and the unit hip line (right
    to left); facing is that direction turned 90° about y, so for a body whose left is +x it points
    along +z. Angles are atan2(x, z): 0° faces +z, 90° faces +x.
    """
    P = np.asarray(positions, np.float64)
    across = np.zeros(P.shape[:1] + (3,))
    for left, right in ((left_shoulder, right_shoulder), (left_hip, right_hip)):
        line = P[:, left] - P[:, right]
        across += line / np.maximum(np.linalg.norm(line, axis=-1, keepdims=True), 1e-12)
    forward = np.cross(across, [0.0, 1.0, 0.0])                      # left = +x gives forward = +z
    return np.degrees(np.arctan2(forward[:, 0], forward[:, 2]))


def heading_degrees(direction_xz: np.ndarray) -> np.ndarray:
    """(…, 2) floor directions (x, z) -> angles in degrees, atan2(x, z) as :func:`body_facing`."""
    d = np.asarray(direction_xz, np.float64)
    return np.degrees(np.arctan2(d[..., 0], d[..., 1]))


def trajectory_errors(root_xz: np.ndarray, path_xz: np.ndarray, facing_deg: Optional[np.ndarray] = None,
                      path_facing_deg: Optional[np.ndarray] = None, min_speed: float = 0.1,
                      fps: float = 60.0) -> dict:
    """How well the root follows a commanded path, frame by frame.

    root_xz (F, 2) and path_xz (F, 2): where the root is and where the command says it should be on
    each frame (metres); facing_deg / path_facing_deg (F,): the body's facing (:func:`body_facing`)
    and the commanded facing, degrees.

    Returns position_mean / position_max (m); direction_mean (degrees, the mean absolute wrapped
    difference between the root's direction of travel and the path's, over frames where both move
    faster than ``min_speed`` m/s: a standing command or a standing root has no direction);
    stalled (the share of the path's moving frames on which the root stands); direction_signed
    (degrees, the absolute value of the signed mean, as CAMDM reports it: errors to the left and to
    the right cancel, so it is never larger than direction_mean); with facings, facing_mean and
    facing_signed the same for the facing.
    """
    root = np.asarray(root_xz, np.float64)
    path = np.asarray(path_xz, np.float64)
    if root.ndim != 2 or root.shape[1] != 2 or root.shape != path.shape or len(root) < 2:
        raise ValueError(f"trajectory_errors: root {root.shape} and path {path.shape} must both be (F >= 2, 2)")
    gap = np.linalg.norm(root - path, axis=-1)
    out = dict(position_mean=float(gap.mean()), position_max=float(gap.max()))
    path_step, root_step = np.diff(path, axis=0), np.diff(root, axis=0)
    path_moves = np.linalg.norm(path_step, axis=-1) * fps > min_speed
    root_moves = np.linalg.norm(root_step, axis=-1) * fps > min_speed
    judged = path_moves & root_moves
    # a root that stands while the path moves has no direction of travel: counted apart, not as 0°
    out["stalled"] = float((path_moves & ~root_moves).sum() / max(path_moves.sum(), 1))
    if judged.any():
        diff = _wrap_degrees(heading_degrees(root_step[judged]) - heading_degrees(path_step[judged]))
        out.update(direction_mean=float(np.abs(diff).mean()), direction_signed=float(abs(diff.mean())))
    else:
        out.update(direction_mean=0.0, direction_signed=0.0)
    if (facing_deg is None) != (path_facing_deg is None):
        raise ValueError("trajectory_errors: give both facing_deg and path_facing_deg, or neither")
    if facing_deg is not None:
        f, g = np.asarray(facing_deg, np.float64), np.asarray(path_facing_deg, np.float64)
        if f.shape != (len(root),) or g.shape != (len(root),):
            raise ValueError(f"trajectory_errors: facings {f.shape} and {g.shape} must be ({len(root)},)")
        diff = _wrap_degrees(f - g)
        out.update(facing_mean=float(np.abs(diff).mean()), facing_signed=float(abs(diff.mean())))
    return out


def fid_like(space, generated: np.ndarray, real: np.ndarray, summarised: bool = False) -> float:
    """Squared Fréchet distance between ALL generated windows and ALL real windows, pooled over
    styles, in a :class:`~minifilm.evaluation.style_measures.StyleSpace` (its standardised principal
    components of window summaries): how far the generated motion as a whole lies from the data, the
    role FID plays for image and motion generators. 0 for the same distribution.

    generated / real: (M, T, C) windows of normalised clip features (or (M, 2C) summaries with
    ``summarised``), M >= 2 each.
    """
    return frechet_distance(*gaussian(space.project(generated, summarised)),
                            *gaussian(space.project(real, summarised)))
