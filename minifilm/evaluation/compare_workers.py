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

Stopping: the workers ignore SIGINT (the parent's Ctrl-C or SIGTERM raises in the parent, which
terminates them on its way out, finished or not); on Linux a worker also gets SIGTERM when its
parent dies, so none outlives it. A worker that fails sends its error, one line, which the parent
raises; one that dies stops the run with :class:`minifilm.train.parallel.WorkerDied`.
"""
from __future__ import annotations

import json
import multiprocessing
import os
import signal
import threading
from multiprocessing import connection
from pathlib import Path

import numpy as np

from minifilm.train.parallel import ONE_BLAS_THREAD, WorkerDied
from minifilm.train.parallel_shares import usable_cores


def default_workers(jobs: int) -> int:
    """The cores this process may use, at most one per job."""
    return max(1, min(usable_cores(), jobs))


def _args_text(args) -> str:
    return json.dumps({k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()}, default=str)


def _die_with_parent() -> None:
    """Linux: ask the kernel to send this process SIGTERM when its parent ends (no orphans)."""
    try:
        import ctypes      # here: only the workers need it, and only on Linux
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)     # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        pass


def serve(conn, setup, job) -> None:
    """A worker's loop (called by the target of its process): ``setup()`` makes its state once
    (the comparison's context), then ``job(state, message)`` answers every job it is sent until the
    parent closes the pipe. Replies are JSON: {'ok': figures} or {'error': message}."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent()
    try:
        state = setup()
        conn.send_bytes(json.dumps({"ok": "ready"}).encode())
    except Exception as e:  # noqa: BLE001 -- told to the parent, which raises it as one message
        conn.send_bytes(json.dumps({"error": f"{type(e).__name__}: {e}"}).encode())
        return
    while True:
        try:
            message = json.loads(conn.recv_bytes())
        except (EOFError, OSError):          # the parent closed the pipe or went away: stop
            return
        try:
            reply = {"ok": job(state, message)}
        except Exception as e:  # noqa: BLE001
            reply = {"error": f"{type(e).__name__}: {e}"}
        try:
            conn.send_bytes(json.dumps(reply).encode())
        except (BrokenPipeError, OSError):
            return


def run_figures(r, weights_path) -> dict:
    """What a worker sends back of train_variant's result ``r``; the weights go to ``weights_path``."""
    t = r["trainer"]
    np.savez(weights_path, *[ps.data for ps in t.model.parameter_sets()])
    return ({k: r[k] for k in ("seconds", "steps", "errors", "params", "final_train_loss", "curve")}
            | {"epoch": t.epoch, "history": t.history})


def _start(n: int, args, holdout: str, target):
    """n spawned workers with one BLAS thread each: ([process], [connection])."""
    mp = multiprocessing.get_context("spawn")
    saved = {k: os.environ.get(k) for k in ONE_BLAS_THREAD}
    os.environ.update(ONE_BLAS_THREAD)                 # read by the workers' numpy when it loads
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    procs, conns = [], []
    try:
        for w in range(n):
            mine, theirs = mp.Pipe()
            p = mp.Process(target=target, args=(_args_text(args), holdout, theirs), daemon=True,
                           name=f"minifilm-compare-worker-{w}")
            p.start()
            theirs.close()
            procs.append(p)
            conns.append(mine)
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return procs, conns


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


def stop(procs, conns) -> None:
    """Close the pipes, give the workers a moment to leave, terminate (then kill) any still running."""
    for c in conns:
        c.close()
    for p in procs:
        p.join(timeout=2.0)
    for p in procs:
        if p.is_alive():
            p.terminate()
            p.join(timeout=2.0)
        if p.is_alive():
            p.kill()
            p.join()


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
