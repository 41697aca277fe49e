"""Generate stylised locomotion with the authors' released network, entirely in NumPy (Sec. 4.4).

    python examples/generate_released.py --params ../shared/data/released-lpn --style Zombie --seconds 30 --out zombie.bvh
    python examples/generate_released.py --params ../shared/data/released-lpn --style Old --gif old.gif --html old.html

A walk-through of the runtime API; ``minifilm generate`` does the same with every option (style
blends and switches, other scripts, foot locking, pictures, trained runs).
"""
import argparse

from minifilm.cli import report_errors
from minifilm.cli.args import positive
from minifilm.features.layout import FeatureLayout
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.skeletons import STYLE100
from minifilm.runtime.calibration import calibrate_speed
from minifilm.runtime.control import figure_eight
from minifilm.runtime.controller import Controller
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.released import load_released
from minifilm.files import check_writable
from minifilm.synthetic.generator import rest_motion
from minifilm.viewer import tracks_from_rollout, write_gif, write_html
from minifilm.viewer.deps import check_output_tools


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", required=True, help="the released parameter folder")
    ap.add_argument("--style", default="Neutral", help="one of the 100 released styles")
    ap.add_argument("--seconds", type=positive(float, 3600.0), default=30.0)
    ap.add_argument("--out", default="motion.bvh")
    ap.add_argument("--gif", help="also write the motion as an animated GIF (needs minifilm[viz])")
    ap.add_argument("--html", help="also write it into a 3-D player that opens offline in a browser")
    args = ap.parse_args()
    check_writable(args.out, "--out")   # before the work: a typo in a path or a missing package costs nothing
    for kind in ("gif", "html"):
        if getattr(args, kind):
            check_writable(getattr(args, kind), f"--{kind}")
            check_output_tools(getattr(args, kind), kind)

    # 1. Ω and Φ, the normalisation statistics and 100 FiLM vectors (one per style); Ψ is not
    #    released, nor needed at run time: a style is its FiLM vector.
    released = load_released(args.params)
    film = released.styles[args.style]

    # 2. A controller for the 100STYLE feature layout at 60 fps. Every frame is put on the
    #    skeleton (rigid bones aimed at the predicted joints) and fed back, as the demo does.
    layout = FeatureLayout.for_skeleton(STYLE100)
    skeleton = rest_motion()
    controller = Controller(released.network, layout, fps=60.0, feed_back_fit=True,
                            skeleton=Controller.skeleton_for(layout, skeleton))

    # 3. Ask for 1.3 m/s along a figure-eight; the calibration maps that to the command that makes
    #    this style really move at 1.3 m/s (the network follows the user's trajectory only partly).
    calibration = calibrate_speed(Controller(released.network, layout), film)
    n = int(round(args.seconds * 60))
    rollout = controller.run(figure_eight(args.seconds, speed=1.3), n, film, calibration=calibration)

    # 4. Local rotations on the 100STYLE skeleton, written as BVH in centimetres.
    write_bvh(rollout.to_motion(skeleton, root_joint_indices(layout, skeleton)), args.out)
    speed = rollout.metrics(layout.parents)[0]["speed"]
    print(f"{args.style}: {n} frames, mean speed {speed:.2f} m/s -> {args.out}")

    # 5. See it: a Rollout holds joint positions only, so the layout gives the bones and names.
    if args.gif or args.html:
        tracks = tracks_from_rollout(rollout, layout.parents, [args.style], layout.joint_names)
        if args.gif:
            print(f"animation -> {write_gif(tracks, args.gif, seconds=min(args.seconds, 10.0)).path}")
        if args.html:
            print(f"3-D player -> {write_html(tracks, args.html, title=args.style)}")


if __name__ == "__main__":
    report_errors(main)
