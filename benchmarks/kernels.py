"""The kit's hot kernels alone: Ψ's convolution (forward + backward) and the Adam step.

    python benchmarks/kernels.py                 # everything, about a minute
    python benchmarks/kernels.py --threads 1     # one BLAS thread (the reliable figures here)
    python benchmarks/kernels.py --only conv     # or --only adam

Convolution: both methods of ``fast_conv.conv1d_fast_forward`` / ``conv1d_fast_backward`` (what
training runs) at the sizes of
train_small's Ψ (clip 120 x 300, 32 filters of width 9) and of the paper's (240 x 300, 256
filters of width 25), for several batch sizes (clips per step), each layer with its own workspace
as in Ψ; the first layer skips dx as in training. "im2col" is the method the kit had before the
FFT path (unchanged), so its column is the "before"; "auto" says which one the kit now chooses;
"plain" is the reader's pair of minifilm/nn/conv.py (np.pad + stacked taps, fresh arrays), for
comparison.

Adam: one ``Adam.step`` over train_small's three parameter sets (707,420 numbers) and over the
paper's (44,150,520), hot (the numbers still in the cache from the previous step) and cold (a
64 MB buffer written between steps, as a forward and backward pass would), for chunk sizes
32768 (before), 65536 (now) and the whole buffer at once; plus, for the record, the same update
with scipy.linalg.blas's in-place sscal / saxpy (not used by the kit: see
reports/2026-12-01_fft_convolution_and_adam.md).

Times are in ms: the minimum of several runs, and the median in brackets.
"""
import common  # noqa: F401  (sets the BLAS thread count before numpy is imported)

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from common import header, load_average, table  # noqa: E402
from minifilm.model.config import ModelConfig  # noqa: E402
from minifilm.model.style_model import parameter_counts  # noqa: E402
from minifilm.nn import fast_optim as optim  # noqa: E402  (the chunked Adam and its CHUNK)
from minifilm.nn.fast_optim import ChunkedAdam as Adam  # noqa: E402  (what training uses)
from minifilm.nn.params import Parameters  # noqa: E402
from minifilm.nn import conv, fast_conv  # noqa: E402  (the plain convolution, the one training runs)

# (label, T, C, F, k, need_dx)
CONV_LAYERS = {
    "train_small": [("conv0 120x300->32, k9", 120, 300, 32, 9, False),
                    ("conv1 60x32->32, k9", 60, 32, 32, 9, True)],
    "paper": [("conv0 240x300->256, k25", 240, 300, 256, 25, False),
              ("conv1 120x256->256, k25", 120, 256, 256, 25, True)],
}


def timed(fn, repeat, warmup=1, between=None):
    """(min, median) wall time of fn() in ms; ``between()`` runs untimed before each call."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        if between is not None:
            between()
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * min(times), 1e3 * float(np.median(times))


def fmt(t):
    return f"{t[0]:.2f} ({t[1]:.2f})" if t[0] < 10 else f"{t[0]:.1f} ({t[1]:.1f})"


def conv_rows(model, batches, rng):
    rows = []
    for B in batches:
        for label, T, C, Fo, k, need_dx in CONV_LAYERS[model]:
            x = rng.standard_normal((B, T, C)).astype(np.float32)
            W = (rng.standard_normal((k, C, Fo)) / math.sqrt(k * C)).astype(np.float32)
            b = np.zeros(Fo, np.float32)
            dout = rng.standard_normal((B, T, Fo)).astype(np.float32)
            flops = 2.0 * B * T * k * C * Fo * (3 if need_dx else 2)
            repeat = 3 if flops > 2e10 else (5 if flops > 2e9 else 20)
            row = {"model": model, "layer": label, "batch": B}
            for method in ("im2col", "fft"):
                work = {}

                def step():
                    _, cache = fast_conv.conv1d_fast_forward(x, W, b, work=work, method=method)
                    fast_conv.conv1d_fast_backward(dout, cache, need_dx=need_dx)
                row[method] = timed(step, repeat)

            def plain():
                _, cache = conv.conv1d_forward(x, W, b)
                conv.conv1d_backward(dout, cache, need_dx=need_dx)
            row["plain"] = timed(plain, repeat)
            row["im2col ms"], row["fft ms"], row["plain ms"] = fmt(row["im2col"]), fmt(row["fft"]), fmt(row["plain"])
            row["fft/im2col"] = row["fft"][0] / row["im2col"][0]
            row["auto"] = fast_conv._conv1d_method(B, T, C, Fo, k)
            row["GFLOP (im2col)"] = flops / 1e9
            rows.append(row)
            print(f"  ... {model} {label} batch {B}: im2col {row['im2col ms']}, fft {row['fft ms']}, "
                  f"plain {row['plain ms']}", flush=True)
    return rows


def blas_adam_step(sets, ms, vs, bufs, steps, lr=1e-4, b1=0.9, b2=0.999, eps=1e-8):
    """The same update with in-place BLAS level-1 calls (9 a chunk instead of 12)."""
    from scipy.linalg import blas
    for i, p in enumerate(sets):
        steps[i] += 1
        t = steps[i]
        c = math.sqrt(1 - b2 ** t)
        step, eh = lr * c / (1 - b1 ** t), eps * c
        w, g, m, v, buf = p.data, p.grad, ms[i], vs[i], bufs
        for lo in range(0, p.size, optim.CHUNK):
            hi = min(lo + optim.CHUNK, p.size)
            wc, gc, mc, vc, bc = w[lo:hi], g[lo:hi], m[lo:hi], v[lo:hi], buf[: hi - lo]
            blas.sscal(b1, mc)
            blas.saxpy(gc, mc, a=1 - b1)
            np.square(gc, out=bc)
            blas.sscal(b2, vc)
            blas.saxpy(bc, vc, a=1 - b2)
            np.sqrt(vc, out=bc)
            bc += eh
            np.divide(mc, bc, out=bc)
            blas.saxpy(bc, wc, a=-step)


def adam_rows(rng, repeat_small=100, repeat_paper=8):
    evict = np.ones(16_000_000, np.float32)                     # 64 MB

    def cold():
        np.add(evict, 1.0, out=evict)

    configs = {"train_small": ModelConfig.small(x_dim=348, z_dim=342, clip_frames=120, clip_channels=300), "paper": ModelConfig.paper()}
    rows = []
    for name, config in configs.items():
        counts = parameter_counts(config)
        sizes = [counts["gating"], counts["motion"], counts["film"]]
        sets = [Parameters({"w": (n,)}) for n in sizes]
        for p in sets:
            p.data[...] = rng.standard_normal(p.size, dtype=np.float32)
            p.grad[...] = 1e-2 * rng.standard_normal(p.size, dtype=np.float32)
        repeat = repeat_small if name == "train_small" else repeat_paper
        variants = [("chunks of 32768 (before)", 32768), ("chunks of 65536 (now)", 65536),
                    ("whole buffer per operation", max(sizes))]
        saved = optim.CHUNK
        try:
            for label, chunk in variants:
                optim.CHUNK = chunk
                opt = Adam(sets, lr=1e-4)
                row = {"parameters": f"{name} ({sum(sizes):,})", "variant": label,
                       "hot ms": fmt(timed(opt.step, repeat, warmup=2)),
                       "cold ms": fmt(timed(opt.step, repeat, warmup=1, between=cold))}
                rows.append(row)
                print(f"  ... Adam {name}, {label}: hot {row['hot ms']}, cold {row['cold ms']}", flush=True)
                del opt
            optim.CHUNK = 65536
            ms = [np.zeros_like(p.data) for p in sets]
            vs = [np.zeros_like(p.data) for p in sets]
            buf, steps = np.empty(optim.CHUNK, np.float32), [0] * 3
            fn = lambda: blas_adam_step(sets, ms, vs, buf, steps)   # noqa: E731
            row = {"parameters": f"{name} ({sum(sizes):,})",
                   "variant": f"BLAS sscal/saxpy, chunks of 65536 ({common.THREADS} BLAS threads)",
                   "hot ms": fmt(timed(fn, repeat, warmup=2)),
                   "cold ms": fmt(timed(fn, repeat, warmup=1, between=cold))}
            rows.append(row)
            print(f"  ... Adam {name}, BLAS: hot {row['hot ms']}, cold {row['cold ms']}", flush=True)
        finally:
            optim.CHUNK = saved
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", choices=["conv", "adam"], help="one part only")
    ap.add_argument("--batch-small", type=int, nargs="*", default=[1, 4, 32],
                    help="clips per step for train_small's Ψ")
    ap.add_argument("--batch-paper", type=int, nargs="*", default=[4, 32],
                    help="clips per step for the paper's Ψ")
    ap.add_argument("--threads", type=int, default=common.THREADS, help="BLAS threads")
    ap.add_argument("--coretype", default=common.CORETYPE, help="OpenBLAS kernels (see common.py)")
    args = ap.parse_args()
    header("the kit's kernels, float32, min (median) ms")
    rng = np.random.default_rng(0)
    if args.only in (None, "conv"):
        rows = conv_rows("train_small", args.batch_small, rng) + conv_rows("paper", args.batch_paper, rng)
        print("\nconv1d forward + backward (the first layer without dx), one workspace per layer:")
        table(rows, ["model", "layer", "batch", "GFLOP (im2col)", "im2col ms", "fft ms", "fft/im2col", "auto",
                     "plain ms"])
    if args.only in (None, "adam"):
        rows = adam_rows(rng)
        print("\nAdam.step, float32 (hot: numbers cached from the last step; cold: 64 MB written in between):")
        table(rows, ["parameters", "variant", "hot ms", "cold ms"])
    print(f"# load average at the end: {load_average()}")


if __name__ == "__main__":
    main()
