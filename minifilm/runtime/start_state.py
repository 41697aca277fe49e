"""Where a rollout starts: the skeleton's joints matched to the network's, a start state taken
from a style's own data (:meth:`minifilm.runtime.controller.Controller.run`'s ``phases`` and
``start_x``), and the root's past and future read from such a frame."""
from __future__ import annotations

import numpy as np

from minifilm.features.layout import CURRENT_SAMPLE, FeatureLayout
from minifilm.files.names import few
from minifilm.motion.motion import Motion
from minifilm.runtime.root_frames import to_world2, unit2


def root_joint_indices(layout: FeatureLayout, skeleton: Motion) -> np.ndarray:
    """Index into ``skeleton`` joints of each exported joint of ``layout``, matched by name;
    ValueError naming every missing joint when the skeleton is not the layout's."""
    missing = [n for n in layout.joint_names if n not in skeleton.names]
    if missing:
        raise ValueError(f"{skeleton.source}: the skeleton lacks {len(missing)} of the network's "
                         f"{layout.n_joints} joints ({few(missing)}); its joints are {few(skeleton.names)}. "
                         "Another rig's motion is put on the network's skeleton by `minifilm retarget`")
    return np.array([skeleton.index(n) for n in layout.joint_names], dtype=np.int64)


def start_from_dataset(dataset, style: str, gait: str = "FW", split: str = "train"):
    """A start state for :meth:`~minifilm.runtime.controller.Controller.run` taken from a style's own data: the raw input frame
    x (x_dim,) and phases p (8,) of the middle row of its unmirrored ``gait`` file (any of its
    files when it has none), as ``run(..., phases=p, start_x=x)``.

    The data's mean pose and mean phases (the default start) belong to no style and to no phase
    of a gait cycle; a small network may not get from there into its style's cycle (it stands
    still). ``dataset`` is a :class:`minifilm.dataset.build.Dataset` (raw, unnormalised rows).
    """
    sp = dataset.split(split)
    if style not in dataset.styles:
        raise KeyError(f"start_from_dataset: style {style!r} is not in the data set ({dataset.styles})")
    s = dataset.styles.index(style)
    files = [i for i, f in enumerate(dataset.files)
             if f.get("style") == style and f.get("gait") == gait and not f.get("mirrored")]
    rows = np.flatnonzero((sp.style == s) & np.isin(sp.file, files))
    if rows.size == 0:
        rows = np.flatnonzero(sp.style == s)
    if rows.size == 0:
        raise ValueError(f"start_from_dataset: style {style!r} has no rows in the {split!r} split")
    r = rows[len(rows) // 2]
    return np.asarray(sp.x[r], np.float64), np.asarray(sp.p[r], np.float64)


def trajectory_from_x(traj: np.ndarray, root: np.ndarray, facing: np.ndarray, past_frames: np.ndarray,
                      history: int):
    """The root's past and future from the trajectory block of raw input frames, placed at the
    characters' roots (B, 2) facing (B, 2): the future samples as they are, the history
    interpolated linearly between the past samples (directions renormalised).

    traj (B, 12, 4): x's trajectory samples (position x, z, direction x, z) in the root's frame;
    past_frames (6,): how many frames back each past sample lies (60, 50, .., 10 at 60 fps);
    history: frames of root history kept (the largest of them).
    Returns history_pos, history_dir (B, history, 2), future_pos, future_dir (B, S, 2).
    """
    f = facing[:, None]
    wp = to_world2(traj[..., :2], f) + root[:, None]
    wd = unit2(to_world2(traj[..., 2:], f), f)
    # samples at -past_frames .. 0; history slot -n is n frames ago (n = history .. 1)
    known = np.r_[-past_frames, 0].astype(np.float64)
    n = -np.arange(history, 0, -1).astype(np.float64)
    order = np.argsort(known)
    out = []
    for src in (wp, wd):
        vals = src[:, :CURRENT_SAMPLE + 1][:, order]                      # (B, 7, 2)
        out.append(np.array([[np.interp(n, known[order], vals[b, :, c]) for c in range(2)]
                             for b in range(len(vals))]).transpose(0, 2, 1))   # (B, history, 2)
    return out[0], unit2(out[1], f), wp[:, CURRENT_SAMPLE:].copy(), wd[:, CURRENT_SAMPLE:].copy()
