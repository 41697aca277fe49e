"""The paper's Figure 4: a motion's foot contacts and local phases, one row per end effector.

Each row (left hand, right hand, left foot, right foot) shows the preprocessed source function
(black), each frame's fitted sinusoid at that frame (dashed), the phase as vertical bars whose
opacity is the amplitude, and the foot contacts (green).
"""
from __future__ import annotations

import numpy as np

from minifilm.phases.local_phases import SLOTS
from minifilm.viewer.deps import pyplot, save_figure


def plot_phases(t, phases, contacts, sources, out, title=""):
    """Draw the figure into the PNG ``out``. t (F,) seconds, phases LocalPhases, contacts (F, 2)
    [right, left], sources: the source kind of each slot."""
    plt = pyplot()
    from matplotlib.collections import LineCollection  # with pyplot: part of the optional extra

    fig, axes = plt.subplots(4, 1, figsize=(12, 9), sharex=True)
    amp_max = max(float(phases.amplitude.max()), 1e-9)
    foot_contact = {2: contacts[:, 1], 3: contacts[:, 0]}
    for slot, ax in enumerate(axes):
        src, fit = phases.source[:, slot], phases.fit[:, slot]
        # Phase bars live on a twin axis in [0, 1] (cycles); contacts in a strip below them.
        ax2 = ax.twinx()
        rgba = np.zeros((t.size, 4))
        rgba[:, :3] = (0.15, 0.35, 0.85)
        rgba[:, 3] = np.clip(phases.amplitude[:, slot] / amp_max, 0, 1)
        segments = np.stack([np.stack([t, np.zeros_like(t)], 1), np.stack([t, phases.phase[:, slot]], 1)], 1)
        ax2.add_collection(LineCollection(segments, colors=rgba, linewidths=1.0))
        if slot in foot_contact:
            c = foot_contact[slot] > 0.5
            ax2.fill_between(t, -0.16, -0.04, where=c, color=(0.1, 0.7, 0.2), step="mid", lw=0)
        ax2.set_ylim(-0.18, 1.02)
        ax2.set_yticks([0, 0.25, 0.5, 0.75, 1.0])
        ax2.set_ylabel("phase (cycles)", color=(0.15, 0.35, 0.85))
        ax.plot(t, src, color="k", lw=1.3, label="source (preprocessed)", zorder=3)
        ax.plot(t, fit, color=(0.9, 0.4, 0.0), lw=1.2, ls="--", label="fitted sinusoid at its frame", zorder=3)
        lim = max(1e-3, np.abs(np.concatenate([src, fit])).max()) * 1.1
        ax.set_ylim(-lim - 0.2 * lim, lim)
        ax.set_zorder(ax2.get_zorder() + 1)
        ax.patch.set_visible(False)
        ax.set_ylabel("source")
        med = np.median(phases.amplitude[:, slot])
        ax.set_title(f"{SLOTS[slot]} — {sources[slot]} source, median amplitude {med:.2f}, "
                     f"median frequency {np.median(phases.frequency[:, slot]):.2f} Hz", fontsize=10, loc="left")
        if slot == 0:
            ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s); blue bars: phase, opacity = amplitude; green: contact")
    axes[-1].set_xlim(t[0], t[-1])
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    save_figure(fig, out, dpi=110)
