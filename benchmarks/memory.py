"""Peak memory of one training step of the paper-size style model (batch 32 by default).

Each measurement runs in a fresh subprocess, so that nothing from another measurement is counted:

  numpy arrays  tracemalloc (numpy reports every array allocation to it): the memory held before
                the step (weights, gradients, Adam moments, inputs) and the peak during a step
                (that plus activations, caches and temporaries). Python objects are included too.
  process peak  the largest resident set of the whole process (interpreter, numpy, BLAS buffers,
                everything): VmHWM of /proc/self/status (ru_maxrss where that is missing), at
                the end and right after the imports (the fixed cost of interpreter and numpy).

The PyTorch row (when torch is installed) gives the process peak of the same step in PyTorch
(its allocations are not visible to tracemalloc). Cases as in train_step.py: (a) Φ + Ω with FiLM
given, (b) the full model with Ψ on 240 x 300 clips.

    python benchmarks/memory.py [--batch 32] [--case a b]
"""
import argparse  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tracemalloc  # noqa: E402

import common  # noqa: F401  (sets the BLAS thread count before numpy is imported)
import numpy as np  # noqa: E402
from common import header, random_batch, table  # noqa: E402

MB = 1024 * 1024


def maxrss_mb() -> float:
    """Peak resident set of this process so far, in MB.

    /proc/self/status VmHWM where available: it starts afresh at exec, whereas ru_maxrss keeps
    the parent's resident set at fork time (this script's parent would otherwise leak into it).
    """
    try:
        for line in open("/proc/self/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024                     # kB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024   # Linux reports KiB


def child(side: str, case: str, batch: int) -> dict:
    """Run in the subprocess: build, take one step (warm-up), then measure the next step."""
    rss_imports = maxrss_mb()
    from minifilm.model.config import ModelConfig
    from minifilm.model.losses import mse_loss
    from minifilm.model.style_model import StyleModel
    from minifilm.nn.fast_optim import ChunkedAdam as Adam

    config = ModelConfig.paper()
    rng = np.random.default_rng(0)
    with_clip = case == "b"
    if side == "numpy":
        tracemalloc.start()
    model = StyleModel(config, rng, with_film_generator=with_clip)
    x, p, film, clip, target = random_batch(config, batch, rng, with_clip)
    if side == "numpy":
        opt = Adam(model.parameter_sets())

        def step():
            model.zero_grad()
            if with_clip:
                z = model.forward(x, p, clip, train=True, rng=rng)
                model.backward(mse_loss(z, target)[1])
            else:
                z = model.forward_with_film(x, p, film, train=True, rng=rng)
                model.backward_with_film(mse_loss(z, target)[1])
            opt.step()
    else:
        from torch_reference import from_numpy, load_torch
        torch = load_torch(common.THREADS)
        tmodel = from_numpy(torch, model)
        del model                                       # only the torch copy remains
        tmodel.train()
        topt = torch.optim.Adam(tmodel.parameters(), lr=1e-4)
        X, P, F, Z = (torch.from_numpy(a) for a in (x, p, film, target))
        C = None if clip is None else torch.from_numpy(np.ascontiguousarray(clip.transpose(0, 2, 1)))

        def step():
            topt.zero_grad(set_to_none=True)
            z = tmodel(X, P, C) if with_clip else tmodel.forward_with_film(X, P, F)
            torch.nn.functional.mse_loss(z, Z).backward()
            topt.step()
    step()                                              # first step: Adam moments, lazy buffers
    result = {"rss_imports": rss_imports}
    if side == "numpy":
        result["held"] = tracemalloc.get_traced_memory()[0] / MB
        tracemalloc.reset_peak()
        step()
        result["peak"] = tracemalloc.get_traced_memory()[1] / MB
        tracemalloc.stop()
    else:
        step()
    result["rss_peak"] = maxrss_mb()
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--case", nargs="*", default=["a", "b"], choices=["a", "b"])
    ap.add_argument("--threads", type=int, default=common.THREADS)
    ap.add_argument("--coretype", default=common.CORETYPE, help="OpenBLAS kernels (see common.py)")
    ap.add_argument("--child", nargs=3, metavar=("SIDE", "CASE", "BATCH"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        side, case, batch = args.child
        print(json.dumps(child(side, case, int(batch))))
        return

    # find_spec, not import: the parent stays small (and torch-free) while the children run
    sides = ["numpy", "torch"] if importlib.util.find_spec("torch") is not None else ["numpy"]
    header(f"peak memory of one training step, paper config, batch {args.batch}, float32 (MB = 2^20 bytes)")
    rows = []
    for case in args.case:
        for side in sides:
            cmd = [sys.executable, __file__, "--threads", str(args.threads), "--child", side, case, str(args.batch)]
            if args.coretype != "env":
                cmd[2:2] = ["--coretype", args.coretype]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
            r = json.loads(out.strip().splitlines()[-1])
            rows.append({"case": f"({case}) " + ("Φ+Ω, FiLM given" if case == "a" else "Φ+Ω+Ψ, 240x300 clip"),
                         "side": side,
                         "numpy held MB": r.get("held", "-"), "numpy step peak MB": r.get("peak", "-"),
                         "process peak MB": r["rss_peak"], "after imports MB": r["rss_imports"]})
    table(rows, ["case", "side", "numpy held MB", "numpy step peak MB", "process peak MB", "after imports MB"])
    print("# numpy held = weights + gradients + Adam moments + inputs before the step (tracemalloc);")
    print("# step peak = the most numpy memory alive at once during a step; process peak = VmHWM.")


if __name__ == "__main__":
    main()
