"""Training speed of the main job's model: where a step's time goes, and one process against MPI ranks.

    python benchmarks/mpi_training.py                 # the step profile, then 1 process vs mpiexec -n 2
    python benchmarks/mpi_training.py --profile       # only the profile of one step
    python benchmarks/mpi_training.py --ranks 2 3     # 1 process vs 2 and 3 ranks (oversubscribed on 2 cores)
    python benchmarks/mpi_training.py --job           # also the whole examples/train_small.py, both ways
    python benchmarks/mpi_training.py --allreduce     # the gradients' exchange, the main job's and the paper's sizes

The model and minibatches are the main job's (ModelConfig.small for x 348, z 342, clips 120 x 300;
batch 32 of one style sharing 4 clips, dropout on; minifilm/pipeline/train_small.py) on random data
of those shapes: a step's arithmetic does not depend on the numbers.

The profile times each stage of the step (Ψ, Ω, Φ forward; the losses; Φ, Ω, Ψ backward; the NaN
check; Adam), its kernels (functions of minifilm/nn, cumulative, with cProfile's small overhead),
and compares the step's floating-point operations (counted from the layer sizes) per second with a
large float32 matrix product on the same core: how close the step comes to what the machine does.

The ranks table trains the same steps in one process and under ``mpiexec -n N`` (each rank on its
share of every minibatch, minifilm/train/mpi.py) and prints the step time, the speed-up and the
time per step in the ranks' collective calls (the exchange, and the waits for the slower rank).
One BLAS thread per process, as the main job.
"""
import os
os.environ.setdefault("MINIFILM_BENCH_THREADS", "1")     # one BLAS thread per process, as the main job
import common  # noqa: E402,F401  (sets the BLAS thread count before numpy loads)

import argparse  # noqa: E402
import cProfile  # noqa: E402
import json  # noqa: E402
import pstats  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from common import ROOT, header, load_average, table  # noqa: E402
from machine import cpu_name  # noqa: E402
from minifilm.dataset.arrays import TrainData  # noqa: E402
from minifilm.dataset.stats import NormStats  # noqa: E402
from minifilm.model.config import ModelConfig  # noqa: E402
from minifilm.model.style_model import StyleModel  # noqa: E402
from minifilm.train.trainer import TrainConfig, Trainer  # noqa: E402

CONFIG = ModelConfig.small(x_dim=348, z_dim=342, clip_frames=120, clip_channels=300)
STYLES, FRAMES, CLIPS = 8, 8000, 64


def main_job_trainer(ranks=None, seed=0) -> tuple:
    """A Trainer of the main job's model and settings, and random training data of its shapes."""
    rng = np.random.default_rng(seed)
    c, f32 = CONFIG, np.float32
    data = TrainData(x=rng.standard_normal((FRAMES, c.x_dim)).astype(f32),
                     p=rng.standard_normal((FRAMES, c.phase_dim)).astype(f32),
                     z=rng.standard_normal((FRAMES, c.z_dim)).astype(f32), style=np.arange(FRAMES) % STYLES,
                     clips=rng.standard_normal((CLIPS, c.clip_frames, c.clip_channels)).astype(f32),
                     clip_style=np.arange(CLIPS) % STYLES)
    stats = NormStats(x_mean=np.zeros(c.x_dim), x_std=np.ones(c.x_dim), z_mean=np.zeros(c.z_dim),
                      z_std=np.ones(c.z_dim), p_mean=np.zeros(c.phase_dim), p_std=np.ones(c.phase_dim))
    joints = c.z_dim // 3 // 4                 # some joint positions for the bone-length loss
    trainer = Trainer(StyleModel(c, np.random.default_rng(seed)), stats,
                      TrainConfig(batch_size=32, lr=5e-4, clips_per_batch=4, progress=False, seed=seed),
                      positions_idx=np.arange(3 * joints).reshape(joints, 3),
                      parents=np.arange(joints) - 1, ranks=ranks)
    return trainer, data


def steps(trainer, data):
    """Minibatches without end, epoch after epoch."""
    while True:
        yield from trainer.minibatches(data)


# ---- the profile of one step ---------------------------------------------------------------------
def step_flops(c: ModelConfig, batch: int = 32, clips: int = 4) -> dict:
    """Floating-point operations of one training step, counted from the layer sizes (a multiply
    and an add are two; backward of a product is two products: dx and dW; the clips and the inputs
    x, p need no gradient). Elementwise work (norms, ELU, dropout, Adam) is left out: it is a few
    operations per number, not per product."""
    T1, T2 = c.clip_frames, c.clip_frames // 2
    conv0 = 2 * clips * T1 * c.conv_kernel * c.clip_channels * c.conv_filters
    conv1 = 2 * clips * T2 * c.conv_kernel * c.conv_filters * c.conv_filters
    dense = 2 * clips * (c.flat_dim * c.film_dense + c.film_dense * c.film_dim)
    sizes = [c.x_dim, c.hidden, c.hidden, c.z_dim]
    phi = sum(2 * batch * c.n_experts * sizes[i] * sizes[i + 1] for i in range(3))
    omega = 2 * batch * (c.phase_dim * c.gating_hidden + c.gating_hidden ** 2 + c.gating_hidden * c.n_experts)
    forward = conv0 + conv1 + dense + phi + omega
    backward = conv0 + 2 * conv1 + 2 * dense + 2 * phi + omega   # conv0 and Ω's first layer: dW only
    return {"forward": forward, "backward": backward, "step": forward + backward}


def gemm_gflops(n: int = 2048) -> float:
    """float32 GFLOP/s of one large matrix product on this process's BLAS threads (median of 5)."""
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((n, n), np.float32), rng.standard_normal((n, n), np.float32)
    a @ b
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        a @ b
        times.append(time.perf_counter() - t0)
    return 2 * n ** 3 / statistics.median(times) / 1e9


def timed(stages: dict, name: str, fn):
    def wrapper(*args, **kw):
        t0 = time.perf_counter()
        out = fn(*args, **kw)
        stages[name] = stages.get(name, 0.0) + time.perf_counter() - t0
        return out
    return wrapper


def profile(n_steps: int) -> None:
    trainer, data = main_job_trainer()
    m, stages = trainer.model, {}
    for net, name in ((m.film, "Ψ"), (m.gating, "Ω"), (m.motion, "Φ")):
        net.forward = timed(stages, f"{name} forward", net.forward)
        net.backward = timed(stages, f"{name} backward", net.backward)
    trainer.losses = timed(stages, "losses (Eq. 5-7)", trainer.losses)
    trainer.check_finite = timed(stages, "NaN / inf check", trainer.check_finite)
    trainer.optimizer.step = timed(stages, "Adam", trainer.optimizer.step)
    batches = steps(trainer, data)
    for _ in range(20):                                  # warm-up: buffers, caches
        trainer.train_step(next(batches))
    stages.clear()
    t0 = time.perf_counter()
    for _ in range(n_steps):
        trainer.train_step(next(batches))
    step_ms = (time.perf_counter() - t0) / n_steps * 1e3
    rows = [{"stage": k, "ms / step": 1e3 * v / n_steps, "share": f"{100 * 1e3 * v / n_steps / step_ms:.0f} %"}
            for k, v in stages.items()]
    rest = step_ms - sum(r["ms / step"] for r in rows)
    rows.append({"stage": "the rest (minibatch, zero_grad, Python)", "ms / step": rest,
                 "share": f"{100 * rest / step_ms:.0f} %"})
    print(f"\none training step of the main job's model, {n_steps} steps: {step_ms:.2f} ms")
    table(rows, ["stage", "ms / step", "share"])

    prof = cProfile.Profile()                            # the kernels, by function
    prof.enable()
    for _ in range(n_steps):
        trainer.train_step(next(batches))
    prof.disable()
    st = pstats.Stats(prof)
    kernels = [(fn[2], fn[0], tt / n_steps * 1e3, ct / n_steps * 1e3)
               for fn, (_, _, tt, ct, _) in st.stats.items() if "/minifilm/nn/" in fn[0]]
    kernels.sort(key=lambda k: -k[2])
    print("\nkernels of minifilm/nn (own time, cProfile; the 12 largest):")
    table([{"function": f"{Path(f).name}::{name}", "ms / step": tt} for name, f, tt, _ in kernels[:12]],
          ["function", "ms / step"])

    flops, peak = step_flops(CONFIG), gemm_gflops()
    achieved = flops["step"] / (step_ms * 1e-3) / 1e9
    print(f"\nthe step: {flops['step'] / 1e9:.3f} GFLOP (forward {flops['forward'] / 1e9:.3f}, backward "
          f"{flops['backward'] / 1e9:.3f}) in {step_ms:.2f} ms = {achieved:.1f} GFLOP/s; one 2048^3 float32 "
          f"matrix product on this core: {peak:.1f} GFLOP/s -> the step runs at {100 * achieved / peak:.0f} % of it")


# ---- one process against MPI ranks --------------------------------------------------------------
def rank_run(n_steps: int, warmup: int, out: str) -> None:
    """In each rank (or the one process): time n_steps training steps and the collective calls
    inside them (reduce-scatter, all-reduce of the losses, all-gather; their waits included)."""
    from minifilm.train import mpi
    ranks = mpi.world()
    trainer, data = main_job_trainer(ranks)
    waited = [0.0]
    if ranks is not None:                   # time the step's collective calls (they include the waits)
        comm = ranks.comm

        class Timed:
            def __getattr__(self, name):
                call = getattr(comm, name)

                def timed_call(*args, **kw):
                    t0 = time.perf_counter()
                    out = call(*args, **kw)
                    waited[0] += time.perf_counter() - t0
                    return out
                return timed_call
        ranks.comm = Timed()
    batches = steps(trainer, data)
    for _ in range(warmup):
        trainer.train_step(next(batches))
    waited[0] = 0.0
    t0 = time.perf_counter()
    for _ in range(n_steps):
        trainer.train_step(next(batches))
    seconds = time.perf_counter() - t0
    if ranks is None or ranks.rank == 0:
        weights = np.concatenate([ps.data for ps in trainer.model.parameter_sets()])
        Path(out).write_text(json.dumps({"step_ms": seconds / n_steps * 1e3, "allreduce_ms": waited[0] / n_steps * 1e3,
                                         "cpu_s": time.process_time(), "checksum": float(np.abs(weights).sum())}))


def compare_ranks(rank_counts, n_steps: int, repeats: int) -> None:
    mpiexec = shutil.which("mpiexec")
    if mpiexec is None:
        print("\nno mpiexec on the PATH: pip install -e '.[mpi]' for the ranks table")
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeats):                         # interleaved: every count sees the same load
            for n in (1, *rank_counts):
                out = Path(tmp) / f"{n}.json"
                cmd = [sys.executable, __file__, "--rank-run", str(n_steps), str(out)]
                if n > 1:
                    cmd = [mpiexec, "-n", str(n)] + cmd
                subprocess.run(cmd, check=True, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
                rows.append({"processes": n, "repeat": r + 1, **json.loads(out.read_text())})
    one = statistics.median(row["step_ms"] for row in rows if row["processes"] == 1)
    print(f"\n{n_steps} training steps of the main job's model, 1 process against mpiexec -n N "
          f"(medians of {repeats}, interleaved; load now {load_average()}):")
    summary = []
    for n in (1, *rank_counts):
        mine = [row for row in rows if row["processes"] == n]
        ms = statistics.median(row["step_ms"] for row in mine)
        summary.append({"processes": n, "step ms": ms, "speed-up": one / ms,
                        "collectives ms / step": statistics.median(row["allreduce_ms"] for row in mine),
                        "weights (|w| sum)": f"{mine[0]['checksum']:.4f}"})
    table(summary, ["processes", "step ms", "speed-up", "collectives ms / step", "weights (|w| sum)"])


def allreduce_run(sizes, out: str) -> None:
    """In each rank: for each size, the median time of an in-place float32 Allreduce (sum), and of
    the training step's exchange: a Reduce_scatter_block of the gradients and an Allgather of the
    weights (minifilm/train/mpi.py)."""
    from mpi4py import MPI   # here: only under mpiexec, in the child this script starts
    comm = MPI.COMM_WORLD
    result = {}
    for n in sizes:
        part = np.empty(-(-n // comm.size), np.float32)     # equal parts, padded, as the training
        buf = np.ones(len(part) * comm.size, np.float32)

        def exchange():
            comm.Reduce_scatter_block(buf, part, op=MPI.SUM)
            comm.Allgather(MPI.IN_PLACE, buf)
        row = {}
        for name, call in (("allreduce", lambda: comm.Allreduce(MPI.IN_PLACE, buf, op=MPI.SUM)),
                           ("exchange", exchange)):
            times = []
            for i in range(13):
                comm.Barrier()
                t0 = time.perf_counter()
                call()
                times.append(time.perf_counter() - t0)
            row[name] = statistics.median(times[3:]) * 1e3
        result[n] = row
    if comm.rank == 0:
        Path(out).write_text(json.dumps(result))


def compare_allreduce(rank_counts) -> None:
    from minifilm.model.style_model import parameter_counts
    small = sum(v for k, v in parameter_counts(CONFIG).items() if k != "per_style")
    paper = sum(v for k, v in parameter_counts(ModelConfig.paper()).items() if k != "per_style")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in rank_counts:
            out = Path(tmp) / "allreduce.json"
            subprocess.run([shutil.which("mpiexec"), "-n", str(n), sys.executable, __file__, "--allreduce-run",
                            str(out), str(small), str(paper)], check=True)
            for size, ms in json.loads(out.read_text()).items():
                rows.append({"ranks": n, "parameters": int(size), "MB": 4 * int(size) / 1e6,
                             "all-reduce ms": ms["allreduce"], "reduce-scatter + all-gather ms": ms["exchange"],
                             "GB/s (2 S (N-1) / N / t)": 2 * 4 * int(size) * (n - 1) / n / (ms["exchange"] * 1e-3) / 1e9})
    print(f"\nfloat32 gradients summed on this machine (medians of 10; load now {load_average()}):")
    table(rows, ["ranks", "parameters", "MB", "all-reduce ms", "reduce-scatter + all-gather ms",
                 "GB/s (2 S (N-1) / N / t)"])


def compare_job(rank_counts, repeats: int) -> None:
    mpiexec = shutil.which("mpiexec")
    rows = []
    for r in range(repeats):
        for n in (1, *rank_counts):
            with tempfile.TemporaryDirectory() as tmp:
                cmd = [sys.executable, str(ROOT / "examples" / "train_small.py"), "--out", str(Path(tmp) / "run")]
                if n > 1:
                    cmd = [mpiexec, "-n", str(n)] + cmd
                t0 = time.perf_counter()
                proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
                wall = time.perf_counter() - t0
                epochs = [float(line.split()[-1].rstrip("s")) for line in proc.stdout.splitlines()
                          if line.strip()[:1].isdigit() and line.rstrip().endswith("s") and len(line.split()) == 6]
                mse = next(line.split()[1] for line in proc.stdout.splitlines() if line.strip().startswith("mean "))
                recog = next(line.split()[-1] for line in proc.stdout.splitlines() if "mean style recognition" in line)
                rows.append({"processes": n, "repeat": r + 1, "whole script s": wall, "epochs s": sum(epochs),
                             "test MSE": mse, "recognition": recog, "load": load_average()})
    print("\nexamples/train_small.py, whole script:")
    table(rows, ["processes", "repeat", "whole script s", "epochs s", "test MSE", "recognition", "load"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--threads", type=int, default=1, help="BLAS threads per process (common.py)")
    parser.add_argument("--profile", action="store_true", help="only the profile of one step")
    parser.add_argument("--ranks", type=int, nargs="+", default=[2], help="rank counts to compare with 1 process")
    parser.add_argument("--steps", type=int, default=300, help="timed steps per run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--job", action="store_true", help="also the whole main job, 1 process and each rank count")
    parser.add_argument("--allreduce", action="store_true", help="only the gradients' exchange, main job and paper sizes")
    parser.add_argument("--rank-run", nargs=2, metavar=("STEPS", "OUT"), help=argparse.SUPPRESS)
    parser.add_argument("--allreduce-run", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.rank_run:
        rank_run(int(args.rank_run[0]), 20, args.rank_run[1])
        return
    if args.allreduce_run:
        allreduce_run([int(n) for n in args.allreduce_run[1:]], args.allreduce_run[0])
        return
    if args.allreduce:
        header("all-reduce of a network's gradients (minifilm/train/mpi.py)")
        compare_allreduce(args.ranks)
        return
    header("training speed of the main job's model (minifilm/train/mpi.py)")
    print(f"# CPU: {cpu_name()}")
    profile(min(args.steps, 200))
    if not args.profile:
        compare_ranks(args.ranks, args.steps, args.repeats)
        if args.job:
            compare_job(args.ranks, args.repeats)


if __name__ == "__main__":
    main()
