"""What one training epoch is made of: its minibatches (:class:`Minibatch`, drawn by
:meth:`minifilm.train.trainer.Trainer.minibatches`) and the per-style sums of their losses with the
one-line progress display (:class:`EpochLosses`)."""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np


@dataclass
class Minibatch:
    """One training minibatch (:meth:`minifilm.train.trainer.Trainer.minibatches`): samples of one style and their clips.

    x (B, x_dim), p (B, phase_dim), z (B, z_dim), clips (M, T, C); kw: the model's extra forward
    arguments (``clip_index`` (B,) when M clips are shared by the batch, ``style`` ids for the
    comparison variants, ``masks`` under mpiexec); index of count in the epoch; where: "epoch e,
    batch i, style s"; share: the part of the minibatch's rows these are (1 in one process; under
    mpiexec a rank's n_r / B, minifilm/train/mpi.py)."""

    index: int
    count: int
    style: int
    x: np.ndarray
    p: np.ndarray
    z: np.ndarray
    clips: np.ndarray
    kw: dict
    where: str
    share: float = 1.0


class EpochLosses:
    """Per-style sums of an epoch's minibatch losses, and the one-line progress display on stderr
    (config.progress; None: only when stderr is a terminal)."""

    def __init__(self, trainer):
        self.trainer, self.sums, self.t0 = trainer, {}, time.time()
        progress = trainer.config.progress
        self.show = progress if progress is not None else sys.stderr.isatty()

    def add(self, b: Minibatch, mse: float, bll: float) -> None:
        acc = self.sums.setdefault(b.style, [0.0, 0.0, 0])
        acc[0] += mse
        acc[1] += bll
        acc[2] += 1
        if self.show:
            t = self.trainer
            rate = (b.index + 1) / max(time.time() - self.t0, 1e-9)
            sys.stderr.write(f"\repoch {t.epoch + 1}/{t.config.epochs}  batch {b.index + 1}/{b.count}  "
                             f"loss {mse + bll:.4f}  {rate:.1f} batch/s ")
            sys.stderr.flush()

    def summary(self) -> dict:
        """{'mse', 'bll', 'loss', 'per_style'}: means over each style's minibatches, styles equal."""
        if self.show:
            sys.stderr.write("\n")
        return self.trainer._summarise(self.sums)
