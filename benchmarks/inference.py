"""Inference time of Φ + Ω with precomputed FiLM parameters: minifilm (NumPy) vs PyTorch eager.

    batch 1   the real-time case: one character, one frame (Sec. 4.4); ms per frame
    batch 64  many characters at once; frames per second

The style is a precomputed FiLM vector (4 x 512 numbers), as at run time; Ψ is not run. NumPy
batch 1 uses ``RuntimeNetwork.predict`` (the one run-time path), larger batches
``forward_with_film``; PyTorch runs the same model (copied weights) under ``torch.inference_mode()``.
NumPy and PyTorch calls are interleaved (at batch 1 in blocks of 50 calls, so that each side's
weights can stay in the cache as in a real-time loop); times are medians after warm-up.

    python benchmarks/inference.py [--repeat 200] [--threads N] [--profile]
"""
import argparse  # noqa: E402

import common  # noqa: F401  (sets the BLAS thread count before numpy is imported)
import numpy as np  # noqa: E402
from common import THREADS, compare_ms, header, random_batch, table  # noqa: E402
from torch_reference import from_numpy, load_torch  # noqa: E402

from minifilm.dataset.stats import NormStats  # noqa: E402
from minifilm.model.config import ModelConfig  # noqa: E402
from minifilm.model.style_model import StyleModel  # noqa: E402
from minifilm.runtime.network import RuntimeNetwork  # noqa: E402


def profile_batch1(net, x, p, film, repeat):
    """Where a batch-1 frame's time goes: Ω, each expert product, the rest (median ms)."""
    from common import median_ms

    x, p = x[None, :], p[None, :]
    xn = (x - net._x_mean) * net._x_inv
    alpha = net.gate(xn, p)
    ins = [xn]
    for Wc, b, O in net.layers[:2]:                      # the real inputs of layers 1 and 2
        f = np.matmul(alpha[:, None, :], (ins[-1] @ Wc).reshape(1, net.n_experts, O))[:, 0] + alpha @ b
        ins.append(net.hidden(len(ins) - 1, f, alpha, film))
    rows = [{"part": "Ω gating (3 small layers)", "ms": median_ms(lambda: net.gate(xn, p), repeat, 20)}]
    total_bytes = 0
    for l, (Wc, b, O) in enumerate(net.layers):
        nbytes = Wc.nbytes + b.nbytes
        total_bytes += nbytes
        t = median_ms(lambda: ins[l] @ Wc, repeat, 20)
        rows.append({"part": f"Φ expert product {l} {Wc.shape}", "ms": t,
                     "weights MB": nbytes / 1e6, "GB/s": nbytes / t / 1e6})
    whole = median_ms(lambda: net.predict(x, p, film), repeat, 20)
    rows.append({"part": "whole RuntimeNetwork.predict", "ms": whole, "weights MB": total_bytes / 1e6,
                 "GB/s": total_bytes / whole / 1e6})
    print("\nbatch-1 profile (NumPy): the expert products must read all K expert matrices every frame")
    table(rows, ["part", "ms", "weights MB", "GB/s"])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batch", type=int, nargs="*", default=[1, 64])
    ap.add_argument("--repeat", type=int, default=200)
    ap.add_argument("--threads", type=int, default=THREADS, help="BLAS / torch threads")
    ap.add_argument("--coretype", default=common.CORETYPE, help="OpenBLAS kernels (see common.py)")
    ap.add_argument("--no-torch", action="store_true")
    ap.add_argument("--profile", action="store_true", help="also break a batch-1 frame down")
    args = ap.parse_args()

    torch = None if args.no_torch else load_torch(THREADS)
    header("inference, Φ + Ω with a precomputed FiLM vector, paper config, float32, median ms per call"
           + ("" if torch else "  [PyTorch not installed: NumPy only]"))
    config = ModelConfig.paper()
    rng = np.random.default_rng(0)
    model = StyleModel(config, rng, with_film_generator=False)
    net = RuntimeNetwork.from_model(model, NormStats.identity(config.x_dim, config.z_dim, config.phase_dim))
    tmodel = from_numpy(torch, model).eval() if torch is not None else None
    rows, checks = [], []
    for batch in args.batch:
        x, p, film, _, _ = random_batch(config, batch, rng, with_clip=False)
        style = film[0]                                  # one style for every character
        if batch == 1:
            np_fn = lambda: net.predict(x, p, style)                        # noqa: E731
            z_np = np_fn()
        else:
            np_fn = lambda: model.forward_with_film(x, p, style)            # noqa: E731
            z_np = np_fn()
        fns = {"numpy": np_fn}
        if torch is not None:
            X, P = torch.from_numpy(x), torch.from_numpy(p)
            S = torch.from_numpy(np.tile(style, (batch, 1)))

            def torch_fn():
                with torch.inference_mode():
                    return tmodel.forward_with_film(X, P, S)
            fns["torch"] = torch_fn
            z_t = torch_fn().numpy()
            checks.append({"batch": batch, "max rel diff z": f"{np.abs(z_np - z_t).max() / np.abs(z_t).max():.1e}"})
        t = compare_ms(fns, args.repeat, warmup=10, block=50 if batch == 1 else 1)
        row = {"batch": batch, "numpy ms": t["numpy"], "numpy ms/frame": t["numpy"] / batch,
               "numpy frames/s": f"{1e3 * batch / t['numpy']:.0f}"}
        if torch is not None:
            row.update({"torch ms": t["torch"], "torch frames/s": f"{1e3 * batch / t['torch']:.0f}",
                        "torch/numpy": t["torch"] / t["numpy"]})
        rows.append(row)
    if checks:
        print("same model check (NumPy vs PyTorch with copied weights):")
        table(checks, ["batch", "max rel diff z"])
        print()
    table(rows, ["batch", "numpy ms", "numpy ms/frame", "numpy frames/s", "torch ms", "torch frames/s",
                 "torch/numpy"])
    if args.profile:
        x, p, film, _, _ = random_batch(config, 1, rng, with_clip=False)
        profile_batch1(net, x[0], p[0], film[0], args.repeat)
    print(f"# load average at the end: {common.load_average()}")


if __name__ == "__main__":
    main()
