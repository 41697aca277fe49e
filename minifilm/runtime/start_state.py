"""Where a rollout starts: the skeleton's joints matched to the network's, and a start state taken
from a style's own data (:meth:`minifilm.runtime.controller.Controller.run`'s ``phases`` and
``start_x``)."""
from __future__ import annotations

import numpy as np

from minifilm.features.layout import FeatureLayout
from minifilm.motion.motion import Motion


def root_joint_indices(layout: FeatureLayout, skeleton: Motion) -> np.ndarray:
    """Index into ``skeleton`` joints of each exported joint of ``layout``, matched by name;
    ValueError naming every missing joint when the skeleton is not the layout's."""
    missing = [n for n in layout.joint_names if n not in skeleton.names]
    if missing:
        raise ValueError(f"{skeleton.source}: the skeleton lacks {len(missing)} of the network's "
                         f"{layout.n_joints} joints ({missing}); its joints are {skeleton.names}")
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
