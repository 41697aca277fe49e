"""Does minifilm's own labelling agree with what a network did? (a check of generated training data)

When the released network makes a data set (:mod:`minifilm.pipeline.from_released`), it also says,
every frame, which feet it put down (its contact outputs, Sec. 4.1.2) and where each limb is in
its cycle (the local phases it carries, Eq. 1). A model trained on that data set never sees those
outputs: its labels come from :func:`minifilm.phases.label.label` run on the written BVH. This
module measures how far the two agree, per file:

* ``contacts``: the fraction of (frame, foot) pairs where the labelled contact (0/1) equals the
  network's contact output thresholded at 0.5;
* ``phase_error``: the median circular distance, in cycles (0 .. 0.5), between the labelled foot
  phase φ and the network's foot phase atan2(s, c) / 2π, over frames where both feet's
  amplitudes are at least ``min_amplitude`` of their file's 90th percentile (a standing foot has
  no meaningful phase);
* ``phase_within``: the fraction of those frames within ``tolerance`` cycles.
"""
from __future__ import annotations

from typing import Dict, Sequence

import numpy as np

from minifilm.phases.label import Labels

#: the foot slots of the 8 phase numbers (Eq. 1): [left hand, right hand, left foot, right foot]
FOOT_SLOTS = (2, 3)


def phase_angles(vectors: np.ndarray) -> np.ndarray:
    """(F, 8) phase vectors amplitude·(sin 2πφ, cos 2πφ) -> (F, 4) φ in [0, 1), cycles."""
    v = np.asarray(vectors, dtype=np.float64)
    return (np.arctan2(v[:, 0::2], v[:, 1::2]) / (2 * np.pi)) % 1.0


def circular_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance between phases in cycles, on the circle: in [0, 0.5]."""
    d = np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64)) % 1.0
    return np.minimum(d, 1.0 - d)


def agreement(labels: Labels, net_contacts: np.ndarray, net_phases: np.ndarray, min_amplitude: float = 0.25,
              tolerance: float = 0.1) -> Dict[str, float]:
    """How one file's labels agree with the network's own outputs for the same frames.

    labels: :func:`minifilm.phases.label.label` of the file (F frames); net_contacts (F, 2)
    [right, left] in [0, 1]; net_phases (F, 8) the network's phase vectors. Returns
    dict(contacts, phase_error, phase_within, phase_frames) (see the module docstring); the phase
    entries are NaN when no frame has both amplitudes.
    """
    c_net = np.asarray(net_contacts, np.float64)
    p_net = np.asarray(net_phases, np.float64)
    F = len(labels.contacts)
    if c_net.shape != (F, 2) or p_net.shape != (F, 8):
        raise ValueError(f"agreement: network contacts {c_net.shape} and phases {p_net.shape} must be "
                         f"({F}, 2) and ({F}, 8) for a labelled file of {F} frames")
    contacts = float(np.mean((c_net > 0.5) == (labels.contacts > 0.5)))
    slots = list(FOOT_SLOTS)
    amp_net = np.hypot(p_net[:, 0::2], p_net[:, 1::2])[:, slots]
    amp_lab = labels.phases.amplitude[:, slots]

    def strong(a):
        ref = np.percentile(a, 90, axis=0)
        return (a >= min_amplitude * ref) & (ref > 0)

    use = strong(amp_net) & strong(amp_lab)
    d = circular_distance(phase_angles(p_net)[:, slots], labels.phases.phase[:, slots])[use]
    if d.size == 0:
        return dict(contacts=contacts, phase_error=float("nan"), phase_within=float("nan"), phase_frames=0)
    return dict(contacts=contacts, phase_error=float(np.median(d)), phase_within=float(np.mean(d <= tolerance)),
                phase_frames=int(d.size))


def summarise(per_file: Sequence[Dict[str, float]]) -> Dict[str, float]:
    """Frame-weighted means of several files' :func:`agreement` (phase entries over files that have them)."""
    rows = list(per_file)
    if not rows:
        raise ValueError("summarise: no files")
    out = dict(contacts=float(np.mean([r["contacts"] for r in rows])))
    w = np.array([r["phase_frames"] for r in rows], np.float64)
    if w.sum() == 0:
        return dict(out, phase_error=float("nan"), phase_within=float("nan"), phase_frames=0)
    for k in ("phase_error", "phase_within"):
        vals = np.array([0.0 if r["phase_frames"] == 0 else r[k] for r in rows])
        out[k] = float(np.sum(vals * w) / w.sum())
    out["phase_frames"] = int(w.sum())
    return out
