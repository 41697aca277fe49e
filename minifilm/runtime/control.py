"""User control for the runtime: what the character is asked to do, frame by frame (Sec. 4.4).

A *script* answers one question per frame: "given where the character is and which way it faces,
which way should it face and how fast (m/s, world x/z) should it move?"  Two kinds:

* :class:`CommandScript` -- open loop: keyframed speed, heading and movement direction over time
  (walk / run / stop / turn / sidestep / backwards). Its commanded path is the integral of the
  commanded velocity.
* :class:`PathScript` -- closed loop: follow a polyline of waypoints (pure pursuit), with a speed
  schedule and a facing mode ('travel', 'backward' or a fixed world direction for strafing).

Ready scripts: :func:`straight_walk`, :func:`figure_eight`, :func:`walk_run_stop`, :func:`strafe`,
:func:`stop_and_go` (walk, stand, walk, stand: the runtime must come to a stop and stand,
``minifilm/runtime/standing.py``).

:func:`blend_future_trajectory` is the user-trajectory blend of the original runtime
(docs/original-code.md §10.4, after Zhang et al. 2018), rewritten at the network's own future sample
spacing (0.2 s, the training spacing; the demo used 1/6 s, §12 item 10) and in m/s: the user's
velocity times the sample spacing is a displacement in metres, so no per-style "bias" is needed.

Everything here works on plain arrays. 2-D vectors are world ``(x, z)`` pairs (y is up). A heading
angle ``theta`` means the direction ``(sin theta, cos theta)``: 0 is +z, +90 degrees is +x.
"""
from __future__ import annotations

from typing import Optional, Sequence, Tuple, Union

import numpy as np

__all__ = [
    "Script", "CommandScript", "PathScript", "straight_walk", "figure_eight", "walk_run_stop",
    "strafe", "stop_and_go", "SCRIPTS", "make_script", "blend_future_trajectory", "distance_to_path",
    "heading_vector",
]


def heading_vector(theta) -> np.ndarray:
    """Unit world (x, z) direction(s) for heading angle(s) ``theta`` in radians: (..., 2)."""
    theta = np.asarray(theta, dtype=np.float64)
    return np.stack([np.sin(theta), np.cos(theta)], axis=-1)


def _normalize(v: np.ndarray, fallback: Optional[np.ndarray] = None, eps: float = 1e-9) -> np.ndarray:
    """Unit vectors along the last axis; rows shorter than eps become ``fallback`` (default +z)."""
    v = np.asarray(v, dtype=np.float64)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    if fallback is None:
        fallback = np.zeros(v.shape[-1])
        fallback[-1] = 1.0
    fallback = np.broadcast_to(np.asarray(fallback, dtype=np.float64), v.shape)
    return np.where(n > eps, v / np.maximum(n, eps), fallback)


class Script:
    """Base class. Subclasses implement :meth:`command`; ``path`` is the commanded path (N, 2) or None."""

    duration: float = np.inf
    path: Optional[np.ndarray] = None

    def reset(self) -> None:
        """Forget any per-character state (call before a new rollout)."""

    def command(self, t: float, position: np.ndarray, facing: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Target (facing (2,) unit, velocity (2,) m/s) at time ``t`` seconds.

        ``position`` (2,) and ``facing`` (2,) are the character's current root on the floor.
        """
        raise NotImplementedError

    def start(self) -> Tuple[np.ndarray, np.ndarray]:
        """Where the character should start: (position (2,), facing (2,))."""
        return np.zeros(2), np.array([0.0, 1.0])


def _keyframes(keys, what: str) -> Tuple[np.ndarray, np.ndarray]:
    arr = np.asarray(keys, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[0] < 1:
        raise ValueError(f"{what}: expected a list of (time, value...) keyframes, got shape {arr.shape}")
    if np.any(np.diff(arr[:, 0]) < 0):
        raise ValueError(f"{what}: keyframe times must not decrease, got {arr[:, 0].tolist()}")
    return arr[:, 0], arr[:, 1:]


class CommandScript(Script):
    """Open-loop keyframed commands, linearly interpolated in time.

    Args:
        keys: rows ``(time s, speed m/s, heading deg, move deg)``. ``heading`` is the facing
            direction in the world; ``move`` is the direction of travel relative to the facing:
            0 forwards, 180 backwards, +90 sidestep to the heading rotated by +90 degrees (+x when
            facing +z, the left of a 100STYLE character), -90 the other way. Angles are
            interpolated as numbers, so a heading going 0 -> 360 turns a full circle.
        start_position, start_heading_deg: where the character starts.
        fps: sampling rate of the stored commanded path (for :func:`distance_to_path`).
    """

    def __init__(self, keys: Sequence[Sequence[float]], start_position=(0.0, 0.0), fps: float = 60.0):
        self.times, vals = _keyframes(keys, "CommandScript keys")
        if vals.shape[1] != 3:
            raise ValueError(f"CommandScript keys: rows must be (time, speed, heading_deg, move_deg), "
                             f"got {vals.shape[1] + 1} numbers per row")
        self.speeds = vals[:, 0]
        self.headings = np.radians(vals[:, 1])
        self.moves = np.radians(vals[:, 2])
        self.duration = float(self.times[-1])
        self._start = np.asarray(start_position, dtype=np.float64)
        t = np.arange(0.0, self.duration + 1.0 / fps, 1.0 / fps)
        vel = self._velocity(t)
        self.path = self._start + np.concatenate([[[0.0, 0.0]], np.cumsum(vel[:-1], axis=0) / fps])

    def _velocity(self, t) -> np.ndarray:
        """Commanded velocity (..., 2) at time(s) t."""
        heading = np.interp(t, self.times, self.headings)
        move = np.interp(t, self.times, self.moves)
        return np.interp(t, self.times, self.speeds)[..., None] * heading_vector(heading + move)

    def start(self):
        return self._start.copy(), heading_vector(self.headings[0])

    def command(self, t, position, facing):
        return heading_vector(np.interp(t, self.times, self.headings)), self._velocity(t)


class PathScript(Script):
    """Follow a polyline of waypoints by pure pursuit (closed loop).

    Each frame the character's position is projected onto the path near where it was last frame
    (a search window keeps progress monotone, so a self-crossing figure-eight is followed in order),
    and it is steered towards the point ``lookahead`` metres further along.

    Args:
        waypoints: (N, 2) world (x, z) points, N >= 2.
        speed: m/s, a constant or keyframes ``[(time s, speed), ...]`` (linearly interpolated).
        facing: 'travel' (face where you go), 'backward' (walk backwards), or a world (x, z)
            direction to keep facing (strafing / sidestepping).
        closed: the path loops back to its first waypoint (and is followed forever).
        lookahead: pure-pursuit distance along the path, metres.
    """

    def __init__(self, waypoints, speed: Union[float, Sequence] = 1.3, facing="travel",
                 closed: bool = False, lookahead: float = 1.0, duration: float = np.inf):
        pts = np.asarray(waypoints, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError(f"PathScript: waypoints must be (N>=2, 2) world (x, z) points, got {pts.shape}")
        if closed:
            pts = np.concatenate([pts, pts[:1]])
        seg = np.diff(pts, axis=0)
        seglen = np.linalg.norm(seg, axis=1)
        keep = np.concatenate([[True], seglen > 1e-9])
        pts = pts[keep]
        self.path = pts
        self._seg = np.diff(pts, axis=0)
        self._len = np.linalg.norm(self._seg, axis=1)
        self._cum = np.concatenate([[0.0], np.cumsum(self._len)])
        self.length = float(self._cum[-1])
        self.closed = closed
        self.lookahead = float(lookahead)
        if np.isscalar(speed):
            self._speed_t, self._speed_v = np.array([0.0]), np.array([float(speed)])
        else:
            self._speed_t, v = _keyframes(speed, "PathScript speed")
            self._speed_v = v[:, 0]
        if isinstance(facing, str):
            if facing not in ("travel", "backward"):
                raise ValueError(f"PathScript: facing must be 'travel', 'backward' or an (x, z) "
                                 f"direction, got {facing!r}")
            self.facing_mode = facing
            self._fixed = None
        else:
            self.facing_mode = "fixed"
            self._fixed = _normalize(np.asarray(facing, dtype=np.float64).reshape(2))
        self.duration = duration
        self._grid = np.linspace(0.0, 1.0, 48)
        self.reset()

    def reset(self):
        self._s = 0.0
        self._last_dir = self._tangent(0.0)

    def _points(self, s: np.ndarray) -> np.ndarray:
        """Path points (N, 2) at arc lengths s (N,) (wrapped when closed, clamped otherwise)."""
        s = np.asarray(s, dtype=np.float64)
        s = s % self.length if self.closed else np.clip(s, 0.0, self.length)
        i = np.clip(np.searchsorted(self._cum, s, side="right") - 1, 0, len(self._len) - 1)
        return self.path[i] + ((s - self._cum[i]) / self._len[i])[:, None] * self._seg[i]

    def _point(self, s: float) -> np.ndarray:
        return self._points(np.array([s]))[0]

    def _tangent(self, s: float) -> np.ndarray:
        if self.closed:
            s = s % self.length
        i = min(max(int(np.searchsorted(self._cum, s, side="right")) - 1, 0), len(self._len) - 1)
        return self._seg[i] / self._len[i]

    def _project(self, p: np.ndarray, lo: float, hi: float) -> float:
        """Arc length of the closest path point to p with arc length in [lo, hi]."""
        ss = lo + (hi - lo) * self._grid
        pts = self._points(ss)
        return float(ss[np.argmin(np.sum((pts - p) ** 2, axis=1))])

    def speed(self, t: float) -> float:
        return float(np.interp(t, self._speed_t, self._speed_v))

    def start(self):
        facing = self._tangent(0.0) if self.facing_mode == "travel" else (
            -self._tangent(0.0) if self.facing_mode == "backward" else self._fixed)
        return self.path[0].copy(), facing.copy()

    def command(self, t, position, facing):
        p = np.asarray(position, dtype=np.float64)
        hi = self._s + 2.0 + self.lookahead
        if not self.closed:
            hi = min(hi, self.length)
        self._s = max(self._s, self._project(p, max(self._s - 0.5, 0.0), hi))
        target = self._point(self._s + self.lookahead)
        speed = self.speed(t)
        if not self.closed and self._s >= self.length - 1e-3:
            speed = 0.0  # arrived
        to_target = target - p
        if np.linalg.norm(to_target) > 1e-6:
            self._last_dir = to_target / np.linalg.norm(to_target)
        velocity = speed * self._last_dir
        if self.facing_mode == "fixed":
            return self._fixed.copy(), velocity
        travel = self._tangent(self._s)
        return (travel if self.facing_mode == "travel" else -travel), velocity


# ----------------------------------------------------------------------------- ready scripts

def straight_walk(seconds: float = 30.0, speed: float = 1.3) -> PathScript:
    """Walk straight ahead (+z) at ``speed`` m/s."""
    return PathScript([[0.0, 0.0], [0.0, speed * seconds + 5.0]], speed=speed, duration=seconds)


def figure_eight(seconds: float = 30.0, speed: float = 1.3, size: float = 3.0) -> PathScript:
    """A figure-eight (1:2 Lissajous curve, x = size sin 2u, z = 2 size sin u), looped forever.

    The tightest radius of curvature is 2 * size metres.
    """
    u = np.linspace(0.0, 2 * np.pi, 241)[:-1]
    pts = np.stack([size * np.sin(2 * u), 2 * size * np.sin(u)], axis=1)
    return PathScript(pts, speed=speed, closed=True, duration=seconds)


def walk_run_stop(seconds: float = 30.0, speed: float = 1.3, run: float = 3.5) -> PathScript:
    """Straight line: walk at ``speed``, speed up to ``run``, slow down to a walk, then stop
    (in thirds of the time)."""
    if seconds <= 0:
        raise ValueError(f"walk_run_stop: seconds must be positive, got {seconds}")
    walk = speed
    a, b = seconds / 3.0, 2 * seconds / 3.0
    r = min(1.0, seconds / 12.0)     # speed changes take 1 s, less in short scripts (times keep increasing)
    keys = [(0.0, walk), (a - r, walk), (a, run), (b - 1.5 * r, run), (b - 0.5 * r, walk),
            (b + 0.5 * (seconds - b), walk), (b + 0.5 * (seconds - b) + r, 0.0), (seconds, 0.0)]
    return PathScript([[0.0, 0.0], [0.0, run * seconds + 5.0]], speed=keys, duration=seconds)


def strafe(seconds: float = 30.0, speed: float = 1.0, width: float = 4.0) -> PathScript:
    """Face +z the whole time; walk forward 3 m, then sidestep back and forth along x."""
    legs = max(int(np.ceil(seconds * speed / width)) + 1, 2)
    pts = [[0.0, 0.0], [0.0, 3.0]]
    for k in range(legs):
        pts.append([-width if k % 2 == 0 else 0.0, 3.0])
    return PathScript(pts, speed=speed, facing=(0.0, 1.0), lookahead=0.6, duration=seconds)


def stop_and_go(seconds: float = 30.0, speed: float = 1.3) -> PathScript:
    """Straight line, in quarters of the time: walk at ``speed``, stop and stand, walk on, stop and
    stand. (Speed changes take a quarter of a second: a released key.)"""
    if seconds <= 0:
        raise ValueError(f"stop_and_go: seconds must be positive, got {seconds}")
    q = seconds / 4.0
    r = min(0.25, q / 4.0)
    keys = [(0.0, speed), (q - r, speed), (q, 0.0), (2 * q, 0.0), (2 * q + r, speed), (3 * q - r, speed),
            (3 * q, 0.0), (seconds, 0.0)]
    return PathScript([[0.0, 0.0], [0.0, speed * seconds + 5.0]], speed=keys, duration=seconds)


SCRIPTS: dict = {
    "straight": straight_walk,
    "figure8": figure_eight,
    "walk_run_stop": walk_run_stop,
    "strafe": strafe,
    "stop_and_go": stop_and_go,
}


def make_script(name: str, seconds: float, **kwargs) -> Script:
    """A ready script by name (one of ``SCRIPTS``)."""
    if name not in SCRIPTS:
        raise KeyError(f"unknown script {name!r}; choose one of {sorted(SCRIPTS)}")
    return SCRIPTS[name](seconds=seconds, **kwargs)


# ----------------------------------------------------------------------------- trajectory blend

def blend_future_trajectory(positions: np.ndarray, directions: np.ndarray, target_velocity: np.ndarray,
                            target_facing: np.ndarray, sample_dt: float, position_bias: float = 0.75,
                            direction_bias: float = 1.25) -> Tuple[np.ndarray, np.ndarray]:
    """Blend the predicted future trajectory with the user's target (docs/original-code.md §10.4).

    Sample 0 is the current root and is kept. For future sample s = 1..S-1 with w = s/(S-1):
    ``p_s = p'_{s-1} + lerp(P_s - P_{s-1}, v * sample_dt, 1 - (1-w)^position_bias)`` and
    ``d_s = normalize(lerp(D_s, target_facing, 1 - (1-w)^direction_bias))``: near samples keep the
    network's prediction, far samples follow the user. ``v * sample_dt`` turns the user's m/s into
    the displacement between two samples, so speed is calibrated in metres per second.

    Args:
        positions: (B, S, 2) world (x, z) future samples, sample 0 = current root.
        directions: (B, S, 2) their unit facing directions.
        target_velocity: (B, 2) m/s; target_facing: (B, 2) unit.
        sample_dt: seconds between samples (0.2 s in the training data).
    Returns:
        (positions (B, S, 2), directions (B, S, 2)), new arrays.
    """
    P = np.asarray(positions, dtype=np.float64)
    D = np.asarray(directions, dtype=np.float64)
    if P.ndim != 3 or P.shape[-1] != 2 or D.shape != P.shape:
        raise ValueError(f"blend_future_trajectory: positions/directions must both be (B, S, 2), "
                         f"got {P.shape} and {D.shape}")
    S = P.shape[1]
    w = np.arange(S) / (S - 1)
    sp = (1.0 - (1.0 - w) ** position_bias)[None, :, None]            # 0 at the root, 1 at the end
    sd = (1.0 - (1.0 - w) ** direction_bias)[None, :, None]
    step = (np.asarray(target_velocity, dtype=np.float64) * sample_dt)[:, None, :]   # (B, 1, 2)
    # p_s = p_{s-1} + lerp(P_s - P_{s-1}, step, sp_s): a cumulative sum of blended increments
    inc = (1 - sp[:, 1:]) * np.diff(P, axis=1) + sp[:, 1:] * step
    out_p = np.concatenate([P[:, :1], P[:, :1] + np.cumsum(inc, axis=1)], axis=1)
    face = np.asarray(target_facing, dtype=np.float64)[:, None, :]
    out_d = _normalize((1 - sd) * D + sd * face, fallback=D)
    return out_p, out_d


def distance_to_path(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance (metres) from each point (F, 2) to the polyline ``path`` (N, 2): (F,)."""
    p = np.asarray(points, dtype=np.float64)[:, None, :]          # (F, 1, 2)
    a = np.asarray(path, dtype=np.float64)[None, :-1, :]          # (1, N-1, 2)
    d = np.diff(np.asarray(path, dtype=np.float64), axis=0)[None]  # (1, N-1, 2)
    L2 = np.maximum(np.sum(d * d, axis=-1), 1e-12)
    u = np.clip(np.sum((p - a) * d, axis=-1) / L2, 0.0, 1.0)       # (F, N-1)
    closest = a + u[..., None] * d
    return np.sqrt(np.min(np.sum((p - closest) ** 2, axis=-1), axis=1))
