"""A still picture of a generated motion: side-view stick figures in a row, the path from above,
and the hips height, toe height and root speed over time."""
from __future__ import annotations

import numpy as np

from minifilm.viewer.deps import pyplot, save_figure


def draw_strip(rollout, parents, joint_names, path, out, every=10, max_figures=14, title="", start=60):
    """Side-view stick figures of character 0 every ``every`` frames from ``start``, the root path
    from above (with the commanded ``path`` (N, 2) when given), and hips height / toe height /
    root speed over time, into the PNG ``out``. Right-side bones are drawn red."""
    plt = pyplot()

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
                        color="tab:red" if "Right" in joint_names[j] else "k")
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
    if "RightToe" in joint_names:
        ax3.plot(t, P[:, list(joint_names).index("RightToe"), 1], label="right toe height (m)", lw=0.8)
    speed = np.r_[0, np.linalg.norm(np.diff(root, axis=0), axis=1) * rollout.fps]
    ax3.plot(t, speed, label="root speed (m/s)", lw=0.8)
    ax3.set_xlabel("time (s)")
    ax3.legend(fontsize=7, loc="upper right")
    return save_figure(fig, out, dpi=75)
