"""The whole method, end to end, on data minifilm makes itself (about two minutes on a 2-core laptop).

    python examples/train_small.py                      # synthetic data, default settings
    python examples/train_small.py --data DIR           # your own folder of <Style>_<Gait>.bvh files
    python examples/train_small.py --quick              # a smaller, faster run of the same steps

The same job as ``minifilm train``, with the same options, outputs and numbers. The training loop
is written out below; the package makes the data before it and the results after it
(minifilm/pipeline/train_small.py):

 1. data:     8 synthetic styles x 6 gaits, written as 100STYLE-like BVH files;
 2. phases:   foot contacts, then local phases (Sec. 4.1, Eq. 1), checked against the true ones;
 3. dataset:  x / p / z rows and style clips y, split and normalised (Sec. 3.2);
 4. training: the small LPN + FiLM model, forward / loss / backward / Adam per minibatch (Eq. 2-7);
 5. results:  test MSE per style, one FiLM vector per style, one generated BVH per style along a
              figure-eight, how well a classifier recognises each style in it, a GIF and an HTML player.

Everything is written to the run folder runs/train_small/ (--out), which ``minifilm generate --run``
and ``minifilm finetune --run`` read back.
"""
import argparse
import os
import time

from minifilm.cli import ONE_BLAS_THREAD

# One BLAS thread, set before numpy loads: the matrices are small, and on a shared machine a second
# thread made steps slower (benchmarks/README.md), as for `minifilm train`.
for key, value in ONE_BLAS_THREAD.items():
    os.environ.setdefault(key, value)

from minifilm.cli import Parser, run_command  # noqa: E402
from minifilm.cli import train as options  # noqa: E402
from minifilm.pipeline.train_small import finish, log_epoch, main_job, new_trainer, workers  # noqa: E402
from minifilm.train.trainer import EpochLosses  # noqa: E402


def main(argv=None) -> None:
    # ---- settings: those of `minifilm train` (defaults in minifilm/pipeline/train_small.py::Settings:
    # 30 epochs, batch 32, Adam lr 5e-4, 4 style clips per minibatch, seed 0)
    parser = Parser(prog="minifilm train", description=options.__doc__,
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    options.add_arguments(parser)
    args = parser.parse_args(argv)
    options.check_options(args)
    settings = options.settings(args)

    # ---- 1-3. data, local phases, dataset (the run is built beside --out and swapped in at the end)
    with main_job(settings, args.data) as job:
        train_data, val_data = job.ds.train_data("train"), job.ds.train_data("val")

        # ---- 4. training: Ω, Φ, Ψ (minifilm/model/), the losses of Eq. (5)-(7), Adam
        trainer = new_trainer(job)                # the model, Adam, the random generator, the history
        model, adam, rng = trainer.model, trainer.optimizer, trainer.rng
        # --workers N (default: every core): each minibatch is split across N processes, each
        # computing the lines below on its share (minifilm/train/parallel.py); the same numbers
        with workers(trainer, settings) as pool:
            for _ in range(settings.epochs):
                t0 = time.perf_counter()
                losses = EpochLosses(trainer)
                for b in trainer.minibatches(train_data):   # one style per minibatch, 4 clips of that style
                    if pool is not None:
                        mse, bll = pool.gradients(b)          # the same forward / backward, in the workers
                    else:
                        model.zero_grad()
                        z = model.forward(b.x, b.p, b.clips, train=True, rng=rng, **b.kw)   # Eq. (4)
                        mse, bll, dz = trainer.losses(z, b.z)                          # Eq. (5)-(7), dL/dz
                        model.backward(dz, need_input_grads=False)   # Ψ, Φ, Ω in reverse, by hand
                    trainer.check_finite(b, mse, bll)            # a NaN or inf stops here, before the update
                    adam.lr = trainer.learning_rate(trainer.epoch + b.index / b.count)
                    if pool is not None:
                        pool.update(adam)                        # the same Adam step, each worker on its part
                    else:
                        adam.step()                              # minifilm/nn/fast_optim.py (nn/optim.py: plain)
                    trainer.step += 1
                    losses.add(b, mse, bll)
                record = trainer.end_epoch(losses.summary(), val_data)   # validation MSE / BLL, checkpoint
                log_epoch(record, time.perf_counter() - t0)

        # ---- 5. results: test table, loss curve, styles.npz, generated BVH, style recognition, GIF, HTML
        finish(job, trainer)


if __name__ == "__main__":
    run_command(main)      # bad input: one line "error: ..." and exit code 2, as `minifilm train`
