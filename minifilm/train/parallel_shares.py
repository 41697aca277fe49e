"""How data-parallel training (parallel.py) divides its work: how many workers by default, and
which rows of a minibatch -- and which of its style clips -- each worker computes."""
from __future__ import annotations

import numpy as np

from minifilm.processes import usable_cores


def default_workers(trainer) -> int:
    """Every usable core, but no more workers than the style clips a minibatch shares: a worker
    without a clip of its own would run Psi on a clip another worker runs too."""
    clips = trainer.config.clips_per_batch or trainer.config.batch_size
    return max(1, min(usable_cores(), clips))


def shares(batch: int, clip_index, n_clips: int, workers: int):
    """[(lo, hi, clo, chi)] per worker: rows lo:hi of the minibatch and the clips clo:chi they use.
    clip_index (batch,) sorted ascending (the rows ordered by clip), or None: one clip per sample
    (clip rows = sample rows)."""
    if clip_index is None:
        return [(w * batch // workers, (w + 1) * batch // workers) * 2 for w in range(workers)]
    counts = np.bincount(clip_index, minlength=n_clips)
    starts = np.concatenate([[0], np.cumsum(counts)])          # rows of clip j: starts[j]:starts[j+1]
    out = []
    for w in range(workers):
        if n_clips >= workers:                                  # split at clip boundaries
            clo, chi = w * n_clips // workers, (w + 1) * n_clips // workers
            lo, hi = int(starts[clo]), int(starts[chi])
        else:                                                   # split the rows; clips may repeat
            lo, hi = w * batch // workers, (w + 1) * batch // workers
            if hi == lo:
                out.append((lo, hi, 0, 0))
                continue
            clo, chi = int(clip_index[lo]), int(clip_index[hi - 1]) + 1
        out.append((lo, hi, clo, chi))
    return out
