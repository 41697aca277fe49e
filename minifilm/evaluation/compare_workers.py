"""The comparison's training runs (every variant x every seed) in worker processes, one BLAS thread
each, so that ``minifilm compare`` uses every core (``--workers``).

    parent                                         worker w (started with 'spawn')
    build the data set (its cache), the context    rebuild the same context from the same options
    send job (variant, seed, epochs)  ------------> train_variant(...) exactly as one process does
                                      <------------ the run's figures (JSON) + its weights (.npz)
    rebuild the variant from the weights, then rollouts, interpolation, fine-tuning as before

Why the results equal one process's: a run depends only on its variant, its seed and the data (the
model's initialisation and the batch order come from the seed), the worker trains it with the very
same code, and the parent gets its weights back bit for bit (.npz, float32 as trained). With one
BLAS thread in the parent too (``OPENBLAS_NUM_THREADS=1``, as the report's command line says) every
number of the report is the same for any ``--workers``.

Starting, serving and stopping the processes is minifilm/processes.py's (shared with the data set
builder). Stopping: the workers ignore SIGINT (the parent's Ctrl-C or SIGTERM raises in the parent, which
terminates them on its way out, finished or not); on Linux a worker also gets SIGTERM when its
parent dies, so none outlives it. A worker that fails sends its error, one line, which the parent
raises; one that dies stops the run with :class:`minifilm.processes.WorkerDied`.
"""
from __future__ import annotations

import json
from multiprocessing import connection
from pathlib import Path

import numpy as np

from minifilm.processes import WorkerDied, spawn, stop


def _args_text(args) -> str:
    return json.dumps({k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()}, default=str)


def run_figures(r, weights_path) -> dict:
    """What a worker sends back of train_variant's result ``r``; the weights go to ``weights_path``."""
    t = r["trainer"]
    np.savez(weights_path, *[ps.data for ps in t.model.parameter_sets()])
    return ({k: r[k] for k in ("seconds", "steps", "errors", "params", "final_train_loss", "curve")}
            | {"epoch": t.epoch, "history": t.history})


def _start(n: int, args, holdout: str, target):
    """n spawned workers (minifilm/processes.py) running ``target(args text, holdout, connection)``:
    ([process], [connection])."""
    return spawn(n, target, (_args_text(args), holdout), "minifilm-compare-worker")


def _receive(conn, proc, where: str):
    """The worker's next reply, or WorkerDied / the worker's error as one message."""
    try:
        reply = json.loads(conn.recv_bytes())
    except (EOFError, OSError):
        proc.join(timeout=1.0)
        raise WorkerDied(f"compare: worker {proc.name} ended ({where}; exit code {proc.exitcode})") from None
    if "error" in reply:
        raise RuntimeError(f"compare: worker {proc.name} failed ({where}): {reply['error']}")
    return reply["ok"]


def train_in_workers(jobs, args, holdout: str, epochs: int, workers: int, target, log=print) -> dict:
    """Train every (variant, seed) of ``jobs`` in ``workers`` processes, each running ``target(args
    text, holdout, connection)`` (compare.training_worker, a module-level function for 'spawn'). Returns {(variant, seed):
    (figures, weights)} with figures as train_variant returns them (without the trainer) plus
    'epoch' and 'history', and weights the list of the model's parameter arrays."""
    folder = Path(args.work) / "worker_weights"
    folder.mkdir(parents=True, exist_ok=True)
    procs, conns = _start(min(workers, len(jobs)), args, holdout, target)
    out, pending, busy = {}, list(enumerate(jobs)), {}
    try:
        for c, p in zip(conns, procs):
            _receive(c, p, "starting")
        idle = list(range(len(procs)))
        while pending or busy:
            while idle and pending:
                w = idle.pop(0)
                i, (variant, seed) = pending.pop(0)
                path = folder / f"run_{i}.npz"
                conns[w].send_bytes(json.dumps({"variant": variant, "seed": seed, "epochs": epochs,
                                                "weights": str(path)}).encode())
                busy[w] = (variant, seed, path)
            ready = connection.wait([conns[w] for w in busy] + [procs[w].sentinel for w in busy])
            for w in list(busy):
                if conns[w] in ready or procs[w].sentinel in ready:
                    variant, seed, path = busy.pop(w)
                    figures = _receive(conns[w], procs[w], f"training {variant}, seed {seed}")
                    with np.load(path, allow_pickle=False) as z:
                        weights = [z[f"arr_{k}"] for k in range(len(z.files))]
                    path.unlink()
                    out[(variant, seed)] = (figures, weights)
                    log(f"[worker] {variant}, seed {seed}: {figures['steps']} steps in {figures['seconds']:.0f} s")
                    idle.append(w)
    finally:
        stop(procs, conns)
        for leftover in folder.glob("run_*.npz"):
            leftover.unlink()
        try:
            folder.rmdir()
        except OSError:
            pass
    return out
