"""Generate stylised locomotion with the authors' released network or a model trained here (Sec. 4.4).

    minifilm generate --params ../shared/data/released-lpn --style Zombie --script figure8 --seconds 30 --out zombie.bvh
    minifilm generate --run runs/train_small --style Drunk --seconds 20 --out drunk.bvh
    minifilm generate --params DIR --style Neutral --style2 Old --blend 0.5 --out blend.bvh
    minifilm generate --params DIR --style Neutral --style2 Old --style3 Zombie --weights 0.2 0.3 0.5
    minifilm generate --params DIR --style Neutral --switch-to Zombie --switch-at 10 --out switch.bvh
    minifilm generate --params DIR --style Old --seconds 10 --gif old.gif --html old.html
    minifilm generate --params DIR --list-styles
    minifilm generate --params DIR --styles PACK --style Strut --out strut.bvh    # a style taught with finetune --params

Scripts: straight, figure8, walk_run_stop, strafe, stop_and_go (minifilm/runtime/control.py). Every frame is put
on the source skeleton (rigid bones aimed at the predicted joints, the demo's arm IK for the whole
body) and the BVH is written on that skeleton in its own channel order. For the released network
the fitted pose is fed back to the network, as the demo feeds back its post-IK pose, and the speed
is calibrated per style; for a trained run the fit is an output post-process and the run's own
start frames and settings are used (both measured choices, see --fit and --no-calibrate).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from minifilm.cli.args import (add_network_source, bvh_path, gif_path, html_path, in_range, input_path, png_path,
                               positive)
from minifilm.cli.memory import GENERATE_BYTES_PER_JOINT_FRAME, VIEW_BYTES_PER_JOINT_FRAME, add_memory_option, \
    check_memory
from minifilm.dataset.progress import Progress
from minifilm.errors import InputError
from minifilm.features.layout import FeatureLayout
from minifilm.files import check_writable, few
from minifilm.body.read import read_in_metres
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.measures import bone_length_cv, foot_sliding
from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.run_folder import RunFolder
from minifilm.runtime.adapted import with_adapters
from minifilm.runtime.calibration import calibrate_speed
from minifilm.runtime.control import SCRIPTS, distance_to_path, make_script
from minifilm.runtime.controller import Controller
from minifilm.runtime.held_body import TOE_NAMES, foot_locker, toe_joints
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.released import load_released
from minifilm.runtime.style_library import StyleLibrary
from minifilm.runtime.style_pack import load_pack, with_pack
from minifilm.runtime.walk_checks import walk_report
from minifilm.synthetic.generator import rest_motion
from minifilm.viewer.builders import tracks_from_rollout
from minifilm.viewer.deps import check_output_tools
from minifilm.viewer.gif import write_gif
from minifilm.viewer.html import write_html
from minifilm.viewer.strip import draw_strip

HELP = "generate motion with the released network or a trained run"


def add_arguments(ap) -> None:
    add_network_source(ap)
    ap.add_argument("--style", type=style_name, help="style name (see --list-styles); default: the first style")
    ap.add_argument("--style2", type=style_name, help="second style, blended with --blend w: (1-w) style + w style2")
    ap.add_argument("--blend", type=in_range(0.0, 1.0), help="weight of --style2, in [0, 1] (default 0.5)")
    ap.add_argument("--style3", type=style_name, help="third style: barycentric blend with --weights w1 w2 w3")
    ap.add_argument("--weights", type=in_range(0.0, 1.0), nargs=3, help="three weights >= 0 summing to 1")
    ap.add_argument("--switch-to", type=style_name, help="switch to this style at --switch-at seconds (smooth, 1 s)")
    ap.add_argument("--switch-at", type=in_range(0.0, 24 * 3600.0),
                    help="seconds (default 10, or half the motion when shorter)")
    ap.add_argument("--script", default="figure8", choices=sorted(SCRIPTS))
    ap.add_argument("--speed", type=in_range(0.0, 10.0), default=1.3, help="walking speed, m/s (0-10)")
    ap.add_argument("--seconds", type=positive(float, 3600.0), default=30.0, help="length, seconds")
    ap.add_argument("--out", type=bvh_path, default=Path("motion.bvh"), help="BVH file to write")
    ap.add_argument("--skeleton-bvh", type=input_path,
                    help="BVH whose hierarchy, offsets and channel order the output uses: the network's "
                         "skeleton (its joint names) with other proportions or channels; another rig goes "
                         "through `minifilm retarget` (default: the run's skeleton, or the 100STYLE skeleton "
                         "for the released network)")
    ap.add_argument("--foot-lock", action="store_true", help="pin feet in predicted contact (leg IK)")
    ap.add_argument("--fit", choices=("feedback", "output", "none"),
                    help="put each frame on the skeleton and feed that pose back (released default), fit the "
                         "output only (trained-run default), or no fit")
    ap.add_argument("--no-calibrate", action="store_true", help="command the raw speed (no calibration)")
    ap.add_argument("--gif", type=gif_path, help="also write the motion as an animated GIF")
    ap.add_argument("--html", type=html_path, help="also write the motion into an offline 3-D HTML player")
    ap.add_argument("--png", type=png_path, help="also draw the motion into this PNG")
    ap.add_argument("--png-from", type=in_range(0.0, 24 * 3600.0),
                    help="first drawn frame, seconds (default 1, the first second starting from the mean pose; "
                         "half the motion when it is shorter than 2 s)")
    ap.add_argument("--png-every", type=in_range(1, 100_000, int), default=10, help="frames between drawn figures")
    ap.add_argument("--list-styles", action="store_true", help="print the style names and stop")
    add_memory_option(ap)


#: The fastest --script strafe is walked: it is a sidestepping walk, and sidesteps go at walking pace.
STRAFE_TOP_SPEED = 1.0


def style_name(text: str) -> str:
    """A style option's name; an argparse error for an empty one (it would be taken for no style)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("give a style name (see --list-styles), not an empty string")
    return text


def script_speed(script: str, speed: float) -> float:
    """The speed ``script`` is walked at for ``--speed``: strafe's sideways steps at most
    :data:`STRAFE_TOP_SPEED`, said on stdout when it caps the speed asked for."""
    if script == "strafe" and speed > STRAFE_TOP_SPEED:
        print(f"note: --script strafe walks sideways at most {STRAFE_TOP_SPEED:g} m/s: --speed {speed:g} "
              f"is capped to {STRAFE_TOP_SPEED:g} m/s")
        return STRAFE_TOP_SPEED
    return speed


class Source:
    """What drives the character: network, layout, styles, skeleton, settings and start frames."""

    def __init__(self, args):
        self.starts, self.pack = {}, None
        if args.params is not None:
            rel = load_released(args.params)
            if args.styles is not None:
                self.pack = load_pack(args.styles, film_dim=4 * rel.model.config.hidden, reserved=rel.styles,
                                      network=rel.network)
            # a pack style's adapter acts only while that style is on (runtime/adapted.py)
            self.network, self.library = with_adapters(rel.network, with_pack(rel.styles, self.pack),
                                                       self.pack.adapters if self.pack else {})
            self.layout, self.fps, self.bvh_scale = FeatureLayout.for_skeleton(STYLE100), 60.0, STYLE100.bvh_scale
            self.skeleton = rest_motion()
            self.fit, self.calibrate, self.options = args.fit or "feedback", not args.no_calibrate, {}
        else:
            if args.styles is not None:
                raise InputError("--styles (a style pack) is for --params; a run folder keeps its styles itself")
            run = RunFolder.load(args.run)
            self.network, self.library = run.adapted()
            self.layout, self.fps, self.bvh_scale = run.layout, run.fps, run.bvh_scale
            self.skeleton = run.template()
            self.starts = run.starts()
            # a small model trained here does not survive commands far outside its data's speeds
            # (calibrate_speed asks for them), and stops stepping more often when fed the fitted pose
            self.fit, self.calibrate = args.fit or "output", False
            self.options = {"position_bias": run.position_bias}
        if args.skeleton_bvh is not None:
            self.skeleton = skeleton_in_metres(args.skeleton_bvh, self.bvh_scale)


def skeleton_in_metres(path, run_unit: float):
    """The ``--skeleton-bvh`` file in metres, its unit found as ``view`` and ``retarget`` find it
    (minifilm.body.read.read_in_metres): a skeleton in millimetres or metres is converted
    (and said so), one that is not a humanoid or has no size (all-zero offsets) is refused."""
    skeleton, humanoid, unit = read_in_metres(path)
    if humanoid is None:
        raise InputError(f"--skeleton-bvh {path}: its size cannot be told ({unit.how}); give a humanoid "
                         "skeleton with its bones' real offsets")
    if abs(unit.metres_per_unit / run_unit - 1.0) > 1e-6:
        print(f"[generate] --skeleton-bvh {path}: read in {unit.how}; the output is written in "
              f"{run_unit:g} m per unit like the skeleton it replaces")
    return skeleton


def style_condition(args, lib: StyleLibrary, n: int, fps: float):
    """(film for the whole run or per frame, the film of the start style, a label)."""
    style = lib.names[0] if args.style is None else args.style
    lib[style]                       # an unknown name fails here, before any work
    for flag, value, needs in (("--blend", args.blend, args.style2), ("--switch-at", args.switch_at, args.switch_to)):
        if value is not None and not needs:
            raise InputError(f"{flag} needs {'--style2' if flag == '--blend' else '--switch-to'}")
    blend = 0.5 if args.blend is None else args.blend
    switch_at = min(10.0, args.seconds / 2) if args.switch_at is None else args.switch_at
    if args.weights and not args.style3:
        raise InputError("--weights w1 w2 w3 needs --style2 and --style3 (three styles to weigh)")
    if args.style3:
        if not args.weights or not args.style2:
            raise InputError("--style3 needs --style2 and --weights w1 w2 w3")
        film = lib.barycentric([style, args.style2, args.style3], args.weights)
        label = f"{style}/{args.style2}/{args.style3} at {args.weights}"
    elif args.style2:
        film = lib.blend([(style, 1 - blend), (args.style2, blend)])
        label = f"{style} + {blend:g} {args.style2}"
    else:
        film, label = lib[style], style
    films = film
    if args.switch_to and switch_at >= args.seconds:
        raise InputError(f"--switch-at {switch_at:g}: the motion lasts only {args.seconds:g} s (--seconds)")
    if args.switch_to:
        films = lib.schedule([(0.0, {style: 1.0}), (switch_at, args.switch_to)], n, fps)
        label += f" -> {args.switch_to} at {switch_at:g} s"
    return films, film, label


def walk_problems(args, src, r, script, toes, parents, k0) -> list:
    """The failures a user must be told about, in words: no stepping, feet off the floor, the path
    lost, bones stretching; for a pack style also steps/s and hip height against its clip's.
    toes: the [right, left] toe joints (:func:`~minifilm.runtime.held_body.toe_joints`; None: no check)."""
    if toes is None:
        return []
    clip = {}
    if src.pack is not None and args.style in src.pack.info and not (args.style2 or args.switch_to):
        clip = src.pack.info[args.style].get("clip", {})
    rep = walk_report(r, 0, toes, script.path,
                      clip_steps_per_s=clip.get("steps_per_s"), clip_hips=clip.get("hips"))
    problems = rep.problems() if args.speed > 0.2 else []
    cv = bone_length_cv(r.network_positions[0, k0:], parents).max()
    if cv > 0.1:
        problems.append(f"the predicted bones stretch by {cv:.0%} (coefficient of variation of the worst bone)")
    far = start_far_outside(src, args.style or src.library.names[0])
    return problems + ([far] if far else [])


def start_far_outside(src, style: str):
    """For a run's style, words when its start frame (the first frame of the motion it was trained
    or taught from, starts.npz) lies far outside the run's data: more than 1 % of its normalised
    input numbers beyond 5 σ, as ``finetune`` warns about the whole clip; else None."""
    x0 = src.starts.get(style, (None, None))[0]
    if x0 is None:
        return None
    share = float(np.mean(np.abs(src.network.stats.normalize_x(np.asarray(x0, np.float64))) > 5.0))
    if share <= 0.01:
        return None
    return (f"the style {style!r} was taught from motion far outside the run's data ({share:.0%} of the input "
            "numbers of its first frame beyond 5 σ of the run's data): it will not move like its clip")


def run(args) -> int:
    src = Source(args)                   # first: the files it reads may not be outputs (checked next)
    out = check_writable(args.out, "--out")
    for flag in ("png", "gif", "html"):  # every picture checked (path, tools) before the rollout
        if getattr(args, flag):
            check_writable(getattr(args, flag), f"--{flag}")
            check_output_tools(getattr(args, flag), flag)
    lib = src.library
    if args.list_styles:
        print(" ".join(lib.names))
        return 0
    n = int(round(args.seconds * src.fps))
    if n < 2:
        raise InputError(f"--seconds {args.seconds:g}: fewer than two frames at {src.fps:g} fps; "
                         f"give at least {2 / src.fps:.3g} s")
    per_frame = src.layout.n_joints * (GENERATE_BYTES_PER_JOINT_FRAME + (VIEW_BYTES_PER_JOINT_FRAME if args.html else 0))
    check_memory(n * per_frame, args.max_memory, f"--seconds {args.seconds:g} ({n:,} frames)",
                 "generate fewer seconds")
    if args.png_from is None:
        args.png_from = min(1.0, args.seconds / 2)
    if args.png and args.png_from >= args.seconds:
        raise InputError(f"--png-from {args.png_from:g}: the motion lasts only {args.seconds:g} s (--seconds); "
                         "the drawing would be empty")
    films, film, label = style_condition(args, lib, n, src.fps)
    joints = root_joint_indices(src.layout, src.skeleton)
    locker = foot_locker(src.layout) if args.foot_lock else None
    if args.foot_lock and locker is None:
        raise InputError(f"--foot-lock: the skeleton's toes are not found among its joints ({few(src.layout.joint_names)}): "
                         f"foot locking knows the toes named {few(n for pair in TOE_NAMES for n in pair)}")
    body = None if src.fit == "none" else Controller.skeleton_for(src.layout, src.skeleton)
    ctrl = Controller(src.network, src.layout, fps=src.fps, foot_locker=locker, skeleton=body,
                      feed_back_fit=src.fit == "feedback", **src.options)
    start_x, phases = src.starts.get(lib.names[0] if args.style is None else args.style, (None, None))

    cal = None
    if src.calibrate:
        t0 = time.perf_counter()
        cal = calibrate_speed(Controller(src.network, src.layout, fps=src.fps, **src.options), film,
                              phases=phases, start_x=start_x)
        achieved = "; ".join(f"{d:g} deg: {row[1:].round(2).tolist()}" for d, row in zip(cal.directions, cal.achieved))
        print(f"speed calibration ({time.perf_counter() - t0:.1f} s): commands {cal.commanded[1:].round(1).tolist()} m/s "
              f"-> achieved m/s by direction from the facing ({achieved})")
    speed = script_speed(args.script, args.speed)
    script = make_script(args.script, args.seconds, speed=speed)
    t0 = time.perf_counter()
    shown = Progress(n, "generate", enabled=args.seconds > 60, unit="frames")   # (a minute takes seconds)
    r = ctrl.run(script, n, films, calibration=cal, phases=phases, start_x=start_x, progress=shown.update)
    dt = time.perf_counter() - t0
    if not np.all(np.isfinite(r.positions)):
        raise ValueError(f"the network's output became non-finite during the rollout ({label}); nothing written")

    write_bvh(r.to_motion(src.skeleton, joints), out, scale=src.bvh_scale)
    names = list(src.layout.joint_names)
    parents = src.layout.parents
    k0 = min(int(round(src.fps)), n - 2)
    d = distance_to_path(r.root_positions[0], script.path)
    hips = r.positions[0, :, 0, 1]
    mean_speed = np.linalg.norm(np.diff(r.root_positions[0], axis=0), axis=1).mean() * src.fps
    toes = toe_joints(names)                          # [right, left], None on a rig without known toes
    sliding = (f", foot sliding {foot_sliding(r.positions[0, k0:], r.contacts[0, k0:], toes, src.fps):.3f} m/s"
               if toes is not None else "")
    print(f"{label}: {n} frames in {dt:.1f} s ({dt / n * 1e3:.2f} ms/frame) -> {out}")
    print(f"  path distance mean {d.mean():.2f} m (max {d.max():.2f}), mean speed {mean_speed:.2f} m/s, "
          f"hips {hips.min():.2f}-{hips.max():.2f} m, bone CV max "
          f"{bone_length_cv(r.network_positions[0, k0:], parents).max():.1%} as predicted "
          f"({bone_length_cv(r.positions[0, k0:], parents).max():.1%} output){sliding}")
    problems = walk_problems(args, src, r, script, toes, parents, k0)
    if problems:
        print("  WARNING: " + "; ".join(problems))
    if args.gif or args.html:
        track = tracks_from_rollout(r, parents, [label], names, toes)
        if args.html:
            print(f"  3-D player -> {write_html(track, args.html, title=label)}")
        if args.gif:
            write_gif(track, args.gif)
            print(f"  animation -> {args.gif}")
    if args.png:
        path = draw_strip(r, parents, names, script.path, args.png, every=args.png_every, title=label,
                          start=int(round(args.png_from * src.fps)))
        print(f"  drawing -> {path}")
    return 0
