"""Generate stylised locomotion with the authors' released network, entirely in NumPy (Sec. 4.4).

    python examples/generate_released.py --style Zombie --script figure8 --seconds 30 --out zombie.bvh --png zombie.png
    python examples/generate_released.py --style Neutral --style2 Old --blend 0.5 --out blend.bvh
    python examples/generate_released.py --style Neutral --style2 Old --style3 Zombie --weights 0.2 0.3 0.5
    python examples/generate_released.py --style Neutral --switch-to Zombie --switch-at 10 --out switch.bvh
    python examples/generate_released.py --list-styles

Scripts: straight, figure8, walk_run_stop, strafe (minifilm.runtime.control). The BVH goes onto the
100STYLE skeleton read from --skeleton-bvh (default: ../shared/data/100style/Neutral_FR_first3frames.bvh),
in its own channel order; every frame is put on that skeleton (rigid bones, the demo's arm IK for
the whole body) and fed back to the network, as the demo does (--fit). --png draws side-view stick figures, the path from above, and the hips
height / root speed over time.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from minifilm.runtime.control import distance_to_path, make_script, SCRIPTS  # noqa: E402
from minifilm.motion.measures import bone_length_cv, foot_sliding  # noqa: E402
from minifilm.motion.bvh import read_bvh  # noqa: E402
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.foot_ik import FootLocker  # noqa: E402
from minifilm.features.layout import FeatureLayout  # noqa: E402
from minifilm.motion.skeletons import STYLE100  # noqa: E402
from minifilm.runtime.calibration import calibrate_speed  # noqa: E402
from minifilm.runtime.controller import Controller, root_joint_indices  # noqa: E402
from minifilm.runtime.network import RuntimeNetwork  # noqa: E402
from minifilm.runtime.style_library import StyleLibrary  # noqa: E402

SHARED = REPO.parent / "shared" / "data"


def render(rollout, parents, path, out, every=10, max_figures=14, title="", start=60):
    """Side-view stick figures of character 0 every ``every`` frames from ``start``, the root path
    from above, and hips height / toe height / root speed over time, into a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    P, root, contacts = rollout.positions[0], rollout.root_positions[0], rollout.contacts[0]
    F = len(P)
    frames = np.arange(start, F, every)[:max_figures]
    fig = plt.figure(figsize=(3 + 1.0 * len(frames), 7.5))
    ax = fig.add_axes([0.03, 0.47, 0.94, 0.47])
    for n, k in enumerate(frames):
        facing = rollout.root_facing[0, k]
        fwd = np.array([facing[0], 0.0, facing[1]])
        u = (P[k] - P[k, 0]) @ fwd + 1.0 * n          # the character's own forward axis, laid in a row
        for j, p in enumerate(parents):
            if p >= 0:
                ax.plot([u[p], u[j]], [P[k, p, 1], P[k, j, 1]], "-", lw=1.6,
                        color="tab:red" if "Right" in STYLE100.joints[j] else "k")
        ax.text(1.0 * n, -0.15, f"{k}\nR{contacts[k, 0]:.1f} L{contacts[k, 1]:.1f}", ha="center", fontsize=7)
    ax.axhline(0, color="gray", lw=0.8)
    ax.set_aspect("equal")
    ax.set_ylim(-0.25, 1.95)
    ax.set_xticks([])
    ax.set_title(f"{title} — side view (facing right; right side red), every {every} frames")
    ax2 = fig.add_axes([0.04, 0.05, 0.3, 0.36])
    if path is not None:
        ax2.plot(path[:, 0], path[:, 1], "-", color="lightgray", lw=4, label="commanded")
    ax2.plot(root[:, 0], root[:, 1], "-", color="tab:red", lw=1, label="root")
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.legend(fontsize=7)
    ax2.set_title("top view (x, z), metres", fontsize=9)
    ax3 = fig.add_axes([0.42, 0.05, 0.55, 0.36])
    t = np.arange(F) / rollout.fps
    ax3.plot(t, P[:, 0, 1], label="hips height (m)")
    ax3.plot(t, P[:, STYLE100.joints.index("RightToe"), 1], label="right toe height (m)", lw=0.8)
    speed = np.r_[0, np.linalg.norm(np.diff(root, axis=0), axis=1) * rollout.fps]
    ax3.plot(t, speed, label="root speed (m/s)", lw=0.8)
    ax3.set_xlabel("time (s)")
    ax3.legend(fontsize=7, loc="upper right")
    fig.savefig(out, dpi=75)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", default=str(SHARED / "released-lpn"), help="released parameter folder")
    ap.add_argument("--style", default="Neutral")
    ap.add_argument("--style2", help="second style, blended with --blend w: (1-w) style + w style2")
    ap.add_argument("--blend", type=float, default=0.5)
    ap.add_argument("--style3", help="third style: barycentric blend with --weights w1 w2 w3")
    ap.add_argument("--weights", type=float, nargs=3)
    ap.add_argument("--switch-to", help="switch to this style at --switch-at seconds (smooth, 1 s)")
    ap.add_argument("--switch-at", type=float, default=10.0)
    ap.add_argument("--script", default="figure8", choices=sorted(SCRIPTS))
    ap.add_argument("--speed", type=float, default=1.3, help="walking speed, m/s")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--out", default="motion.bvh")
    ap.add_argument("--skeleton-bvh", default=str(SHARED / "100style" / "Neutral_FR_first3frames.bvh"),
                    help="BVH whose hierarchy, offsets and channel order the output uses")
    ap.add_argument("--foot-lock", action="store_true", help="pin feet in predicted contact (leg IK)")
    ap.add_argument("--fit", choices=("feedback", "output", "none"), default="feedback",
                    help="put each frame on the skeleton (rigid bones) and feed that pose back, as the demo "
                         "feeds back its post-IK pose (default); fit the output only; or no fit")
    ap.add_argument("--no-calibrate", action="store_true", help="command the raw speed (no calibration)")
    ap.add_argument("--png", help="also draw the motion into this PNG")
    ap.add_argument("--png-from", type=float, default=1.0, help="first drawn frame, seconds")
    ap.add_argument("--png-every", type=int, default=10, help="frames between drawn figures")
    ap.add_argument("--list-styles", action="store_true")
    args = ap.parse_args(argv)

    from minifilm.runtime.released import load_released

    rel = load_released(args.params)
    lib = StyleLibrary(rel.styles)
    if args.list_styles:
        print(" ".join(lib.names))
        return 0
    layout = FeatureLayout.for_skeleton(STYLE100)
    net = RuntimeNetwork.from_model(rel.model, rel.stats, runtime_layer_norm=True)
    locker = FootLocker.from_names(layout.joint_names) if args.foot_lock else None
    skeleton = read_bvh(args.skeleton_bvh)
    body = None if args.fit == "none" else Controller.skeleton_for(layout, skeleton)
    ctrl = Controller(net, layout, foot_locker=locker, skeleton=body, feed_back_fit=args.fit == "feedback")

    if args.style3:
        if not args.weights:
            ap.error("--style3 needs --weights w1 w2 w3")
        film = lib.barycentric([args.style, args.style2, args.style3], args.weights)
        label = f"{args.style}/{args.style2}/{args.style3} at {args.weights}"
    elif args.style2:
        film = lib.blend({args.style: 1 - args.blend, args.style2: args.blend})
        label = f"{args.style} + {args.blend:g} {args.style2}"
    else:
        film = lib[args.style]
        label = args.style
    n = int(round(args.seconds * ctrl.fps))
    films = film
    if args.switch_to:
        films = lib.schedule([(0.0, {args.style: 1.0}), (args.switch_at, args.switch_to)], n, ctrl.fps)
        label += f" -> {args.switch_to} at {args.switch_at:g} s"

    cal = None
    if not args.no_calibrate:
        t0 = time.perf_counter()
        cal = calibrate_speed(Controller(net, layout), film)
        achieved = "; ".join(f"{d:g} deg: {row[1:].round(2).tolist()}" for d, row in zip(cal.directions, cal.achieved))
        print(f"speed calibration ({time.perf_counter() - t0:.1f} s): commands {cal.commanded[1:].round(1).tolist()} m/s "
              f"-> achieved m/s by direction from the facing ({achieved})")
    script = make_script(args.script, args.seconds, speed=args.speed) if args.script != "strafe" else \
        make_script(args.script, args.seconds, speed=min(args.speed, 1.0))
    t0 = time.perf_counter()
    r = ctrl.run(script, n, films, calibration=cal)
    dt = time.perf_counter() - t0

    motion = r.to_motion(skeleton, root_joint_indices(layout, skeleton))
    write_bvh(motion, args.out)
    toes = [layout.joint_names.index("RightToe"), layout.joint_names.index("LeftToe")]
    d = distance_to_path(r.root_positions[0], script.path)
    hips = r.positions[0, :, 0, 1]
    speed = np.linalg.norm(np.diff(r.root_positions[0], axis=0), axis=1).mean() * ctrl.fps
    print(f"{label}: {n} frames in {dt:.1f} s ({dt / n * 1e3:.2f} ms/frame) -> {args.out}")
    print(f"  path distance mean {d.mean():.2f} m (max {d.max():.2f}), mean speed {speed:.2f} m/s, "
          f"hips {hips.min():.2f}-{hips.max():.2f} m, bone CV max {bone_length_cv(r.network_positions[0, 60:], STYLE100.parents).max():.1%} "
          f"as predicted ({bone_length_cv(r.positions[0, 60:], STYLE100.parents).max():.1%} output), "
          f"foot sliding {foot_sliding(r.positions[0, 60:], r.contacts[0, 60:], toes, ctrl.fps):.3f} m/s")
    if args.png:
        render(r, STYLE100.parents, script.path, args.png, every=args.png_every, title=label,
               start=int(round(args.png_from * ctrl.fps)))
        print(f"  drawing -> {args.png}")
    return 0


if __name__ == "__main__":
    from minifilm.cli import run

    run(main)
