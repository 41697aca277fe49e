"""Shared set-up for the speed benchmarks: thread count, timing, tables, inputs.

IMPORT THIS MODULE BEFORE NUMPY. OpenBLAS (numpy's BLAS) reads its thread count from the
environment once, when numpy is first imported, so ``import common`` sets OMP_NUM_THREADS,
OPENBLAS_NUM_THREADS and MKL_NUM_THREADS first. The count is ``--threads N`` on the command line,
else $MINIFILM_BENCH_THREADS, else the number of cores. PyTorch gets the same count through
``torch.set_num_threads`` (see torch_reference.py), so both sides use the same cores.

OpenBLAS kernels: OpenBLAS picks its kernels from the CPU unless $OPENBLAS_CORETYPE names them.
On this machine the environment sets OPENBLAS_CORETYPE=Haswell (AVX2 kernels) although the CPU
(AMD EPYC, Zen 5) has AVX-512, for which OpenBLAS's own detection picks its SkylakeX kernels;
PyTorch's bundled oneDNN/MKL use AVX-512 regardless. By default the benchmarks keep the
environment as it is; ``--coretype auto`` removes the variable for the benchmark process (OpenBLAS
detects the CPU), ``--coretype NAME`` forces a kernel family. The header of every table says which
kernels were used, and benchmarks/README.md reports both.

Timing: ``median_ms(fn, repeat, warmup)`` runs ``fn`` ``warmup`` times untimed (first-call costs:
page faults of fresh buffers, BLAS thread start-up, PyTorch's lazy initialisation), then
``repeat`` times, and returns the median wall time in milliseconds.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _thread_count() -> int:
    argv = sys.argv
    if "--threads" in argv:
        i = argv.index("--threads")
        return int(argv[i + 1])
    return int(os.environ.get("MINIFILM_BENCH_THREADS", os.cpu_count() or 1))


def _coretype() -> str:
    """OpenBLAS kernel choice: ``--coretype NAME`` or ``auto`` (OpenBLAS detects the CPU); without
    the option, whatever the environment says ('env')."""
    if "--coretype" in sys.argv:
        return sys.argv[sys.argv.index("--coretype") + 1]
    return "env"


THREADS = _thread_count()
CORETYPE = _coretype()
if "numpy" in sys.modules:
    raise RuntimeError("benchmarks/common.py must be imported before numpy, so that the BLAS "
                       "thread count and kernel choice below take effect")
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = str(THREADS)
if CORETYPE == "auto":
    os.environ.pop("OPENBLAS_CORETYPE", None)
elif CORETYPE != "env":
    os.environ["OPENBLAS_CORETYPE"] = CORETYPE

import statistics  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402


def median_ms(fn, repeat: int = 10, warmup: int = 2) -> float:
    """Median wall time of ``fn()`` in milliseconds, after ``warmup`` untimed calls."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def compare_ms(fns: dict, repeat: int = 10, warmup: int = 2, block: int = 1) -> dict:
    """Median wall time (ms) of each function in ``fns`` ({name: fn}), timed INTERLEAVED.

    The cores are shared with other processes whose load comes and goes; running the candidates
    in turn (a, b, a, b, ...) exposes them to the same conditions, so their ratio is fairer than
    that of two medians taken minutes apart. With ``block`` > 1 each candidate runs ``block``
    times in a row per turn (``repeat`` calls in all): for calls of well under a millisecond
    whose weights should stay in the CPU cache, as they would in a real-time loop, instead of
    being evicted by the other candidate's copy every call.
    """
    for fn in fns.values():
        for _ in range(warmup):
            fn()
    times = {name: [] for name in fns}
    for _ in range(max(1, repeat // block)):
        for name, fn in fns.items():
            for _ in range(block):
                t0 = time.perf_counter()
                fn()
                times[name].append(time.perf_counter() - t0)
    return {name: 1e3 * statistics.median(t) for name, t in times.items()}


def blas_core() -> str:
    """The kernel family numpy's OpenBLAS actually uses (e.g. 'Haswell', 'SkylakeX'), if it says."""
    import ctypes
    import glob
    libdir = Path(np.__file__).resolve().parent.parent / "numpy.libs"
    for lib in sorted(glob.glob(str(libdir / "*openblas*"))):
        for name in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename",
                     "openblas_get_corename64_", "openblas_get_corename"):
            try:
                fn = getattr(ctypes.CDLL(lib), name)
            except (AttributeError, OSError):
                continue
            fn.restype = ctypes.c_char_p
            return fn().decode()
    return "unknown"


def load_average() -> str:
    """The 1-minute load average (other processes sharing the cores make timings noisy)."""
    try:
        return f"{os.getloadavg()[0]:.2f}"
    except OSError:
        return "n/a"


def header(title: str) -> None:
    """Print what was measured and under which conditions."""
    print(f"# {title}")
    print(f"# threads {THREADS} (numpy: OPENBLAS_NUM_THREADS; torch: set_num_threads), "
          f"cores {os.cpu_count()}, load average {load_average()}")
    print(f"# numpy {np.__version__}, OpenBLAS kernels {blas_core()} (OPENBLAS_CORETYPE "
          f"{os.environ.get('OPENBLAS_CORETYPE', 'unset')}; --coretype auto: OpenBLAS's own choice)")


def table(rows: list[dict], columns: list[str]) -> None:
    """Print rows (dicts) as an aligned plain-text table."""
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.3f}" if abs(v) < 10 else f"{v:.1f}"
        return str(v)
    cells = [[fmt(r.get(c, "")) for c in columns] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(columns)]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    print("  ".join("-" * w for w in widths))
    for row in cells:
        print("  ".join(v.ljust(w) for v, w in zip(row, widths)))


def random_batch(config, batch: int, rng: np.random.Generator, with_clip: bool = True):
    """Normalised-looking float32 inputs for one minibatch: x, p, film, clip, target z."""
    f32 = np.float32
    x = rng.standard_normal((batch, config.x_dim)).astype(f32)
    p = rng.standard_normal((batch, config.phase_dim)).astype(f32)
    # FiLM given directly: gamma around 1, beta around 0 (what Ψ produces at initialisation)
    film = (0.1 * rng.standard_normal((batch, config.film_dim))).astype(f32)
    H = config.hidden
    film[:, 0:H] += 1
    film[:, 2 * H:3 * H] += 1
    clip = (rng.standard_normal((batch, config.clip_frames, config.clip_channels)).astype(f32)
            if with_clip else None)
    z = rng.standard_normal((batch, config.z_dim)).astype(f32)
    return x, p, film, clip, z
