"""Training-step time of the paper-size style model: minifilm (NumPy) vs the same model in PyTorch.

One step = zero the gradients, forward with dropout, MSE loss, backward, Adam update.

    (a) Φ + Ω, FiLM parameters given (what Ψ would output; no Ψ in the model or the optimiser)
    (b) the full model Φ + Ω + Ψ on 240 x 300 style clips

Both sides get the same float32 inputs, the same thread count and the same weights (the
PyTorch model is a copy of the NumPy one; the first table checks that they compute the same
outputs and gradients). Times are medians after warm-up, NumPy and PyTorch steps interleaved
so that both see the same background load.

    python benchmarks/train_step.py                      # batches 32 and 256, both cases
    python benchmarks/train_step.py --batch 32 --case a  # one cell
    python benchmarks/train_step.py --threads 1          # another thread count
    python benchmarks/train_step.py --config small --batch 32 --case b   # train_small's model

``--config small`` is the model of examples/train_small.py (K = 4, hidden 128, Ψ with 32 filters
of width 9 and a dense layer of 128, clips 120 x 300, x 348, z 342: 707,420 parameters), one clip
per sample as in the original code.
"""
import common  # noqa: F401  (sets the BLAS thread count before numpy is imported)

import argparse  # noqa: E402

import numpy as np  # noqa: E402

from common import THREADS, compare_ms, header, random_batch, table  # noqa: E402
from minifilm.model.config import ModelConfig  # noqa: E402
from minifilm.model.losses import mse_loss  # noqa: E402
from minifilm.model.style_model import StyleModel  # noqa: E402
from minifilm.nn.fast_optim import ChunkedAdam as Adam  # noqa: E402  (what training uses)
from torch_reference import from_numpy, load_torch  # noqa: E402


# examples/train_small.py's model on its synthetic data (x 348, z 342, clips of 2 s at 60 fps)
def small_config() -> ModelConfig:
    return ModelConfig.small(x_dim=348, z_dim=342, clip_frames=120, clip_channels=300)


def numpy_step(model, opt, x, p, film, clip, target, rng):
    """One minifilm training step; with clip None, case (a) (FiLM given)."""
    def step():
        model.zero_grad()
        if clip is None:
            z = model.forward_with_film(x, p, film, train=True, rng=rng)
            _, dz = mse_loss(z, target)
            model.backward_with_film(dz)
        else:
            z = model.forward(x, p, clip, train=True, rng=rng)
            _, dz = mse_loss(z, target)
            model.backward(dz, need_input_grads=False)    # like PyTorch: the clip needs no gradient
        opt.step()
    return step


def torch_step(torch, tmodel, topt, x, p, film, clip, target):
    """The same step in PyTorch (inputs converted once, outside the timed step)."""
    X, P, Z = (torch.from_numpy(a) for a in (x, p, target))
    FILM = torch.from_numpy(film)
    CLIP = None if clip is None else torch.from_numpy(np.ascontiguousarray(clip.transpose(0, 2, 1)))
    mse = torch.nn.functional.mse_loss

    def step():
        topt.zero_grad(set_to_none=True)
        if CLIP is None:
            z = tmodel.forward_with_film(X, P, FILM)
        else:
            z = tmodel(X, P, CLIP)
        mse(z, Z).backward()
        topt.step()
    return step


def check_same_model(torch, model, tmodel, config, with_clip, rng):
    """Largest relative difference of z and of every parameter gradient (eval mode, batch 4)."""
    x, p, film, clip, target = random_batch(config, 4, rng, with_clip)
    model.zero_grad()
    if with_clip:
        z = model.forward(x, p, clip)
        model.backward(mse_loss(z, target)[1])
    else:
        z = model.forward_with_film(x, p, film)
        model.backward_with_film(mse_loss(z, target)[1])
    tmodel.eval()
    tmodel.zero_grad(set_to_none=True)
    if with_clip:
        tz = tmodel(torch.from_numpy(x), torch.from_numpy(p),
                    torch.from_numpy(np.ascontiguousarray(clip.transpose(0, 2, 1))))
    else:
        tz = tmodel.forward_with_film(torch.from_numpy(x), torch.from_numpy(p), torch.from_numpy(film))
    torch.nn.functional.mse_loss(tz, torch.from_numpy(target)).backward()
    tmodel.train()
    rel = lambda a, b: float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-30))  # noqa: E731
    worst_grad = 0.0
    for name, tp in tmodel.motion.named_parameters():
        i, what = name.split(".")[1], name.split(".")[2]
        worst_grad = max(worst_grad, rel(tp.grad.numpy(), model.motion.params.grads[f"{what}{i}"]))
    for i, layer in enumerate(tmodel.gating.layers):
        worst_grad = max(worst_grad, rel(layer.weight.grad.numpy().T, model.gating.params.grads[f"W{i}"]))
    if with_clip:
        g = model.film.params.grads
        worst_grad = max(worst_grad, rel(tmodel.film.conv0.weight.grad.numpy().transpose(2, 1, 0), g["conv0_W"]))
        worst_grad = max(worst_grad, rel(tmodel.film.dense1.weight.grad.numpy().T, g["dense1_W"]))
    return rel(tz.detach().numpy(), z), worst_grad


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batch", type=int, nargs="*", default=[32, 256])
    ap.add_argument("--case", nargs="*", default=["a", "b"], choices=["a", "b"])
    ap.add_argument("--repeat", type=int, default=0, help="timed runs (default: 20 for (a), 5 for (b))")
    ap.add_argument("--threads", type=int, default=THREADS, help="BLAS / torch threads")
    ap.add_argument("--coretype", default=common.CORETYPE, help="OpenBLAS kernels (see common.py)")
    ap.add_argument("--no-torch", action="store_true", help="time NumPy only")
    ap.add_argument("--config", choices=["paper", "small"], default="paper",
                    help="the paper's model (default) or train_small's")
    args = ap.parse_args()

    torch = None if args.no_torch else load_torch(THREADS)
    header(f"training step (forward + backward + Adam), {args.config} config, float32, median ms"
           + ("" if torch else "  [PyTorch not installed: NumPy only]"))
    config = ModelConfig.paper() if args.config == "paper" else small_config()
    rows, checks = [], []
    for case in args.case:
        with_clip = case == "b"
        rng = np.random.default_rng(0)
        model = StyleModel(config, rng, with_film_generator=with_clip)
        opt = Adam(model.parameter_sets(), lr=1e-4)
        tmodel = topt = None
        if torch is not None:
            tmodel = from_numpy(torch, model)
            dz, dg = check_same_model(torch, model, tmodel, config, with_clip, rng)
            checks.append({"case": case, "max rel diff z": f"{dz:.1e}", "max rel diff grads": f"{dg:.1e}"})
            tmodel.train()
            topt = torch.optim.Adam(tmodel.parameters(), lr=1e-4)
        for batch in args.batch:
            small = args.config == "small"
            repeat = args.repeat or (20 if case == "a" or small else (5 if batch <= 64 else 3))
            warmup = 2 if case == "a" else 1
            x, p, film, clip, target = random_batch(config, batch, rng, with_clip)
            fns = {"numpy": numpy_step(model, opt, x, p, film, clip, target, rng)}
            if torch is not None:
                fns["torch"] = torch_step(torch, tmodel, topt, x, p, film, clip, target)
            t = compare_ms(fns, repeat, warmup)            # interleaved: same load for both
            t_np = t["numpy"]
            clip_size = f"{config.clip_frames}x{config.clip_channels}"
            row = {"case": f"({case}) " + ("Φ+Ω, FiLM given" if case == "a" else f"Φ+Ω+Ψ, {clip_size} clip"),
                   "batch": batch, "numpy ms": t_np}
            if torch is not None:
                row.update({"torch ms": t["torch"], "numpy/torch": t_np / t["torch"]})
            row["runs"] = repeat
            rows.append(row)
            print(f"  ... ({case}) batch {batch}: numpy {t_np:.1f} ms"
                  + (f", torch {row['torch ms']:.1f} ms" if torch is not None else ""), flush=True)
    if checks:
        print("\nsame model check (eval mode, batch 4, NumPy vs PyTorch with copied weights):")
        table(checks, ["case", "max rel diff z", "max rel diff grads"])
    print()
    table(rows, ["case", "batch", "numpy ms", "torch ms", "numpy/torch", "runs"])
    print(f"# load average at the end: {common.load_average()}")


if __name__ == "__main__":
    main()
