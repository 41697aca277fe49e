"""A base that has seen real capture: the data of studies/dense_study.py made of the released
network's 100 styles *and* real motion capture retargeted onto the 100STYLE rig, with some real
styles held out to be taught from 30 s with Ψ alone.

    minifilm dataset --from-released ../shared/data/released-lpn --out study/released100
    python studies/real_capture_base.py --released study/released100 --work study/real
    python studies/dense_study.py --trained study/real/trained --held study/real/held \\
        --work study/real/work --epochs 20 --hidden 256 --fps 60 --variants teacher --measure figure-eight

This script writes the two data folders' manifests (and the retargeted files they name):

* ``trained/manifest.csv``: every file of the released network's data set, and the real styles
  trained on: Bandai-Namco-2 normal, Bandai-Namco-1 normal, proud and old, each capped at
  ``--seconds`` spread over its kinds of motion (walk, run, turns, ...);
* ``held/manifest.csv``: the held-out real styles, Bandai-Namco-2 active, elderly, exhausted and
  feminine (up to ``--held-seconds`` each): dense_study teaches each from its first 30 s of walking
  and measures the generated motion against all of its files.

Why these four are held out: they are the four real styles taught to the released network in
reports/2026-12-04_teaching_the_released_network.md, so the two bases are compared on the same
clips; and they are not looked at while building either (the joint-axis alignment was found on
Bandai-Namco-1's proud walk). The base still sees the same actor and studio (Bandai-Namco-2's
normal walk), as the paper's held-out 100STYLE styles share the actor of the trained ones. Xia's
and CMU's files (1-3 s each) are shorter than a style clip and its trajectory window and are left
out, as are files under 3 s.

Real styles are named by their dataset (``Bandai2Elderly``, ``Bandai1Proud``, ...): the two
datasets' "normal" walks are different actors and sessions. Files are read in name order; the cap
takes whole files, kind by kind, until the kind's share of ``--seconds`` is reached.
"""
from __future__ import annotations

import argparse
import os
import re
import sys
from collections import defaultdict
from pathlib import Path

from minifilm.dataset.manifest import MotionFile, read_manifest, write_manifest
from minifilm.motion.bvh import bvh_duration
from minifilm.body.retarget_clip import retarget_file
from minifilm.body.target import builtin_rig

SHARED_DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))

#: the kind of motion in a Bandai-Namco file name -> 100STYLE's gait code, and its share of the cap
KINDS = {"walk": ("FW", 0.5), "run": ("FR", 0.3), "walk-turn-left": ("TR1", 0.1), "walk-turn-right": ("TR1", 0.1),
         "walk-back": ("BW", 0.2), "walk-left": ("SW", 0.2)}
TRAINED = {"bandai2": ("normal",), "bvh/bandai1": ("normal", "proud", "old", "tired")}
HELD = {"bandai2": ("active", "elderly", "exhausted", "feminine")}
SHORTEST = 3.0      # seconds: a file shorter than a 2 s style clip beside the 2 s trajectory window is skipped
SHORTEST_STYLE = 8.0  # seconds of a style in all (Bandai-Namco-1's tired run, 4.4 s, is left out)
NAME = re.compile(r"^dataset-(\d)_([a-z-]+)_([a-z]+)_(\d+)\.bvh$")


def chosen_files(folder: Path, styles, seconds: float) -> dict:
    """{style name: [(path, gait, seconds)]}: the files of ``styles`` in ``folder``, capped per kind."""
    by_kind = defaultdict(list)
    for path in sorted(folder.glob("*.bvh")):
        m = NAME.match(path.name)
        if m and m.group(3) in styles and m.group(2) in KINDS:
            by_kind[(f"Bandai{m.group(1)}{m.group(3).capitalize()}", m.group(2))].append(path)
    out = defaultdict(list)
    for (style, kind), paths in sorted(by_kind.items()):
        gait, share = KINDS[kind]
        total = 0.0
        for p in paths:
            if total >= share * seconds:
                break
            length = bvh_duration(p)
            if length < SHORTEST:
                continue
            out[style].append((p, gait, length))
            total += length
    # a style needs a 2 s clip inside its training share (80 % of each file) beside the 2 s window
    return {k: v for k, v in out.items() if sum(f[2] for f in v) >= SHORTEST_STYLE}


def write_folder(groups: dict, folder: Path, extra=()) -> int:
    """Retarget every chosen file onto the 100STYLE rig into ``folder`` and write its manifest
    (``extra``: files already on it); returns the number of files."""
    folder.mkdir(parents=True, exist_ok=True)
    rig = builtin_rig("100style")
    files = list(extra)
    for style, chosen in sorted(groups.items()):
        for path, gait, _ in chosen:
            out = folder / f"{style}_{path.stem}.bvh"
            if not out.is_file():
                retarget_file(path, rig, out)
            files.append(MotionFile(out, style, gait))
    write_manifest(files, folder / "manifest.csv")
    return len(files)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--released", type=Path, required=True, help="a folder of minifilm dataset --from-released")
    ap.add_argument("--work", type=Path, required=True, help="where trained/ and held/ are written")
    ap.add_argument("--seconds", type=float, default=120.0, help="seconds per trained real style (default 120)")
    ap.add_argument("--held-seconds", type=float, default=240.0, help="seconds per held-out style (default 240)")
    a = ap.parse_args(argv)
    released = read_manifest(a.released / "manifest.csv")
    trained, held = defaultdict(list), defaultdict(list)
    for sub, styles in TRAINED.items():
        trained.update(chosen_files(SHARED_DATA / sub, styles, a.seconds))
    for sub, styles in HELD.items():
        held.update(chosen_files(SHARED_DATA / sub, styles, a.held_seconds))
    n = write_folder(trained, a.work / "trained", extra=released)
    m = write_folder(held, a.work / "held")
    for name, groups in (("trained", trained), ("held", held)):
        for style, chosen in sorted(groups.items()):
            print(f"{name}: {style}: {len(chosen)} files, {sum(f[2] for f in chosen):.0f} s")
    print(f"{a.work / 'trained'}: {n} files ({len(released)} of the released network's); {a.work / 'held'}: {m} files")
    return 0


if __name__ == "__main__":
    sys.exit(main())
