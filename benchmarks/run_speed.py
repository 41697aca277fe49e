"""How fast does the authors' released network run? Per style, three ways (the study behind Shift).

    python benchmarks/run_speed.py                         # all 100 styles (a few minutes)
    python benchmarks/run_speed.py --styles Neutral Angry  # some styles
    python benchmarks/run_speed.py --markdown reports/2026-12-04_released_run_speed.md

1. **The data's speeds, from the normalisation statistics.** The network's input and output
   statistics (Xmean/Xstd, Ymean/Ystd) are those of its training rows, all styles and gaits
   together: the mean and spread of the next frame's root step (output trajectory sample 0, times
   60: m/s) and of the root's offset one second ahead (input sample 11, metres in one second).
2. **Closed loop, as the demo drives it** (the fitted pose fed back, the user's velocity blended into
   the future trajectory, Sec. 4.4): a straight run at each command of ``COMMANDS`` m/s for 8 s,
   the mean root speed over the last 4 s; the style's top is the largest, its flight share the
   frames where the network reports neither foot in contact (both contact outputs < 0.5).
3. **The network's own ceiling.** The trajectory input is overwritten every frame with a perfect
   straight run at v m/s (past samples at -v t, future at +v t, for each v of ``IDEAL``): the
   network is told it has been running and will go on running, and its own root step (which
   moves the root) says how fast it runs then. The largest over v is the fastest the network
   reproduces for that style, our estimate of what the style's training runs reached (the
   data itself is not released with the network).
4. **Shift in the demo**: the same closed loop with the demo's run feed (``Controller.run_feed``
   at ``Character``'s speed, ``DemoSource.run_feed_speed``): the trajectory input is that
   perfect run while the root, the pose and the phases are the network's own. Its speed against
   the ceiling is the target (at least 90 %).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))

from minifilm.demo.source import DemoSource  # noqa: E402
from minifilm.runtime.calibration import CALIBRATION_COMMANDS  # noqa: E402
from minifilm.runtime.control import CommandScript  # noqa: E402
from minifilm.runtime.controller import Controller  # noqa: E402

COMMANDS = tuple(c for c in CALIBRATION_COMMANDS if c >= 2.0)
IDEAL = (3.0, 5.0, 7.0, 10.0, 14.0)
SECONDS, SETTLE = 8.0, 4.0


def data_speeds(source) -> dict:
    """The root's speed in the training rows, from the normalisation statistics (m/s)."""
    L, st = source.layout, source.network.stats
    step = L.trajectory_columns("z", 6)[:2]          # next frame's root (x, z), metres per frame
    ahead = L.trajectory_columns("x", 11)[:2]        # the root one second ahead, metres
    fps = source.fps
    return {"step_mean": st.z_mean[step] * fps, "step_std": st.z_std[step] * fps,
            "ahead_mean": st.x_mean[ahead], "ahead_std": st.x_std[ahead]}


def speeds(roots: np.ndarray, fps: float) -> np.ndarray:
    """Mean root speed (m/s) of (B, F, 2) paths over the frames after SETTLE seconds."""
    k0 = int(round(SETTLE * fps))
    r = roots[:, k0:]
    return np.linalg.norm(np.diff(r, axis=1), axis=-1).sum(axis=1) / ((r.shape[1] - 1) / fps)


def closed_loop(ctrl, film, fps):
    """(top m/s, command giving it, flight share at it) for one style, straight runs at COMMANDS."""
    n = int(round(SECONDS * fps))
    r = ctrl.run([CommandScript([(0, v, 0, 0), (SECONDS, v, 0, 0)]) for v in COMMANDS], n, film)
    s = speeds(r.root_positions, fps)
    k0 = int(round(SETTLE * fps))
    flight = np.mean(np.all(r.contacts[:, k0:] < 0.5, axis=-1), axis=1)
    i = int(np.argmax(s))
    return float(s[i]), COMMANDS[i], float(flight[i])


def shift_run(source, films, feed_speed):
    """(m/s, flight share) per style of the demo's Shift, all styles in one batch with the demo's
    settings (its sources' options: the heading follow): the run feed at ``feed_speed`` m/s."""
    ctrl = Controller(source.network, source.layout, fps=source.fps,
                      skeleton=Controller.skeleton_for(source.layout, source.skeleton), feed_back_fit=True,
                      **source.options)
    fps, n = source.fps, int(round(SECONDS * source.fps))
    ctrl.run_feed, ctrl.run_feed_speed = np.ones(len(films)), feed_speed
    r = ctrl.run([CommandScript([(0, feed_speed, 0, 0), (SECONDS, feed_speed, 0, 0)]) for _ in films], n, films)
    k0 = int(round(SETTLE * fps))
    return speeds(r.root_positions, fps), np.mean(np.all(r.contacts[:, k0:] < 0.5, axis=-1), axis=1)


def ideal_run(ctrl, film, fps):
    """(ceiling m/s, the v giving it, flight share) with the trajectory input overwritten by a
    perfect straight run at each v of IDEAL."""
    v = np.asarray(IDEAL)
    B, n = len(v), int(round(SECONDS * fps))
    ctrl.reset(np.zeros((B, 2)), np.tile([0.0, 1.0], (B, 1)))
    S = ctrl.layout.n_future_samples
    past_t = -np.arange(ctrl.history, 0, -1) / fps
    future_t = np.arange(S) * ctrl.sample_dt
    roots, contacts = np.empty((B, n, 2)), np.empty((B, n, 2))
    for k in range(n):
        st = ctrl.state
        f = st.facing
        st.history_pos = st.root[:, None] + f[:, None] * (v[:, None, None] * past_t[None, :, None])
        st.history_dir = np.repeat(f[:, None], ctrl.history, axis=1)
        st.future_pos = st.root[:, None] + f[:, None] * (v[:, None, None] * future_t[None, :, None])
        st.future_dir = np.repeat(f[:, None], S, axis=1)
        ctrl.step(f, f * v[:, None], film)
        roots[:, k], contacts[:, k] = ctrl.state.root, ctrl.state.contacts
    s = speeds(roots, fps)
    k0 = int(round(SETTLE * fps))
    flight = np.mean(np.all(contacts[:, k0:] < 0.5, axis=-1), axis=1)
    i = int(np.argmax(s))
    return float(s[i]), IDEAL[i], float(flight[i])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--params", default=str(DATA / "released-lpn"))
    ap.add_argument("--styles", nargs="+")
    ap.add_argument("--markdown", type=Path, help="also write the table as Markdown")
    args = ap.parse_args(argv)
    source = DemoSource.released(args.params, calibrate=False)
    styles = args.styles or list(source.library.names)
    body = Controller.skeleton_for(source.layout, source.skeleton)
    ctrl = Controller(source.network, source.layout, fps=source.fps, skeleton=body, feed_back_fit=True)
    d = data_speeds(source)
    lines = [
        "released network: the root's speed in its training rows (normalisation statistics, all styles and gaits)",
        f"  next frame's step x 60: mean (x {d['step_mean'][0]:+.3f}, z {d['step_mean'][1]:+.3f}) m/s, "
        f"std (x {d['step_std'][0]:.3f}, z {d['step_std'][1]:.3f}) m/s",
        f"  root one second ahead: mean (x {d['ahead_mean'][0]:+.3f}, z {d['ahead_mean'][1]:+.3f}) m, "
        f"std (x {d['ahead_std'][0]:.3f}, z {d['ahead_std'][1]:.3f}) m",
        f"  (a 2.5 m/s forward run is {(2.5 / 60 - d['step_mean'][1] / 60) / (d['step_std'][1] / 60):.1f} "
        "standard deviations out on the step)",
        "",
        "| style | loop top m/s (command) | flight | network ceiling m/s (ideal v) | flight | Shift m/s | flight "
        "| loop / ceiling | Shift / ceiling |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    print("\n".join(lines), flush=True)
    ratios, shift = [], []
    shift_speeds, shift_flight = shift_run(source, np.stack([source.library[n] for n in styles]),
                                           source.run_feed_speed)
    for i, name in enumerate(styles):
        film = source.library[name]
        top, cmd, fl = closed_loop(ctrl, film, source.fps)
        ceil, v, fl2 = ideal_run(ctrl, film, source.fps)
        run, fl3 = shift_speeds[i], shift_flight[i]
        ratios.append(top / ceil)
        shift.append(run / ceil)
        row = (f"| {name} | {top:.2f} ({cmd:g}) | {fl:.0%} | {ceil:.2f} ({v:g}) | {fl2:.0%} | {run:.2f} | {fl3:.0%} "
               f"| {top / ceil:.0%} | {run / ceil:.0%} |")
        lines.append(row)
        print(row, flush=True)
    ratios, shift = np.array(ratios), np.array(shift)
    summary = "\n" + "\n".join(
        f"{what} / network ceiling: median {np.median(x):.0%}, worst {x.min():.0%} ({styles[int(x.argmin())]}); "
        f"{np.sum(x >= 0.9)}/{len(x)} styles at 90 % or more"
        for what, x in (("loop top (the calibrated command)", ratios), ("Shift (the run feed)", shift)))
    lines.append(summary)
    print(summary)
    if args.markdown:
        args.markdown.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
