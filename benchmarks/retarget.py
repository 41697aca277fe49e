"""Retargeting checks on the real data, per source (figures in benchmarks/README.md).

    python benchmarks/retarget.py                                   # every real file -> 100STYLE, round trips
    python benchmarks/retarget.py --released DIR                    # + 100STYLE-rig clips (e.g. made by
                                                                    #   minifilm generate --params ...) round trips
    python benchmarks/retarget.py --every 10 --gifs docs/img        # every 10th file; the GIFs of docs/retargeting.md

Per source (Bandai-1, Bandai-2, Xia, CMU), every file retargeted to the 100STYLE rig:
  * bone directions: per mapped bone, the median over frames of the angle between source and
    target; the table gives the median over files and the worst file, per bone;
  * contacts: the fraction of frames on which source and target foot contacts agree (min, median);
  * skating: target minus source mean toe-tip speed during contacts, cm/s (max over files);
  * standing height (min, max over files), metres;
  * the floor: the target's lowest toe tip (y = 0 is the floor) and the share of frames on which a
    toe tip is more than 1 cm below it; the source's lowest toe tip above its own floor;
  * smoothness: the toe tips' peak acceleration (m/s^2, the largest second difference of a tip's
    position times fps^2; median over files / worst file) and its 99th percentile, target and source;
  * phases: whether local phases could be labelled on the result (minifilm.phases.label, the
    labelling ``minifilm phases`` draws), on every ``--phases-every``-th file.
Round trips (mapped joints, after the leg-length scale; median and 95th percentile over frames,
pooled over files, and the worst single file): 100STYLE clips -> Bandai -> 100STYLE, and Bandai ->
100STYLE -> Bandai, each file coming back onto its own skeleton (the file's hierarchy as the target
rig, as ``minifilm retarget --to FILE.bvh``); with the feet planted (the whole method) and without
(the pose transfer and root scaling alone).
Timings are not measured; the load (``uptime``) is printed for the record.
"""
from __future__ import annotations

import argparse
import glob
import os
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np

from minifilm.evaluation.retargeting import (bone_direction_errors, contact_agreement, round_trip_errors, skating,
                                             standing_height)
from minifilm.body import read_source, retarget_motion
from minifilm.body.feet import floor_height
from minifilm.body.roles import sensor_positions
from minifilm.pipeline.run_rig import load_target as load_rig
from minifilm.motion.skeletons import STYLE100
from minifilm.phases.label import label

from retarget_gifs import write_pictures

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"


def sources(data: Path):
    return {"Bandai-1": sorted(glob.glob(str(data / "bvh" / "bandai1" / "*.bvh"))),
            "Bandai-2": sorted(glob.glob(str(data / "bandai2" / "*.bvh"))),
            "Xia": sorted(glob.glob(str(data / "bvh" / "xia" / "*.bvh"))),
            "CMU": sorted(glob.glob(str(data / "bvh" / "cmu" / "*.bvh")))}


def to_100style(name, files, target, every_phases):
    per_bone = defaultdict(list)
    agree, skate, height, phases_ok, phases_tried = [], [], [], 0, 0
    lowest, sunk, src_lowest = [], [], []     # the target's toe tips below the floor (y = 0)
    acc, src_acc = [], []                        # the tips' (peak, 99th percentile) accelerations
    for i, path in enumerate(files):
        m, roles = read_source(path)
        out = retarget_motion(m, target, roles)
        for bone, err in bone_direction_errors(m, roles, out, target.roles).items():
            per_bone[bone.split(" ", 1)[-1]].append(float(np.median(err)))
        agree.append(contact_agreement(m, roles, out, target.roles))
        skate.append(skating(out, target.roles) - skating(m, roles))
        height.append(standing_height(out, target.roles))
        tips = out.world()[0][:, [out.names.index(target.roles.limb(s).sensor) for s in ("left", "right")], 1]
        lowest.append(float(tips.min()))
        sunk.append(float(np.mean(tips.min(axis=1) < -0.01)))
        s_tips = sensor_positions(m.world()[0], m, roles)
        src_lowest.append(float(s_tips[..., 1].min() - floor_height(s_tips, m.fps)))
        acc.append(tip_acceleration(out, target.roles))
        src_acc.append(tip_acceleration(m, roles))
        if i % every_phases == 0:
            phases_tried += 1
            try:
                label(out, STYLE100)
                phases_ok += 1
            except ValueError as e:
                print(f"    phases failed on {path}: {e}")
    print(f"\n{name}: {len(files)} files -> 100style")
    print(f"  contacts agree: min {min(agree):.3f}, median {np.median(agree):.3f}; files below 0.95: "
          f"{sum(a < 0.95 for a in agree)}")
    print(f"  skating, target - source: max {100 * max(skate):+.2f} cm/s, median {100 * np.median(skate):+.2f} cm/s")
    print(f"  standing height: {min(height):.2f} - {max(height):.2f} m")
    print(f"  toe tips below the floor: lowest {100 * min(lowest):.1f} cm (median over files {100 * np.median(lowest):.1f}); "
          f"frames with a tip below -1 cm: median {100 * np.median(sunk):.0f} %, max {100 * max(sunk):.0f} %; "
          f"the source's lowest tip above its floor: {100 * min(src_lowest):.1f} cm")
    a, sa = np.array(acc), np.array(src_acc)
    print(f"  toe-tip acceleration, m/s^2 (median over files / worst): peak {np.median(a[:, 0]):.0f} / {a[:, 0].max():.0f}, "
          f"99th pct {np.median(a[:, 1]):.0f} / {a[:, 1].max():.0f}; source peak {np.median(sa[:, 0]):.0f} / "
          f"{sa[:, 0].max():.0f}, 99th pct {np.median(sa[:, 1]):.0f} / {sa[:, 1].max():.0f}")
    print(f"  phases labelled on {phases_ok} of {phases_tried} results")
    print("  bone direction error, degrees (median over frames; median over files / worst file):")
    for bone, v in per_bone.items():
        print(f"    {bone:16s} {np.median(v):6.2f} / {max(v):6.2f}")


def tip_acceleration(motion, roles):
    """(peak, 99th percentile) of the toe tips' acceleration (m/s^2): second differences times fps^2."""
    s = sensor_positions(motion.world()[0], motion, roles)
    if len(s) < 3:
        return np.zeros(2)
    a = np.linalg.norm(s[2:] - 2 * s[1:-1] + s[:-2], axis=-1) * motion.fps ** 2
    return np.array([a.max(), np.percentile(a, 99)])


def round_trip(label_text, files, second, plant=True):
    """Each file -> ``second`` -> back onto the file's own skeleton (its hierarchy as the rig, as
    ``minifilm retarget --to FILE.bvh`` takes it), so a file whose proportions differ from the
    built-in rig of its kind (Bandai-1 ``run_normal_001``'s legs are 3.5 % longer) comes back to
    itself."""
    per_joint, per_file = defaultdict(list), {}
    for path in files:
        m, roles = read_source(path)
        own = load_rig(path)
        there = retarget_motion(m, second, roles, plant=plant)
        back = retarget_motion(there, own, second.roles, plant=plant)
        errors = round_trip_errors(m, roles, back, own.roles)
        for joint, d in errors.items():
            per_joint[joint].append(d)
        per_file[Path(path).stem] = max(np.percentile(d, 95) for d in errors.values()) * 100
    print(f"\nround trip {label_text}{'' if plant else ', feet not planted'}: {len(files)} files, each back onto "
          "its own skeleton; mapped joints, cm (median / 95th percentile)")
    worst = 0.0
    for joint, ds in per_joint.items():
        d = np.concatenate(ds) * 100
        worst = max(worst, np.percentile(d, 95))
        print(f"    {joint:16s} {np.median(d):5.2f} / {np.percentile(d, 95):5.2f}")
    print(f"  largest 95th percentile: {worst:.2f} cm")
    name = max(per_file, key=per_file.get)
    print(f"  worst single file: {name}, largest 95th percentile {per_file[name]:.2f} cm; files over 3 cm: "
          f"{sorted(k for k, v in per_file.items() if v > 3.0)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DATA, help="the shared data folder")
    ap.add_argument("--released", type=Path, help="folder of 100STYLE-rig BVH files (the released network's output)")
    ap.add_argument("--every", type=int, default=1, help="take every n-th file of each source")
    ap.add_argument("--phases-every", type=int, default=1, help="label phases on every n-th result")
    ap.add_argument("--gifs", type=Path, help="write one GIF per source (original beside retargeted) here, as "
                    "benchmarks/retarget_gifs.py does")
    args = ap.parse_args()
    print(f"load: {os.popen('uptime').read().strip()}")
    target, bandai = load_rig("100style"), load_rig("bandai")
    groups = {k: v[::args.every] for k, v in sources(args.data).items() if v}
    for name, files in groups.items():
        to_100style(name, files, target, args.phases_every)
    if args.gifs is not None:
        print("\nGIFs, one clip per source beside itself on 100STYLE (benchmarks/retarget_gifs.py):")
        write_pictures(args.data, args.gifs)
    for plant in (True, False):
        if args.released is not None:
            round_trip("100STYLE -> Bandai -> 100STYLE", sorted(glob.glob(str(args.released / "*.bvh"))), bandai,
                       plant)
        round_trip("Bandai -> 100STYLE -> Bandai", groups.get("Bandai-1", []) + groups.get("Bandai-2", []), target,
                   plant)


if __name__ == "__main__":
    with tempfile.TemporaryDirectory():
        main()
