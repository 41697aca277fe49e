"""Autoregressive stylised synthesis (Sec. 4.4): the network's output frame is its next input.

:meth:`Controller.step` makes one frame for every character of a batch, in the paper's order
(the original's loop: docs/original-code.md §10.2-10.4, with the §12 fixes), one method per step:

1. ``_blend_user_trajectory``: the user's command (a :mod:`minifilm.runtime.control` script) is
   blended into the future trajectory, after Zhang et al. 2018 (near samples keep the
   prediction, far samples follow the user);
2. ``build_input``: the input frame x (Sec. 3.2): 12 trajectory samples (the past from the root's
   history, the future from step 1, at the *training* sample times) and the previous frame's
   joints, all relative to the current root;
3. ``_predict``: z = Φ(x; Ω(p), film) with a precomputed FiLM vector (:class:`RuntimeNetwork`);
4. ``_read_prediction``, ``_move_root``: the joints and the future trajectory are read back into
   the world, and the root moves to the predicted next root;
5. ``_advance_phases``: p <- 0.5 p_pred + 0.5 (p + Δp_pred), the original's rule (§10.2);
6. ``_post_process``: the paper's IK post-processing gives the pose shown (foot contact IK:
   foot locking, :mod:`minifilm.motion.foot_ik`; its arm IK becomes a fit of the whole body
   onto the skeleton), and the pose fed back as the next input is chosen.

What the runtime adds to the paper's loop (standing still, heading follow, the demo's velocity
blend, held feet) is kept out of that path, in :class:`~minifilm.runtime.additions.RuntimeAdditions`,
called once at each of its named points; the run feed (:mod:`~minifilm.runtime.run_feed`) changes
only the trajectory input (``_trajectory_input``).

PAPER: departures from the paper and the authors' demo (§12): future samples at the training
spacing (+0.2 .. +1.0 s, not 1/6 s); FiLM applied from hidden unit 0; the user's speed in m/s,
mapped to the command that makes the network move at that speed by a measured per-style
calibration (:func:`~minifilm.runtime.calibration.calibrate_speed`) instead of the demo's
velocity bias of unclear units; the root moves by the full predicted delta; the demo's smoothing
of the future trajectory with the previous one (weight 0.15) is an option. A run starts from the
data's mean pose (the input means) with a still past and the mean phases, or (``start_x``,
:func:`~minifilm.runtime.start_state.start_from_dataset`) from a frame of the style's own data,
in mid-stride: a small trained network may never leave the mean pose. The skeleton fit
(``skeleton=``, :class:`~minifilm.motion.skeleton_fit.SkeletonFit`) is fed back to the network
like the demo's post-IK pose only when asked (``feed_back_fit``; foot locking then applies to
the fitted pose and is fed back with it). Without a skeleton, the next input takes the locked
positions but the predicted axes; with a skeleton not fed back, it is the network's own pose,
so neither the fit nor the locking changes the motion.

Everything reads its columns from a :class:`~minifilm.features.layout.FeatureLayout`.
"""
from __future__ import annotations

from typing import Callable, Optional, Sequence, Union

import numpy as np

from minifilm.errors import InputError
from minifilm.features.compute import trajectory_offsets
from minifilm.features.layout import CURRENT_SAMPLE, FeatureLayout
from minifilm.motion.motion import Motion
from minifilm.motion.retarget import axes_to_rotation
from minifilm.motion.skeleton_fit import SkeletonFit
from minifilm.runtime.additions import RuntimeAdditions
from minifilm.runtime.calibration import SpeedCalibration
from minifilm.runtime.control import Script, blend_future_trajectory
from minifilm.runtime.heading import HeadingFollow
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.rollout import Rollout, run_scripts
from minifilm.runtime.root_frames import to_local2, to_local3, to_world2, to_world3, unit2
from minifilm.runtime.run_feed import run_trajectory
from minifilm.runtime.standing import StandStill
from minifilm.runtime.start_state import root_joint_indices, trajectory_from_x
from minifilm.runtime.state import CharacterState, Prediction


class NonFiniteOutputError(InputError):
    """The network produced a non-finite frame: the rollout stops there instead of returning NaN."""


class Controller:
    """Frame-by-frame autoregressive synthesis for a batch of characters.

    Args:
        network: a :class:`RuntimeNetwork` (e.g. ``RuntimeNetwork.from_model(model, stats)``).
        layout: the feature layout the network was trained with.
        fps: frame rate the network was trained at (60 for 100STYLE).
        velocity_blend: weight of the predicted position against ``previous + velocity / fps``
            (original: 0.5; 1.0 = use predicted positions as they are).
        future_smoothing: weight of the previous future trajectory when reading the predicted one
            (original: 0.15; 0 = none).
        position_bias, direction_bias: exponents of the user-trajectory blend (original: 0.75, 1.25).
        foot_locker: optional :class:`minifilm.motion.foot_ik.FootLocker` applied every frame.
        skeleton: optional :class:`minifilm.motion.skeleton_fit.SkeletonFit` (e.g.
            :meth:`Controller.skeleton_for`): every frame the predicted joints are put on this
            rigid skeleton (bones swung onto the predicted positions at their rest lengths, the
            demo's arm IK for the whole body), before foot locking. The output is then a pose the
            skeleton can take (a BVH on it reproduces it exactly); the network's own positions
            stay in ``Rollout.network_positions``.
        feed_back_fit: with ``skeleton``, the next input takes the fitted (and foot-locked) pose,
            positions and axes, as the demo feeds back its post-IK pose. Default False: the network
            sees its own prediction, so the fit and the locking are pure post-processes. Fed
            back, the released network's own bone-length CV drops a little (median over its 100
            styles 5.1 % -> 4.6 %, ``benchmarks/released_styles.py``), but small models trained
            here stopped stepping more often (``benchmarks/trained_rollout.py --fit``).
        stand: what is done at a zero command so the character stops and stands
            (:class:`~minifilm.runtime.standing.StandStill`: future pinned to the root, the
            network's leftover root drift faded out, phase amplitudes decayed, then the body held:
            facing kept, feet planted by leg IK, its own velocities fed back); None: the paper's
            loop unchanged at every command (the released network then keeps walking at about
            0.4 m/s when asked to stop). While anything is asked the two are the same, bit for bit.
        heading_follow: while a movement is asked, turn each predicted frame towards the target
            facing by what the network's own turn leaves (:class:`~minifilm.runtime.heading.HeadingFollow`,
            the demo's setting: a slowly turning network otherwise never follows a heading that
            keeps turning); None: the paper's loop.

    ``skeleton``, ``feed_back_fit`` and ``foot_locker`` are plain attributes that may be changed
    between frames (the demo switches the fit and the foot locking live); so may ``run_feed``
    (B,), the weights of a perfect run in the trajectory input (:mod:`~minifilm.runtime.run_feed`,
    the demo's Shift; None: the paper's input), and ``run_feed_speed`` (m/s). ``stand``,
    ``heading_follow`` and ``velocity_blend`` are kept in ``additions``
    (:class:`~minifilm.runtime.additions.RuntimeAdditions`).
    """

    def __init__(self, network: RuntimeNetwork, layout: FeatureLayout, fps: float = 60.0,
                 velocity_blend: float = 0.5, future_smoothing: float = 0.15,
                 position_bias: float = 0.75, direction_bias: float = 1.25, foot_locker=None,
                 skeleton: Optional[SkeletonFit] = None, feed_back_fit: bool = False,
                 stand: Optional[StandStill] = StandStill(), heading_follow: Optional[HeadingFollow] = None):
        if network.x_dim != layout.x_dim or network.z_dim != layout.z_dim:
            raise ValueError(f"Controller: network sizes (x {network.x_dim}, z {network.z_dim}) do not match "
                             f"the layout (x {layout.x_dim}, z {layout.z_dim})")
        if skeleton is not None and len(skeleton.joint_indices) != layout.n_joints:
            raise ValueError(f"Controller: the skeleton fit places {len(skeleton.joint_indices)} joints, "
                             f"the layout has {layout.n_joints}")
        self.net, self.layout, self.fps = network, layout, float(fps)
        self.future_smoothing = float(future_smoothing)
        self.position_bias, self.direction_bias = position_bias, direction_bias
        self.foot_locker, self.skeleton, self.feed_back_fit = foot_locker, skeleton, bool(feed_back_fit)
        # what the runtime adds to the paper's loop, called at its points of the step
        self.additions = RuntimeAdditions(stand, heading_follow, velocity_blend, layout, self.fps)
        self.run_feed: Optional[np.ndarray] = None
        self.run_feed_speed = 8.0
        self._target = None             # the command of the frame being made: facing, velocity (B, 2)
        L = layout
        # the training features' rounding (halves away from zero), so a sample on half a frame
        # (e.g. -1/6 s at 15 fps) reads the same frame here as in the data set
        self.past_frames = -trajectory_offsets(self.fps, L.trajectory_seconds)[:CURRENT_SAMPLE]  # 60, 50, .., 10
        future = np.asarray(L.trajectory_seconds)[CURRENT_SAMPLE:]
        self.sample_dt = float(np.mean(np.diff(future)))                              # 0.2 s
        self.sample_times = np.r_[-self.past_frames / self.fps, future]             # (12,) seconds
        self.history = int(self.past_frames.max())
        self.x_traj_cols = np.stack([L.trajectory_columns("x", s) for s in range(L.n_trajectory_samples)])
        self.z_traj_cols = np.stack([L.trajectory_columns("z", s)
                                     for s in range(CURRENT_SAMPLE, L.n_trajectory_samples)])
        self.x_cols = {f: L.joint_columns("x", f) for f in ("position", "forward", "up", "velocity")}
        self.z_cols = {f: L.joint_columns("z", f) for f in ("position", "forward", "up", "velocity")}
        self.state = None

    @staticmethod
    def skeleton_for(layout: FeatureLayout, skeleton: Motion) -> SkeletonFit:
        """The ``skeleton=`` argument for a source skeleton (e.g. a BVH of the training data),
        its joints matched to the layout's by name."""
        return SkeletonFit(skeleton, root_joint_indices(layout, skeleton))

    def reset(self, start_positions: np.ndarray, start_facing: np.ndarray,
              phases: Optional[np.ndarray] = None, start_x: Optional[np.ndarray] = None) -> None:
        """Start B characters standing at (B, 2) world (x, z) positions facing (B, 2), in the mean
        pose of the training data (from the input statistics); ``phases`` (B, 8) or the mean.

        ``start_x`` (x_dim,) or (B, x_dim): raw input frames (e.g. a frame of a style's data,
        with its phases as ``phases``) whose joint block gives the start pose instead of the mean
        pose, which no style ever takes (its joints are an average of different gait cycles),
        and whose trajectory gives the past (interpolated between the samples) and future
        trajectory instead of standing still: the character starts in mid-stride, as in the data."""
        pos = np.asarray(start_positions, dtype=np.float64).reshape(-1, 2)
        face = unit2(np.asarray(start_facing, dtype=np.float64).reshape(-1, 2), np.array([0.0, 1.0]))
        B, X, S = len(pos), self.layout.x_dim, self.layout.n_future_samples
        pose = self.net.stats.x_mean if start_x is None else np.asarray(start_x, dtype=np.float64)
        if pose.shape[-1] != X or pose.ndim > 2 or (pose.ndim == 2 and len(pose) not in (1, B)):
            raise ValueError(f"Controller.reset: start_x must be ({X},) or ({B}, {X}), got {pose.shape}")
        frames = np.broadcast_to(pose.reshape(-1, X), (B, X))          # one start frame per character
        if start_x is None:             # standing still: the whole past and future at the root
            history_pos, history_dir = np.repeat(pos[:, None], self.history, 1), np.repeat(face[:, None], self.history, 1)
            future_pos, future_dir = np.repeat(pos[:, None], S, 1), np.repeat(face[:, None], S, 1)
        else:
            history_pos, history_dir, future_pos, future_dir = trajectory_from_x(
                frames[:, self.x_traj_cols], pos, face, self.past_frames, self.history)
        local = {f: frames[:, c] for f, c in self.x_cols.items()}      # (B, J, 3), the root's frame
        joint_pos = to_world3(local["position"], face)
        joint_pos[..., 0] += pos[:, 0, None]
        joint_pos[..., 2] += pos[:, 1, None]
        joint_fwd, joint_up = to_world3(local["forward"], face), to_world3(local["up"], face)
        start_phases = self.net.stats.p_mean if phases is None else np.asarray(phases, dtype=np.float64).reshape(-1, 8)
        self.state = CharacterState(
            root=pos.copy(), facing=face.copy(), history_pos=history_pos, history_dir=history_dir,
            future_pos=future_pos, future_dir=future_dir, joint_pos=joint_pos, joint_fwd=joint_fwd,
            joint_up=joint_up, joint_vel=to_world3(local["velocity"], face),
            phases=np.broadcast_to(start_phases, (B, 8)).copy(), contacts=np.zeros((B, 2)),
            network_pos=joint_pos, out_pos=joint_pos, out_fwd=joint_fwd, out_up=joint_up,
            idle_seconds=np.zeros(B), quiet_seconds=np.zeros(B), rest_seconds=np.zeros(B), feet_weight=np.zeros(B))
        if self.foot_locker is not None:
            self.foot_locker.reset(B)

    # ------------------------------------------------------------------ one frame, Sec. 4.4
    def step(self, target_facing: np.ndarray, target_velocity: np.ndarray, film: np.ndarray) -> dict:
        """Advance every character by one frame.

        Args:
            target_facing (B, 2), target_velocity (B, 2) m/s: the user's command (world x, z).
            film: (4H,) shared or (B, 4H) per character.
        Returns the new frame (see :meth:`frame`; arrays are the live state, copy to keep them).
        """
        film = self._check_command(target_facing, target_velocity, film)
        self._target = (np.asarray(target_facing, dtype=np.float64), np.asarray(target_velocity, dtype=np.float64))
        self._blend_user_trajectory()           # 1. the user's trajectory
        self.additions.before_input(self.state, *self._target)      # (standing)
        x = self.build_input()                  # 2. x (the run feed inside)
        z = self._predict(x, film)              # 3. z = Φ(x; Ω(p), film)
        self._apply_output(z)                   # 4.-6.
        return self.frame()

    def _apply_output(self, z: np.ndarray) -> None:
        """Steps 4-6: the next frame from the network's output z (B, z_dim)."""
        previous = self.state.joint_pos         # the pose this frame was made from
        prediction = self._read_prediction(z)   # 4. z in the world
        prediction = self.additions.correct(self.state, prediction, self._target)   # (standing, heading, ...)
        self._move_root(prediction)             # 4. the root moves
        self._advance_phases(z)                 # 5. the phases advance
        self._post_process(prediction)          # 6. the pose shown, the pose fed back
        self.additions.after_frame(self.state, previous)           # (standing)

    def _blend_user_trajectory(self) -> None:
        """Step 1: the command blended into the future trajectory (:func:`blend_future_trajectory`)."""
        st, (facing, velocity) = self.state, self._target
        st.future_pos, st.future_dir = blend_future_trajectory(
            st.future_pos, st.future_dir, velocity, facing, self.sample_dt, self.position_bias, self.direction_bias)

    def build_input(self) -> np.ndarray:
        """Step 2: the raw input frame x (B, x_dim) of the current state (Sec. 3.2): the trajectory
        and the joints, relative to the current root."""
        st, L = self.state, self.layout
        root, face = st.root, st.facing
        tp, td = self._trajectory_input()
        x = np.empty((len(root), L.x_dim))
        x[:, self.x_traj_cols] = np.concatenate([to_local2(tp, face[:, None]), to_local2(td, face[:, None])], axis=-1)
        rel = st.joint_pos.copy()
        rel[..., 0] -= root[:, 0, None]
        rel[..., 2] -= root[:, 1, None]
        x[:, self.x_cols["position"]] = to_local3(rel, face)
        x[:, self.x_cols["forward"]] = to_local3(st.joint_fwd, face)
        x[:, self.x_cols["up"]] = to_local3(st.joint_up, face)
        x[:, self.x_cols["velocity"]] = to_local3(st.joint_vel, face)
        return x

    def _trajectory_input(self):
        """The 12 trajectory samples of x: positions relative to the root (B, 12, 2, world axes)
        and directions (B, 12, 2); the past from the root's history, the future blended in step 1.
        With ``run_feed``, a perfect run blended in (:func:`~minifilm.runtime.run_feed.run_trajectory`)."""
        st = self.state
        tp = np.concatenate([st.history_pos[:, -self.past_frames], st.future_pos], axis=1) - st.root[:, None]
        td = np.concatenate([st.history_dir[:, -self.past_frames], st.future_dir], axis=1)
        if self.run_feed is not None and self._target is not None and np.any(self.run_feed > 0):
            tp, td = run_trajectory(tp, td, self.run_feed, self.run_feed_speed, *self._target, self.sample_times)
        return tp, td

    def _predict(self, x: np.ndarray, film: np.ndarray) -> np.ndarray:
        """Step 3: z (B, z_dim) = Φ(x; Ω(p), film), raw features (:meth:`RuntimeNetwork.predict`);
        NonFiniteOutputError at once if any is not finite (one NaN would spread to every later frame)."""
        # overflow is caught just below as one clear error, not as a screen of RuntimeWarnings
        with np.errstate(over="ignore", invalid="ignore"):
            z = self.net.predict(x, self.state.phases, film).astype(np.float64)
        if not np.all(np.isfinite(z)):
            b = int(np.argwhere(~np.isfinite(z))[0][0])
            raise NonFiniteOutputError(f"the network's output for character {b} is not finite (the motion "
                                       "diverged: its style vector or speed is far outside the training data, "
                                       "or the network's weights are corrupt)")
        return z

    def _read_prediction(self, z: np.ndarray) -> Prediction:
        """Step 4: the future trajectory and the joints of z, relative to the current root, read into
        the world; the joints as predicted are kept (``network_positions``)."""
        st, L = self.state, self.layout
        root, face = st.root, st.facing
        traj = z[:, self.z_traj_cols]                                   # (B, 6, 4), current root frame
        joints = to_world3(z[:, self.z_cols["position"]], face)
        joints[..., 0] += root[:, 0, None]
        joints[..., 2] += root[:, 1, None]
        st.network_pos = joints
        return Prediction(
            trajectory_pos=to_world2(traj[..., :2], face[:, None]) + root[:, None],
            trajectory_dir=unit2(to_world2(traj[..., 2:], face[:, None]), st.future_dir),
            joint_pos=joints, joint_fwd=to_world3(z[:, self.z_cols["forward"]], face),
            joint_up=to_world3(z[:, self.z_cols["up"]], face),
            joint_vel=to_world3(z[:, self.z_cols["velocity"]], face), contacts=z[:, L.z_contacts])

    def _move_root(self, prediction: Prediction) -> None:
        """Step 4: the root's history takes the current root, the root moves to the predicted next
        root (future sample 0), and the predicted future becomes the trajectory to blend next."""
        st, s = self.state, self.future_smoothing
        new_pos, new_dir = prediction.trajectory_pos, prediction.trajectory_dir
        st.history_pos = np.concatenate([st.history_pos[:, 1:], st.root[:, None]], axis=1)
        st.history_dir = np.concatenate([st.history_dir[:, 1:], st.facing[:, None]], axis=1)
        # PAPER: the demo's smoothing of the future with the previous one (§10.3; 0 turns it off)
        fut_pos = (1 - s) * new_pos + s * st.future_pos
        fut_dir = unit2((1 - s) * new_dir + s * st.future_dir, new_dir)
        fut_pos[:, 0], fut_dir[:, 0] = new_pos[:, 0], new_dir[:, 0]
        st.future_pos, st.future_dir = fut_pos, fut_dir
        st.root, st.facing = new_pos[:, 0].copy(), new_dir[:, 0].copy()

    def _advance_phases(self, z: np.ndarray) -> None:
        """Step 5: p <- 0.5 p_pred + 0.5 (p + Δp_pred), the original's update (§10.2), amplitude kept."""
        st, L = self.state, self.layout
        st.phases = 0.5 * z[:, L.z_phases] + 0.5 * (st.phases + z[:, L.z_phase_updates])

    def _post_process(self, prediction: Prediction) -> None:
        """Step 6: the pose shown (``out_*``) and the pose fed back as the next input (``joint_*``).

        PAPER: the paper's post-processing is foot contact IK and IK along the arms; here the arm
        IK is a fit of the whole body onto the skeleton (``skeleton``), fed back only with
        ``feed_back_fit``; foot locking (``foot_locker``) follows the predicted contacts."""
        st = self.state
        st.contacts = prediction.contacts
        pos, fwd, up = prediction.joint_pos, prediction.joint_fwd, prediction.joint_up
        if self.skeleton is not None:
            pos, rot = self.skeleton.fit(pos, axes_to_rotation(fwd, up))
            pos, rot = self.additions.refit(st, self.skeleton, pos, rot)     # (standing: held feet)
            fwd, up = rot[..., 2], rot[..., 1]
        if self.foot_locker is not None:
            pos = self.foot_locker.apply(pos, st.contacts)
        st.out_pos, st.out_fwd, st.out_up = pos, fwd, up
        if self.skeleton is not None and not self.feed_back_fit:      # the network's own pose
            pos, fwd, up = prediction.joint_pos, prediction.joint_fwd, prediction.joint_up
        st.joint_pos, st.joint_fwd, st.joint_up, st.joint_vel = pos, fwd, up, prediction.joint_vel

    def _check_command(self, target_facing, target_velocity, film) -> np.ndarray:
        """The user's command and style vector as arrays of the right shapes with finite values;
        InputError naming the argument otherwise (a public entry point: the demo calls it)."""
        B = self.state.root.shape[0]
        for name, a in (("target_facing", target_facing), ("target_velocity", target_velocity)):
            a = np.asarray(a)
            if a.shape != (B, 2) or not np.all(np.isfinite(a)):
                raise InputError(f"Controller.step: {name} must be ({B}, 2) finite numbers, got shape {a.shape}")
        D = getattr(self.net, "film_dim", None)
        if D is None:                   # a comparison variant's own conditioning (style ids, ...)
            return film
        film = np.asarray(film)
        if film.shape not in ((D,), (B, D)) or film.dtype.kind not in "fiu" or not np.all(np.isfinite(film)):
            raise InputError(f"Controller.step: film must be ({D},) or ({B}, {D}) finite numbers, got "
                             f"{film.dtype} {film.shape}")
        return film

    def frame(self) -> dict:
        """The current frame: positions (B, J, 3) and forward/up axes (B, J, 3) as output (after the
        skeleton fit and foot locking, when on), contacts, phases, root, and network_positions
        (B, J, 3): the joints exactly as the network predicted them (before any smoothing or fit)."""
        st = self.state
        return dict(positions=st.out_pos, forward=st.out_fwd, up=st.out_up, contacts=st.contacts,
                    phases=st.phases, root=st.root, facing=st.facing, network_positions=st.network_pos)

    # ------------------------------------------------------------------ whole rollouts
    def run(self, scripts: Union[Script, Sequence[Script]], n_frames: int,
            film: Union[np.ndarray, Callable[[int], np.ndarray]], phases: Optional[np.ndarray] = None,
            calibration: Optional[SpeedCalibration] = None, start_x: Optional[np.ndarray] = None,
            progress: Optional[Callable[[int], None]] = None) -> Rollout:
        """Run B = len(scripts) characters for ``n_frames`` frames, each from where its script
        starts (:func:`~minifilm.runtime.rollout.run_scripts` says what each argument may be)."""
        return run_scripts(self, scripts, n_frames, film, phases, calibration, start_x, progress)
