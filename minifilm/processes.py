"""Worker processes, for every part of minifilm that starts them (the data set builder, the
comparison; data-parallel training takes its core count and thread settings from here): how many,
how they start, how they answer, how they stop.

    usable_cores() / default_workers(jobs)   how many: the cores this process may run on
    spawn(n, target, args, name)             n workers, 'spawn' start, one BLAS thread each
    serve(conn, setup, job)                  a worker's loop: set up once, then answer jobs
    stop(procs, conns)                       close the pipes, then terminate (kill) what still runs

Why 'spawn': a fresh interpreter inherits nothing of the parent's threads, locks or BLAS state, so
it is safe whatever the parent runs, and it is the start method every platform has. Why one BLAS
thread each: the matrices are small, and two processes with two BLAS threads each on two cores
only take turns.

Messages are JSON text; a job's arrays follow its reply as one more message of raw bytes (an
.npz archive), read back with ``allow_pickle=False``. Nothing is pickled: a worker's answer
cannot run code in the parent.

Stopping: workers ignore SIGINT (Ctrl-C reaches the whole process group; the parent decides, and
stops them on its way out, finished or not), and on Linux a worker gets SIGTERM when its parent
dies (PR_SET_PDEATHSIG), so none outlives it.

This module imports nothing of minifilm and not numpy, so every layer may use it, and the command
line before numpy is loaded (numpy reads the BLAS thread count once, when it loads).
"""
from __future__ import annotations

import json
import multiprocessing
import os
import signal
import threading
from typing import Any, Callable, NamedTuple

#: the environment of a worker: one BLAS thread (OpenBLAS, OpenMP or MKL, whichever numpy uses)
ONE_BLAS_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class WorkerDied(ChildProcessError):
    """A worker process ended or failed while it had work (an OSError, so the command prints it as
    one line)."""


class WithBytes(NamedTuple):
    """What a job returns to send arrays too: ``figures`` as the JSON reply, then ``data`` (bytes,
    an .npz archive) as the next message on the pipe."""
    figures: Any
    data: bytes


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity; os.cpu_count() where that is unknown)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def default_workers(jobs: int) -> int:
    """The cores this process may use, at most one per job; 1 inside a worker process (a daemonic
    process may not start processes of its own)."""
    if multiprocessing.current_process().daemon:
        return 1
    return max(1, min(usable_cores(), jobs))


def die_with_parent() -> None:
    """Linux: ask the kernel to send this process SIGTERM when its parent ends (no orphans)."""
    try:
        import ctypes      # here: only the workers need it, and only on Linux
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)     # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        pass


def error_reply(e: BaseException) -> dict:
    """A worker's error as JSON: 'error' the one line ``Kind: message``; 'kind' the class's full
    name, 'message' and 'notes' for a parent that raises the same kind of error again."""
    kind = type(e)
    return {"error": f"{kind.__name__}: {e}", "kind": f"{kind.__module__}.{kind.__qualname__}",
            "message": str(e), "notes": [str(n) for n in getattr(e, "__notes__", [])]}


def serve(conn, setup: Callable[[], Any], job: Callable[[Any, dict], Any]) -> None:
    """A worker's loop (called by the target of its process): ``setup()`` makes its state once,
    then ``job(state, message)`` answers every job it is sent until the parent closes the pipe.
    Replies are JSON: {'ok': figures} or :func:`error_reply`; a job that returns
    :class:`WithBytes` sends {'ok': figures, 'bytes': size}, then the bytes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent()
    try:
        state = setup()
        conn.send_bytes(json.dumps({"ok": "ready"}).encode())
    except Exception as e:  # noqa: BLE001 -- told to the parent, which raises it as one message
        conn.send_bytes(json.dumps(error_reply(e)).encode())
        return
    while True:
        try:
            message = json.loads(conn.recv_bytes())
        except (EOFError, OSError):          # the parent closed the pipe or went away: stop
            return
        data = None
        try:
            out = job(state, message)
            if isinstance(out, WithBytes):
                out, data = out
            reply = {"ok": out} if data is None else {"ok": out, "bytes": len(data)}
        except Exception as e:  # noqa: BLE001
            reply = error_reply(e)
        try:
            conn.send_bytes(json.dumps(reply).encode())
            if data is not None:
                conn.send_bytes(data)
        except (BrokenPipeError, OSError):
            return


def spawn(n: int, target, args: tuple, name: str):
    """n processes running ``target(*args, connection)`` (a module-level function, for 'spawn'),
    each with one BLAS thread: ([process], [this side's connection]). They start with SIGINT
    ignored, so a Ctrl-C while they import prints nothing from them (serve() keeps it ignored);
    this process's handler is back once they exist. If one cannot start, those started are stopped."""
    mp = multiprocessing.get_context("spawn")
    saved = {k: os.environ.get(k) for k in ONE_BLAS_THREAD}
    os.environ.update(ONE_BLAS_THREAD)                 # read by the workers' numpy when it loads
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    procs, conns = [], []
    try:
        for w in range(n):
            mine, theirs = mp.Pipe()
            p = mp.Process(target=target, args=(*args, theirs), daemon=True, name=f"{name}-{w}")
            conns.append(mine)
            p.start()
            theirs.close()
            procs.append(p)
    except BaseException:
        stop(procs, conns)
        raise
    finally:
        if main_thread:     # (None: a handler set outside Python; Python's own takes its place)
            signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return procs, conns


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
