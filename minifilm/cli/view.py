"""Show BVH files: an animated GIF (and MP4 with ffmpeg) and a self-contained HTML player.

    minifilm view walk.bvh run.bvh --gif walks.gif          # characters side by side, no ffmpeg needed
    minifilm view walk.bvh --html walk.html                  # 3-D player: orbit, play/pause/scrub/speed
    minifilm view runs/train_small/generated/*.bvh --gif styles.gif --html styles.html --seconds 6
    minifilm view walk.bvh --out walk.mp4                    # --out: the format its extension names
    minifilm view bandai_walk.bvh --on 100style --gif on_100style.gif   # any humanoid on the standard character

Each file is one character, titled with its name (shortened to fit its panel) and drawn from its
own hierarchy at its true size: the unit comes from the skeleton, else from the body's height
(minifilm/body/units.py). On any humanoid skeleton, found by its joint names or its shape
(minifilm/body/humanoid.py), the foot contacts are highlighted. The HTML page opens offline from
disk (three.js is inlined). Without --out, --gif, --mp4 or --html: --html view.html.
"""
from __future__ import annotations

import argparse
import tempfile
from typing import Sequence
from pathlib import Path

from minifilm.cli.args import gif_path, html_path, in_range, input_path, mp4_path, non_empty, positive
from minifilm.cli.memory import VIEW_BYTES_PER_JOINT_FRAME, add_memory_option, check_memory
from minifilm.errors import InputError
from minifilm.files import check_writable
from minifilm.motion.bvh import bvh_header
from minifilm.motion.bvh_write import write_bvh
from minifilm.pipeline.run_rig import load_target
from minifilm.body import read_source, retarget_motion
from minifilm.viewer.builders import track_and_unit, track_with_contacts
from minifilm.viewer.deps import check_output_tools
from minifilm.viewer.gif import write_gif
from minifilm.viewer.html import write_html
from minifilm.viewer.mp4 import write_mp4

HELP = "show BVH files as an animated GIF and an offline 3-D HTML player"

#: --out's extensions and the output each names
OUTPUT_KINDS = {".gif": "gif", ".mp4": "mp4", ".html": "html", ".htm": "html"}


def output_path(text: str):
    """(kind, path) of an --out argument, the kind named by its extension; an argparse error for
    any other extension (found now, before any file is read)."""
    p = Path(text)
    kind = OUTPUT_KINDS.get(p.suffix.lower())
    if kind is None:
        shown = f"'{p.suffix}'" if p.suffix else "no extension"
        raise argparse.ArgumentTypeError(f"{text} has {shown}; --out writes the format its extension names: "
                                         ".gif (animated GIF), .mp4 (video, needs ffmpeg) or .html (3-D player)")
    if p.is_dir() or not p.stem:
        raise argparse.ArgumentTypeError(f"{text}: give a file name, not a folder")
    return kind, p


output_path.output, output_path.suffixes = "file", tuple(OUTPUT_KINDS)


def add_arguments(ap) -> None:
    ap.add_argument("files", nargs="+", type=input_path, help="BVH files, one character each")
    ap.add_argument("--out", type=output_path, action="append", default=[], metavar="FILE",
                    help="file to write, its format named by its extension: .gif, .mp4 or .html (repeatable)")
    ap.add_argument("--gif", type=gif_path, help="animated GIF to write")
    ap.add_argument("--mp4", type=mp4_path, help="MP4 to write (needs ffmpeg on the PATH)")
    ap.add_argument("--html", type=html_path, help="self-contained HTML player to write")
    ap.add_argument("--seconds", type=positive(float, 3600.0), help="length of the GIF / MP4 (default: the longest file)")
    ap.add_argument("--every", type=in_range(1, 1000, int),
                    help="keep every n-th frame in the GIF / MP4 (default: all frames, except that a GIF "
                         "keeps at most 50 fps, since browsers slow faster GIFs down: 60 fps becomes 30)")
    ap.add_argument("--size", type=in_range(40, 2000, int), nargs=2, default=(240, 300), metavar=("W", "H"),
                    help="pixels per character panel in the GIF / MP4 (default 240 300)")
    ap.add_argument("--no-contacts", action="store_true", help="do not highlight the foot contacts")
    ap.add_argument("--no-trail", action="store_true", help="do not draw the root's trail")
    ap.add_argument("--on", type=non_empty("--on"), metavar="TARGET", help="draw every file retargeted onto this rig: 100style (the "
                    "standard character), bandai, cmu, a run folder or a BVH file (docs/retargeting.md)")
    add_memory_option(ap)


def run(args) -> int:
    flags = {kind: f"--{kind}" for kind in ("gif", "mp4", "html")}
    for kind, path in args.out:               # --out x.gif is --gif x.gif; one file per format
        if getattr(args, kind) is not None:
            raise InputError(f"two {kind.upper()} outputs given ({getattr(args, kind)} and {path}); "
                             f"give one (--out {path} or --{kind} {path})")
        setattr(args, kind, path)
        flags[kind] = "--out"
    if args.gif is None and args.mp4 is None and args.html is None:
        args.html = Path("view.html")
    for kind in ("gif", "mp4", "html"):  # every output checked before the first one is written
        if getattr(args, kind) is not None:
            check_writable(getattr(args, kind), flags[kind])
            check_output_tools(getattr(args, kind), kind)
    check_view_memory(args.files, args.max_memory)
    if args.on is not None:        # minimal hook for retargeting (retarget's module draws nothing itself)
        tracks = tracks_on(args.files, args.on)
    else:
        tracks = []
        for f, name in zip(args.files, panel_names(args.files)):
            track, unit = track_and_unit(f, name)
            if "skeleton's unit" not in unit.how:   # said when the unit was inferred, not known
                print(f"{f}: {unit.how}")
            tracks.append(track)
    if args.no_contacts:
        for t in tracks:
            t.contacts = t.contact_joints = None
    kw = dict(seconds=args.seconds, every=args.every, size=tuple(args.size), contacts=not args.no_contacts,
              trail=not args.no_trail)
    if args.html is not None:
        print(f"wrote {write_html(tracks, args.html, title=', '.join(t.name for t in tracks))} "
              "(open it in a browser; it works offline)")
    if args.gif is not None:
        r = write_gif(tracks, args.gif, **kw)
        print(f"wrote {args.gif} ({r.n_frames} frames at {r.fps:.4g} fps)")
    if args.mp4 is not None:
        write_mp4(tracks, args.mp4, **kw)
        print(f"wrote {args.mp4}")
    return 0


def check_view_memory(paths: Sequence, max_memory) -> None:
    """InputError before any file is read when the files' tracks would not fit (their headers'
    frames x joints; see minifilm/cli/memory.py)."""
    need, frames = 0, 0
    for path in paths:
        n_frames, _, n_joints = bvh_header(path)
        need += n_frames * max(n_joints, 1) * VIEW_BYTES_PER_JOINT_FRAME
        frames += n_frames
    what = f"{paths[0]}" if len(paths) == 1 else f"{len(paths)} files"
    check_memory(need, max_memory, f"drawing {what} ({frames:,} frames)",
                 "view a shorter part of it (cut the file) or fewer files")


def tracks_on(paths: Sequence, target) -> list:
    """Viewer tracks of BVH files retargeted onto ``target`` (``minifilm view --on``): each file is
    put on the rig, written to a temporary folder and read back as the viewer reads any file
    (true size, contacts), titled '<name> on <rig>'."""
    rig = load_target(target)
    tracks = []
    with tempfile.TemporaryDirectory(prefix="minifilm-view-") as tmp:
        for i, (path, name) in enumerate(zip(paths, panel_names(paths))):
            motion, roles = read_source(path)
            out = Path(tmp) / f"{i}.bvh"
            write_bvh(retarget_motion(motion, rig, roles), out, scale=rig.bvh_scale)
            tracks.append(track_with_contacts(out, name=f"{name} on {Path(rig.name).name}"))
    return tracks


def panel_names(paths: Sequence) -> list:
    """Each file's title: its name without ``.bvh``, with its folder where files share a name
    (``a/walk.bvh`` and ``b/walk.bvh`` are "a/walk" and "b/walk", not two panels called "walk")."""
    stems = [Path(p).stem for p in paths]
    return [f"{Path(p).parent.name}/{s}" if stems.count(s) > 1 else s for p, s in zip(paths, stems)]
