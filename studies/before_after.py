"""Before / after in ONE process: the package at an older commit against the working tree, interleaved.

On a shared machine the load changes between two runs of a script by more than most code changes
do; here both versions run in the same process, their calls alternating (before, after, before,
...), so both see the same load. The older commit's ``minifilm`` is extracted with ``git archive``
into a temporary folder and imported as ``minifilm_before`` (its imports rewritten to that name).

Measured (min and median ms): the rows of ``benchmarks/kernels.py``'s convolution (forward +
backward, the layer's workspace, the first layer without dx, the method the kit picks) and one
training step as in ``benchmarks/train_step.py`` (b) (forward with dropout, MSE, backward without
the clip's gradient, the chunked Adam step) for train_small's model and the paper's, batch 32.

    python studies/before_after.py --before 9fecb8e --threads 1
    python studies/before_after.py --before main --only conv
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))   # the benchmarks' common.py
import common  # noqa: E402,F401  (sets the BLAS thread count before numpy is imported)

import argparse  # noqa: E402
import importlib  # noqa: E402
import io  # noqa: E402
import math  # noqa: E402
import re  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tarfile  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from common import ROOT, header, load_average, table  # noqa: E402

sys.path.insert(0, str(ROOT))      # "after" is this working tree's package, whatever is installed
OLD = "minifilm_before"


def import_commit(rev: str, folder: Path):
    """``minifilm`` at ``rev`` as the package ``minifilm_before`` (written under ``folder``)."""
    data = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "minifilm"], check=True,
                          capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(folder, filter="data")
    (folder / "minifilm").rename(folder / OLD)
    for path in (folder / OLD).rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        text = re.sub(r"\bminifilm\.", f"{OLD}.", text)
        text = re.sub(r"\b(from|import) minifilm\b", rf"\1 {OLD}", text)
        path.write_text(text, encoding="utf-8")
    sys.path.insert(0, str(folder))
    return importlib.import_module(OLD)


def fast_conv_pair(package: str):
    """(forward, backward, method choice) of the convolution training runs, in either layout: since
    the split of plain and fast kernels ``nn/fast_conv.py``'s conv1d_fast_*, before it ``nn/conv.py``'s conv1d_*."""
    try:
        m = importlib.import_module(f"{package}.nn.fast_conv")
        return m.conv1d_fast_forward, m.conv1d_fast_backward, m._conv1d_method
    except ImportError:
        m = importlib.import_module(f"{package}.nn.conv")
        return m.conv1d_forward, m.conv1d_backward, m._conv1d_method


def interleaved(fn_before, fn_after, repeat):
    """((min, median) ms before, (min, median) ms after), the calls alternating after a warm-up."""
    fn_before()
    fn_after()
    t_b, t_a = [], []
    for _ in range(repeat):
        for fn, times in ((fn_before, t_b), (fn_after, t_a)):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
    return tuple((1e3 * min(t), 1e3 * float(np.median(t))) for t in (t_b, t_a))


def ms(t):
    return f"{t[0]:.3g} ({t[1]:.3g})"


LAYERS = [("train_small", "conv0 120x300->32, k9", 120, 300, 32, 9, False, (1, 4, 32)),
          ("train_small", "conv1 60x32->32, k9", 60, 32, 32, 9, True, (1, 4, 32)),
          ("paper", "conv0 240x300->256, k25", 240, 300, 256, 25, False, (4, 32)),
          ("paper", "conv1 120x256->256, k25", 120, 256, 256, 25, True, (4, 32))]


def conv_rows(rng):
    fb, bb, _ = fast_conv_pair(OLD)
    fa, ba, choose = fast_conv_pair("minifilm")
    rows = []
    for model, label, T, C, Fo, k, need_dx, batches in LAYERS:
        for B in batches:
            x = rng.standard_normal((B, T, C)).astype(np.float32)
            W = (rng.standard_normal((k, C, Fo)) / math.sqrt(k * C)).astype(np.float32)
            b = np.zeros(Fo, np.float32)
            dout = rng.standard_normal((B, T, Fo)).astype(np.float32)
            work_b, work_a = {}, {}

            def before():
                bb(dout, fb(x, W, b, work=work_b)[1], need_dx=need_dx)

            def after():
                ba(dout, fa(x, W, b, work=work_a)[1], need_dx=need_dx)
            flops = 2.0 * B * T * k * C * Fo
            t_b, t_a = interleaved(before, after, 5 if flops > 1e10 else (9 if flops > 1e9 else 31))
            rows.append({"model": model, "layer": label, "batch": B, "method": choose(B, T, C, Fo, k),
                         "before ms": ms(t_b), "after ms": ms(t_a), "after/before": t_a[0] / t_b[0]})
            print(f"  ... {model} {label} batch {B}: before {ms(t_b)}, after {ms(t_a)}", flush=True)
    return rows


def step_rows(rng):
    rows = []
    for name, repeat in (("small", 31), ("paper", 4)):
        steps = []
        for package in (OLD, "minifilm"):
            Config = importlib.import_module(f"{package}.model.config").ModelConfig
            config = (Config.small(x_dim=348, z_dim=342, clip_frames=120, clip_channels=300) if name == "small"
                      else Config.paper())
            StyleModel = importlib.import_module(f"{package}.model.style_model").StyleModel
            mse_loss = importlib.import_module(f"{package}.model.losses").mse_loss
            try:
                Adam = importlib.import_module(f"{package}.nn.fast_optim").ChunkedAdam
            except ImportError:
                Adam = importlib.import_module(f"{package}.nn.optim").Adam
            steps.append((config, StyleModel, mse_loss, Adam))
        config = steps[1][0]
        data = [rng.standard_normal(s).astype(np.float32) for s in
                ((32, config.x_dim), (32, config.phase_dim), (32, config.clip_frames, config.clip_channels),
                 (32, config.z_dim))]

        def make(config, StyleModel, mse_loss, Adam):
            model = StyleModel(config, np.random.default_rng(1))
            opt, drop_rng = Adam(model.parameter_sets(), lr=1e-4), np.random.default_rng(2)
            x, p, clip, z = data

            def step():
                model.zero_grad()
                out = model.forward(x, p, clip, train=True, rng=drop_rng)
                model.backward(mse_loss(out, z)[1], need_input_grads=False)
                opt.step()
            return step
        t_b, t_a = interleaved(make(*steps[0]), make(*steps[1]), repeat)
        rows.append({"training step, batch 32": f"{name} model", "before ms": ms(t_b), "after ms": ms(t_a),
                     "after/before": t_a[0] / t_b[0]})
        print(f"  ... training step, {name} model: before {ms(t_b)}, after {ms(t_a)}", flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", default="main", help="the commit to compare with (default main)")
    ap.add_argument("--only", choices=["conv", "step"], help="one part only")
    ap.add_argument("--threads", type=int, default=common.THREADS, help="BLAS threads")
    ap.add_argument("--coretype", default=common.CORETYPE, help="OpenBLAS kernels (see common.py)")
    args = ap.parse_args()
    header(f"before ({args.before}) / after (working tree), interleaved in one process, float32, min (median) ms")
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        import_commit(args.before, Path(tmp))
        if args.only in (None, "conv"):
            table(conv_rows(rng), ["model", "layer", "batch", "method", "before ms", "after ms", "after/before"])
        if args.only in (None, "step"):
            table(step_rows(rng), ["training step, batch 32", "before ms", "after ms", "after/before"])
    print(f"# load average at the end: {load_average()}")


if __name__ == "__main__":
    main()
