"""Is a variant trained to convergence? Validation curves for `minifilm compare`.

The comparison's claims only mean something when every variant has stopped improving. This module
trains a :class:`minifilm.train.trainer.Trainer` exactly as ``Trainer.fit`` does (the same
minibatches, the same random numbers: evaluating never draws from the training generator) while
recording the validation loss every ``eval_every`` steps, and judges the curve by one rule:

    flat at the end  <=>  (v(0.8 N) - v(N)) / v(0.8 N) < 3 %

where N is the number of steps taken, v(N) the validation loss (MSE + bone-length loss of the
variant's own outputs, Eq. 5-7) after the last step and v(0.8 N) the last value recorded at or
before 80 % of the steps. A loss that rises at the end (over-fitting) counts as flat: more steps of
the same training would not help.

- :func:`validation_subset`: a fixed, small validation set (the same frames for every variant);
- :func:`flat_at_end`: the rule on a recorded curve;
- :func:`train_with_curve`: training with the curve recorded, optionally continued in whole
  epochs until the rule holds (``until_flat``, up to ``max_epochs``).
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from minifilm.dataset.arrays import TrainData
from minifilm.train.epoch import EpochLosses

#: the rule of the comparison: the last 20 % of the steps improve the validation loss by < 3 %
TAIL_SHARE = 0.2
TOLERANCE = 0.03


def validation_subset(data: TrainData, frames_per_style: int = 50, clips_per_style: int = 8) -> TrainData:
    """At most ``frames_per_style`` frames and ``clips_per_style`` clips of every style of ``data``,
    evenly spaced over each style's rows (deterministic: every variant and seed is judged on the
    same frames). Small on purpose: the curve is evaluated ~11 times per training run."""
    rows, crows = [], []
    for s in np.unique(data.style):
        own = np.nonzero(data.style == s)[0]
        rows.append(own[np.linspace(0, len(own) - 1, min(frames_per_style, len(own))).round().astype(int)])
        cown = np.nonzero(data.clip_style == s)[0]
        if len(cown):
            crows.append(cown[np.linspace(0, len(cown) - 1, min(clips_per_style, len(cown))).round().astype(int)])
    r = np.unique(np.concatenate(rows))
    c = np.unique(np.concatenate(crows)) if crows else np.arange(len(data.clips))
    return TrainData(x=data.x[r], p=data.p[r], z=data.z[r], style=data.style[r], clips=data.clips[c],
                     clip_style=data.clip_style[c], style_names=list(data.style_names))


def flat_at_end(steps: Sequence[int], losses: Sequence[float], share: float = TAIL_SHARE,
                tolerance: float = TOLERANCE) -> dict:
    """The convergence rule on a curve: steps (n,) increasing, losses (n,) the validation loss
    after each. Returns {'flat': bool, 'improvement': (v(a) - v(N)) / v(a), 'from_step': a,
    'to_step': N} with a the last recorded step <= (1 - share) N. A curve of one point, or whose
    reference loss is not positive, is not judged ('flat': None)."""
    s = np.asarray(steps, dtype=np.float64)
    v = np.asarray(losses, dtype=np.float64)
    if s.ndim != 1 or s.shape != v.shape:
        raise ValueError(f"flat_at_end: steps {s.shape} and losses {v.shape} must be equal 1-D arrays")
    if len(s) < 2 or np.any(np.diff(s) <= 0):
        return {"flat": None, "improvement": float("nan"), "from_step": None, "to_step": None}
    k = int(np.nonzero(s <= (1.0 - share) * s[-1])[0][-1]) if np.any(s <= (1.0 - share) * s[-1]) else 0
    ref, end = v[k], v[-1]
    if not (np.isfinite(ref) and np.isfinite(end) and ref > 0) or k == len(s) - 1:
        return {"flat": None, "improvement": float("nan"), "from_step": int(s[k]), "to_step": int(s[-1])}
    gain = float((ref - end) / ref)
    return {"flat": bool(gain < tolerance), "improvement": gain, "from_step": int(s[k]), "to_step": int(s[-1])}


def train_with_curve(trainer, train: TrainData, val: TrainData, epochs: int, eval_every: int,
                     until_flat: bool = False, max_epochs: Optional[int] = None) -> dict:
    """Train ``trainer`` for ``epochs`` epochs (the same steps and numbers as ``trainer.fit(train,
    epochs=epochs)``), recording the validation loss on ``val`` before the first step, every
    ``eval_every`` steps and after the last. With ``until_flat``, keep training one whole epoch at
    a time while :func:`flat_at_end` does not hold, up to ``max_epochs`` in all.

    Returns {'steps': [..], 'loss': [..], 'epochs': int, **flat_at_end(...)}."""
    if eval_every < 1:
        raise ValueError(f"train_with_curve: eval_every must be >= 1, got {eval_every}")
    steps, losses = [trainer.step], [trainer.evaluate(val)["loss"]]
    limit = max(epochs, max_epochs or epochs) if until_flat else epochs
    while trainer.epoch < limit:
        if trainer.epoch >= epochs and flat_at_end(steps, losses)["flat"] is not False:
            break                          # the budget is spent and more would not help (or cannot be judged)
        record = EpochLosses(trainer)
        for b in trainer.minibatches(train):
            mse, bll = trainer.train_step(b)
            record.add(b, mse, bll)
            if trainer.step % eval_every == 0:
                steps.append(trainer.step)
                losses.append(trainer.evaluate(val)["loss"])
        trainer.end_epoch(record.summary())
        if steps[-1] != trainer.step:
            steps.append(trainer.step)
            losses.append(trainer.evaluate(val)["loss"])
    return {"steps": steps, "loss": [float(x) for x in losses], "epochs": trainer.epoch,
            **flat_at_end(steps, losses)}
