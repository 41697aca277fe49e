"""FROZEN REFERENCE: the Controller as it was before its step was split into the paper's steps.

This is a verbatim copy of ``minifilm/runtime/controller.py`` from before that rewrite, kept only
so that ``test_controller_refactor.py`` can run the old and the new controller side by side, in the
same process, and require the same numbers to the last bit. It is not part of the package; nothing
else imports it. Delete it (and that test) once the rewrite has settled.

The original module docstring follows.

Autoregressive stylised synthesis (Sec. 4.4; docs/original-code.md §10.2-10.4, with the §12 fixes).

Each frame, for every character of a batch:

1. the user's target (a :mod:`minifilm.runtime.control` script) is blended into the future trajectory
   (``blend_future_trajectory``: near samples keep the prediction, far samples follow the user);
2. the input frame x is built: 12 trajectory samples (past from the root history, future from
   step 1, at the *training* sample times of the layout) and the previous frame's joints, all
   re-expressed relative to the current root;
3. z = Φ(x; Ω(p), film) with precomputed FiLM vectors (:class:`RuntimeNetwork`);
4. the root moves by the predicted root delta, joints and the future trajectory are read back into
   the world, the local phases advance with ``p <- 0.5 p_pred + 0.5 (p + Δp_pred)`` (§10.2 step 7),
   and optional foot locking (:mod:`minifilm.motion.foot_ik`) post-processes the legs.

Deviations from the Unity demo (docs/original-code.md §12): future samples at the training spacing
(+0.2 .. +1.0 s, not 1/6 s), FiLM applied from hidden unit 0, user speed given in m/s and mapped
to the command that makes the network really move at that speed by a measured per-style
calibration (:func:`~minifilm.runtime.calibration.calibrate_speed`, instead of the demo's velocity bias of unclear units), the
root moves by the full predicted delta. The demo's smoothing of joint positions with the predicted
velocities (``lerp(p_prev + v dt, p, 0.5)``) and of the future trajectory with the previous one
(weight 0.15) are kept as options. A run starts from the data's mean pose (the input means) with
a still past trajectory and the mean phases, or (``start_x``, :func:`~minifilm.runtime.start_state.start_from_dataset`) from a
frame of the style's own data: pose, trajectory and phases in mid-stride; a small trained
network may never leave the mean pose. The demo's arm IK becomes an optional fit of the whole
body onto the source skeleton every frame (``skeleton=``, :class:`~minifilm.motion.skeleton_fit.SkeletonFit`):
rigid bones aimed at the predicted positions, fed back to the network like the demo's post-IK pose
only when asked (``feed_back_fit``; foot locking then applies to the fitted pose and is fed back
with it). Without a skeleton, with foot locking, the next input takes the locked positions but
the predicted forward/up axes; with a skeleton that is not fed back, the next input is the
network's own (velocity-blended) pose, so neither the fit nor the locking changes the motion.

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
from minifilm.runtime.calibration import SpeedCalibration
from minifilm.runtime.control import Script, blend_future_trajectory
from minifilm.runtime.root_frames import to_local2, to_local3, to_world2, to_world3, unit2
from minifilm.runtime.heading import HeadingFollow
from minifilm.runtime.held_body import leg_chains
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.rollout import Rollout
from minifilm.runtime.standing import StandStill
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.state import CharacterState


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
    """

    def __init__(self, network: RuntimeNetwork, layout: FeatureLayout, fps: float = 60.0,
                 velocity_blend: float = 0.5, future_smoothing: float = 0.15,
                 position_bias: float = 0.75, direction_bias: float = 1.25, foot_locker=None,
                 skeleton: Optional[SkeletonFit] = None, feed_back_fit: bool = False,
                 stand: Optional[StandStill] = StandStill(), heading_follow: Optional[HeadingFollow] = None):
        if network.x_dim != layout.x_dim or network.z_dim != layout.z_dim:
            raise ValueError(f"Controller: network sizes (x {network.x_dim}, z {network.z_dim}) do not match "
                             f"the layout (x {layout.x_dim}, z {layout.z_dim})")
        self.net, self.layout, self.fps = network, layout, float(fps)
        self.velocity_blend, self.future_smoothing = float(velocity_blend), float(future_smoothing)
        self.position_bias, self.direction_bias = position_bias, direction_bias
        self.foot_locker = foot_locker
        if skeleton is not None and len(skeleton.joint_indices) != layout.n_joints:
            raise ValueError(f"Controller: the skeleton fit places {len(skeleton.joint_indices)} joints, "
                             f"the layout has {layout.n_joints}")
        self.skeleton, self.feed_back_fit = skeleton, bool(feed_back_fit)
        self.stand = stand
        self.heading_follow = heading_follow
        self._target = None
        #: (B,) weights in [0, 1] of a perfect run fed as the trajectory input (:meth:`_run_trajectory`;
        #: the demo's Shift); None: the paper's input
        self.run_feed: Optional[np.ndarray] = None
        self.run_feed_speed = 8.0
        self.legs = leg_chains(layout.joint_names, layout.parents)     # (2, 4) or None: no legs to hold
        L = layout
        ts = np.asarray(L.trajectory_seconds)
        # the training features' rounding (halves away from zero), so a sample on half a frame
        # (e.g. -1/6 s at 15 fps) reads the same frame here as in the data set
        self.past_frames = -trajectory_offsets(self.fps, L.trajectory_seconds)[:CURRENT_SAMPLE]  # 60, 50, .., 10
        fut = ts[CURRENT_SAMPLE:]
        self.sample_dt = float(np.mean(np.diff(fut)))                              # 0.2 s
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

    # ------------------------------------------------------------------ state
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
        B, X = len(pos), self.layout.x_dim
        pose = self.net.stats.x_mean
        if start_x is not None:
            pose = np.asarray(start_x, dtype=np.float64)
            if pose.shape[-1] != X or pose.ndim > 2 or (pose.ndim == 2 and len(pose) not in (1, B)):
                raise ValueError(f"Controller.reset: start_x must be ({X},) or ({B}, {X}), got {pose.shape}")
            pose = pose[:, None] if pose.ndim == 2 else pose      # (B, 1, x) broadcasts per character
        S = self.layout.n_future_samples
        history_pos = np.repeat(pos[:, None], self.history, axis=1)      # [:, -n] = root n frames ago
        history_dir = np.repeat(face[:, None], self.history, axis=1)
        future_pos, future_dir = np.repeat(pos[:, None], S, axis=1), np.repeat(face[:, None], S, axis=1)
        if start_x is not None:
            history_pos, history_dir, future_pos, future_dir = self._trajectory_from_x(
                pos, face, np.broadcast_to(pose.reshape(-1, X), (B, X)))
        local = {f: np.broadcast_to(pose[..., c].reshape(-1, *c.shape) if pose.ndim > 1 else pose[c],
                                    (B,) + c.shape) for f, c in self.x_cols.items()}
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

    def _trajectory_from_x(self, root: np.ndarray, facing: np.ndarray, x: np.ndarray):
        """Past root history and future trajectory from raw input frames x (B, x_dim), placed at
        the characters' roots (B, 2) facing (B, 2): the future samples as they are, the history
        interpolated linearly between the past samples (directions renormalised).
        Returns history_pos, history_dir (B, N, 2), future_pos, future_dir (B, S, 2)."""
        traj = x[:, self.x_traj_cols]                                       # (B, 12, 4), root frame
        f = facing[:, None]
        wp = to_world2(traj[..., :2], f) + root[:, None]
        wd = unit2(to_world2(traj[..., 2:], f), f)
        # samples at -past_frames .. 0; history slot -n is n frames ago (n = history .. 1)
        known = np.r_[-self.past_frames, 0].astype(np.float64)
        n = -np.arange(self.history, 0, -1).astype(np.float64)
        order = np.argsort(known)
        history = []
        for src in (wp, wd):
            vals = src[:, :CURRENT_SAMPLE + 1][:, order]                      # (B, 7, 2)
            history.append(np.array([[np.interp(n, known[order], vals[b, :, c]) for c in range(2)]
                                     for b in range(len(vals))]).transpose(0, 2, 1))   # (B, history, 2)
        return (history[0], unit2(history[1], f),
                wp[:, CURRENT_SAMPLE:].copy(), wd[:, CURRENT_SAMPLE:].copy())

    # ------------------------------------------------------------------ one frame
    def build_input(self) -> np.ndarray:
        """The raw input frame x (B, x_dim) for the current state."""
        st, L = self.state, self.layout
        B = len(st.root)
        root, face = st.root, st.facing
        past_p = st.history_pos[:, -self.past_frames]                          # (B, 6, 2)
        past_d = st.history_dir[:, -self.past_frames]
        tp = np.concatenate([past_p, st.future_pos], axis=1) - root[:, None]   # (B, 12, 2)
        td = np.concatenate([past_d, st.future_dir], axis=1)
        f = face[:, None]
        if self.run_feed is not None and self._target is not None and np.any(self.run_feed > 0):
            tp, td = self._run_trajectory(tp, td)
        traj = np.concatenate([to_local2(tp, f), to_local2(td, f)], axis=-1)  # (B, 12, 4)
        x = np.empty((B, L.x_dim))
        x[:, self.x_traj_cols] = traj
        rel = st.joint_pos.copy()
        rel[..., 0] -= root[:, 0, None]
        rel[..., 2] -= root[:, 1, None]
        x[:, self.x_cols["position"]] = to_local3(rel, face)
        x[:, self.x_cols["forward"]] = to_local3(st.joint_fwd, face)
        x[:, self.x_cols["up"]] = to_local3(st.joint_up, face)
        x[:, self.x_cols["velocity"]] = to_local3(st.joint_vel, face)
        return x

    def _run_trajectory(self, tp: np.ndarray, td: np.ndarray):
        """The trajectory input (B, 12, 2) (positions relative to the root, directions) blended by
        ``run_feed`` (B,) into a perfect straight run at ``run_feed_speed`` m/s along the target
        velocity. Told only its own past (walking), the released network walks on (Neutral at most
        1.8 m/s); shown a run, it runs at the speed it learnt for the style (Neutral 2.06 m/s,
        benchmarks/run_speed.py). The state's history and future are not changed."""
        facing, velocity = self._target
        w = self.run_feed[:, None, None]
        speed = np.linalg.norm(velocity, axis=-1, keepdims=True)
        way = np.where(speed > 1e-9, velocity / np.maximum(speed, 1e-9), facing)          # (B, 2)
        times = np.r_[-self.past_frames / self.fps, np.asarray(self.layout.trajectory_seconds)[CURRENT_SAMPLE:]]
        ideal_p = way[:, None] * (self.run_feed_speed * times)[None, :, None]
        ideal_d = np.broadcast_to(facing[:, None], td.shape)
        return (1 - w) * tp + w * ideal_p, unit2((1 - w) * td + w * ideal_d, td)

    def step(self, target_facing: np.ndarray, target_velocity: np.ndarray, film: np.ndarray) -> dict:
        """Advance every character by one frame.

        Args:
            target_facing (B, 2), target_velocity (B, 2) m/s: the user's command (world x, z).
            film: (4H,) shared or (B, 4H) per character.
        Returns the new frame (see :meth:`frame`; arrays are the live state, copy to keep them).
        """
        st = self.state
        film = self._check_command(target_facing, target_velocity, film)
        st.future_pos, st.future_dir = blend_future_trajectory(
            st.future_pos, st.future_dir, target_velocity, target_facing, self.sample_dt,
            self.position_bias, self.direction_bias)
        idle = None
        if self.stand is not None:      # standing.py: a zero command stops and stands
            idle = self.stand.begin_frame(st, target_velocity, target_facing, 1.0 / self.fps)
        self._target = (np.asarray(target_facing, dtype=np.float64), np.asarray(target_velocity, dtype=np.float64))
        x = self.build_input()
        # overflow is caught just below as one clear error, not as a screen of RuntimeWarnings
        with np.errstate(over="ignore", invalid="ignore"):
            z = self.net.predict(x, st.phases, film).astype(np.float64)
        if not np.all(np.isfinite(z)):      # stop at once: one NaN would spread to every later frame
            b = int(np.argwhere(~np.isfinite(z))[0][0])
            raise NonFiniteOutputError(f"the network's output for character {b} is not finite (the motion "
                                       "diverged: its style vector or speed is far outside the training data, "
                                       "or the network's weights are corrupt)")
        self._apply_output(z, idle)
        return self.frame()

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

    def _apply_output(self, z: np.ndarray, idle: Optional[np.ndarray] = None) -> None:
        st, L = self.state, self.layout
        root, face = st.root, st.facing
        f = face[:, None]
        traj = z[:, self.z_traj_cols]                                   # (B, 6, 4), current root frame
        new_pos = to_world2(traj[..., :2], f) + root[:, None]
        new_dir = unit2(to_world2(traj[..., 2:], f), st.future_dir)
        # joints of the next frame, read relative to the current root
        jpos = to_world3(z[:, self.z_cols["position"]], face)
        jpos[..., 0] += root[:, 0, None]
        jpos[..., 2] += root[:, 1, None]
        jvel = to_world3(z[:, self.z_cols["velocity"]], face)
        st.network_pos = jpos
        jfwd = to_world3(z[:, self.z_cols["forward"]], face)
        jup = to_world3(z[:, self.z_cols["up"]], face)
        if idle is not None:
            # standing.py: at a zero command the root's leftover drift fades out, and once idle its
            # turning too; the predicted body and trajectory are moved back with the root
            new_pos, new_dir, jpos, (jfwd, jup, jvel) = self.stand.hold_prediction(
                st, new_pos, new_dir, jpos, (jfwd, jup, jvel))
        if self.heading_follow is not None and self._target is not None:     # heading.py: the body follows the heading
            facing_target, velocity_target = self._target
            moving = np.linalg.norm(velocity_target, axis=-1) > 1e-6
            new_pos, new_dir, jpos, (jfwd, jup, jvel) = self.heading_follow.apply(
                facing_target, moving, new_pos, new_dir, jpos, (jfwd, jup, jvel), 1.0 / self.fps)
        if self.velocity_blend < 1.0:
            integrated = st.joint_pos + jvel / self.fps
            jpos = self.velocity_blend * jpos + (1 - self.velocity_blend) * integrated
        holding = idle is not None and self.stand.holds_feet(st, self.legs)
        if holding:     # standing.py: the feet kept where they came to rest, before the fit and feedback
            jpos = self.stand.plant(st, jpos, self.legs, 1.0 / self.fps)
        else:
            st.feet = None
        st.joint_vel = jvel
        # phases: average of the predicted phase and previous + predicted update (§10.2 step 7)
        st.phases = 0.5 * z[:, L.z_phases] + 0.5 * (st.phases + z[:, L.z_phase_updates])
        if idle is not None:            # standing: the amplitudes decay towards a still body's
            st.phases = st.phases * self.stand.phase_factor(idle, 1.0 / self.fps)[:, None]
            st.phases = self.stand.idle_phases(st.phases, st.rest_seconds)   # held: a slow sway, not a statue
        st.contacts = z[:, L.z_contacts]
        # root history, then move the root by the predicted delta (future sample 0 of the next frame)
        st.history_pos = np.concatenate([st.history_pos[:, 1:], root[:, None]], axis=1)
        st.history_dir = np.concatenate([st.history_dir[:, 1:], face[:, None]], axis=1)
        s = self.future_smoothing
        fut_pos = (1 - s) * new_pos + s * st.future_pos
        fut_dir = unit2((1 - s) * new_dir + s * st.future_dir, new_dir)
        fut_pos[:, 0], fut_dir[:, 0] = new_pos[:, 0], new_dir[:, 0]
        st.future_pos, st.future_dir = fut_pos, fut_dir
        st.root, st.facing = new_pos[:, 0].copy(), new_dir[:, 0].copy()
        blended = jpos
        if self.skeleton is not None:
            fit_pos, fit_rot = self.skeleton.fit(jpos, axes_to_rotation(jfwd, jup))
            if holding:
                fit_pos, fit_rot = self.stand.refit(st, self.skeleton, fit_pos, fit_rot, self.legs)
            st.out_fwd, st.out_up = fit_rot[..., 2], fit_rot[..., 1]
            jpos = fit_pos
        else:
            st.out_fwd, st.out_up = jfwd, jup
        if self.foot_locker is not None:
            jpos = self.foot_locker.apply(jpos, st.contacts)
        st.out_pos = jpos
        previous = st.joint_pos
        if self.skeleton is None or self.feed_back_fit:
            st.joint_pos, st.joint_fwd, st.joint_up = jpos, st.out_fwd, st.out_up
        else:
            st.joint_pos, st.joint_fwd, st.joint_up = blended, jfwd, jup
        if idle is not None:            # standing.py: a held body's own velocities and contacts
            self.stand.settle_feedback(st, previous, self.fps)

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
            calibration: Optional[SpeedCalibration] = None, start_x: Optional[np.ndarray] = None) -> Rollout:
        """Run B = len(scripts) characters for ``n_frames`` frames.

        Args:
            scripts: one :class:`~minifilm.runtime.control.Script` per character (or one for B = 1); each
                starts where its ``start()`` says.
            film: (4H,) or (B, 4H) for all frames, (n_frames, 4H) / (n_frames, B, 4H) per frame
                (style transitions), or a callable frame -> film.
            calibration: maps the user's speed (m/s) to the command that makes this network
                actually move at that speed (see :func:`~minifilm.runtime.calibration.calibrate_speed`); None = use as given.
            phases, start_x: the start phases (B, 8) and pose (raw input frames), see :meth:`reset`.
        """
        if isinstance(scripts, Script):
            scripts = [scripts]
        B = len(scripts)
        for s in scripts:
            s.reset()
        starts = [s.start() for s in scripts]
        self.reset(np.array([p for p, _ in starts]), np.array([f for _, f in starts]), phases, start_x)
        J = self.layout.n_joints
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
            t = k / self.fps
            for b, s in enumerate(scripts):
                tf[b], tv[b] = s.command(t, self.state.root[b], self.state.facing[b])
            if calibration is not None:
                tv = calibration.apply(tv, tf)
            fk = film(k) if callable(film) else (film[k] if per_frame else film)
            fr = self.step(tf, tv, fk)
            for key in ("positions", "forward", "up", "contacts", "phases", "root", "facing", "network_positions"):
                out[key][:, k] = fr[key]
            out["targets"][:, k] = tv
        rotations = axes_to_rotation(out["forward"], out["up"])
        return Rollout(out["positions"], rotations, out["contacts"], out["phases"], out["root"],
                       out["facing"], out["targets"], self.fps, out["network_positions"])
