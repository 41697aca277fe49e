"""Inputs and outputs of the comparison backbones (Sec. 5), derived from the LPN's training data.

The dataset (minifilm/dataset/build.py) produces the LPN's arrays: x, the local phases p (Eq. 1) and z with the
next frame's phases and phase updates. The other backbones see the same motion differently:

PFNN   gate input: ONE global phase φ in [0, 1) (N, 1). It is the angle of the right foot's local
       phase, φ = atan2(s, c) / 2π mod 1 from p's right-foot (sin, cos) pair. The feet's local
       phases are fitted to the foot contacts (phase source 'contact', docs/original-code.md §3), so
       this is a contact-based global phase as the PFNN's: one cycle per right-foot step cycle.
       Output: the 324 motion numbers (trajectory + joints), the phase update Δφ = φ(next) − φ
       wrapped to [−½, ½) (cycles per frame, standardised with the training split's mean / std),
       and the 2 contacts: 327 numbers.
MANN   gate input: the velocities of the 4 phase end effectors (hands, feet), read from x's joint
       block (already normalised): 12 numbers. Output: 324 motion numbers + 2 contacts.
LPN    unchanged.

The motion columns keep their positions (z starts with the trajectory and joints), so the
bone-length loss indices of the layout (`layout.joint_columns('z', 'position')`) and the
dataset's z statistics still apply to the first 324 columns.
"""
from __future__ import annotations

import numpy as np

from minifilm.baselines.variants import SPECS
from minifilm.dataset.arrays import TrainData

#: p / z slot used for the PFNN's global phase (layout.PHASE_SLOTS: left hand, right hand, left foot, right foot)
RIGHT_FOOT_SLOT = 3


def phase_angle(sin_cos) -> np.ndarray:
    """(N, 2) amplitude-scaled (sin 2πφ, cos 2πφ) -> φ (N,) in [0, 1)."""
    return np.mod(np.arctan2(sin_cos[:, 0], sin_cos[:, 1]) / (2 * np.pi), 1.0)


def end_effector_indices(layout, skeleton) -> list:
    """Joint indices (in the layout) of the skeleton's 4 phase bones, in phase-slot order."""
    missing = [b for b in skeleton.phase_bones if b not in layout.joint_names]
    if missing:
        raise ValueError(f"end_effector_indices: phase bones {missing} are not exported joints of the layout")
    return [list(layout.joint_names).index(b) for b in skeleton.phase_bones]


def variant_data(name: str, data: TrainData, layout, stats, end_effectors=None, reference=None,
                 phase_slot: int = RIGHT_FOOT_SLOT):
    """The variant's TrainData and an info dict (column meanings, Δφ statistics).

    data       the LPN's TrainData (normalised with `stats`, a NormStats)
    layout     the FeatureLayout the data was built with
    end_effectors  4 joint indices for the MANN's gate (see end_effector_indices)
    reference  the info returned for the training split: val / test reuse its Δφ statistics
    """
    if name not in SPECS:
        raise ValueError(f"variant_data: unknown variant {name!r}")
    backbone = SPECS[name][0]
    motion = np.arange(0, layout.z_phases.start)
    contacts = np.arange(layout.z_contacts.start, layout.z_contacts.stop)
    info = {"backbone": backbone, "motion_columns": motion}
    if backbone == "lpn":
        return data, info
    if backbone == "mann":
        if end_effectors is None or len(end_effectors) != 4:
            raise ValueError("variant_data: the MANN needs the 4 end-effector joint indices (end_effectors)")
        cols = layout.joint_columns("x", "velocity")[np.asarray(end_effectors)].ravel()
        p = data.x[:, cols]
        z = np.concatenate([data.z[:, motion], data.z[:, contacts]], axis=1)
        info.update(gate_columns_of_x=cols, contact_columns=(len(motion), len(motion) + 2))
    else:
        pair = 2 * phase_slot + np.arange(2)
        p_raw = data.p[:, pair] * stats.p_std[pair] + stats.p_mean[pair]
        zp = layout.z_phases.start + pair
        z_raw = data.z[:, zp] * stats.z_std[zp] + stats.z_mean[zp]
        phase = phase_angle(p_raw)
        dphase = np.mod(phase_angle(z_raw) - phase + 0.5, 1.0) - 0.5
        if reference is None:
            mean, std = float(dphase.mean()), float(dphase.std())
            std = std if std > 1e-8 else 1.0
        else:
            mean, std = reference["phase_update_mean"], reference["phase_update_std"]
        p = phase[:, None]
        z = np.concatenate([data.z[:, motion], ((dphase - mean) / std)[:, None], data.z[:, contacts]], axis=1)
        info.update(phase_slot=phase_slot, phase_update_mean=mean, phase_update_std=std,
                    phase_update_column=len(motion), contact_columns=(len(motion) + 1, len(motion) + 3))
    dtype = data.z.dtype
    out = TrainData(x=data.x, p=np.ascontiguousarray(p, dtype=dtype), z=np.ascontiguousarray(z, dtype=dtype),
                    style=data.style, clips=data.clips, clip_style=data.clip_style,
                    style_names=list(data.style_names))
    return out, info
