"""Local motion phases (Sec. 4.1, Eq. 1; docs/original-code.md §3-§4).

Pipeline per end effector b (left hand, right hand, left foot, right foot, in that order):

    source G_b(t)                    sources.py         (contacts for feet, directed PCA for hands)
      -> preprocess                  sources.py         (1 s normalisation, 4 Hz Butterworth, < 1e-3 -> 0)
      -> sinusoid fit per frame      sinusoid_fit.py    (A sin(2π(F t − S)) + B over 0.5 s; written out
                                                          frame by frame in sinusoid_fit_plain.py)
      -> phase, amplitude            here              (§4.5-§4.6)
      -> p_i = amp · (sin 2πφ, cos 2πφ)                (Eq. 1, §4.7)

Phase (§4.5): φ_k = (F_k t_k − S_k) mod 1, in cycles; a foot's φ ≈ 0.25 at mid-stance (§4.7).
Amplitude (§4.5, Eq. 1): A_k × the largest hips-relative speed of the bone (m/s) within one fitted
period (round(fps/F_k) frames) around frame k. Post-processing (§4.6): (sin, cos) of the phase and
the amplitude are smoothed with the 4 Hz Butterworth filter; the amplitude is clamped at 0.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from minifilm.phases.sinusoid_fit import SinusoidFit, fit_sinusoids, overflow_window, range_reduce
from minifilm.phases.sources import butterworth, contact_source, pca_source, preprocess_source, usable_cutoff

__all__ = ["LocalPhases", "SLOTS", "DEFAULT_SOURCES", "default_sources", "fit_sinusoids", "SinusoidFit",
           "phase_and_amplitude", "extract_local_phases", "phase_updates", "hips_local_positions"]

#: The order of the four local phases (and of the 8 phase numbers, two per slot).
SLOTS = ("left hand", "right hand", "left foot", "right foot")
#: Contact-free PCA for the hands, contacts for the feet (Sec. 4.1.2-4.1.3).
DEFAULT_SOURCES = ("pca", "pca", "contact", "contact")


def default_sources(style: Optional[str] = None) -> tuple:
    """Source kinds per slot for a style name (docs/original-code.md §3.3).

    In hopping styles the lifted foot never touches the floor, so it gets the contact-free source:
    ``LeftHop`` (hopping on the left foot) -> right foot PCA, ``RightHop`` -> left foot PCA.
    """
    s = list(DEFAULT_SOURCES)
    if style == "LeftHop":
        s[3] = "pca"
    elif style == "RightHop":
        s[2] = "pca"
    return tuple(s)


@dataclass
class LocalPhases:
    """Local phases of the four end effectors [left hand, right hand, left foot, right foot].

    phase:     (F, 4) φ in [0, 1), cycles.
    amplitude: (F, 4) >= 0, (units of the normalised source) × m/s.
    Extras for inspection and plotting (None when not computed), all (F, 4):
    source:    the preprocessed source functions that were fitted.
    fit:       each frame's fitted sinusoid evaluated at that frame.
    frequency: fitted frequency in Hz (0 where the window was skipped).
    """

    phase: np.ndarray
    amplitude: np.ndarray
    source: Optional[np.ndarray] = field(default=None, repr=False)
    fit: Optional[np.ndarray] = field(default=None, repr=False)
    frequency: Optional[np.ndarray] = field(default=None, repr=False)

    def mirrored(self) -> "LocalPhases":
        """The phases of the left-right mirrored motion: left and right slots swapped (§3.1,
        ``GetPhases(mirrored=True)``); the phase values themselves do not change."""
        swap = [1, 0, 3, 2]
        pick = lambda a: None if a is None else a[:, swap].copy()
        return LocalPhases(pick(self.phase), pick(self.amplitude), pick(self.source), pick(self.fit),
                           pick(self.frequency))

    def vectors(self) -> np.ndarray:
        """(F, 8) Eq. (1): [s0, c0, ..., s3, c3] = amplitude · (sin 2πφ, cos 2πφ) per slot."""
        angle = 2 * np.pi * self.phase
        out = np.empty(self.phase.shape[:1] + (8,))
        out[:, 0::2] = self.amplitude * np.sin(angle)
        out[:, 1::2] = self.amplitude * np.cos(angle)
        return out


def phase_updates(vectors) -> np.ndarray:
    """(F, 8) phase vectors -> (F-1, 8) updates p_{k+1} − p_k (the network's phase output, §4.7)."""
    p = np.asarray(vectors, dtype=np.float64)
    return p[1:] - p[:-1]


def phase_and_amplitude(fit: SinusoidFit, local_speed, fps: float, cutoff: float = 4.0):
    """Per-frame phase and amplitude from a sinusoid fit (§4.5-§4.6).

    Args:
        fit: the fit of one source function, (F,) arrays.
        local_speed: (F,) the bone's speed relative to the hips (m/s).
        fps: frames per second.
        cutoff: Butterworth cut-off of the post-processing, Hz.
    Returns:
        phase (F,) in [0, 1), amplitude (F,) >= 0.
    """
    speed = np.asarray(local_speed, dtype=np.float64)
    n = speed.size
    # PAPER: Eq. (1)'s ‖v_w‖ is taken "over a one second window"; here, as in the original code,
    # over one fitted period around each frame: W = round(fps / F) frames, the overflow window of
    # W // 2 (the same second for a 1 Hz cycle).
    with np.errstate(divide="ignore"):
        period = np.where(fit.frequency > 0, np.floor(fps / np.where(fit.frequency > 0, fit.frequency, 1) + 0.5), 0)
    lo, hi = overflow_window(np.arange(n), (period // 2).astype(np.int64), n)
    amplitude = fit.amplitude * range_reduce(speed, lo, hi, np.maximum)
    # PAPER: the paper does not smooth the phase or the amplitude after the fit; the original code
    # low-passes both with the source's 4 Hz Butterworth filter (the phase as its sin and cos), as here.
    angle = 2 * np.pi * fit.phase
    cutoff = usable_cutoff(cutoff, fps)
    sc = butterworth(np.stack([np.sin(angle), np.cos(angle)], axis=1), fps, cutoff)
    phase = np.mod(np.arctan2(sc[:, 0], sc[:, 1]) / (2 * np.pi), 1.0)
    phase[(np.hypot(sc[:, 0], sc[:, 1]) == 0) | (phase >= 1.0)] = 0.0
    amplitude = np.maximum(butterworth(amplitude, fps, cutoff), 0.0)
    return phase, amplitude


def hips_local_positions(motion, skeleton) -> np.ndarray:
    """(F, 4, 3) phase-bone positions in the hips' own frame, R_hips^T (p − p_hips) (§3.4)."""
    positions, rotations = motion.world()
    h = skeleton.hips_index(motion)
    bones = skeleton.phase_indices(motion)
    rel = positions[:, bones] - positions[:, h, None]
    return np.einsum("fji,fbj->fbi", rotations[:, h], rel)


def extract_local_phases(motion, skeleton, contacts=None, sources: Optional[Sequence[str]] = None,
                         **fit_options) -> LocalPhases:
    """The four local phases of a motion (Sec. 4.1, Eq. 1).

    Args:
        motion: a Motion (one file: one style and gait, since the PCA is per file).
        skeleton: its Skeleton (phase_bones, contact_bones, hips, facing_axis).
        contacts: (F, 2) 0/1 in the order [right, left] (``foot_contacts``); needed when a slot
            uses the 'contact' source. :func:`minifilm.phases.label.label` computes both.
        sources: 4 strings 'pca' | 'contact' for [left hand, right hand, left foot, right foot];
            default ('pca', 'pca', 'contact', 'contact'); see ``default_sources(style)``.
        **fit_options: passed to ``fit_sinusoids`` (window_seconds, n_frequencies, sweeps, ...).
    Returns:
        LocalPhases with phase, amplitude, and the source, fit and frequency extras.
    """
    sources = tuple(DEFAULT_SOURCES if sources is None else sources)
    if len(sources) != 4 or any(s not in ("pca", "contact") for s in sources):
        raise ValueError(f"extract_local_phases: sources must be 4 of 'pca' | 'contact' for {SLOTS}, got {sources}")
    fps = motion.fps
    n = motion.n_frames
    if n < 2:
        raise ValueError(f"{motion.source}: {n} frame(s); labelling its local phases needs at least 2")
    if contacts is None and "contact" in sources:
        raise ValueError(f"extract_local_phases({motion.source}): the 'contact' sources need the foot "
                         "contacts (label() in minifilm/phases/label.py computes both)")
    if contacts is not None:
        contacts = np.asarray(contacts, dtype=np.float64)
        if contacts.shape != (n, 2):
            raise ValueError(f"extract_local_phases({motion.source}): contacts must have shape ({n}, 2) "
                             f"[right, left], got {contacts.shape}")
    local = hips_local_positions(motion, skeleton)                      # (F, 4, 3)
    speed = np.zeros((n, 4))
    if n >= 2:  # hips-relative velocity, backward difference, frame 0 copies frame 1 (§1.4)
        speed[1:] = np.linalg.norm(local[1:] - local[:-1], axis=-1) * fps
        speed[0] = speed[1]
    contact_column = {2: 1, 3: 0}  # left foot <- contacts[:, 1], right foot <- contacts[:, 0]
    out = {key: np.zeros((n, 4)) for key in ("phase", "amplitude", "source", "fit", "frequency")}
    for slot, kind in enumerate(sources):
        if kind == "contact":
            if slot not in contact_column:
                raise ValueError(f"extract_local_phases: slot {SLOTS[slot]!r} has no foot contact; use 'pca'")
            raw = contact_source(contacts[:, contact_column[slot]])
        else:
            raw = pca_source(local[:, slot], skeleton.facing_axis)
        values = preprocess_source(raw, fps)
        fit = fit_sinusoids(values, fps, **fit_options)
        phase, amplitude = phase_and_amplitude(fit, speed[:, slot], fps)
        for key, value in (("phase", phase), ("amplitude", amplitude), ("source", values),
                           ("fit", fit.fit), ("frequency", fit.frequency)):
            out[key][:, slot] = value
    return LocalPhases(**out)
