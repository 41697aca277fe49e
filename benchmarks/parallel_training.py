"""Data-parallel training (minifilm/train/parallel.py): step time, CPU time / wall time and achieved
GFLOP/s for 1 and 2 worker processes, more workers extrapolated, and (--job) the whole main job.

    python benchmarks/parallel_training.py              # a few minutes: the step table, train_small's model
    python benchmarks/parallel_training.py --quick      # fewer steps (about a minute)
    python benchmarks/parallel_training.py --job        # also time `python examples/train_small.py`
                                                        #   with --workers 1 and 2 (several minutes each)
    python benchmarks/parallel_training.py --job --repeats 3    # each job 3 times, interleaved
    python benchmarks/parallel_training.py --sync       # the round trip to a worker: pipe, semaphores, counters
    python benchmarks/parallel_training.py --profile    # cProfile of the one-process step, top functions
    python benchmarks/parallel_training.py --bound      # the most 2 workers can gain, from one process's parts
    python benchmarks/parallel_training.py --contention # the same with both cores busy (two copies of a share)

The model and minibatches are those of examples/train_small.py (ModelConfig.small on x 348, z 342,
clips 120 x 300; batch 32, 4 clips per minibatch, dropout 0.2, Adam), on random normalised data
of the same shapes (a step's cost does not depend on the values). Each row runs the same seeded
steps; rows are interleaved in blocks (1 worker, 2 workers, 1, 2, ...) so both see the same
background load; a row's step time is the least of its blocks' medians (the block the other
load disturbed least; the summary also gives the median of the blocks). Every process uses one
BLAS thread; with W workers this process is worker 0 and W - 1 worker processes run beside it.

Columns:
  step ms        wall time of a whole training step (gradients, sum, NaN check, Adam), see above
  speed-up       step time of 1 worker / this row's
  CPU / wall     (CPU time of the parent + its workers) / wall time, over the timed steps (Linux:
                 the workers' CPU time from /proc/<pid>/stat)
  GFLOP/s        floating-point operations of a step (counted from the layer sizes: 2 per
                 multiply-add of every matrix product and convolution, forward once and backward
                 twice -- weights and inputs -- except the input gradient of each network's first
                 layer, which training skips; element-wise work not counted) / step time
  % of peak      GFLOP/s against ONE core's float32 peak: vector lanes (16 with avx512f in
                 /proc/cpuinfo's flags, 8 with avx2, 4 otherwise) x 2 (fma) x 2 FMA units per
                 core (assumed: most current x86 cores; Zen 4 has one 512-bit unit's worth) x the
                 clock (/proc/cpuinfo's "cpu MHz", the current one)
  parent's own   this process's serial work in a step: the dropout masks, the minibatch into shared memory
  waiting ms     this process waiting, after its own share, for the other workers to finish theirs
Rows for more workers are extrapolated (marked ~): the parent's own work stays serial, the rest
of the one-process step (gradients, their sum, Adam) divides by W, and what the 2-worker step
costs beyond those two (synchronisation, waiting for the slower share) stays as measured --
Amdahl's law, an estimate for a machine with that many free cores. The last table (the summary)
puts the step, the job (--job), CPU / wall, the job's test MSE and style recognition and the load
side by side.
"""
from __future__ import annotations

import os

os.environ.update({"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})

import argparse  # noqa: E402
import cProfile  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import pstats  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from multiprocessing import shared_memory  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from minifilm.dataset.arrays import TrainData  # noqa: E402
from minifilm.dataset.stats import NormStats  # noqa: E402
from minifilm.model.config import ModelConfig  # noqa: E402
from minifilm.model.style_model import StyleModel  # noqa: E402
from minifilm.train.parallel import DataParallel  # noqa: E402
from minifilm.train.parallel_worker import wait_until  # noqa: E402
from minifilm.train.trainer import TrainConfig, Trainer  # noqa: E402

STYLES, FRAMES_PER_STYLE = 8, 2400        # about train_small's training split (8 styles x 5 gaits x 8 s)


def config() -> ModelConfig:
    return ModelConfig.small(x_dim=348, z_dim=342, clip_frames=120, clip_channels=300)


def random_data(c: ModelConfig, seed: int = 0) -> TrainData:
    rng = np.random.default_rng(seed)
    n, clips = STYLES * FRAMES_PER_STYLE, 16 * STYLES
    f = np.float32
    return TrainData(x=rng.standard_normal((n, c.x_dim), f), p=rng.standard_normal((n, c.phase_dim), f),
                     z=rng.standard_normal((n, c.z_dim), f), style=np.arange(n) % STYLES,
                     clips=rng.standard_normal((clips, c.clip_frames, c.clip_channels), f),
                     clip_style=np.arange(clips) % STYLES)


def new_trainer(c: ModelConfig, batch: int = 32, clips: int = 4) -> Trainer:
    stats = NormStats(x_mean=np.zeros(c.x_dim), x_std=np.ones(c.x_dim), z_mean=np.zeros(c.z_dim),
                      z_std=np.ones(c.z_dim), p_mean=np.zeros(c.phase_dim), p_std=np.ones(c.phase_dim))
    positions = np.arange(3 * 23).reshape(23, 3)                  # 23 joints, as the 100STYLE skeleton
    parents = np.arange(-1, 22)
    return Trainer(StyleModel(c, np.random.default_rng(0)), stats,
                   TrainConfig(batch_size=batch, lr=5e-4, clips_per_batch=clips, seed=0),
                   positions_idx=positions, parents=parents)


def step_flops(c: ModelConfig, batch: int = 32, clips: int = 4) -> float:
    """Floating-point operations of one training step (see the module's docstring)."""
    K, H = c.n_experts, c.hidden
    def dense(rows, n_in, n_out, first=False):
        return 2.0 * rows * n_in * n_out * (2 if first else 3)
    omega = (dense(batch, c.phase_dim, c.gating_hidden, True) + dense(batch, c.gating_hidden, c.gating_hidden)
             + dense(batch, c.gating_hidden, K))
    phi = (dense(batch, K * c.x_dim, H, True) + dense(batch, K * H, H) + dense(batch, K * H, c.z_dim))
    T, k, F = c.clip_frames, c.conv_kernel, c.conv_filters
    psi = (dense(clips * T, k * c.clip_channels, F, True) + dense(clips * (T // 2), k * F, F)
           + dense(clips, c.flat_dim, c.film_dense) + dense(clips, c.film_dense, c.film_dim))
    return omega + phi + psi


def core_peak() -> tuple[float, str]:
    """(GFLOP/s, how it was computed) of one core in float32, from /proc/cpuinfo."""
    flags, mhz = set(), None
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "flags" and not flags:
                flags = set(value.split())
            if key.strip() == "cpu MHz" and mhz is None:
                mhz = float(value)
    except OSError:
        pass
    lanes = 16 if "avx512f" in flags else 8 if "avx2" in flags else 4
    fma = 2 if "fma" in flags else 1
    ghz = (mhz or 0.0) / 1000
    isa = "AVX-512" if lanes == 16 else "AVX2" if lanes == 8 else "SSE"
    return lanes * fma * 2 * ghz, f"{lanes} lanes ({isa}) x {fma} (FMA) x 2 units x {ghz:.2f} GHz"


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform
    return platform.processor() or "unknown CPU"


def autogroup() -> str:
    """Whether Linux's autogroup scheduling is on: then all processes of one login session (this
    script and its workers) share ONE group's part of the CPUs against the other login sessions,
    so on a shared machine a second worker process may only split that part."""
    try:
        on = Path("/proc/sys/kernel/sched_autogroup_enabled").read_text().strip() == "1"
    except OSError:
        return "autogroup scheduling unknown"
    return "autogroup scheduling on (the processes of one login session share one group's CPU)" if on else "no autogroup"


def load() -> str:
    try:
        return "load average " + " / ".join(f"{x:.2f}" for x in os.getloadavg()) + " (1 / 5 / 15 min)"
    except OSError:
        return "load average unknown"


def proc_cpu(pids) -> float:
    """CPU seconds (user + system) of the processes ``pids`` (Linux /proc; 0 elsewhere)."""
    total, tick = 0.0, os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / tick
        except (OSError, IndexError, ValueError):
            pass
    return total


class Runner:
    """One trainer, in this process (workers 1) or with a DataParallel pool, stepping through the
    same seeded minibatches."""

    def __init__(self, workers: int, data: TrainData):
        self.trainer, self.data, self.workers = new_trainer(config()), data, workers
        self.pool = DataParallel(self.trainer, workers) if workers > 1 else None
        self.batches = self._batches()
        self.times, self.wall, self.cpu = [], 0.0, 0.0

    def _batches(self):
        return endless(self.trainer, self.data)

    def run(self, steps: int) -> None:
        t = self.trainer
        pids = self.pool.pids[1:] if self.pool else []
        c0, w0 = time.process_time() + proc_cpu(pids), time.perf_counter()
        for _ in range(steps):
            s0 = time.perf_counter()
            t.train_step(next(self.batches), self.pool)      # with a pool: DataParallel.train_step
            self.times.append(time.perf_counter() - s0)
        self.wall += time.perf_counter() - w0
        self.cpu += time.process_time() + proc_cpu(pids) - c0

    def close(self):
        if self.pool:
            self.pool.close()


def step_table(steps: int, blocks: int) -> dict:
    """Print the step table; returns {workers: (min over blocks of the block medians, the median
    of them, CPU / wall)} and the load before and after."""
    before = load()
    data = random_data(config())
    runners = {w: Runner(w, data) for w in (1, 2)}
    try:
        for r in runners.values():
            r.run(10)                                      # warm-up: page faults, caches
            r.times, r.wall, r.cpu = [], 0.0, 0.0
            if r.pool:
                r.pool.seconds = dict.fromkeys(r.pool.seconds, 0.0)
        per_block = {w: [] for w in runners}
        for _ in range(blocks):
            for w, r in runners.items():
                n0 = len(r.times)
                r.run(steps // blocks)
                per_block[w].append(statistics.median(r.times[n0:]))
        # a check that the rows computed the same thing
        w1, w2 = (np.concatenate([p.data for p in runners[w].trainer.model.parameter_sets()]) for w in (1, 2))
        drift = float(np.abs(w1 - w2).max() / np.abs(w1).max())
    finally:
        for r in runners.values():
            r.close()
    flops = step_flops(config())
    peak, how = core_peak()
    one = min(per_block[1])
    n_steps = steps // blocks * blocks
    r2 = runners[2]
    print(f"# {cpu_name()}; {os.cpu_count()} logical CPUs, {len(os.sched_getaffinity(0))} usable; {before} before, "
          f"{load()} after")
    print(f"# train_small's model ({sum(p.size for p in runners[1].trainer.model.parameter_sets()):,} parameters), "
          f"batch 32, 4 clips per minibatch; {n_steps} timed steps per row in {blocks} interleaved blocks; "
          "step ms: the least of the blocks' medians (the block least disturbed by other load)")
    print(f"# one step: {flops / 1e9:.3f} GFLOP; one core's float32 peak {peak:.1f} GFLOP/s = {how}")
    print(f"# largest weight difference, 1 vs 2 workers, after {len(r2.times) + 10} steps: {drift:.1e} (relative)")
    print()
    print("| workers | step ms | speed-up | CPU / wall | GFLOP/s | % of one core's peak | parent's own ms | "
          "waiting ms |")
    print("|---|---|---|---|---|---|---|---|")
    for w, r in runners.items():
        ms = min(per_block[w])
        own = [f"{r.pool.seconds[k] / len(r.times) * 1e3:.2f}" for k in ("parent", "waiting")] if r.pool else "--"
        print(f"| {w} | {ms * 1e3:.2f} | {one / ms:.2f}x | {r.cpu / r.wall:.2f} | {flops / ms / 1e9:.1f} | "
              f"{100 * flops / ms / 1e9 / peak:.0f} % | {own[0]} | {own[1]} |")
    # Amdahl: the parent's own work (masks, writing the minibatch) stays serial; the gradients,
    # their sum and Adam divide by W; the rest of the 2-worker step (messages, waiting for the
    # slower share) is taken as a fixed cost per step
    own = r2.pool.seconds["parent"] / len(r2.times)
    two = min(per_block[2])
    work = one                                                   # gradients + Adam, one process
    messages = max(two - own - work / 2, 0.0)
    for w in (4, 8, 16):
        ms = own + work / w + messages
        print(f"| ~{w} | ~{ms * 1e3:.2f} | ~{one / ms:.2f}x | - | ~{flops / ms / 1e9:.1f} | - | - | - |")
    print(f"\n(extrapolated rows: the parent's own work {own * 1e3:.2f} ms + the one-process step "
          f"{work * 1e3:.2f} ms / W + messages and waiting {messages * 1e3:.2f} ms per step)")
    steps_per_epoch = STYLES * (FRAMES_PER_STYLE // 32)
    print(f"training of the main job, estimated: 30 epochs x {steps_per_epoch} steps = "
          + ", ".join(f"{w} worker(s) {30 * steps_per_epoch * min(per_block[w]):.0f} s" for w in runners)
          + " (validation and the other steps of the job not included)")
    return {w: (min(per_block[w]), statistics.median(per_block[w]), r.cpu / r.wall) for w, r in runners.items()}, \
        (before, load())


def job_table(repeats: int = 1) -> dict:
    """Run `python examples/train_small.py --workers W` for W = 1, 2 (``repeats`` times, interleaved);
    print each run; returns {W: [(wall s, CPU s, test MSE, recognition, load before, after)]}."""
    print("\n| workers | `python examples/train_small.py` wall s | CPU s | CPU / wall | test MSE | recognition | "
          "load before / after (1 min) |")
    print("|---|---|---|---|---|---|---|")
    runs = {1: [], 2: []}
    for _ in range(repeats):
        for w in runs:
            before = os.getloadavg()[0]
            with tempfile.TemporaryDirectory() as tmp:
                used = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                r = subprocess.run([sys.executable, str(ROOT / "examples" / "train_small.py"), "--workers", str(w),
                                    "--out", str(Path(tmp) / "run")], capture_output=True, text=True,
                                   env={**os.environ, "PYTHONPATH": str(ROOT)})
                wall = time.perf_counter() - t0
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
            if r.returncode != 0:
                print(f"| {w} | failed: {r.stderr.strip().splitlines()[-1:]} | | | | | |")
                continue
            cpu = (after.ru_utime - used.ru_utime) + (after.ru_stime - used.ru_stime)
            mean = [line.split() for line in r.stdout.splitlines() if line.strip().startswith("mean")]
            mse = next((float(m[1]) for m in mean if len(m) == 3), float("nan"))            # "mean 0.0483 1.0574"
            recognition = next((float(m[-1]) for m in mean if "recognition" in m), float("nan"))
            runs[w].append((wall, cpu, mse, recognition, before, os.getloadavg()[0]))
            print(f"| {w} | {wall:.0f} | {cpu:.0f} | {cpu / wall:.2f} | {mse:.4f} | {recognition:.2f} | "
                  f"{before:.1f} / {os.getloadavg()[0]:.1f} |", flush=True)
    return runs


def summary(steps: dict, step_load, jobs: dict | None) -> None:
    """The figures of the run in one table, for a coordinator to compare machines."""
    print(f"\n## Summary: {cpu_name()}, {len(os.sched_getaffinity(0))} usable cores, {autogroup()}; steps: "
          f"{step_load[0]} before, {step_load[1]} after")
    print("| measure | 1 worker | 2 workers | 1 / 2 |\n|---|---|---|---|")
    (a, am, ac), (b, bm, bc) = steps[1], steps[2]
    print(f"| training step ms (least block median) | {a * 1e3:.2f} | {b * 1e3:.2f} | {a / b:.2f}x |")
    print(f"| training step ms (median of blocks) | {am * 1e3:.2f} | {bm * 1e3:.2f} | {am / bm:.2f}x |")
    print(f"| CPU / wall of the steps | {ac:.2f} | {bc:.2f} | |")
    if jobs and jobs[1] and jobs[2]:
        best = {w: min(runs) for w, runs in jobs.items()}
        print(f"| train_small.py wall s (least of {len(jobs[1])}) | {best[1][0]:.0f} | {best[2][0]:.0f} | "
              f"{best[1][0] / best[2][0]:.2f}x |")
        print(f"| its CPU / wall | {best[1][1] / best[1][0]:.2f} | {best[2][1] / best[2][0]:.2f} | |")
        print(f"| its test MSE | {best[1][2]:.4f} | {best[2][2]:.4f} | |")
        print(f"| its style recognition | {best[1][3]:.2f} | {best[2][3]:.2f} | |")
        print(f"| load (1 min) before / after it | {best[1][4]:.1f} / {best[1][5]:.1f} | "
              f"{best[2][4]:.1f} / {best[2][5]:.1f} | |")


def spin_wait(ready) -> None:
    """The first version's wait, for the comparison only: tries, then the core given up between
    tries (os.sched_yield) for 2 ms, then naps of 0.2 ms."""
    for _ in range(200):
        if ready():
            return
    start = time.perf_counter()
    while not ready():
        os.sched_yield() if time.perf_counter() - start < 0.002 else time.sleep(0.0002)


def _pong(kind: str, n: int, link) -> None:
    """The other end of :func:`sync_table`'s ping-pong, in a worker process: answer n pings."""
    if kind == "pipe":
        for _ in range(n):
            link.send_bytes(link.recv_bytes())
        return
    if kind == "semaphores":
        ping, pong = link
        for _ in range(n):
            ping.acquire()
            pong.release()
        return
    name, (ping, pong) = link
    shm = shared_memory.SharedMemory(name=name)
    flags = np.ndarray((2, 8), dtype=np.int64, buffer=shm.buf)[:, 0]
    for i in range(1, n + 1):
        if kind == "counters, spinning":
            spin_wait(lambda: flags[0] >= i)
        else:
            wait_until(lambda: flags[0] >= i, lambda: None, ping)
        flags[1] = i
        pong.release()
    del flags
    shm.close()


KINDS = ("pipe", "semaphores", "counters, spinning", "counters + semaphores (training's)")


def sync_table(n: int = 2000, repeats: int = 5) -> dict:
    """Round-trip time of one message to a worker process and its answer: through a pipe (the
    earlier version's messages), a pair of multiprocessing.Semaphores, counters in shared memory
    waited on by spinning (spin_wait), and counters waited on by parallel_worker.wait_until (a
    few tries, then the semaphore: what training uses). Min and median of ``repeats`` runs of
    ``n`` round trips, the kinds interleaved."""
    ctx = multiprocessing.get_context("spawn")
    times = {kind: [] for kind in KINDS}
    shm = shared_memory.SharedMemory(create=True, size=128)
    flags = np.ndarray((2, 8), dtype=np.int64, buffer=shm.buf)[:, 0]
    try:
        for _ in range(repeats):
            for kind in times:
                sems = (ctx.Semaphore(0), ctx.Semaphore(0))
                flags[:] = 0
                link = ctx.Pipe() if kind == "pipe" else sems if kind == "semaphores" else (shm.name, sems)
                proc = ctx.Process(target=_pong, args=(kind, n + 1, link[1] if kind == "pipe" else link), daemon=True)
                proc.start()
                for i in range(n + 1):                  # the first round trip: the worker is up
                    if i == 1:
                        t0 = time.perf_counter()
                    if kind == "pipe":
                        link[0].send_bytes(b"x")
                        link[0].recv_bytes()
                    elif kind == "semaphores":
                        sems[0].release()
                        sems[1].acquire()
                    else:
                        flags[0] = i + 1
                        sems[0].release()
                        if kind == "counters, spinning":
                            spin_wait(lambda: flags[1] >= i + 1)
                        else:
                            wait_until(lambda: flags[1] >= i + 1, lambda: None, sems[1])
                times[kind].append((time.perf_counter() - t0) / n)
                proc.join()
    finally:
        del flags
        shm.close()
        shm.unlink()
    return {k: (min(v), statistics.median(v)) for k, v in times.items()}


def print_sync(n: int = 2000) -> dict:
    before = load()
    result = sync_table(n)
    print(f"\n# a round trip to a worker process and back ({n} in a row, min / median of 5); {before} before, "
          f"{load()} after")
    print("| how | min µs | median µs |\n|---|---|---|")
    for kind, (low, mid) in result.items():
        print(f"| {kind} | {low * 1e6:.1f} | {mid * 1e6:.1f} |")
    return result


def endless(trainer: Trainer, data: TrainData):
    """The trainer's minibatches, epoch after epoch."""
    while True:
        yield from trainer.minibatches(data)


def bound(steps: int, blocks: int = 6) -> None:
    """The most 2 workers can gain on this step, from one process's parts: a 2-worker step is at
    least one worker's half of the gradients (batch 16, 2 clips) plus half of Adam, so

        bound = (gradients(32) + Adam) / (gradients(16) + Adam / 2)

    (the sum of the two gradient slots and every wait come on top). Blocks interleaved, the least
    block median counts."""
    data = random_data(config())
    trainers = {32: new_trainer(config(), 32, 4), 16: new_trainer(config(), 16, 2)}
    streams = {b: endless(t, data) for b, t in trainers.items()}
    times = {"g32": [], "g16": [], "adam": []}
    for _ in range(blocks):
        for b, t in trainers.items():
            got = []
            for _ in range(steps):
                mb = next(streams[b])
                s0 = time.perf_counter()
                t.gradients(mb)
                got.append(time.perf_counter() - s0)
                if b == 32:
                    s0 = time.perf_counter()
                    t.optimizer.step()
                    times["adam"].append(time.perf_counter() - s0)
            times[f"g{b}"].append(statistics.median(got))
    n = len(times["adam"]) // blocks
    adam = min(statistics.median(times["adam"][k * n:(k + 1) * n]) for k in range(blocks))
    g32, g16 = min(times["g32"]), min(times["g16"])
    print(f"# the most 2 workers can gain on train_small's step; {cpu_name()}; {load()}")
    print(f"gradients, batch 32 / 4 clips: {g32 * 1e3:.2f} ms; batch 16 / 2 clips: {g16 * 1e3:.2f} ms "
          f"({g32 / g16:.2f}x); Adam: {adam * 1e3:.2f} ms")
    print(f"one-process step {(g32 + adam) * 1e3:.2f} ms; a 2-worker step at least {(g16 + adam / 2) * 1e3:.2f} ms: "
          f"speed-up at most {(g32 + adam) / (g16 + adam / 2):.2f}x")


def _share_times(batch: int, clips: int, steps: int, start, out) -> None:
    """A worker's share on its own (no pool, no messages): ``steps`` gradients at ``batch`` / ``clips``
    and Adam steps, begun together with the other copies (``start``, a barrier); medians to ``out``."""
    data = random_data(config())
    t = new_trainer(config(), batch, clips)
    stream = endless(t, data)
    for _ in range(20):                 # warm: first products, allocations
        t.gradients(next(stream))
        t.optimizer.step()
    start.wait()
    grads, adam = [], []
    for _ in range(steps):
        mb = next(stream)
        t0 = time.perf_counter()
        t.gradients(mb)
        t1 = time.perf_counter()
        t.optimizer.step()
        grads.append(t1 - t0)
        adam.append(time.perf_counter() - t1)
    out.put((statistics.median(grads), statistics.median(adam)))


def contention(steps: int, repeats: int = 3) -> None:
    """What the two cores give each other when both are busy: one process's step at batch 32
    (the 1-worker step's work), then a worker's share (batch 16, 2 clips) run alone and run as
    two independent processes at once, with no messages between them. The least of ``repeats``
    counts. With both cores busy a share costs what it costs beside another, so

        most a 2-worker step can gain = (gradients(32) + Adam) / (gradients(16, two at once) + Adam(two at once) / 2)

    which is --bound's figure with the slowdown two busy cores cause each other (shared cache,
    memory bandwidth, the hypervisor) folded in."""
    ctx = multiprocessing.get_context("spawn")
    got = {}
    for _ in range(repeats):
        for batch, clips, copies in ((32, 4, 1), (16, 2, 1), (16, 2, 2)):
            out, start = ctx.Queue(), ctx.Barrier(copies)
            procs = [ctx.Process(target=_share_times, args=(batch, clips, steps, start, out)) for _ in range(copies)]
            for p in procs:
                p.start()
            times = [out.get(timeout=600) for _ in procs]
            for p in procs:
                p.join()
            g, a = max(t[0] for t in times), max(t[1] for t in times)
            old = got.get((batch, copies), (math.inf, math.inf))
            got[(batch, copies)] = (min(old[0], g), min(old[1], a))
    (g32, a32), (g16, a16), (g16x2, a16x2) = got[(32, 1)], got[(16, 1)], got[(16, 2)]
    print(f"# two busy cores: a worker's share alone and beside a copy of itself; {cpu_name()}; {load()}")
    print("| work | alone ms | two at once ms | slowdown |")
    print("|---|---|---|---|")
    print(f"| gradients, batch 16 / 2 clips | {g16 * 1e3:.2f} | {g16x2 * 1e3:.2f} | {g16x2 / g16:.2f}x |")
    print(f"| Adam step | {a16 * 1e3:.2f} | {a16x2 * 1e3:.2f} | {a16x2 / a16:.2f}x |")
    print(f"one-process step (batch 32): {(g32 + a32) * 1e3:.2f} ms; a 2-worker step at least "
          f"{(g16 + a16 / 2) * 1e3:.2f} ms with a free core each, {(g16x2 + a16x2 / 2) * 1e3:.2f} ms with both busy: "
          f"speed-up at most {(g32 + a32) / (g16 + a16 / 2):.2f}x / {(g32 + a32) / (g16x2 + a16x2 / 2):.2f}x")


def profile(steps: int) -> None:
    data = random_data(config())
    r = Runner(1, data)
    r.run(10)
    prof = cProfile.Profile()
    prof.enable()
    r.run(steps)
    prof.disable()
    print(f"# cProfile of {steps} one-process steps; {cpu_name()}; {load()}")
    pstats.Stats(prof).sort_stats("tottime").print_stats(25)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer steps (about a minute)")
    ap.add_argument("--job", action="store_true", help="also time the whole main job with 1 and 2 workers")
    ap.add_argument("--profile", action="store_true", help="cProfile of the one-process step only")
    ap.add_argument("--sync", action="store_true", help="only the round trip to a worker: pipe, semaphores, "
                    "shared counters")
    ap.add_argument("--bound", action="store_true", help="only the most 2 workers can gain: one process's "
                    "gradients at batch 32 and 16 and its Adam step")
    ap.add_argument("--contention", action="store_true", help="only what two busy cores cost each other: a "
                    "worker's share alone and as two independent processes at once")
    ap.add_argument("--repeats", type=int, default=1, help="with --job: runs of each job (the least time counts)")
    ap.add_argument("--steps", type=int, help="timed steps per row (default 600, --quick 120)")
    a = ap.parse_args()
    steps = a.steps or (120 if a.quick else 600)
    if a.profile:
        profile(steps)
        return
    if a.sync:
        print_sync()
        return
    if a.bound:
        bound(steps // 2)
        return
    if a.contention:
        contention(steps // 2)
        return
    steps_, step_load = step_table(steps, blocks=6)
    jobs = job_table(a.repeats) if a.job else None
    summary(steps_, step_load, jobs)


if __name__ == "__main__":
    main()
