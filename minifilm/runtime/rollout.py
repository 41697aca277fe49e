"""Whole rollouts: scripts run through a controller frame by frame (:func:`run_scripts`, what
:meth:`~minifilm.runtime.controller.Controller.run` does), the :class:`Rollout` it returns, and
the checks of one."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, Union

import numpy as np

from minifilm.motion.measures import bone_length_cv, foot_sliding
from minifilm.motion.motion import Motion
from minifilm.motion.retarget import axes_to_rotation, retarget
from minifilm.runtime.control import Script, distance_to_path


@dataclass
class Rollout:
    """The result of :meth:`~minifilm.runtime.controller.Controller.run` for B characters and F frames.

    positions (B, F, J, 3) world joint positions (after foot locking, if on), metres;
    rotations (B, F, J, 3, 3) world joint rotations from the predicted forward/up axes;
    contacts (B, F, 2) predicted foot contacts [right, left]; phases (B, F, 8);
    root_positions (B, F, 2) and root_facing (B, F, 2) world (x, z) of the root on the floor;
    targets (B, F, 2) the commanded velocities (m/s); fps;
    network_positions (B, F, J, 3) float32: the joints exactly as the network predicted them,
    before the velocity blend, the skeleton fit and foot locking.
    """

    positions: np.ndarray
    rotations: np.ndarray
    contacts: np.ndarray
    phases: np.ndarray
    root_positions: np.ndarray
    root_facing: np.ndarray
    targets: np.ndarray
    fps: float
    network_positions: Optional[np.ndarray] = None

    def metrics(self, parents: Sequence[int], path: Optional[np.ndarray] = None,
                toes: Optional[Sequence[int]] = None, warmup_seconds: float = 1.0) -> List[dict]:
        """Per character: the run-time quality checks, after ``warmup_seconds`` (the start pose is the
        data's mean pose). Keys: bone_cv_max (coefficient of variation of the worst bone, output
        positions), network_bone_cv_max (the same for the network's own positions),
        hips_min / hips_max (m, joint 0 height), speed (mean root speed, m/s), and when given,
        path_mean / path_max (m, root distance to the polyline ``path`` (N, 2)) and foot_sliding
        (m/s, toes = joint index per contact column)."""
        parents = np.asarray(parents)
        k0 = min(int(round(warmup_seconds * self.fps)), self.positions.shape[1] - 2)
        out = []
        for b in range(self.positions.shape[0]):
            P = self.positions[b, k0:]
            m = dict(bone_cv_max=float(bone_length_cv(P, parents).max()),
                     hips_min=float(P[:, 0, 1].min()), hips_max=float(P[:, 0, 1].max()),
                     speed=float(np.linalg.norm(np.diff(self.root_positions[b, k0:], axis=0), axis=1).mean() * self.fps))
            if self.network_positions is not None:
                m["network_bone_cv_max"] = float(bone_length_cv(self.network_positions[b, k0:], parents).max())
            if path is not None:
                d = distance_to_path(self.root_positions[b, k0:], path)
                m.update(path_mean=float(d.mean()), path_max=float(d.max()))
            if toes is not None:
                m["foot_sliding"] = foot_sliding(P, self.contacts[b, k0:], toes, self.fps)
            out.append(m)
        return out

    def to_motion(self, skeleton: Motion, joint_indices: Sequence[int], character: int = 0,
                  fit_positions: bool = True) -> Motion:
        """Character ``character`` as a Motion on ``skeleton`` (see :func:`retarget`), for BVH export."""
        return retarget(self.positions[character], self.rotations[character], skeleton, joint_indices,
                        frame_time=1.0 / self.fps, fit_positions=fit_positions)


def run_scripts(controller, scripts: Union[Script, Sequence[Script]], n_frames: int,
                film: Union[np.ndarray, Callable[[int], np.ndarray]], phases: Optional[np.ndarray] = None,
                calibration=None, start_x: Optional[np.ndarray] = None,
                progress: Optional[Callable[[int], None]] = None) -> Rollout:
    """Run B = len(scripts) characters for ``n_frames`` frames with ``controller`` (a
    :class:`~minifilm.runtime.controller.Controller`): reset to the scripts' starts, then one
    :meth:`~minifilm.runtime.controller.Controller.step` per frame with each script's command.

    Args:
        scripts: one :class:`~minifilm.runtime.control.Script` per character (or one for B = 1); each
            starts where its ``start()`` says.
        film: (4H,) or (B, 4H) for all frames, (n_frames, 4H) / (n_frames, B, 4H) per frame
            (style transitions), or a callable frame -> film.
        calibration: a :class:`~minifilm.runtime.calibration.SpeedCalibration` that maps the user's
            speed (m/s) to the command that makes this network actually move at that speed (see
            :func:`~minifilm.runtime.calibration.calibrate_speed`); None = use as given.
        phases, start_x: the start phases (B, 8) and pose (raw input frames), see
            :meth:`~minifilm.runtime.controller.Controller.reset`.
        progress: called with the number of frames done after each frame (a long rollout's display).
    """
    if isinstance(scripts, Script):
        scripts = [scripts]
    B, fps = len(scripts), controller.fps
    for s in scripts:
        s.reset()
    starts = [s.start() for s in scripts]
    controller.reset(np.array([p for p, _ in starts]), np.array([f for _, f in starts]), phases, start_x)
    J = controller.layout.n_joints
    out = dict(positions=np.empty((B, n_frames, J, 3)), forward=np.empty((B, n_frames, J, 3)),
               network_positions=np.empty((B, n_frames, J, 3), dtype=np.float32),
               up=np.empty((B, n_frames, J, 3)),
               contacts=np.empty((B, n_frames, 2)), phases=np.empty((B, n_frames, 8)),
               root=np.empty((B, n_frames, 2)), facing=np.empty((B, n_frames, 2)),
               targets=np.empty((B, n_frames, 2)))
    per_frame = (not callable(film)) and np.ndim(film) >= 2 and np.shape(film)[0] == n_frames \
        and not (np.ndim(film) == 2 and B == n_frames)
    tf, tv = np.empty((B, 2)), np.empty((B, 2))
    for k in range(n_frames):
        t = k / fps
        for b, s in enumerate(scripts):
            tf[b], tv[b] = s.command(t, controller.state.root[b], controller.state.facing[b])
        if calibration is not None:
            tv = calibration.apply(tv, tf)
        fk = film(k) if callable(film) else (film[k] if per_frame else film)
        fr = controller.step(tf, tv, fk)
        for key in ("positions", "forward", "up", "contacts", "phases", "root", "facing", "network_positions"):
            out[key][:, k] = fr[key]
        out["targets"][:, k] = tv
        if progress is not None:
            progress(k + 1)
    rotations = axes_to_rotation(out["forward"], out["up"])
    return Rollout(out["positions"], rotations, out["contacts"], out["phases"], out["root"],
                   out["facing"], out["targets"], fps, out["network_positions"])
