"""Put motion capture of any humanoid rig onto another rig (docs/retargeting.md).

    minifilm retarget walk_bandai.bvh run_cmu.bvh --to 100style --out retargeted/
    minifilm retarget clip.bvh --to runs/train_small --out on_run/          # the run's skeleton
    minifilm retarget clip.bvh --to my_rig.bvh --out out/ --map clip_map.json --to-map my_rig_map.json

TARGET is a built-in rig (100style, bandai, cmu), a run folder written by ``minifilm train`` (its
skeleton.bvh) or any BVH file (its hierarchy). Each source file is written to OUT/<its name>.bvh on
the target rig, in the target's channel order and units. Joints are matched by role (hips, spine,
neck, head, arms, legs); a rig minifilm does not recognise needs a JSON map of its roles (--map for
the sources, --to-map for the target). Every input (target, sources, maps, outputs) is checked
before anything is printed or written.
"""
from __future__ import annotations

from pathlib import Path

from minifilm.cli.args import in_range, input_path, non_empty, output_folder
from minifilm.errors import InputError
from minifilm.files import check_writable, child_path, shared_file_names
from minifilm.motion.bvh_write import write_bvh
from minifilm.pipeline.run_rig import load_target
from minifilm.body import read_source, retarget_motion

HELP = "put motion of any humanoid rig onto another rig (100style, bandai, cmu, a run, a BVH)"


def add_arguments(ap) -> None:
    ap.add_argument("files", nargs="+", type=input_path, help="BVH files to retarget (any humanoid rig)")
    ap.add_argument("--to", required=True, type=non_empty("--to"), metavar="TARGET",
                    help="100style, bandai, cmu, a run folder, or a BVH file whose hierarchy is the rig")
    ap.add_argument("--out", type=output_folder, required=True, help="folder to write the retargeted BVH files into")
    ap.add_argument("--map", type=input_path, help="JSON map of the source files' joint roles (docs/retargeting.md)")
    ap.add_argument("--to-map", type=input_path, help="JSON map of the target rig's joint roles")
    ap.add_argument("--scale", type=in_range(1e-6, 1e6, low_open=True),
                    help="metres per BVH unit of the source files (default: a built-in rig's, else guessed "
                         "from the legs)")
    ap.add_argument("--no-plant", action="store_true", help="do not pin the feet during contacts (only put them on the floor)")


def run(args) -> int:
    target = load_target(args.to, args.to_map)
    stems = [Path(f).stem for f in args.files]
    shared = shared_file_names(stems)      # after the names are made safe: a:b.bvh and a_b.bvh meet in a_b.bvh
    if shared:
        made, names = shared[0]
        given = list(dict.fromkeys(str(f) for f, s in zip(args.files, stems) if s in names))
        raise InputError(f"the source files {', '.join(given)} would all be written to {args.out / (made + '.bvh')} "
                         "(names are made safe for every file system and compared regardless of case); "
                         "rename one or retarget them into different --out folders")
    outs = [child_path(args.out, stem, ".bvh") for stem in stems]
    for out in outs:                                    # every output checked before the first is written
        check_writable(out, "retargeted BVH")
    # Every source read (and its roles found) before anything is printed or written, so a missing
    # or bad file late in the list is one error, not a half-written folder. The motions are not
    # kept: a batch of hundreds of clips would not fit in memory, and reading is cheap beside
    # retargeting.
    for f in args.files:
        read_source(f, args.map, args.scale)
    print(f"[retarget] target rig {target.name}: {target.template.n_joints} joints, "
          f"{target.bvh_scale:g} m per unit")
    args.out.mkdir(parents=True, exist_ok=True)
    for f, out in zip(args.files, outs):
        motion, roles = read_source(f, args.map, args.scale)
        result = retarget_motion(motion, target, roles, plant=not args.no_plant)
        write_bvh(result, out, scale=target.bvh_scale)
        print(f"    {f} -> {out} ({result.n_frames} frames at {result.fps:.4g} fps)")
    return 0
