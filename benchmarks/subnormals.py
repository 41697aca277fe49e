"""What subnormal float32 numbers cost on this machine, and that training makes none.

    python benchmarks/subnormals.py --threads 1  # about a minute; one BLAS thread, as training
    python benchmarks/subnormals.py --repeat 50

Many CPUs (Intel's among them) take a slow microcode path for every arithmetic operation on a
subnormal number (below 1.18e-38 in float32); AMD's Zen cores pay far less. Before the flush,
train_small's final checkpoint held 189,855 subnormal first moments in Ψ (67 %, the moments of
units whose gradient had been 0 for hundreds of steps: m shrinks by beta1 a step). This script
rebuilds that state on train_small's three parameter sets and times, each the minimum of
``--repeat`` rounds (each round runs every variant once, so all see the same background load),
with the weights and moments restored before every run:

* the Adam update without the flush (the kernel before the flush) on those moments, and on the
  same moments set to 0 — their ratio is what subnormals cost here;
* the Adam update now (ChunkedAdam, which flushes them) on the same two states;
* a whole training step (forward, loss, backward, Adam) of train_small's model at batch 32 with
  4 shared clips, with the old and the new update, on both states;

and counts the subnormal numbers left in the moments after one update of each kind.
"""
import common  # noqa: F401  (sets the BLAS thread count before numpy is imported)

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from common import header, load_average, random_batch, table  # noqa: E402
from minifilm.model.config import ModelConfig  # noqa: E402
from minifilm.model.losses import mse_loss  # noqa: E402
from minifilm.model.style_model import StyleModel  # noqa: E402
from minifilm.nn import fast_optim  # noqa: E402
from minifilm.nn.fast_optim import ChunkedAdam  # noqa: E402

#: the share of Ψ's first moments that were subnormal in train_small's checkpoint before the flush
PSI_SHARE = 0.67


def unflushed_chunk(w, g, m, v, buf, beta1, beta2, step_size, eps_hat, tiny):
    """The chunk update as it was before the flush was added."""
    np.subtract(g, m, out=buf)
    buf *= 1 - beta1
    m += buf
    np.multiply(g, g, out=buf)
    buf -= v
    buf *= 1 - beta2
    v += buf
    np.sqrt(v, out=buf)
    buf += eps_hat
    np.divide(m, buf, out=buf)
    buf *= step_size
    w -= buf


def subnormals(a) -> int:
    return int(np.count_nonzero((a != 0) & (np.abs(a) < np.finfo(a.dtype).tiny)))


def dead_state(model, rng):
    """Moments as train_small left them: normal everywhere, and in PSI_SHARE of Ψ's entries (the
    dead units, whose gradient is 0) a subnormal m. Returns (m, v, dead mask of Ψ)."""
    sets = model.parameter_sets()
    m = [(1e-5 * rng.standard_normal(p.size)).astype(np.float32) for p in sets]
    v = [(1e-9 * (1 + rng.random(p.size))).astype(np.float32) for p in sets]
    dead = rng.random(sets[2].size) < PSI_SHARE
    m[2][dead] = (rng.random(int(dead.sum())) * 1e-38 * np.sign(rng.standard_normal(int(dead.sum())))).astype(np.float32)
    return m, v, dead


def interleaved(cases: dict, repeat: int) -> dict:
    """{key: (set_up, fn)} -> {key: min ms}: ``repeat`` rounds, each running every case once."""
    times = {key: [] for key in cases}
    for _ in range(repeat):
        for key, (set_up, fn) in cases.items():
            set_up()
            t0 = time.perf_counter()
            fn()
            times[key].append(time.perf_counter() - t0)
    return {key: 1e3 * min(t) for key, t in times.items()}


def with_kernel(kernel, fn):
    """fn run with ``kernel`` as the chunk update of ChunkedAdam."""
    def run():
        fast_optim._adam_chunk, real = kernel, fast_optim._adam_chunk
        try:
            fn()
        finally:
            fast_optim._adam_chunk = real
    return run


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=30)
    ap.add_argument("--threads", type=int, default=common.THREADS, help="BLAS threads (training uses 1)")
    ap.add_argument("--coretype", default=common.CORETYPE, help="OpenBLAS kernels (see common.py)")
    args = ap.parse_args()
    header("subnormal float32 numbers in the Adam update and a training step (train_small), min ms")
    rng = np.random.default_rng(0)
    config = ModelConfig.small(x_dim=348, z_dim=342, clip_frames=120, clip_channels=300)
    model = StyleModel(config, np.random.default_rng(0))
    sets = model.parameter_sets()
    opt = ChunkedAdam(sets, lr=5e-4)
    m_dead, v_dead, dead = dead_state(model, rng)
    m_zero = [a.copy() for a in m_dead]
    m_zero[2][dead] = 0
    x, p, _, clip, z = random_batch(config, 32, rng)
    clips, index = clip[:4], np.arange(32) % 4
    grads = [(1e-3 * rng.standard_normal(s.size)).astype(np.float32) for s in sets]
    grads[2][dead] = 0
    weights = [s.data.copy() for s in sets]

    def restore(m):
        def before():
            for i, s in enumerate(sets):
                s.data[...] = weights[i]
                opt.m[i][...] = m[i]
                opt.v[i][...] = v_dead[i]
                opt.steps[i] = 1000
        return before

    def adam():
        for i, s in enumerate(sets):
            s.grad[...] = grads[i]
        opt.step()

    def train_step():
        model.zero_grad()
        out = model.forward(x, p, clips, train=True, rng=np.random.default_rng(1), clip_index=index)
        model.backward(mse_loss(out, z)[1], need_input_grads=False)
        sets[2].grad[dead] = 0                           # the dead units get no gradient
        opt.step()

    kernels = {"before (no flush)": unflushed_chunk, "now (flushes)": fast_optim._adam_chunk}
    states = {"67 % of Ψ's m subnormal": m_dead, "those m set to 0": m_zero}
    cases, left = {}, {}
    for update, kernel in kernels.items():
        for state, m in states.items():
            restore(m)()
            with_kernel(kernel, adam)()
            left[update, state] = sum(subnormals(a) for a in opt.m + opt.v)
            for what, fn in (("Adam update", adam), ("training step", train_step)):
                cases[update, state, what] = (restore(m), with_kernel(kernel, fn))
    ms = interleaved(cases, args.repeat)
    rows = [{"update": update, "moments before the step": state,
             "subnormal in": f"{sum(subnormals(a) for a in m):,}",
             "Adam ms": f"{ms[update, state, 'Adam update']:.2f}",
             "step ms": f"{ms[update, state, 'training step']:.1f}",
             "subnormal after one update": f"{left[update, state]:,}"}
            for update in kernels for state, m in states.items()]
    table(rows, ["update", "moments before the step", "subnormal in", "Adam ms", "step ms",
                 "subnormal after one update"])
    b, n = "before (no flush)", "now (flushes)"
    s, zero = "67 % of Ψ's m subnormal", "those m set to 0"
    print(f"\nwhat the subnormals cost here (before, subnormal / zero): Adam "
          f"{ms[b, s, 'Adam update'] / ms[b, zero, 'Adam update']:.2f}x, training step "
          f"{ms[b, s, 'training step'] / ms[b, zero, 'training step']:.2f}x")
    print(f"what the flush costs here (now / before, no subnormals): Adam "
          f"{ms[n, zero, 'Adam update'] / ms[b, zero, 'Adam update']:.2f}x, training step "
          f"{ms[n, zero, 'training step'] / ms[b, zero, 'training step']:.2f}x")
    print(f"# load average at the end: {load_average()}")


if __name__ == "__main__":
    main()
