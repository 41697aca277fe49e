"""Rows the model feeds itself: the rollout-aware part of teaching a new style (Sec. 5.3.2).

Teacher-forced fine-tuning shows Ψ only frames of the clip: every input pose is the clip's own.
When the network generates, it reads the pose it predicted a frame before, and a small error in a
new style's pose is read back as a pose of a *trained* style, which the frozen Φ then continues:
the motion drifts back to the styles Φ knows (exposure bias; measured in studies/new_style_ceiling.py
and studies/dense_study.py). The remedy here is the DAgger idea, made simple by the clip's path
being known: roll the model out along the clip and train on the states it visits, labelled with
the clip's next frame.

For a clip's consecutive rows (x_t, p_t, z_t) and a start s, with film = mean Ψ(clips):

    x̃_s, p̃_s = x_s, p_s
    for k = 0 .. H-1:
        ẑ = Φ(x̃_{s+k}; Ω(p̃_{s+k}), film)                  the model's own next frame
        row  (x̃_{s+k}, p̃_{s+k}) -> z_{s+k}                 its own state, the clip's answer
        x̃_{s+k+1} = x_{s+k+1} with ẑ's joints moved into the clip's next root frame
        p̃_{s+k+1} = ½ ẑ_phases + ½ (p̃_{s+k} + ẑ_updates)    the runtime's phase update

The trajectory columns stay the clip's: at run time the user's command keeps the character on its
path, and the pose and phases are what drift. The target z_{s+k} is the clip's frame at the same
time; horizons are short (a second) so that the rollout's gait cycle stays close to the clip's.
Everything here works in raw (unnormalised) units; ``stats`` converts for the network.

What it did on the 90-style runs (reports/2026-12-02_dense_style_space.md): three rounds
lowered the rollout error along the clip by 10-32 % for each of five held-out styles, and
reproduced no more of them on a new path (3 of 5 either way); so `minifilm finetune` leaves it
off unless asked (``--rollout-rounds``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, List, Sequence, Tuple

import numpy as np

from minifilm.dataset.arrays import TrainData
from minifilm.features.layout import JOINT_FIELDS, FeatureLayout

#: joint fields that are points (moved with the root) rather than directions (only turned)
POINT_FIELDS = ("position",)


def into_next_root(z: np.ndarray, root_delta: np.ndarray, layout: FeatureLayout) -> np.ndarray:
    """The joints of next-frame outputs z (B, z_dim), which are seen from the current root, seen
    from the next root instead: the x joint block (B, joint_dim) of the next input frame.

    root_delta (B, 4): ``[pos_x, pos_z, dir_x, dir_z]`` of the next root in the current root's frame
    (z's first four columns; here the clip's, so the path is the clip's).
    """
    B = len(z)
    offset = np.zeros((B, 1, 3))
    offset[:, 0, 0], offset[:, 0, 2] = root_delta[:, 0], root_delta[:, 1]
    d = root_delta[:, 2:4] / np.maximum(np.linalg.norm(root_delta[:, 2:4], axis=1, keepdims=True), 1e-9)
    fx, fz = d[:, 0, None], d[:, 1, None]
    out = np.empty((B, layout.joint_dim))
    x0 = layout.x_joints.start
    for field in JOINT_FIELDS:
        v = z[:, layout.joint_columns("z", field)]                 # (B, J, 3)
        if field in POINT_FIELDS:
            v = v - offset
        cols = layout.joint_columns("x", field) - x0
        out[:, cols[:, 0]] = fz * v[..., 0] - fx * v[..., 2]        # R^T v for R = LookRotation(d)
        out[:, cols[:, 1]] = v[..., 1]
        out[:, cols[:, 2]] = fx * v[..., 0] + fz * v[..., 2]
    return out


def rollout_rows(model, stats, layout: FeatureLayout, segments: Sequence[Tuple[np.ndarray, np.ndarray, np.ndarray]],
                 film: np.ndarray, horizon: int, every: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The states the model visits when it generates along the clips, with the clips' answers.

    segments: raw (x (F, x_dim), p (F, 8), z (F, z_dim)) of consecutive frames, one per file.
    film (4H,): the style vector the model generates with. horizon: frames per rollout; a rollout
    starts every ``every`` frames. Returns raw x (N, x_dim), p (N, 8), z (N, z_dim) and the mean
    joint-position error (m) of the rolled-out poses against the clip's: the rollout measure.
    """
    # every clip's rows end to end; a rollout from start s reads rows s, s + 1, ... of its own file
    X, P, Z = (np.concatenate([np.asarray(seg[i], np.float64) for seg in segments]) for i in range(3))
    first = np.cumsum([0] + [len(seg[0]) for seg in segments])[:-1]
    starts = np.array([f + s for f, seg in zip(first, segments) for s in range(0, len(seg[0]) - horizon, every)],
                      dtype=np.int64)
    if len(starts) == 0:
        return (np.zeros((0, layout.x_dim)), np.zeros((0, layout.phase_dim)), np.zeros((0, layout.z_dim)), 0.0)
    xs, ps = X[starts], P[starts]
    joints, pos_cols = layout.x_joints, layout.joint_columns("x", "position")
    out_x, out_p, out_z, errors = [], [], [], []
    dtype = model.dtype
    for k in range(horizon):
        true_z = Z[starts + k]
        if k > 0:
            errors.append(np.linalg.norm(xs[:, pos_cols] - X[starts + k][:, pos_cols], axis=-1).mean())
        out_x.append(xs)
        out_p.append(ps)
        out_z.append(true_z)
        z_hat = stats.denormalize_z(model.forward_with_film(stats.normalize_x(xs).astype(dtype),
                                                           stats.normalize_p(ps).astype(dtype), film))
        z_hat = np.asarray(z_hat, np.float64)
        if k + 1 < horizon:
            xs = X[starts + k + 1]                    # a fresh array: the path is the clip's ...
            xs[:, joints] = into_next_root(z_hat, true_z[:, layout.z_root_delta], layout)   # ... the pose the model's
            ps = 0.5 * z_hat[:, layout.z_phases] + 0.5 * (ps + z_hat[:, layout.z_phase_updates])
    return (np.concatenate(out_x), np.concatenate(out_p), np.concatenate(out_z),
            float(np.mean(errors)) if errors else 0.0)


@dataclass(frozen=True)
class SelfFed:
    """Settings of the rollout-aware rounds that follow teacher-forced fine-tuning.

    rounds: how many times rows are collected from the model's own rollouts (0: teacher forcing
    alone, the paper). horizon: frames per rollout. every: a rollout starts every so many frames
    of the clip. steps: fine-tuning steps per round, on the clip's rows and every round's rollout
    rows so far (DAgger's aggregation).
    """

    rounds: int = 3
    horizon: int = 60
    every: int = 10
    steps: int = 150

    def __post_init__(self):
        for name in ("rounds", "horizon", "every", "steps"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or v < (0 if name == "rounds" else 1):
                raise ValueError(f"SelfFed: {name} must be a whole number >= {0 if name == 'rounds' else 1}, got {v!r}")


def style_film(model, clips: np.ndarray, chunk: int = 64) -> np.ndarray:
    """The style vector the run library would store: mean Ψ(clip) over the normalised clips (M, T, C)."""
    dtype = model.dtype
    return np.concatenate([model.film_parameters(clips[a:a + chunk].astype(dtype))
                           for a in range(0, len(clips), chunk)]).mean(axis=0)


def self_fed_rounds(trainer, data: TrainData, segments, layout: FeatureLayout, stats, settings: SelfFed,
                    log: Callable[[str], None] = print) -> List[float]:
    """Continue fine-tuning ``trainer`` (Ψ alone) with rows from its own rollouts, and keep the Ψ whose
    rollouts follow the clip best (mean joint-position error over the rollouts, in metres).

    data: the clip's normalised teacher-forced rows (style 0); segments: the same rows raw, per file.
    Returns the rollout error before each round and after the last; Ψ ends at the best of them.
    """
    psi = trainer.model.film.params
    errors, best = [], (math.inf, psi.data.copy())
    pool = []
    f32 = np.float32
    for r in range(settings.rounds + 1):
        film = style_film(trainer.model, data.clips)
        x, p, z, error = rollout_rows(trainer.model, stats, layout, segments, film, settings.horizon, settings.every)
        errors.append(error)
        if error < best[0]:
            best = (error, psi.data.copy())
        if r == settings.rounds or len(x) == 0:
            break
        pool.append((stats.normalize_x(x).astype(f32), stats.normalize_p(p).astype(f32),
                     stats.normalize_z(z).astype(f32)))
        x = np.concatenate([data.x] + [a[0] for a in pool])
        p = np.concatenate([data.p] + [a[1] for a in pool])
        z = np.concatenate([data.z] + [a[2] for a in pool])
        # one epoch of exactly ``steps`` minibatches, drawn from everything gathered so far
        pick = trainer.rng.choice(len(x), size=min(len(x), settings.steps * trainer.config.batch_size), replace=False)
        rows = TrainData(x=x[pick], p=p[pick], z=z[pick], style=np.zeros(len(pick), np.int64), clips=data.clips,
                         clip_style=data.clip_style, style_names=data.style_names)
        trainer.fit(rows, epochs=trainer.epoch + 1)
        log(f"    round {r + 1}: rollout error {error * 100:.1f} cm before it; {len(x)} rows gathered")
    psi.data[...] = best[1]
    return errors
