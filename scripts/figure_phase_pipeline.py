"""Draw the local-phase pipeline of one foot on a real walk, one panel per step (Sec. 4.1, Eq. 1).

    python scripts/figure_phase_pipeline.py            # a Bandai-Namco walk from ../shared/data
    python scripts/figure_phase_pipeline.py --bvh FILE.bvh --out pipeline.png

toe tip -> contacts -> phase source -> fitted sinusoid -> phase φ and amplitude -> p (Eq. 1), for
the left foot, each panel titled with the function that computes it (``path::name``, taken from
the function objects, so it follows the code). The figure uses the package's one labelling recipe
(minifilm/phases/label.py::label) and recomputes the intermediate steps with the functions named on
the panels, checking that they give the recipe's numbers. Writes docs/img/phase_pipeline_bandai_walk.png.
"""
from __future__ import annotations

import argparse
import io
import os
from pathlib import Path

import numpy as np

from minifilm.motion.bvh import read_bvh
from minifilm.motion.motion import Motion
from minifilm.body.rig import detect_skeleton
from minifilm.phases.contacts import estimate_floor_height, foot_contacts
from minifilm.phases.label import label
from minifilm.phases.local_phases import LocalPhases, fit_sinusoids, phase_and_amplitude
from minifilm.phases.sources import contact_source, preprocess_source
from minifilm.viewer.deps import pyplot

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))
DEFAULT_BVH = SHARED_DATA / "bandai2" / "dataset-2_walk_normal_001.bvh"
SLOT, SIDE = 2, 1          # the left foot: phase slot 2 of [LH, RH, LF, RF], contact column 1 of [right, left]


def ref(fn) -> str:
    """``path::name`` of a function or method, from the object itself."""
    return f"{fn.__module__.replace('.', '/')}.py::{fn.__qualname__}"


def pipeline(path: Path) -> dict:
    """Every intermediate of the left foot's phase, as the package computes it."""
    skeleton = detect_skeleton(read_bvh(path, scale=1.0))
    motion = read_bvh(path, scale=skeleton.bvh_scale)
    labels = label(motion, skeleton)
    fps, n = motion.fps, motion.n_frames
    toes = motion.world()[0][:, skeleton.contact_indices(motion)]           # (F, 2, 3) right, left
    speed = np.zeros(toes.shape[:2])
    speed[1:] = np.linalg.norm(np.diff(toes, axis=0), axis=-1) * fps
    speed[0] = speed[1]
    contacts = foot_contacts(toes, fps)
    source = preprocess_source(contact_source(contacts[:, SIDE]), fps)
    fit = fit_sinusoids(source, fps)
    # the steps above are the recipe's own: check before drawing them
    assert np.array_equal(contacts, labels.contacts)
    assert np.allclose(source, labels.phases.source[:, SLOT]) and np.allclose(fit.fit, labels.phases.fit[:, SLOT])
    return dict(name=path.name, fps=fps, t=np.arange(n) / fps, toes=toes, speed=speed, contacts=contacts,
                floor=estimate_floor_height(toes[..., 1], speed), source=source, fit=fit,
                phase=labels.phases.phase[:, SLOT], amplitude=labels.phases.amplitude[:, SLOT],
                p=labels.vectors[:, 2 * SLOT:2 * SLOT + 2])


PANELS = [("1  toe tip: height above the floor and speed", Motion.world),
          ("2  foot contacts: slow and near the floor (Sec. 4.1.2)", foot_contacts),
          ("3  phase source: contacts, normalised in 1 s, low-passed at 4 Hz (Sec. 4.1.4)", preprocess_source),
          ("4  a sinusoid fitted around every frame (0.5 s windows, Sec. 4.1.4)", fit_sinusoids),
          ("5  phase φ (cycles) and amplitude (fitted A × the foot's speed)", phase_and_amplitude),
          ("6  p = amplitude · (sin 2πφ, cos 2πφ), the gating network's input (Eq. 1)", LocalPhases.vectors)]


def draw(d: dict, out: Path) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(len(PANELS), 1, figsize=(11, 12.5), sharex=True)
    t, left = d["t"], "#c0392b"
    for ax, (title, fn) in zip(axes, PANELS):
        ax.set_title(f"{title}\n{ref(fn)}", fontsize=9, loc="left")
        ax.grid(alpha=0.3)
    ax = axes[0]
    ax.plot(t, (d["toes"][:, SIDE, 1] - d["floor"]) * 100, color=left, label="height above the floor (cm)")
    ax.axhline(1.0, color=left, ls=":", lw=1)
    ax.set_ylabel("cm")
    twin = ax.twinx()
    twin.plot(t, d["speed"][:, SIDE], color="0.35", lw=1, label="speed (m/s)")
    twin.axhline(0.15, color="0.35", ls=":", lw=1)
    twin.set_ylabel("m/s")
    ax.legend(loc="upper left", fontsize=8)
    twin.legend(loc="upper right", fontsize=8)
    ax.text(t[-1], 1.0, "1 cm ", ha="right", va="bottom", fontsize=7, color=left)
    ax = axes[1]
    ax.step(t, d["contacts"][:, 0] * 0.7 + 1.3, where="mid", color="0.5", label="right foot")
    ax.step(t, d["contacts"][:, SIDE] * 0.7, where="mid", color=left, label="left foot")
    ax.set_yticks([0, 0.7, 1.3, 2.0], ["0", "1", "0", "1"])
    ax.set_ylim(-0.15, 2.6)
    ax.legend(loc="upper right", fontsize=8, ncol=2)
    ax = axes[2]
    ax.step(t, d["contacts"][:, SIDE], where="mid", color="0.7", label="left contact (the raw source)")
    ax.plot(t, d["source"], color=left, label="preprocessed source")
    ax.legend(loc="upper right", fontsize=8, ncol=2)
    ax = axes[3]
    fit = d["fit"]
    ax.plot(t, d["source"], color="0.6", lw=2.5, label="source")
    half = np.arange(-int(0.25 * d["fps"]), int(0.25 * d["fps"]) + 1) / d["fps"]
    for i, k in enumerate(range(int(0.3 * d["fps"]), len(t), int(0.45 * d["fps"]))):
        if not fit.skipped[k]:
            ax.plot(t[k] + half, fit.curve(k, half), color=plt.cm.viridis(i % 8 / 8), lw=1.2)
            ax.plot(t[k], fit.fit[k], "o", ms=3, color=plt.cm.viridis(i % 8 / 8))
    ax.plot([], [], color=plt.cm.viridis(0.3), label="A sin(2π(Fτ + φ)) + B around a few frames")
    ax.legend(loc="upper right", fontsize=8, ncol=2)
    ax = axes[4]
    ax.plot(t, d["phase"], color=left, label="phase φ (cycles)")
    ax.set_ylim(-0.05, 1.05)
    twin = ax.twinx()
    twin.plot(t, d["amplitude"], color="0.3", lw=1.2, label="amplitude")
    ax.legend(loc="upper left", fontsize=8)
    twin.legend(loc="upper right", fontsize=8)
    ax = axes[5]
    ax.plot(t, d["p"][:, 0], color=left, label="amplitude · sin 2πφ")
    ax.plot(t, d["p"][:, 1], color="#2471a3", label="amplitude · cos 2πφ")
    ax.legend(loc="upper right", fontsize=8, ncol=2)
    ax.set_xlabel("time (s)")
    fig.suptitle(f"Local phase of the left foot: {d['name']} ({d['fps']:.0f} fps)", fontsize=11, x=0.01, ha="left")
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=85)
    plt.close(fig)
    from PIL import Image           # Pillow comes with matplotlib (the viz extra)
    buffer.seek(0)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.open(buffer).convert("RGB").quantize(colors=96).save(out, optimize=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bvh", type=Path, default=DEFAULT_BVH, help="a BVH walk on a known skeleton")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "phase_pipeline_bandai_walk.png")
    args = ap.parse_args()
    draw(pipeline(args.bvh), args.out)
    print(f"wrote {args.out} ({args.out.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
