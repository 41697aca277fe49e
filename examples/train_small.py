"""The whole method, end to end, on data minifilm makes itself (a few minutes on a 2-core laptop).

    python examples/train_small.py                      # synthetic data, default settings
    python examples/train_small.py --data DIR           # your own folder of <Style>_<Gait>.bvh files
    python examples/train_small.py --quick              # a smaller, faster run of the same steps

Steps (each prints what it did):
 1. data:     generate the synthetic stylised locomotion set (8 styles x 6 gaits, 100STYLE skeleton,
              60 fps) and write it as BVH files, so it flows through the same pipeline as real data;
 2. phases:   measure local-phase extraction against the generator's true phases (Sec. 4.1);
 3. dataset:  read the BVH files, detect contacts, extract local phases, build x / p / z / clips,
              split 80/10/10 per file, normalise (Sec. 3.2);
 4. training: a small LPN + FiLM model (Eq. 1-7) with style-balanced minibatches (Sec. 4.3);
 5. results:  test error per style against the predict-the-mean baseline, a loss-curve PNG and one
              generated BVH per style made by the autoregressive runtime (Sec. 4.4).

Everything is written to --out (default runs/train_small): data/, model.npz (checkpoint with the
normalisation statistics), styles.npz (FiLM vector per style), loss_curve.png, generated/*.bvh.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from minifilm.dataset.build import build_dataset                                         # noqa: E402
from minifilm.model.config import ModelConfig                                   # noqa: E402
from minifilm.model.style_model import StyleModel                               # noqa: E402
from minifilm.synthetic import generator as synthetic                                           # noqa: E402
from minifilm.phases.contacts import foot_contacts                              # noqa: E402
from minifilm.phases.local_phases import default_sources, extract_local_phases        # noqa: E402
from minifilm.motion.skeletons import STYLE100, builtin_skeleton                 # noqa: E402
from minifilm.runtime.control import make_script                                        # noqa: E402
from minifilm.motion.bvh import read_bvh                             # noqa: E402
from minifilm.motion.bvh_write import write_bvh
from minifilm.runtime.controller import Controller, root_joint_indices, start_from_dataset  # noqa: E402
from minifilm.runtime.network import RuntimeNetwork  # noqa: E402
from minifilm.runtime.style_library import StyleLibrary                                 # noqa: E402
from minifilm.train.trainer import TrainConfig, Trainer                                 # noqa: E402

# ---- settings -------------------------------------------------------------------------------------
SEED = 0
OUT = Path("runs/train_small")
STYLES = synthetic.STYLES          # Neutral, PendulumHands, LeftHop, Limp, HandsAbove, Crouched, Swimming, Drunk
SECONDS_PER_CLIP = 10.0            # synthetic seconds per style and gait
GAITS = ("FW", "BW", "FR", "SW", "TR", "ID")   # idle files are generated but skipped, as in 100STYLE
CLIP_SECONDS = 2.0                 # style clip y fed to the FiLM generator (paper: 4 s)
# 20 rather than 12: over three seeds the 60 s rollouts kept every style stepping and followed the
# path better (benchmarks/trained_rollout.py; validation MSE still falls after 12)
EPOCHS = 20
BATCH_SIZE = 32
# 1e-3 kills the ReLUs of the FiLM generator Ψ within 12 epochs (all of conv1's, most of its dense
# layer's), so several styles get the same FiLM vector (its bias) and share one motion; 3e-4 and
# 5e-4 keep them alive (benchmarks/trained_rollout.py; the paper uses 1e-4 for its 40x larger network)
LEARNING_RATE = 5e-4
# dropout 0.2 rather than the paper's 0.3 on a 4x narrower network: measured in 60 s rollouts, every
# style keeps stepping (0.3 and 0.1 left some in a frozen pose sliding along the path)
MODEL = dict(n_experts=4, hidden=128, gating_hidden=32, conv_filters=32, conv_kernel=9,
             film_dense=128, dropout=0.2)
GENERATE_SECONDS = 10.0            # length of each generated BVH
# weight of the user's trajectory in the near future samples (the demo's 0.75 suits the released
# network; a small model's own trajectory drifts more: with 2 the mean distance to a figure-eight
# over 60 s fell from 0.31-3.9 m to 0.20-0.85 m across five trained models)
POSITION_BIAS = 2.0

QUICK = dict(SECONDS_PER_CLIP=6.0, GAITS=("FW", "FR", "TR"), EPOCHS=2, GENERATE_SECONDS=2.0,
             MODEL=dict(MODEL, hidden=32, conv_filters=8, film_dense=32))


def log(msg: str = "") -> None:
    print(msg, flush=True)


# ---- 1. data --------------------------------------------------------------------------------------
def make_synthetic(out: Path, styles, gaits, seconds: float, seed: int):
    """Generate and write the synthetic set; returns the clips (with their true phases)."""
    t0 = time.perf_counter()
    clips = synthetic.default_dataset(seed=seed, seconds=seconds, styles=styles, gaits=gaits)
    synthetic.write_dataset(out, clips)
    frames = sum(c.motion.n_frames for c in clips)
    log(f"[data] {len(clips)} synthetic files ({len(styles)} styles x {len(gaits)} gaits, "
        f"{frames} frames at 60 fps) written to {out} in {time.perf_counter() - t0:.1f} s")
    return clips


# ---- 2. phase accuracy ----------------------------------------------------------------------------
def circular_error(a, b):
    """|a - b| on the unit circle of cycles, in [0, 0.5]."""
    d = np.abs(a - b) % 1.0
    return np.minimum(d, 1.0 - d)


def phase_accuracy(clips):
    """Median circular error (cycles) of the extracted local phases per end effector, over the frames
    where the generator says the limb really oscillates; feet split by source (contact / PCA)."""
    errors = {}
    for c in clips:
        m = c.motion
        positions, _ = m.world()
        contacts = foot_contacts(positions[:, STYLE100.contact_indices(m)], m.fps)
        sources = default_sources(c.style)
        lp = extract_local_phases(m, STYLE100, contacts, sources)
        err = circular_error(lp.phase, c.true_phase)
        for slot, name in enumerate(("left hand", "right hand", "left foot", "right foot")):
            key = f"{name} ({sources[slot]})"
            errors.setdefault(key, []).append(err[c.phase_active[:, slot], slot])
    log("[phases] median circular error against the generator's true phases (cycles):")
    table = {}
    for key, parts in errors.items():
        e = np.concatenate(parts)
        table[key] = float(np.median(e)) if len(e) else float("nan")
        log(f"    {key:<24} {table[key]:.4f}   ({len(e)} frames)")
    return table


# ---- 4. training ----------------------------------------------------------------------------------
def train(ds, out: Path, model_sizes: dict, epochs: int, seed: int):
    layout = ds.layout
    train_data, val_data = ds.train_data("train"), ds.train_data("val")
    config = ModelConfig(x_dim=layout.x_dim, z_dim=layout.z_dim, phase_dim=layout.phase_dim,
                         clip_frames=train_data.clips.shape[1], clip_channels=layout.clip_dim,
                         **model_sizes)
    model = StyleModel(config, np.random.default_rng(seed))
    trainer = Trainer(model, ds.stats,
                      TrainConfig(epochs=epochs, batch_size=BATCH_SIZE, lr=LEARNING_RATE, seed=seed,
                                  checkpoint_path=str(out / "model.npz")),
                      positions_idx=layout.joint_columns("z", "position"), parents=np.asarray(layout.parents),
                      style_names=ds.styles)
    n_params = sum(s.size for s in model.parameter_sets())
    log(f"[train] {n_params:,} parameters; {len(train_data)} training / {len(val_data)} validation frames; "
        f"clips {train_data.clips.shape[1]} x {layout.clip_dim}")
    log(f"    {'epoch':>5} {'train MSE':>10} {'train BLL':>10} {'val MSE':>9} {'val BLL':>9} {'time':>7}")
    for epoch in range(1, epochs + 1):
        t0 = time.perf_counter()
        trainer.fit(train_data, val_data, epochs=epoch)
        rec = trainer.history[-1]
        log(f"    {epoch:>5} {rec['train']['mse']:>10.4f} {rec['train']['bll']:>10.4f} "
            f"{rec['val']['mse']:>9.4f} {rec['val']['bll']:>9.4f} {time.perf_counter() - t0:>6.1f}s")
    return trainer


# ---- 5. results -----------------------------------------------------------------------------------
def test_table(trainer, ds):
    """Test MSE per style (normalised units) against predicting the training mean (which is 0 in
    normalised units, so its MSE is the mean squared normalised target)."""
    test = ds.train_data("test")
    result = trainer.evaluate(test)
    log("[test] MSE per style, normalised units (predict-the-mean baseline in brackets):")
    log(f"    {'style':<14} {'model':>8} {'baseline':>9}")
    baselines = []
    for s, name in enumerate(ds.styles):
        rows = test.style == s
        if not np.any(rows):
            continue
        base = float(np.mean(test.z[rows].astype(np.float64) ** 2))
        baselines.append(base)
        log(f"    {name:<14} {result['per_style'][name]['mse']:>8.4f} {base:>9.4f}")
    log(f"    {'mean':<14} {result['mse']:>8.4f} {np.mean(baselines):>9.4f}")
    return result


def save_loss_curve(history, path: Path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        log("[plot] matplotlib is not installed (pip install 'minifilm[viz]'): no loss curve")
        return
    epochs = [r["epoch"] for r in history]
    fig, ax = plt.subplots(figsize=(6, 4))
    for split, style in (("train", "-"), ("val", "--")):
        ax.plot(epochs, [r[split]["mse"] for r in history], style, color="C0", label=f"{split} MSE")
        ax.plot(epochs, [r[split]["bll"] for r in history], style, color="C1", label=f"{split} BLL")
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss (normalised units)")
    ax.set_yscale("log")
    ax.legend()
    ax.set_title("minifilm train_small: LPN + FiLM")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    log(f"[plot] loss curve saved to {path}")


def generate_per_style(trainer, ds, data_dir: Path, out: Path, seconds: float):
    """One BVH per style from the autoregressive runtime (Sec. 4.4): FiLM vectors precomputed from
    the style's training clips, a figure-eight path, the motion put back on the source skeleton.
    Each style starts in mid-stride from a frame of its own forward walk (pose, trajectory and
    phases): from the data's mean pose a network this small may never get going."""
    train_data = ds.train_data("train")
    library = StyleLibrary()
    for s, name in enumerate(ds.styles):
        library.add_from_clips(name, trainer.model, train_data.clips[train_data.clip_style == s])
    library.save(out / "styles.npz")
    network = RuntimeNetwork.from_model(trainer.model, trainer.stats)
    # the output skeleton is the first source file's own, written back in its own units; every
    # frame is put on it (rigid bones); the network keeps seeing its own prediction (fed back, the
    # fitted pose made small models stop stepping more often: benchmarks/trained_rollout.py --fit)
    skeleton = builtin_skeleton(ds.skeleton)
    template = read_bvh(ds.files[0]["path"], scale=skeleton.bvh_scale)
    joints = root_joint_indices(ds.layout, template)
    controller = Controller(network, ds.layout, fps=ds.fps, skeleton=Controller.skeleton_for(ds.layout, template),
                            position_bias=POSITION_BIAS)
    n_frames = int(round(seconds * ds.fps))
    (out / "generated").mkdir(exist_ok=True)
    log(f"[generate] {seconds:g} s per style along a figure-eight:")
    for name in ds.styles:
        script = make_script("figure8", seconds)
        start_x, phases = start_from_dataset(ds, name)
        rollout = controller.run(script, n_frames, library[name], phases=phases, start_x=start_x)
        path = out / "generated" / f"{name}.bvh"
        write_bvh(rollout.to_motion(template, joints), path, scale=skeleton.bvh_scale)
        hips = rollout.positions[0, :, 0, 1]
        speed = np.linalg.norm(np.diff(rollout.root_positions[0], axis=0), axis=1).mean() * ds.fps
        log(f"    {name:<14} hips {hips.mean():.2f} m  speed {speed:.2f} m/s   -> {path}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, help="folder of <Style>_<Gait>.bvh files, or a CSV manifest "
                        "(file,style,gait[,start,end]) for other datasets (default: synthetic data)")
    parser.add_argument("--out", type=Path, default=OUT, help=f"output folder (default {OUT})")
    parser.add_argument("--epochs", type=int, help=f"training epochs (default {EPOCHS})")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--quick", action="store_true", help="a smaller, faster run of every step")
    parser.add_argument("--styles", help="comma-separated synthetic styles (default: all)")
    parser.add_argument("--gaits", help=f"comma-separated synthetic gaits (default: {','.join(GAITS)})")
    parser.add_argument("--seconds", type=float, help="synthetic seconds per style and gait")
    parser.add_argument("--generate-seconds", type=float, help="seconds of motion generated per style")
    args = parser.parse_args(argv)

    s = dict(STYLES=STYLES, SECONDS_PER_CLIP=SECONDS_PER_CLIP, GAITS=GAITS, EPOCHS=EPOCHS, MODEL=MODEL,
             GENERATE_SECONDS=GENERATE_SECONDS)
    if args.quick:
        s.update(QUICK)
    for key, value in (("EPOCHS", args.epochs), ("SECONDS_PER_CLIP", args.seconds),
                       ("GENERATE_SECONDS", args.generate_seconds),
                       ("STYLES", args.styles and args.styles.split(",")),
                       ("GAITS", args.gaits and args.gaits.split(","))):
        if value is not None:
            s[key] = value
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()

    if args.data is None:
        data_dir = out / "data"
        clips = make_synthetic(data_dir, s["STYLES"], s["GAITS"], s["SECONDS_PER_CLIP"], args.seed)
        phase_accuracy(clips)
    else:
        data_dir = args.data

    t0 = time.perf_counter()
    ds = build_dataset(data_dir, cache_dir=out / "cache", progress=True, clip_seconds=CLIP_SECONDS,
                       clip_stride_seconds=CLIP_SECONDS / 2, seed=args.seed)
    log(f"[dataset] built in {time.perf_counter() - t0:.1f} s")
    log(ds.summary())

    trainer = train(ds, out, s["MODEL"], s["EPOCHS"], args.seed)
    trainer.save(out / "model.npz")
    log(f"[train] checkpoint (model, optimiser, normalisation statistics) saved to {out / 'model.npz'}")
    result = test_table(trainer, ds)
    save_loss_curve(trainer.history, out / "loss_curve.png")
    generate_per_style(trainer, ds, data_dir, out, s["GENERATE_SECONDS"])
    log(f"[done] {time.perf_counter() - t_start:.0f} s in all; outputs in {out}")
    return result


if __name__ == "__main__":
    from minifilm.cli import run

    run(lambda: main() and 0)
