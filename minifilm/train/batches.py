"""Style-balanced minibatches (Sec. 4.3) and the style clip each sample is paired with.

The paper (Sec. 4.3): each minibatch contains only one style, the styles are cycled in a fixed
order (so every S consecutive minibatches hold all S styles), and one epoch is one pass through the
shortest style's training frames; every style then gets the same number of updates however much
data it has (the per-style normalisation 1/N_s of Eq. 5 and 7). That is all it says about a
minibatch: neither its size nor which clip y^s of the style (Eq. 4) each sample reads.

What this code does beside it. The batch size is 32, the original code's. Every sample of a
minibatch reads a clip of the minibatch's style, drawn at random for it (:func:`draw_clips`), so Ψ
runs on as many clips as there are samples; the original does the same, pairing the i-th frame of a
minibatch with the i-th of 32 clips of the style taken from a shuffled stream (docs/original-code.md
§14). With ``TrainConfig.clips_per_batch = n`` (the main job: 4) the minibatch draws n clips of its
style and its samples share them (:func:`draw_shared_clips`): a departure from the original, for
speed, since Ψ is the most expensive part of a training step.
"""
from __future__ import annotations

import numpy as np

from minifilm.dataset.arrays import TrainData


def epoch_batches(style, batch_size, rng):
    """The minibatches of one epoch, as (style id, frame indices) in training order.

    Each style's frames are shuffled; one epoch takes n_min // batch_size batches from every
    style (n_min = frames of the shortest style), cycling through the styles in a fixed
    (ascending id) order, so every run of S consecutive batches holds all S styles once.
    A shortest style with fewer frames than batch_size gives one smaller batch per style.
    """
    styles = np.unique(style)
    perms = [rng.permutation(np.nonzero(style == s)[0]) for s in styles]
    n_min = min(len(p) for p in perms)
    size = min(batch_size, n_min)
    n_batches = n_min // size
    return [(int(s), perm[k * size:(k + 1) * size])
            for k in range(n_batches) for s, perm in zip(styles, perms)]


def draw_clips(data: TrainData, style_ids, rng):
    """One clip index per sample, drawn uniformly among the clips of the sample's style."""
    out = np.empty(len(style_ids), dtype=np.int64)
    for s in np.unique(style_ids):
        pool = np.nonzero(data.clip_style == s)[0]
        where = np.nonzero(style_ids == s)[0]
        out[where] = pool[rng.integers(0, len(pool), size=len(where))]
    return out


def draw_shared_clips(data: TrainData, style: int, n_clips: int, batch: int, rng):
    """Clips shared by a minibatch of one style (TrainConfig.clips_per_batch): ``n_clips`` clips
    drawn uniformly among the style's clips (at most one per sample), and for each of the
    ``batch`` samples which of them it uses, spread evenly in a random order.

    Returns (clip indices (M,), assignment (batch,) ints in [0, M)), M = min(n_clips, batch).
    Ψ then runs on M clips instead of ``batch``; the original gives every sample its own clip (the
    paper does not say; see the module docstring)."""
    pool = np.flatnonzero(data.clip_style == style)
    m = max(1, min(int(n_clips), int(batch)))
    chosen = pool[rng.integers(0, len(pool), size=m)]
    assign = rng.permutation(np.arange(batch) % m)
    return chosen, assign
