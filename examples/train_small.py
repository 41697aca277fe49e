"""The whole method, end to end, on data minifilm makes itself (a few minutes on a 2-core laptop).

    python examples/train_small.py                       # synthetic data, the default settings
    python examples/train_small.py --data DIR            # your own folder of <Style>_<Gait>.bvh files
    python examples/train_small.py --quick               # a smaller, faster run of the same steps
    python examples/train_small.py --epochs 10 --out runs/ten      # --help lists every setting
    mpiexec -n 2 python examples/train_small.py          # each minibatch split across 2 MPI ranks

The same job as ``minifilm train``, with its settings (minifilm/pipeline/train_small.py::Settings
says why each default is what it is). The package makes the data before the training loop and the
results after it; the loop itself is here:

 1. data:     8 synthetic styles x 6 gaits, written as 100STYLE-like BVH files;
 2. phases:   foot contacts, then local phases (Sec. 4.1, Eq. 1), checked against the true ones;
 3. dataset:  x / p / z rows and style clips y, split and normalised (Sec. 3.2);
 4. training: the small LPN + FiLM model: for every epoch, for every minibatch, the forward pass
              (Eq. 2-4), the losses (Eq. 5-7), every gradient by hand, Adam;
 5. results:  test MSE per style, one FiLM vector per style, one generated BVH per style along a
              figure-eight, how well a classifier recognises each style in it, a GIF and an HTML player.

Everything is written to the run folder runs/train_small/ (--out), which ``minifilm generate --run``
and ``minifilm finetune --run`` read back.
"""
import os
import time

# One BLAS thread, set before numpy loads: the matrices are small, and on a shared machine a second
# thread made steps slower (benchmarks/README.md), as for `minifilm train`.
for key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(key, "1")

from minifilm.cli import Parser, run_command  # noqa: E402
from minifilm.cli.train import add_arguments, check_options, settings  # noqa: E402
from minifilm.pipeline.train_small import finish, log_epoch, main_job, new_trainer  # noqa: E402
from minifilm.train import mpi  # noqa: E402
from minifilm.train.epoch import EpochLosses  # noqa: E402


def main(argv=None) -> int:
    parser = Parser(prog="examples/train_small.py", description=__doc__.split("\n")[0])
    add_arguments(parser)                       # the options of `minifilm train`
    args = parser.parse_args(argv)
    check_options(args)
    ranks = mpi.world()                         # None: one process; under mpiexec: this rank of N

    # ---- 1-3. data, local phases, dataset (the run is built beside --out and swapped in at the end)
    with mpi.one_job(ranks), main_job(settings(args), args.data, ranks) as job:
        train_data, val_data = job.ds.train_data("train"), job.ds.train_data("val")

        # ---- 4. training: Ω, Φ, Ψ (minifilm/model/), the losses of Eq. (5)-(7), Adam
        trainer = new_trainer(job)              # the model, Adam, the random generator, the history
        model = trainer.model
        for epoch in range(job.settings.epochs):
            t0, losses = time.perf_counter(), EpochLosses(trainer)
            # one style per minibatch, 4 style clips shared by its 32 samples (train/batches.py);
            # under mpiexec each rank gets its rows of it (train/mpi.py)
            for b in trainer.minibatches(train_data):
                model.zero_grad()
                z = model.forward(b.x, b.p, b.clips, train=True, rng=trainer.rng, **b.kw)  # Eq. (4)
                mse, bll, dz = trainer.losses(z, b.z)              # Eq. (5)-(7) and dL/dz
                model.backward(dz, need_input_grads=False)          # Ψ, Φ, Ω in reverse, by hand
                mse, bll = trainer.sum_over_ranks(b, mse, bll)      # mpiexec: the gradients summed
                trainer.update(b, mse, bll)                         # NaN check, then Adam's step
                losses.add(b, mse, bll)
            record = trainer.end_epoch(losses.summary(), val_data)  # validation MSE / BLL, checkpoint
            log_epoch(job, record, time.perf_counter() - t0)

        # ---- 5. results: test table, loss curve, styles.npz, generated BVH, style recognition, GIF, HTML
        finish(job, trainer)
    return 0


if __name__ == "__main__":
    run_command(main)   # bad input: one line `error: ...` (exit code 2); Ctrl-C, SIGTERM: cleaned up
