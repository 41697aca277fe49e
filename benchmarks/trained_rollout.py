"""Minute-long rollouts of a minifilm-trained model, one character per style: the run-time checks of benchmarks/released_styles.py.

    python benchmarks/trained_rollout.py --run runs/train_small
    python benchmarks/trained_rollout.py --run DIR --start mean --fit none --position-bias 0.75 --png out.png

DIR is a run folder, what ``minifilm train --out DIR`` (= ``examples/train_small.py``) writes:
model.npz (checkpoint with the normalisation statistics), styles.npz (FiLM vector per style),
starts.npz (a start frame per style) and skeleton.bvh; it works from any working directory. Every style
walks a figure-eight at --speed m/s for --seconds (default 60 s = 3,600 frames at 60 fps), all
styles in one batch, with the runtime settings of train_small (every frame put on the data's
skeleton, ``--fit``; user trajectory weight ``--position-bias 2``). Printed per style (after the
first second): the worst bone's coefficient of variation of length in the network's own
prediction and in the output (0 on the skeleton), the hips' height range, the mean root speed,
the mean and largest distance of the root to the path, and foot sliding (toe speed while the
predicted contact is on).

--start data (default) starts each style from a frame of its own forward-walk data (pose,
trajectory and phases); --start mean from the data's mean pose and mean phases. --calibrate maps
the commanded speed through each style's measured speed calibration (runtime.calibrate_speed).
"foot phase sd" is the smallest standard deviation of a foot phase channel: near 0 when the gait
has stopped and the character slides along in a frozen pose.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from minifilm.runtime.calibration import PerCharacterCalibration, calibrate_speed  # noqa: E402
from minifilm.pipeline.run_folder import RunFolder  # noqa: E402
from minifilm.runtime.control import figure_eight  # noqa: E402


def rollout_metrics(run: Path, seconds: float = 60.0, speed: float = 1.3, start: str = "data",
                    calibrate: bool = False, styles=None, png=None, controller_options=None, fit: str = "output"):
    """Run every style of the run folder ``run`` for ``seconds`` along a figure-eight; returns
    (style names, metrics list, seconds taken, rollout). ``fit``: "output" puts every frame on the
    training data's skeleton (Controller ``skeleton=``), as train_small does; "feedback" also feeds
    that pose back to the network; "none" does not fit."""
    folder = RunFolder.load(run)
    library = folder.styles()
    names = list(styles or library.names)
    films = np.stack([library[n] for n in names])
    layout, fps = folder.layout, folder.fps
    x0 = p0 = None
    if start == "data":
        x0, p0 = folder.start_states(names)
    options = dict(controller_options or {})
    if fit not in ("feedback", "output", "none"):
        raise ValueError(f"fit must be feedback, output or none, got {fit!r}")
    if fit != "none":
        options["feed_back_fit"] = fit == "feedback"
    ctl = folder.controller(fit=fit != "none", **options)
    cals = []
    if calibrate:
        for b in range(len(names)):
            cals.append(calibrate_speed(ctl, films[b], phases=None if p0 is None else p0[b],
                                        start_x=None if x0 is None else x0[b]))

    n = int(round(seconds * fps))
    scripts = [figure_eight(seconds, speed=speed) for _ in names]
    t0 = time.perf_counter()
    r = ctl.run(scripts, n, films, phases=p0, calibration=PerCharacterCalibration(cals) if calibrate else None, start_x=x0)
    elapsed = time.perf_counter() - t0
    toes = [layout.joint_names.index("RightToe"), layout.joint_names.index("LeftToe")]
    metrics = r.metrics(layout.parents, scripts[0].path, toes)
    k0 = int(round(fps))
    for b, m in enumerate(metrics):   # a gait that stopped (frozen pose sliding along) has still foot phases
        m["foot_phase_std"] = float(r.phases[b, k0:, 4:8].std(axis=0).min())
    if png:
        _render(r, layout.parents, scripts[0].path, names, png)
    return names, metrics, elapsed, r


def _render(r, parents, path, names, out):
    """Top view of every style's root path and the phases (sin of each slot) of the first style."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    B = r.root_positions.shape[0]
    fig, axes = plt.subplots(2, B, figsize=(2.6 * B, 5.4), squeeze=False)
    t = np.arange(r.phases.shape[1]) / r.fps
    for b in range(B):
        ax = axes[0, b]
        ax.plot(path[:, 0], path[:, 1], color="0.8", lw=3)
        ax.plot(r.root_positions[b, :, 0], r.root_positions[b, :, 1], "r", lw=0.8)
        ax.set_title(names[b], fontsize=8)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=6)
        ax = axes[1, b]
        k = min(len(t), int(5 * r.fps))
        for slot in range(4):
            ax.plot(t[:k], r.phases[b, :k, 2 * slot], lw=0.8)
        ax.plot(t[:k], r.positions[b, :k, 0, 1], "k", lw=0.8)
        ax.set_xlabel("s (first 5)", fontsize=6)
        ax.tick_params(labelsize=6)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", "--checkpoint", dest="run", required=True, type=Path,
                    help="a run folder (what minifilm train / examples/train_small.py writes)")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--speed", type=float, default=1.3, help="commanded speed along the path, m/s")
    ap.add_argument("--start", choices=("data", "mean"), default="data")
    ap.add_argument("--calibrate", action="store_true",
                    help="map the speed through each style's calibrate_speed (off: it commands far more "
                         "than the data's speeds, which small trained models do not survive)")
    ap.add_argument("--styles", nargs="+")
    ap.add_argument("--png", help="write root paths and phases to this PNG")
    ap.add_argument("--velocity-blend", type=float, default=0.5, help="Controller velocity_blend (1 = off)")
    ap.add_argument("--future-smoothing", type=float, default=0.15, help="Controller future_smoothing (0 = off)")
    ap.add_argument("--position-bias", type=float, default=2.0,
                    help="Controller position_bias (default 2 as in train_small; the demo's is 0.75; larger: "
                         "the user's trajectory weighs more in near samples)")
    ap.add_argument("--fit", choices=("output", "feedback", "none"), default="output",
                    help="put every frame on the data's skeleton (default, as train_small), also feed that "
                         "pose back to the network, or no fit")
    a = ap.parse_args()
    names, ms, elapsed, r = rollout_metrics(a.run, a.seconds, a.speed, a.start, a.calibrate, a.styles, a.png,
                                            dict(velocity_blend=a.velocity_blend, future_smoothing=a.future_smoothing,
                                                 position_bias=a.position_bias),
                                            fit=a.fit)
    print(f"{a.run}: {a.seconds:g} s figure-eight at {a.speed} m/s, start={a.start}, "
          f"calibrated={a.calibrate}, velocity_blend={a.velocity_blend}, future_smoothing={a.future_smoothing}, "
          f"position_bias={a.position_bias}, "
          f"skeleton fit={a.fit}, {len(names)} styles in one batch ({elapsed:.1f} s)")
    print("bone CV: the worst bone's coefficient of variation in the network's own prediction (output: after the fit)")
    print(f"{'style':14s} {'bone CV':>8s} {'output':>7s} {'hips m':>10s} {'speed':>6s} {'path mean/max m':>16s} "
          f"{'sliding m/s':>12s} {'foot phase sd':>14s}")
    for n, m in zip(names, ms):
        print(f"{n:14s} {m['network_bone_cv_max']:8.1%} {m['bone_cv_max']:7.1%} {m['hips_min']:4.2f}-{m['hips_max']:.2f} "
              f"{m['speed']:6.2f} {m['path_mean']:8.2f}/{m['path_max']:<7.2f} {m['foot_sliding']:12.3f} "
              f"{m['foot_phase_std']:14.2f}")
    worst = max(m["network_bone_cv_max"] for m in ms)
    print(f"worst bone CV {worst:.1%}; styles under 5 %: {sum(m['network_bone_cv_max'] < 0.05 for m in ms)}/{len(ms)}; "
          f"mean path distance {np.mean([m['path_mean'] for m in ms]):.2f} m; mean speed "
          f"{np.mean([m['speed'] for m in ms]):.2f} m/s; styles still stepping (foot phase sd > 0.2): "
          f"{sum(m['foot_phase_std'] > 0.2 for m in ms)}/{len(ms)}")


if __name__ == "__main__":
    main()
