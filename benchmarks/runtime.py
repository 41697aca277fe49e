"""Runtime speed with the released network (paper config: 348 -> 512 -> 512 -> 342, 8 experts).

    python benchmarks/runtime.py [--params DIR] [--frames 600] [--batch 8 64]
    python benchmarks/runtime.py --quality [--styles Neutral Old Zombie] [--seconds 60]

Prints a table:
  * the network alone at batch 1 with a precomputed FiLM vector, three ways: experts side by side
    (one (I, K*O) product per layer, what RuntimeNetwork does), blend the weights first
    (Σ α_k W_k, then one product);
  * one whole controller frame at batch 1 (input features + network + read-back + trajectory blend);
  * many characters updated together in one batch: frames per second and character-frames per second;
  * the same with every frame put on the 100STYLE skeleton (Controller ``skeleton=``, the default of
    examples/generate_released.py).
With --quality it instead runs the run-time quality checks (bone lengths, hips, speed, distance to the path) for a minute (or --seconds) per style, all
styles in one batch, along a figure-eight at 1.3 m/s with per-style speed calibration, without and
with foot locking: bone-length CV, hips range, speed, distance to the path, foot sliding.

The paper reports 4.53 ms per frame for the LPN FiLM in Unity (Table 2). BLAS threads default to 1
here (the machine is shared); set OPENBLAS_NUM_THREADS / OMP_NUM_THREADS to change that.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]

from minifilm.features.layout import FeatureLayout  # noqa: E402
from minifilm.motion.bvh import read_bvh  # noqa: E402
from minifilm.runtime.released import load_released  # noqa: E402
from minifilm.motion.skeletons import STYLE100  # noqa: E402
from minifilm.runtime.held_body import foot_locker  # noqa: E402
from minifilm.runtime.calibration import calibrate_speed  # noqa: E402
from minifilm.runtime.control import CommandScript, figure_eight  # noqa: E402
from minifilm.runtime.controller import Controller  # noqa: E402
from minifilm.runtime.network import RuntimeNetwork  # noqa: E402


def timeit(fn, repeat=5, number=100):
    """Median over ``repeat`` runs of the mean time per call (seconds)."""
    fn()
    runs = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(number):
            fn()
        runs.append((time.perf_counter() - t) / number)
    return float(np.median(runs))


def blend_first(net: RuntimeNetwork, model, x, p, film):
    """Batch 1 with the expert weights blended first: W = Σ_k α_k W_k (the original runtime's form, docs/original-code.md §10.2)."""
    h = (x - net._x_mean) * net._x_inv
    alpha = net.gate(h[None], p[None])[0]
    m = model.motion.params.params
    H = net.hidden.hidden
    for l in range(3):
        W = np.tensordot(alpha, m[f"W{l}"], axes=1)
        h = h @ W + alpha @ m[f"b{l}"]
        if l < 2:
            h = (h - h.mean()) / h.std()
            h = film[2 * l * H:(2 * l + 1) * H] * h + film[(2 * l + 1) * H:(2 * l + 2) * H]
            h = np.where(h > 0, h, np.expm1(np.minimum(h, 0)))
    return h * net._z_std + net._z_mean


def quality(rel, layout, styles, seconds, body):
    """Minute-long rollouts of several styles, without and with foot locking, every frame put on
    the skeleton ``body`` (a SkeletonFit): bone CV of the network's own prediction and of the output."""
    net = rel.network
    n = int(round(seconds * 60))
    toes = [layout.joint_names.index("RightToe"), layout.joint_names.index("LeftToe")]
    print(f"{seconds:g} s per style along a figure-eight at 1.3 m/s (speed calibrated per style)")
    print(f"{'style':16s} {'lock':>5s} {'bone CV':>8s} {'output':>7s} {'hips m':>11s} {'speed':>6s} {'path mean/max m':>16s} "
          f"{'sliding m/s':>12s}")
    for lock in (False, True):
        for style in styles:   # calibration differs per style, so one style per run (the rollout is batch 1)
            film = rel.styles[style]
            cal = calibrate_speed(Controller(net, layout), film)
            locker = foot_locker(layout) if lock else None
            script = figure_eight(seconds, speed=1.3)
            r = Controller(net, layout, foot_locker=locker, skeleton=body, feed_back_fit=True).run(
                script, n, film, calibration=cal)
            m = r.metrics(STYLE100.parents, script.path, toes)[0]
            print(f"{style:16s} {str(lock):>5s} {m['network_bone_cv_max']:8.1%} {m['bone_cv_max']:7.1%} "
                  f"{m['hips_min']:5.2f}-{m['hips_max']:.2f} "
                  f"{m['speed']:6.2f} {m['path_mean']:8.2f}/{m['path_max']:.2f} {m['foot_sliding']:12.3f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", default=str(REPO.parent / "shared" / "data" / "released-lpn"))
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--batch", type=int, nargs="+", default=[8, 64])
    ap.add_argument("--quality", action="store_true", help="run the motion-quality checks instead")
    ap.add_argument("--styles", nargs="+", default=["Neutral", "Old", "Zombie", "Aeroplane", "Strutting"])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--skeleton-bvh", default=str(REPO.parent / "shared" / "data" / "100style" / "Neutral_FR_first3frames.bvh"),
                    help="skeleton every frame is put on (Controller skeleton=)")
    args = ap.parse_args()

    rel = load_released(args.params)
    body = Controller.skeleton_for(FeatureLayout.for_skeleton(STYLE100), read_bvh(args.skeleton_bvh))
    if args.quality:
        quality(rel, FeatureLayout.for_skeleton(STYLE100), args.styles, args.seconds, body)
        return
    net = rel.network
    layout = FeatureLayout.for_skeleton(STYLE100)
    film = rel.styles["Neutral"] if "Neutral" in rel.styles else next(iter(rel.styles.values()))
    rng = np.random.default_rng(0)
    x = (rel.stats.x_mean + 0.1 * rng.normal(size=layout.x_dim)).astype(np.float32)
    p = np.array([0, 2, 0, -2, 2, 0, -2, 0], dtype=np.float32)

    rows = []
    t = timeit(lambda: net.predict(x[None], p[None], film))
    rows.append(("network, batch 1, experts side by side (RuntimeNetwork)", t * 1e3, 1 / t))
    t = timeit(lambda: blend_first(net, rel.model, x, p, film), number=20)
    rows.append(("network, batch 1, blend expert weights first", t * 1e3, 1 / t))

    walk = lambda: CommandScript([(0, 2.0, 0, 0), (1000, 2.0, 360, 0)])  # noqa: E731  (walk in a big circle)
    ctrl = Controller(net, layout)
    F = args.frames
    ctrl.run(walk(), 30, film)
    t0 = time.perf_counter()
    ctrl.run(walk(), F, film)
    t = (time.perf_counter() - t0) / F
    rows.append(("whole controller frame, batch 1 (run(), incl. script)", t * 1e3, 1 / t))
    ctrl.reset(np.zeros((1, 2)), np.array([[0.0, 1.0]]))
    tf, tv = np.array([[0.0, 1.0]]), np.array([[0.0, 2.0]])
    t = timeit(lambda: ctrl.step(tf, tv, film), number=50)
    rows.append(("controller.step(), batch 1", t * 1e3, 1 / t))
    for B in args.batch:
        films = np.stack([film] * B)
        ctrl.reset(rng.normal(size=(B, 2)) * 10, np.tile([0.0, 1.0], (B, 1)))
        tfB, tvB = np.tile(tf, (B, 1)), np.tile(tv, (B, 1))
        t = timeit(lambda: ctrl.step(tfB, tvB, films), number=20)
        rows.append((f"controller.step(), batch {B}", t * 1e3, B / t))
    fitted = Controller(net, layout, skeleton=body, feed_back_fit=True)
    for B in [1] + list(args.batch):
        films = np.stack([film] * B)
        fitted.reset(rng.normal(size=(B, 2)) * 10, np.tile([0.0, 1.0], (B, 1)))
        tfB, tvB = np.tile(tf, (B, 1)), np.tile(tv, (B, 1))
        t = timeit(lambda: fitted.step(tfB, tvB, films), number=20)
        rows.append((f"controller.step() with the skeleton fit, batch {B}", t * 1e3, B / t))

    print(f"BLAS threads: OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}; "
          f"paper (Unity, Table 2): 4.53 ms/frame")
    print(f"{'what':60s} {'ms/frame':>10s} {'character-frames/s':>20s}")
    for name, ms, cps in rows:
        print(f"{name:60s} {ms:10.3f} {cps:20.0f}")


if __name__ == "__main__":
    main()
