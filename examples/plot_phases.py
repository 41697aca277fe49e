"""Plot the local phases of a BVH file like the paper's Figure 4 (Sec. 4.1).

One row per end effector (left hand, right hand, left foot, right foot): the preprocessed source
function (white in the paper, black here), each frame's fitted sinusoid at that frame (dashed),
the phase as vertical bars whose opacity is the amplitude, and the foot contacts (green).

    python examples/plot_phases.py path/to/file.bvh [--out fig.png] [--skeleton NAME]
                                   [--start SECONDS] [--stop SECONDS] [--style NAME]

``--skeleton`` is one of the built-ins (100style, bandai, cmu, cmu-mb); by default it is detected
from the joint names. ``--style LeftHop`` / ``RightHop`` switches the lifted foot to the
contact-free source.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from minifilm.motion.bvh import read_bvh  # noqa: E402
from minifilm.phases.contacts import foot_contacts  # noqa: E402
from minifilm.phases.local_phases import SLOTS, default_sources, extract_local_phases  # noqa: E402
from minifilm.motion.skeletons import builtin_skeleton, detect_skeleton  # noqa: E402


def load(path, skeleton_name=None):
    """Read ``path`` in metres with its skeleton (named, or detected from the joint names)."""
    if skeleton_name:
        skeleton = builtin_skeleton(skeleton_name)
    else:
        skeleton = detect_skeleton(read_bvh(path, scale=1.0))
    return read_bvh(path, scale=skeleton.bvh_scale), skeleton


def plot_phases(t, phases, contacts, sources, out, title=""):
    """Draw the figure. t (F,) seconds, phases LocalPhases, contacts (F, 2) [right, left]."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

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
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("bvh")
    parser.add_argument("--out", default="phases.png")
    parser.add_argument("--skeleton", default=None)
    parser.add_argument("--style", default=None, help="style name, e.g. LeftHop (chooses the sources)")
    parser.add_argument("--start", type=float, default=0.0, help="first second to draw")
    parser.add_argument("--stop", type=float, default=None, help="last second to draw")
    args = parser.parse_args(argv)

    motion, skeleton = load(args.bvh, args.skeleton)
    positions, _ = motion.world()
    contacts = foot_contacts(positions[:, skeleton.contact_indices(motion)], motion.fps)
    sources = default_sources(args.style)
    phases = extract_local_phases(motion, skeleton, contacts, sources)
    t = np.arange(motion.n_frames) / motion.fps
    keep = (t >= args.start) & (t <= (args.stop if args.stop is not None else t[-1]))
    if not np.any(keep):
        raise SystemExit(f"no frames between {args.start} s and {args.stop} s (the file lasts {t[-1]:.2f} s)")
    from minifilm.phases.local_phases import LocalPhases
    view = LocalPhases(*(None if a is None else a[keep] for a in
                         (phases.phase, phases.amplitude, phases.source, phases.fit, phases.frequency)))
    title = f"{Path(args.bvh).name}: {motion.n_frames} frames at {motion.fps:.0f} fps, skeleton {skeleton.name}"
    plot_phases(t[keep], view, contacts[keep], sources, args.out, title)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    from minifilm.cli import run

    run(main)
