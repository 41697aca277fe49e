"""Autoregressive stylised synthesis (Sec. 4.4; original-pipeline §10.2-10.4, with the §12 fixes).

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

Deviations from the Unity demo (original-pipeline §12): future samples at the training spacing
(+0.2 .. +1.0 s, not 1/6 s), FiLM applied from hidden unit 0, user speed given in m/s and mapped
to the command that makes the network really move at that speed by a measured per-style
calibration (:func:`calibrate_speed`, instead of the demo's velocity bias of unclear units), the
root moves by the full predicted delta. The demo's smoothing of joint positions with the predicted
velocities (``lerp(p_prev + v dt, p, 0.5)``) and of the future trajectory with the previous one
(weight 0.15) are kept as options. A run starts from the data's mean pose (the input means) with
a still past trajectory and the mean phases, or (``start_x``, :func:`start_from_dataset`) from a
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

from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, Union

import numpy as np

from minifilm.runtime.control import Script, blend_future_trajectory
from minifilm.model.motion_net import split_film
from minifilm.features.compute import trajectory_offsets
from minifilm.features.layout import CURRENT_SAMPLE, FeatureLayout
from minifilm.motion.motion import Motion
from minifilm.motion.retarget import axes_to_rotation, retarget
from minifilm.motion.skeleton_fit import SkeletonFit
from minifilm.nn import functional as F

__all__ = ["RuntimeStats", "RuntimeNetwork", "Controller", "Rollout", "root_joint_indices",
           "SpeedCalibration", "PerCharacterCalibration", "calibrate_speed", "start_from_dataset"]


# =============================================================================== network

@dataclass
class RuntimeStats:
    """Normalisation statistics: x = (X - x_mean) / x_std, p likewise, Z = z * z_std + z_mean."""

    x_mean: np.ndarray
    x_std: np.ndarray
    p_mean: np.ndarray
    p_std: np.ndarray
    z_mean: np.ndarray
    z_std: np.ndarray

    def __post_init__(self):
        for name in ("x_mean", "x_std", "p_mean", "p_std", "z_mean", "z_std"):
            v = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1)
            if not np.all(np.isfinite(v)):
                raise ValueError(f"RuntimeStats.{name} has non-finite values")
            if name.endswith("std") and np.any(v <= 0):
                raise ValueError(f"RuntimeStats.{name} has entries <= 0 (at {np.flatnonzero(v <= 0)[:5]})")
            setattr(self, name, v)

    @classmethod
    def from_any(cls, obj) -> "RuntimeStats":
        """From a RuntimeStats, a mapping or an object with the six fields (x_mean, x_std, ...)."""
        if isinstance(obj, cls):
            return obj
        get = obj.__getitem__ if isinstance(obj, dict) else lambda k: getattr(obj, k)
        try:
            return cls(*(get(k) for k in ("x_mean", "x_std", "p_mean", "p_std", "z_mean", "z_std")))
        except (KeyError, AttributeError) as e:
            raise ValueError(f"normalisation statistics need x_mean, x_std, p_mean, p_std, z_mean, "
                             f"z_std; missing {e}") from None


class RuntimeNetwork:
    """Ω and Φ for inference only, laid out for speed (Eq. 3-4).

    Each expert layer is stored as one matrix ``(I, K*O)`` (the K experts side by side), so a
    frame costs one matrix product per layer, ``y = Σ_k α_k (h W_k + b_k)``; at batch 1 this reads
    each weight once and is faster here than blending the weights first (same result; see
    ``benchmarks/runtime.py``). The FiLM vector (4H,) or (B, 4H) is given per call.

    Args:
        gating: [(W (in, out), b (out,))] * 3 of Ω (ELU, ELU, softmax).
        experts: [(W (K, in, out), b (K, out))] * 3 of Φ.
        stats: normalisation statistics (:class:`RuntimeStats` or anything ``from_any`` takes).
        ln_unbiased, ln_eps: layer-norm convention (released runtime: False, 0.0).
        dtype: computation dtype (float32 for speed).
    """

    def __init__(self, gating, experts, stats, ln_unbiased: bool = False, ln_eps: float = 0.0,
                 dtype=np.float32):
        self.dtype = np.dtype(dtype)
        self.stats = RuntimeStats.from_any(stats)
        self.gating = [(np.asarray(W, self.dtype), np.asarray(b, self.dtype)) for W, b in gating]
        if len(self.gating) != 3 or len(experts) != 3:
            raise ValueError(f"RuntimeNetwork: need 3 gating and 3 expert layers, got {len(self.gating)} and {len(experts)}")
        self.K = int(np.asarray(experts[0][0]).shape[0])
        self.layers = []
        for l, (W, b) in enumerate(experts):
            W = np.asarray(W, self.dtype)
            K, I, O = W.shape
            if K != self.K or np.shape(b) != (K, O):
                raise ValueError(f"RuntimeNetwork: expert layer {l} has W {W.shape}, b {np.shape(b)}; "
                                 f"expected ({self.K}, in, out) and ({self.K}, out)")
            self.layers.append((np.ascontiguousarray(W.transpose(1, 0, 2).reshape(I, K * O)),
                                np.asarray(b, self.dtype), O))
        self.x_dim = self.layers[0][0].shape[0]
        self.z_dim = self.layers[2][2]
        self.hidden = self.layers[0][2]
        self.ln_unbiased, self.ln_eps = bool(ln_unbiased), float(ln_eps)
        s = self.stats
        if (len(s.x_mean), len(s.z_mean), len(s.p_mean)) != (self.x_dim, self.z_dim, self.gating[0][0].shape[0]):
            raise ValueError(f"RuntimeNetwork: statistics sizes x {len(s.x_mean)}, z {len(s.z_mean)}, "
                             f"p {len(s.p_mean)} do not match the network ({self.x_dim}, {self.z_dim}, "
                             f"{self.gating[0][0].shape[0]})")
        c = lambda v: v.astype(self.dtype)
        self._x_mean, self._x_inv = c(s.x_mean), c(1.0 / s.x_std)
        self._p_mean, self._p_inv = c(s.p_mean), c(1.0 / s.p_std)
        self._z_mean, self._z_std = c(s.z_mean), c(s.z_std)

    @classmethod
    def from_model(cls, model, stats, runtime_layer_norm: bool = False, dtype=np.float32) -> "RuntimeNetwork":
        """From a :class:`minifilm.model.style_model.StyleModel` (its Ω and Φ; Ψ is not needed).

        ``runtime_layer_norm`` picks the released runtime's layer norm (biased σ, no eps) instead
        of the model's training convention.
        """
        g, m = model.gating.params.params, model.motion.params.params
        gating = [(g[f"W{l}"], g[f"b{l}"]) for l in range(3)]
        experts = [(m[f"W{l}"], m[f"b{l}"]) for l in range(3)]
        if runtime_layer_norm:
            unbiased, eps = False, 0.0
        else:
            unbiased, eps = model.config.ln_unbiased, model.config.ln_eps
        return cls(gating, experts, stats, unbiased, eps, dtype)

    def gate(self, p_raw: np.ndarray) -> np.ndarray:
        """Ω: raw phases (B, 8) -> expert weights α (B, K)."""
        h = (np.asarray(p_raw, self.dtype) - self._p_mean) * self._p_inv
        for l, (W, b) in enumerate(self.gating):
            h = h @ W + b
            if l < 2:
                h = F.elu_forward(h)[0]
        return F.softmax_forward(h)[0]

    def predict(self, x_raw: np.ndarray, p_raw: np.ndarray, film: np.ndarray) -> np.ndarray:
        """Raw (de-normalised) output Z (B, z_dim) from raw x (B, x_dim), raw p (B, 8), film (4H,) or (B, 4H)."""
        alpha = self.gate(p_raw)                                      # (B, K)
        B = alpha.shape[0]
        h = (np.asarray(x_raw, self.dtype) - self._x_mean) * self._x_inv
        film = np.asarray(film, self.dtype)
        films = split_film(film, self.hidden)
        for l, (Wc, b, O) in enumerate(self.layers):
            if 1 < B < 5:   # BLAS is slower on a skinny matrix product than on a few vector products
                y = np.stack([row @ Wc for row in h]).reshape(B, self.K, O)
            else:
                y = (h @ Wc).reshape(B, self.K, O)                    # every expert's output
            h = np.matmul(alpha[:, None, :], y)[:, 0] + alpha @ b     # Σ_k α_k (h W_k + b_k)
            if l < 2:
                h = F.layer_norm_forward(h, unbiased=self.ln_unbiased, eps=self.ln_eps)[0]
                gamma, beta = films[l]
                h = F.elu_forward(gamma * h + beta)[0]                 # Eq. (3)
        return h * self._z_std + self._z_mean


# =============================================================================== rollout state

def _to_local2(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """World (x, z) vectors (..., 2) into the frame of a root facing f (..., 2): R^T v."""
    out = np.empty(np.broadcast_shapes(v.shape, f.shape))   # filled in place: np.stack costs more per frame
    out[..., 0] = f[..., 1] * v[..., 0] - f[..., 0] * v[..., 1]
    out[..., 1] = f[..., 0] * v[..., 0] + f[..., 1] * v[..., 1]
    return out


def _to_world2(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_to_local2`: R v for R = LookRotation(f)."""
    out = np.empty(np.broadcast_shapes(v.shape, f.shape))
    out[..., 0] = f[..., 1] * v[..., 0] + f[..., 0] * v[..., 1]
    out[..., 1] = -f[..., 0] * v[..., 0] + f[..., 1] * v[..., 1]
    return out


def _to_local3(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """World 3-vectors (B, J, 3) into root frames facing f (B, 2): R^T v (y unchanged)."""
    fx, fz = f[:, 0, None], f[:, 1, None]
    out = np.empty(np.broadcast_shapes(v.shape, (len(f), 1, 3)))
    out[..., 0] = fz * v[..., 0] - fx * v[..., 2]
    out[..., 1] = v[..., 1]
    out[..., 2] = fx * v[..., 0] + fz * v[..., 2]
    return out


def _to_world3(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_to_local3`."""
    fx, fz = f[:, 0, None], f[:, 1, None]
    out = np.empty(np.broadcast_shapes(v.shape, (len(f), 1, 3)))
    out[..., 0] = fz * v[..., 0] + fx * v[..., 2]
    out[..., 1] = v[..., 1]
    out[..., 2] = -fx * v[..., 0] + fz * v[..., 2]
    return out


def _unit2(v: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 1e-8, v / np.maximum(n, 1e-8), fallback)


@dataclass
class Rollout:
    """The result of :meth:`Controller.run` for B characters and F frames.

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
        """Per character: the checks of the issue, after ``warmup_seconds`` (the start pose is the
        data's mean pose). Keys: bone_cv_max (coefficient of variation of the worst bone, output
        positions), network_bone_cv_max (the same for the network's own positions),
        hips_min / hips_max (m, joint 0 height), speed (mean root speed, m/s), and when given,
        path_mean / path_max (m, root distance to the polyline ``path`` (N, 2)) and foot_sliding
        (m/s, toes = joint index per contact column)."""
        from minifilm.runtime.control import distance_to_path
        from minifilm.evaluation.metrics import bone_length_cv
        from minifilm.motion.foot_ik import foot_sliding

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


def root_joint_indices(layout: FeatureLayout, skeleton: Motion) -> np.ndarray:
    """Index into ``skeleton`` joints of each exported joint of ``layout``, matched by name;
    ValueError naming every missing joint when the skeleton is not the layout's."""
    missing = [n for n in layout.joint_names if n not in skeleton.names]
    if missing:
        raise ValueError(f"{skeleton.source}: the skeleton lacks {len(missing)} of the network's "
                         f"{layout.n_joints} joints ({missing}); its joints are {skeleton.names}")
    return np.array([skeleton.index(n) for n in layout.joint_names], dtype=np.int64)


def start_from_dataset(dataset, style: str, gait: str = "FW", split: str = "train"):
    """A start state for :meth:`Controller.run` taken from a style's own data: the raw input frame
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
    """

    def __init__(self, network: RuntimeNetwork, layout: FeatureLayout, fps: float = 60.0,
                 velocity_blend: float = 0.5, future_smoothing: float = 0.15,
                 position_bias: float = 0.75, direction_bias: float = 1.25, foot_locker=None,
                 skeleton: Optional[SkeletonFit] = None, feed_back_fit: bool = False):
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
        face = _unit2(np.asarray(start_facing, dtype=np.float64).reshape(-1, 2), np.array([0.0, 1.0]))
        B = len(pos)
        mean = self.net.stats.x_mean
        if start_x is not None:
            mean = np.asarray(start_x, dtype=np.float64)
            if mean.shape[-1] != self.layout.x_dim or mean.ndim > 2 or (mean.ndim == 2 and len(mean) not in (1, B)):
                raise ValueError(f"Controller.reset: start_x must be ({self.layout.x_dim},) or ({B}, "
                                 f"{self.layout.x_dim}), got {mean.shape}")
            mean = mean[:, None] if mean.ndim == 2 else mean      # (B, 1, x) broadcasts per character
        st = dict(root=pos.copy(), facing=face.copy())
        st["hist_pos"] = np.repeat(pos[:, None], self.history, axis=1)      # [:, -n] = root n frames ago
        st["hist_dir"] = np.repeat(face[:, None], self.history, axis=1)
        S = self.layout.n_future_samples
        st["fut_pos"] = np.repeat(pos[:, None], S, axis=1)
        st["fut_dir"] = np.repeat(face[:, None], S, axis=1)
        if start_x is not None:
            self._trajectory_from_x(st, np.broadcast_to(mean.reshape(-1, self.layout.x_dim), (B, self.layout.x_dim)))
        local = {f: np.broadcast_to(mean[..., c].reshape(-1, *c.shape) if mean.ndim > 1 else mean[c],
                                    (B,) + c.shape) for f, c in self.x_cols.items()}
        st["jpos"] = _to_world3(local["position"], face)
        st["jpos"][..., 0] += pos[:, 0, None]
        st["jpos"][..., 2] += pos[:, 1, None]
        for f, key in (("forward", "jfwd"), ("up", "jup"), ("velocity", "jvel")):
            st[key] = _to_world3(local[f], face)
        st["phase"] = (np.broadcast_to(self.net.stats.p_mean, (B, 8)).copy() if phases is None
                       else np.broadcast_to(np.asarray(phases, dtype=np.float64).reshape(-1, 8), (B, 8)).copy())
        st["contacts"] = np.zeros((B, 2))
        st["network_jpos"], st["out_pos"], st["out_fwd"], st["out_up"] = st["jpos"], st["jpos"], st["jfwd"], st["jup"]
        self.state = st
        if self.foot_locker is not None:
            self.foot_locker.reset(B)

    def _trajectory_from_x(self, st: dict, x: np.ndarray) -> None:
        """Past root history and future trajectory from raw input frames x (B, x_dim), placed at
        the characters' roots: the future samples as they are, the history interpolated linearly
        between the past samples (directions renormalised)."""
        traj = x[:, self.x_traj_cols]                                       # (B, 12, 4), root frame
        f = st["facing"][:, None]
        wp = _to_world2(traj[..., :2], f) + st["root"][:, None]
        wd = _unit2(_to_world2(traj[..., 2:], f), f)
        st["fut_pos"], st["fut_dir"] = wp[:, CURRENT_SAMPLE:].copy(), wd[:, CURRENT_SAMPLE:].copy()
        # samples at -past_frames .. 0; history slot -n is n frames ago (n = history .. 1)
        known = np.r_[-self.past_frames, 0].astype(np.float64)
        n = -np.arange(self.history, 0, -1).astype(np.float64)
        order = np.argsort(known)
        for key, src in (("hist_pos", wp), ("hist_dir", wd)):
            vals = src[:, :CURRENT_SAMPLE + 1][:, order]                      # (B, 7, 2)
            out = np.array([[np.interp(n, known[order], vals[b, :, c]) for c in range(2)]
                            for b in range(len(vals))]).transpose(0, 2, 1)     # (B, history, 2)
            st[key] = out if key == "hist_pos" else _unit2(out, st["facing"][:, None])

    # ------------------------------------------------------------------ one frame
    def build_input(self) -> np.ndarray:
        """The raw input frame x (B, x_dim) for the current state."""
        st, L = self.state, self.layout
        B = len(st["root"])
        root, face = st["root"], st["facing"]
        past_p = st["hist_pos"][:, -self.past_frames]                          # (B, 6, 2)
        past_d = st["hist_dir"][:, -self.past_frames]
        tp = np.concatenate([past_p, st["fut_pos"]], axis=1) - root[:, None]   # (B, 12, 2)
        td = np.concatenate([past_d, st["fut_dir"]], axis=1)
        f = face[:, None]
        traj = np.concatenate([_to_local2(tp, f), _to_local2(td, f)], axis=-1)  # (B, 12, 4)
        x = np.empty((B, L.x_dim))
        x[:, self.x_traj_cols] = traj
        rel = st["jpos"].copy()
        rel[..., 0] -= root[:, 0, None]
        rel[..., 2] -= root[:, 1, None]
        x[:, self.x_cols["position"]] = _to_local3(rel, face)
        x[:, self.x_cols["forward"]] = _to_local3(st["jfwd"], face)
        x[:, self.x_cols["up"]] = _to_local3(st["jup"], face)
        x[:, self.x_cols["velocity"]] = _to_local3(st["jvel"], face)
        return x

    def step(self, target_facing: np.ndarray, target_velocity: np.ndarray, film: np.ndarray) -> dict:
        """Advance every character by one frame.

        Args:
            target_facing (B, 2), target_velocity (B, 2) m/s: the user's command (world x, z).
            film: (4H,) shared or (B, 4H) per character.
        Returns the new frame (see :meth:`frame`; arrays are the live state, copy to keep them).
        """
        st = self.state
        st["fut_pos"], st["fut_dir"] = blend_future_trajectory(
            st["fut_pos"], st["fut_dir"], target_velocity, target_facing, self.sample_dt,
            self.position_bias, self.direction_bias)
        x = self.build_input()
        z = self.net.predict(x, st["phase"], film).astype(np.float64)
        self._apply_output(z)
        return self.frame()

    def _apply_output(self, z: np.ndarray) -> None:
        st, L = self.state, self.layout
        root, face = st["root"], st["facing"]
        f = face[:, None]
        traj = z[:, self.z_traj_cols]                                   # (B, 6, 4), current root frame
        new_pos = _to_world2(traj[..., :2], f) + root[:, None]
        new_dir = _unit2(_to_world2(traj[..., 2:], f), st["fut_dir"])
        # joints of the next frame, read relative to the current root
        jpos = _to_world3(z[:, self.z_cols["position"]], face)
        jpos[..., 0] += root[:, 0, None]
        jpos[..., 2] += root[:, 1, None]
        jvel = _to_world3(z[:, self.z_cols["velocity"]], face)
        st["network_jpos"] = jpos
        if self.velocity_blend < 1.0:
            integrated = st["jpos"] + jvel / self.fps
            jpos = self.velocity_blend * jpos + (1 - self.velocity_blend) * integrated
        jfwd = _to_world3(z[:, self.z_cols["forward"]], face)
        jup = _to_world3(z[:, self.z_cols["up"]], face)
        st["jvel"] = jvel
        # phases: average of the predicted phase and previous + predicted update (§10.2 step 7)
        st["phase"] = 0.5 * z[:, L.z_phases] + 0.5 * (st["phase"] + z[:, L.z_phase_updates])
        st["contacts"] = z[:, L.z_contacts]
        # root history, then move the root by the predicted delta (future sample 0 of the next frame)
        st["hist_pos"] = np.concatenate([st["hist_pos"][:, 1:], root[:, None]], axis=1)
        st["hist_dir"] = np.concatenate([st["hist_dir"][:, 1:], face[:, None]], axis=1)
        s = self.future_smoothing
        fut_pos = (1 - s) * new_pos + s * st["fut_pos"]
        fut_dir = _unit2((1 - s) * new_dir + s * st["fut_dir"], new_dir)
        fut_pos[:, 0], fut_dir[:, 0] = new_pos[:, 0], new_dir[:, 0]
        st["fut_pos"], st["fut_dir"] = fut_pos, fut_dir
        st["root"], st["facing"] = new_pos[:, 0].copy(), new_dir[:, 0].copy()
        blended = jpos
        if self.skeleton is not None:
            fit_pos, fit_rot = self.skeleton.fit(jpos, axes_to_rotation(jfwd, jup))
            st["out_fwd"], st["out_up"] = fit_rot[..., 2], fit_rot[..., 1]
            jpos = fit_pos
        else:
            st["out_fwd"], st["out_up"] = jfwd, jup
        if self.foot_locker is not None:
            jpos = self.foot_locker.apply(jpos, st["contacts"])
        st["out_pos"] = jpos
        if self.skeleton is None or self.feed_back_fit:
            st["jpos"], st["jfwd"], st["jup"] = jpos, st["out_fwd"], st["out_up"]
        else:
            st["jpos"], st["jfwd"], st["jup"] = blended, jfwd, jup

    def frame(self) -> dict:
        """The current frame: positions (B, J, 3) and forward/up axes (B, J, 3) as output (after the
        skeleton fit and foot locking, when on), contacts, phases, root, and network_positions
        (B, J, 3): the joints exactly as the network predicted them (before any smoothing or fit)."""
        st = self.state
        return dict(positions=st["out_pos"], forward=st["out_fwd"], up=st["out_up"], contacts=st["contacts"],
                    phases=st["phase"], root=st["root"], facing=st["facing"], network_positions=st["network_jpos"])

    # ------------------------------------------------------------------ whole rollouts
    def run(self, scripts: Union[Script, Sequence[Script]], n_frames: int,
            film: Union[np.ndarray, Callable[[int], np.ndarray]], phases: Optional[np.ndarray] = None,
            calibration: Optional["SpeedCalibration"] = None, start_x: Optional[np.ndarray] = None) -> Rollout:
        """Run B = len(scripts) characters for ``n_frames`` frames.

        Args:
            scripts: one :class:`~minifilm.runtime.control.Script` per character (or one for B = 1); each
                starts where its ``start()`` says.
            film: (4H,) or (B, 4H) for all frames, (n_frames, 4H) / (n_frames, B, 4H) per frame
                (style transitions), or a callable frame -> film.
            calibration: maps the user's speed (m/s) to the command that makes this network
                actually move at that speed (see :func:`calibrate_speed`); None = use as given.
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
                tf[b], tv[b] = s.command(t, self.state["root"][b], self.state["facing"][b])
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


# =============================================================================== speed calibration

@dataclass
class SpeedCalibration:
    """Measured steady-state root speed (m/s) for each commanded speed (m/s), for one style, per
    direction of travel relative to the facing (degrees: 0 forwards, 90 sideways, 180 backwards;
    left and right are taken as symmetric).

    The network follows the user's trajectory only partly (near future samples keep its own
    prediction, §10.4), so commanding v gives a slower walk. The original demo hid this behind a
    per-style "velocity bias" of unclear units (original-pipeline §12 item 16); here the map is
    measured (:func:`calibrate_speed`) and inverted by linear interpolation (in speed, then in
    direction).

    commanded (N,); achieved (N,) or (D, N); directions (D,) degrees in [0, 180].
    """

    commanded: np.ndarray
    achieved: np.ndarray
    directions: Sequence[float] = (0.0,)

    def __post_init__(self):
        c = np.asarray(self.commanded, dtype=np.float64)
        a = np.atleast_2d(np.asarray(self.achieved, dtype=np.float64))
        d = np.asarray(self.directions, dtype=np.float64).reshape(-1)
        if a.shape != (len(d), len(c)):
            raise ValueError(f"SpeedCalibration: achieved has shape {a.shape}, expected "
                             f"({len(d)} directions, {len(c)} commands)")
        order, dorder = np.argsort(c), np.argsort(d)
        a = np.maximum.accumulate(a[dorder][:, order], axis=1)     # monotone in the command
        self.commanded = np.r_[0.0, c[order]]
        self.achieved = np.concatenate([np.zeros((len(d), 1)), a], axis=1)
        self.directions = d[dorder]

    def command_for(self, speed, direction=0.0) -> np.ndarray:
        """Commanded speed that achieves ``speed`` when moving at ``direction`` degrees from the
        facing (clamped to the largest calibrated command)."""
        speed = np.asarray(speed, dtype=np.float64)
        ramp = 1e-9 * np.arange(self.achieved.shape[1])          # strictly increasing for interp
        per_dir = np.stack([np.interp(speed, a + ramp, self.commanded) for a in self.achieved])
        if len(self.directions) == 1:
            return per_dir[0]
        ang = np.clip(np.abs(np.asarray(direction, dtype=np.float64)), 0.0, 180.0)
        ang = np.broadcast_to(ang, speed.shape)
        i = np.clip(np.searchsorted(self.directions, ang, side="right") - 1, 0, len(self.directions) - 2)
        d0, d1 = self.directions[i], self.directions[i + 1]
        t = np.clip((ang - d0) / np.maximum(d1 - d0, 1e-9), 0.0, 1.0)
        c0 = np.take_along_axis(per_dir, i[None], axis=0)[0]
        c1 = np.take_along_axis(per_dir, (i + 1)[None], axis=0)[0]
        return (1 - t) * c0 + t * c1

    def apply(self, velocity: np.ndarray, facing: Optional[np.ndarray] = None) -> np.ndarray:
        """Rescale velocities (..., 2) so their magnitude is the calibrated command; the direction
        of travel is measured against ``facing`` (..., 2) (forwards if not given)."""
        v = np.asarray(velocity, dtype=np.float64)
        n = np.linalg.norm(v, axis=-1)
        direction = 0.0
        if facing is not None:
            f = np.asarray(facing, dtype=np.float64)
            cos = np.sum(v * f, axis=-1) / np.maximum(n * np.linalg.norm(f, axis=-1), 1e-9)
            direction = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        scale = self.command_for(n, direction) / np.maximum(n, 1e-9)
        return np.where((n > 1e-9)[..., None], v * scale[..., None], 0.0)


class PerCharacterCalibration:
    """One :class:`SpeedCalibration` per character of a batch (e.g. one per style), usable as
    ``Controller.run(..., calibration=)``."""

    def __init__(self, calibrations: Sequence[SpeedCalibration]):
        self.calibrations = list(calibrations)

    def apply(self, velocity: np.ndarray, facing: Optional[np.ndarray] = None) -> np.ndarray:
        """velocity, facing (B, 2) -> (B, 2), character b through calibration b."""
        v = np.asarray(velocity, dtype=np.float64)
        if v.ndim != 2 or len(v) != len(self.calibrations):
            raise ValueError(f"PerCharacterCalibration: velocity {v.shape} must be ({len(self.calibrations)}, 2)")
        return np.stack([c.apply(v[b], None if facing is None else facing[b])
                         for b, c in enumerate(self.calibrations)])


def calibrate_speed(controller: Controller, film: np.ndarray,
                    commands: Sequence[float] = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0),
                    directions: Sequence[float] = (0.0, 90.0, 180.0),
                    seconds: float = 8.0, settle: float = 4.0, phases: Optional[np.ndarray] = None,
                    start_x: Optional[np.ndarray] = None) -> SpeedCalibration:
    """Move at each commanded speed in each direction (degrees from the facing: 0 forwards, 90
    sideways, 180 backwards), all at once as one batch, and measure the mean root speed after
    ``settle`` seconds. ``film`` is the style (4H,); ``phases`` (8,) and ``start_x`` (x_dim,)
    the start state (see :meth:`Controller.reset`; default the data's means).

    Made for the released network. A small network trained on little data may move at its data's
    speeds only (a walk and a run, nothing between), so the calibration asks for commands far
    outside its data; in ``benchmarks/trained_rollout.py`` that made the train_small model's
    bones stretch (CV up to 69 %) and its path error grow, so check before using it there."""
    from minifilm.runtime.control import CommandScript

    n = int(round(seconds * controller.fps))
    k0 = int(round(settle * controller.fps))
    if k0 >= n - 1:
        raise ValueError(f"calibrate_speed: settle ({settle} s) must be shorter than seconds ({seconds} s)")
    scripts = [CommandScript([(0.0, float(v), 0.0, float(d)), (seconds, float(v), 0.0, float(d))])
               for d in directions for v in commands]
    r = controller.run(scripts, n, film, phases=phases, start_x=start_x)
    dist = np.sum(np.linalg.norm(np.diff(r.root_positions[:, k0:], axis=1), axis=-1), axis=1)
    achieved = (dist / ((n - 1 - k0) / controller.fps)).reshape(len(directions), len(commands))
    return SpeedCalibration(np.asarray(commands, dtype=np.float64), achieved, tuple(directions))
