"""Show BVH files: an animated GIF (and MP4 with ffmpeg) and a self-contained HTML player.

    minifilm view walk.bvh run.bvh --gif walks.gif          # characters side by side, no ffmpeg needed
    minifilm view walk.bvh --html walk.html                  # 3-D player: orbit, play/pause/scrub/speed
    minifilm view runs/train_small/generated/*.bvh --gif styles.gif --html styles.html --seconds 6

Each file is one character, titled with its name and drawn from its own hierarchy; on a built-in
skeleton (100STYLE, Bandai Namco, CMU) the foot contacts are highlighted. The HTML page opens
offline from disk (three.js is inlined). Without --gif, --mp4 or --html: --html view.html.
"""
from __future__ import annotations

from pathlib import Path

from minifilm.cli.args import in_range, input_path, positive
from minifilm.files import check_writable
from minifilm.viewer.builders import track_with_contacts
from minifilm.viewer.deps import check_output_tools
from minifilm.viewer.gif import write_gif
from minifilm.viewer.html import write_html
from minifilm.viewer.mp4 import write_mp4

HELP = "show BVH files as an animated GIF and an offline 3-D HTML player"


def add_arguments(ap) -> None:
    ap.add_argument("files", nargs="+", type=input_path, help="BVH files, one character each")
    ap.add_argument("--gif", type=Path, help="animated GIF to write")
    ap.add_argument("--mp4", type=Path, help="MP4 to write (needs ffmpeg on the PATH)")
    ap.add_argument("--html", type=Path, help="self-contained HTML player to write")
    ap.add_argument("--seconds", type=positive(float, 3600.0), help="length of the GIF / MP4 (default: the longest file)")
    ap.add_argument("--every", type=in_range(1, 1000, int),
                    help="keep every n-th frame in the GIF / MP4 (default: all frames, except that a GIF "
                         "keeps at most 50 fps, since browsers slow faster GIFs down: 60 fps becomes 30)")
    ap.add_argument("--size", type=in_range(40, 2000, int), nargs=2, default=(240, 300), metavar=("W", "H"),
                    help="pixels per character panel in the GIF / MP4 (default 240 300)")
    ap.add_argument("--no-contacts", action="store_true", help="do not highlight the foot contacts")
    ap.add_argument("--no-trail", action="store_true", help="do not draw the root's trail")


def run(args) -> int:
    if args.gif is None and args.mp4 is None and args.html is None:
        args.html = Path("view.html")
    for kind in ("gif", "mp4", "html"):  # every output checked before the first one is written
        if getattr(args, kind) is not None:
            check_writable(getattr(args, kind), f"--{kind}")
            check_output_tools(getattr(args, kind), kind)
    tracks = [track_with_contacts(f) for f in args.files]
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
