"""The retargeting pictures: one clip of each real source beside itself on the 100STYLE character.

    python benchmarks/retarget_gifs.py                  # docs/img/retarget_{bandai1,bandai2,cmu}.gif
    python benchmarks/retarget_gifs.py --out gifs  # elsewhere, with the Xia clip too
    python benchmarks/retarget.py --gifs DIR            # the same, after the retargeting checks

Each clip is read as ``minifilm retarget`` reads it, put on the built-in 100STYLE rig with
``retarget_motion`` (feet planted), and both are drawn side by side at their true sizes, the foot
contacts marked (the viewer's contact test on each): the original on the left, the 100STYLE
character on the right. The GIFs are kept small for the repository: at most 3.5 s at about 15 fps,
200 x 250 pixels per character, 32 colours (about 0.4-0.6 MB each). The data's licences are in
docs/retargeting.md (Bandai Namco: CC BY-NC 4.0; Xia et al.: research use; CMU: free with
acknowledgement). The Xia clips carry no licence that allows redistribution, so their picture is
drawn only into a folder of your own (``--out``), never into the repository's docs/img.
"""
from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

from minifilm.motion.bvh_write import write_bvh
from minifilm.body import load_rig, read_source, retarget_motion
from minifilm.viewer.builders import track_with_contacts
from minifilm.viewer.gif import write_gif

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", REPO.parent / "shared" / "data"))
DOCS_IMG = REPO / "docs" / "img"
#: sources whose licence does not let the repository carry pictures made from them
NOT_IN_REPOSITORY = {"xia"}
#: (source, tag, file under the data folder, title of the original): a styled walk of each
CLIPS = (("Bandai-1", "bandai1", "bvh/bandai1/dataset-1_walk_proud_001.bvh", "Bandai-1 proud walk"),
         ("Bandai-2", "bandai2", "bandai2/dataset-2_walk_feminine_001.bvh", "Bandai-2 feminine walk"),
         ("Xia", "xia", "bvh/xia/sexy_01_000.bvh", "Xia sexy walk"),
         ("CMU", "cmu", "bvh/cmu/08_01_trimmed.bvh", "CMU 08_01 walk"))
SECONDS, FPS, SIZE, COLOURS = 3.5, 15.0, (200, 250), 32


def picture(source_path: Path, gif_path: Path, title: str, target) -> Path:
    """Write ``gif_path``: ``source_path`` (left) beside itself retargeted onto ``target`` (right)."""
    motion, roles = read_source(source_path)
    with tempfile.TemporaryDirectory(prefix="retarget-gif-") as tmp:
        on = Path(tmp) / "on.bvh"
        write_bvh(retarget_motion(motion, target, roles), on, scale=target.bvh_scale)
        tracks = [track_with_contacts(source_path, name=title),
                  track_with_contacts(on, name=f"on {Path(target.name).name.upper()}")]
    every = max(1, int(round(motion.fps / FPS)))                   # 30 fps -> 15, 120 fps -> 15
    write_gif(tracks, gif_path, seconds=min(SECONDS, motion.n_frames / motion.fps), every=every, size=SIZE,
              colours=COLOURS)
    return gif_path


def write_pictures(data: Path, out: Path, log=print) -> list:
    """One GIF per source in ``out`` (``retarget_<tag>.gif``); sources whose file is missing are skipped."""
    out.mkdir(parents=True, exist_ok=True)
    target, written = load_rig("100style"), []
    for source, tag, rel, title in CLIPS:
        if tag in NOT_IN_REPOSITORY and out.resolve() == DOCS_IMG.resolve():
            log(f"  {source}: not drawn into docs/img (its licence allows research use only; use --out)")
            continue
        path = data / rel
        if not path.is_file():
            log(f"  {source}: {path} not found, no GIF")
            continue
        gif = picture(path, out / f"retarget_{tag}.gif", title, target)
        log(f"  {source}: {gif} ({gif.stat().st_size / 1e6:.2f} MB)")
        written.append(gif)
    log(f"  together {sum(g.stat().st_size for g in written) / 1e6:.2f} MB")
    return written


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DATA, help="the shared data folder")
    ap.add_argument("--out", type=Path, default=DOCS_IMG, help="folder to write the GIFs into")
    args = ap.parse_args()
    write_pictures(args.data, args.out)


if __name__ == "__main__":
    main()
