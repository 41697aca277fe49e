"""Draw a BVH file's foot contacts and local phases like the paper's Figure 4 (Sec. 4.1).

    minifilm phases FILE.bvh [--out phases.png] [--skeleton NAME] [--style NAME]
                             [--start SECONDS] [--stop SECONDS] [--animation walk.gif]

Any humanoid BVH file: a built-in skeleton (100style, bandai, cmu, cmu-mb) is detected from the
joint names (or named with ``--skeleton``) and labelled as always; any other humanoid is labelled
on its hips, wrists and toes found by names or structure, in the unit its legs give
(minifilm/body/read.py). ``--style LeftHop`` / ``RightHop`` switches the lifted foot to the
contact-free source; every other style is labelled the same way, so other names are refused.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from minifilm.cli.args import gif_path, input_path, png_path, seconds_at_least
from minifilm.files import check_writable
from minifilm.body.read import load_for_phases
from minifilm.body.rig import HumanoidRig
from minifilm.phases.label import label
from minifilm.phases.local_phases import LocalPhases
from minifilm.viewer.deps import check_output_tools
from minifilm.viewer.gif import write_gif
from minifilm.viewer.phase_plot import plot_phases
from minifilm.viewer.tracks import track_from_motion

HELP = "draw a BVH file's contacts and local phases (Figure 4)"


def add_arguments(parser) -> None:
    parser.add_argument("bvh", type=input_path, help="the BVH file")
    parser.add_argument("--out", type=png_path, default=Path("phases.png"), help="PNG to write (default phases.png)")
    parser.add_argument("--skeleton", default=None, help="built-in skeleton name (default: detected; "
                        "any other humanoid is found by its names or structure)")
    parser.add_argument("--style", type=hop_style, default=None,
                        help="LeftHop or RightHop: the lifted foot gets the contact-free source (every other "
                             "style is labelled as without --style)")
    parser.add_argument("--start", type=seconds_at_least(0.0), default=0.0, help="first second to draw")
    parser.add_argument("--stop", type=seconds_at_least(0.0), default=None, help="last second to draw")
    parser.add_argument("--animation", type=gif_path, help="also write the motion of the same seconds as an animated GIF "
                        "(contacts highlighted), to watch beside the plot")


#: the styles whose labelling differs: the foot that never lands gets the contact-free source
HOP_STYLES = ("LeftHop", "RightHop")


def hop_style(text: str) -> str:
    """``--style``: one of :data:`HOP_STYLES` (any case); an argparse error for any other name,
    which would be labelled exactly as without the option."""
    for name in HOP_STYLES:
        if text.strip().lower() == name.lower():
            return name
    raise argparse.ArgumentTypeError(
        f"{text[:60]!r}: only {' and '.join(HOP_STYLES)} change how phases are labelled (the foot that never "
        "lands gets the contact-free source); leave --style out for any other style")


def frames_shown(t: np.ndarray, start: float, stop, source) -> np.ndarray:
    """The mask of the frames at times ``t`` between ``start`` and ``stop`` (None: the end);
    ValueError naming the file's length when none are."""
    if stop is not None and stop < start:
        raise ValueError(f"--stop {stop:g} s comes before --start {start:g} s")
    keep = (t >= start) & (t <= (t[-1] if stop is None else stop))
    if not np.any(keep):
        span = f"from {start:g} s to the end" if stop is None else f"between {start:g} s and {stop:g} s"
        raise ValueError(f"no frames {span}: {source} lasts {t[-1]:.2f} s")
    return keep


def load(path, skeleton_name=None):
    """Read ``path`` in metres with its rig: the built-in skeleton named or detected from the joint
    names, else its humanoid parts (HumanoidError when it has none)."""
    motion, rig, _ = load_for_phases(path, skeleton_name)
    return motion, rig


def run(args) -> int:
    out = check_writable(args.out, "--out")
    check_output_tools(out, "png")
    if args.animation:
        check_writable(args.animation, "--animation")
        check_output_tools(args.animation, "gif")
    motion, skeleton, unit = load_for_phases(args.bvh, args.skeleton)
    if unit is not None:
        print(f"{Path(args.bvh).name}: {skeleton.name}; unit {unit.how}")
    labels = label(motion, skeleton, args.style)
    t = np.arange(motion.n_frames) / motion.fps
    keep = frames_shown(t, args.start, args.stop, args.bvh)
    ph = labels.phases
    view = LocalPhases(*(None if a is None else a[keep] for a in
                         (ph.phase, ph.amplitude, ph.source, ph.fit, ph.frequency)))
    rig = skeleton.name if isinstance(skeleton, HumanoidRig) else f"skeleton {skeleton.name}"
    title = f"{Path(args.bvh).name}: {motion.n_frames} frames at {motion.fps:.0f} fps, {rig}"
    plot_phases(t[keep], view, labels.contacts[keep], labels.sources, out, title)
    print(f"wrote {out}")
    if args.animation:
        frames = np.flatnonzero(keep)
        clip = motion.slice(int(frames[0]), int(frames[-1]) + 1)
        sensors = skeleton.contact_indices(motion)
        track = track_from_motion(clip, name=Path(args.bvh).stem, contacts=labels.contacts[keep],
                                  contact_joints=list(sensors),
                                  humanoid=skeleton.humanoid if isinstance(skeleton, HumanoidRig) else None)
        write_gif(track, args.animation)
        print(f"wrote {args.animation}")
    return 0
