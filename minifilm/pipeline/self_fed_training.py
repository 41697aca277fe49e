"""Rows the model feeds itself, for the whole network: rollout-aware training of Ω, Φ and Ψ.

:mod:`minifilm.pipeline.self_fed` teaches a new style by rolling the model out along the style's
clip and training Ψ on the states it visits. The same idea applies to a trained run as a whole
(DAgger, Ross et al. 2011): after teacher-forced training, roll the model out along every training
file, each style with its own FiLM vector, label each visited state with the file's next frame,
and go on training every network on the teacher-forced rows and the gathered ones together.

    for round r = 1 .. R:
        for every style s:  film_s = mean Ψ(clips of s)
            rows_s = rollout_rows(model, files of s, film_s)     (self_fed.rollout_rows)
        pool += rows of every style
        train one round: as many minibatches as one epoch of the training rows, drawn from the
        training rows and the pool together

The paper trains by teacher forcing alone (Sec. 4.3); this is an addition, and not used by
``minifilm train``. On the 90-style run (reports/2026-12-02_dense_style_space.md) three rounds
cut the rollout error along the training files from 8.6 to 5.1 cm, but doubled the validation MSE
and lowered the share of styles whose generated motion ranks first by Fréchet distance (34 % ->
20 %): the file's frame at the same time is a poor label for a state that has drifted, and pulls
the styles towards one another. ``studies/self_fed_training.py`` runs it on a trained run.
"""
from __future__ import annotations

from typing import Callable, List, Tuple

import numpy as np

from minifilm.dataset.arrays import TrainData
from minifilm.pipeline.self_fed import SelfFed, rollout_rows, style_film


def file_runs(split) -> Tuple[List[Tuple[np.ndarray, np.ndarray, np.ndarray]], np.ndarray]:
    """The raw rows of a data set split cut into runs of consecutive frames of one file:
    [(x (F, x_dim), p (F, 8), z (F, z_dim)), ...] and each run's style id (R,)."""
    starts, stops = split.runs()
    runs = [(split.x[a:b], split.p[a:b], split.z[a:b]) for a, b in zip(starts, stops)]
    return runs, np.asarray(split.style[starts], np.int64)


def gather_rows(model, ds, train: TrainData, runs, run_style: np.ndarray, settings: SelfFed):
    """One round's rows: every style rolled out along its own training files (``runs``, ``run_style``:
    :func:`file_runs` of the training split) with its own FiLM vector. Returns normalised float32
    (x, p, z, style) and the mean joint-position error (m) of the rollouts against the files, over styles."""
    xs, ps, zs, ss, errors = [], [], [], [], []
    for k in range(len(ds.styles)):
        mine = [r for r, s in zip(runs, run_style) if s == k]
        if not mine:
            continue
        film = style_film(model, train.clips[train.clip_style == k])
        x, p, z, error = rollout_rows(model, ds.stats, ds.layout, mine, film, settings.horizon, settings.every)
        xs.append(x), ps.append(p), zs.append(z), ss.append(np.full(len(x), k, np.int64))
        errors.append(error)
    f32 = np.float32
    return (ds.stats.normalize_x(np.concatenate(xs)).astype(f32), ds.stats.normalize_p(np.concatenate(ps)).astype(f32),
            ds.stats.normalize_z(np.concatenate(zs)).astype(f32), np.concatenate(ss), float(np.mean(errors)))


def self_fed_training(trainer, ds, settings: SelfFed = SelfFed(rounds=3, horizon=60, every=60),
                      log: Callable[[str], None] = print, aggregate: bool = True) -> List[float]:
    """Go on training ``trainer`` (every network) for ``settings.rounds`` rounds on the training rows
    and the rows gathered from its own rollouts (module docstring). ``settings.steps`` is unused:
    a round is as many minibatches as one epoch of the training rows. ``aggregate=False`` trains
    the same rounds on the training rows alone (the control: as many more teacher-forced steps).
    Returns the mean rollout error (m) before each round and after the last."""
    train, val = ds.train_data("train"), ds.train_data("val")
    runs, run_style = file_runs(ds.split("train"))          # the same rows every round
    rng = np.random.default_rng(trainer.config.seed + 1)
    pool: List[tuple] = []
    errors = []
    for r in range(settings.rounds + 1):
        x, p, z, s, error = gather_rows(trainer.model, ds, train, runs, run_style, settings)
        errors.append(error)
        log(f"    self-fed round {r}: rollout error {error * 100:.2f} cm; {len(x)} rows gathered")
        if r == settings.rounds:
            break
        if aggregate:
            pool.append((x, p, z, s))
        X = np.concatenate([train.x] + [a[0] for a in pool])
        P = np.concatenate([train.p] + [a[1] for a in pool])
        Z = np.concatenate([train.z] + [a[2] for a in pool])
        S = np.concatenate([train.style] + [a[3] for a in pool])
        pick = rng.choice(len(X), size=len(train), replace=False)
        rows = TrainData(x=X[pick], p=P[pick], z=Z[pick], style=S[pick], clips=train.clips,
                         clip_style=train.clip_style, style_names=train.style_names)
        trainer.fit(rows, val, epochs=trainer.epoch + 1)
        h = trainer.history[-1]
        log(f"    round {r + 1}: train MSE {h['train']['mse']:.4f}, val MSE {h['val']['mse']:.4f}")
    return errors
