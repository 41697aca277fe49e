"""Worker processes, for every part of minifilm that starts them (the data set builder, the
comparison; data-parallel training takes its core count and thread settings from here): how many,
how they start, how they answer, how they stop.

    usable_cores() / default_workers(jobs)   how many: the cores this process may run on
    check_workers(workers, where)            a count given: None or a whole number >= 1
    spawn(n, target, args, name)             n workers, 'spawn' start, one BLAS thread each
    serve(conn, setup, job)                  a worker's loop: set up once, then answer jobs
    read_reply(conn)                         a reply (or a job), its arrays' bytes included
    stop(procs, conns, at_once)              close the pipes, then terminate (kill) what still runs
    WorkerGroup                              a group's ids, messages and errors; leaving its ``with``
                                             block stops it

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

import contextlib
import json
import multiprocessing
import os
import signal
import sys
import threading
from typing import Any, Callable, NamedTuple

#: the environment of a worker: one BLAS thread (OpenBLAS, OpenMP or MKL, whichever numpy uses)
ONE_BLAS_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class WorkerDied(ChildProcessError):
    """A worker process ended or failed while it had work (an OSError, so the command prints it as
    one line)."""


def how_it_ended(proc) -> str:
    """How a worker process whose pipe closed has ended, in words ('was killed by SIGKILL', 'exited
    with code 1'), after waiting up to a second for it to finish dying."""
    proc.join(timeout=1.0)
    code = proc.exitcode
    if code is None or code >= 0:
        return f"exited with code {code}"
    try:
        return f"was killed by {signal.Signals(-code).name}"
    except ValueError:
        return f"was killed by signal {-code}"


def attach(name: str):
    """The existing shared-memory segment ``name``, in a worker. A worker started by 'spawn' shares
    its parent's resource tracker, whose record of the segment is a set: the worker's registration
    adds nothing, and the parent's unlink removes it (the tracker also removes it if the parent is
    killed before it can)."""
    from multiprocessing import shared_memory   # (here: a module that imports this one stays light)
    return shared_memory.SharedMemory(name=name)


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


def check_workers(workers, where: str) -> None:
    """A worker count given to ``where`` (a function's name) is None (every core) or a whole number
    >= 1; ValueError naming it otherwise."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ValueError(f"{where}: workers must be a whole number >= 1 (or None: every core), got {workers!r}")


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


def _as_json(value, default):
    """``value`` as JSON gives it back, or ``default`` when JSON cannot hold it."""
    try:
        return json.loads(json.dumps(value))
    except (TypeError, ValueError):
        return default


def error_reply(e: BaseException) -> dict:
    """A worker's error as JSON: 'error' the one line ``Kind: message``; the class ('module',
    'kind'), its 'args', its own attributes ('attrs', such as a BVHError's line) and 'notes', for a
    parent that raises the same error again (:func:`rebuilt_error`)."""
    kind = type(e)
    attrs = {k: v for k, v in vars(e).items() if k != "__notes__"} if hasattr(e, "__dict__") else {}
    reply = {"error": f"{kind.__name__}: {e}", "module": kind.__module__, "kind": kind.__qualname__,
             "args": _as_json(list(e.args), [str(e)]), "attrs": _as_json(attrs, {}),
             "notes": [str(n) for n in getattr(e, "__notes__", [])]}
    if isinstance(e, OSError) and e.filename is not None:
        reply["filename"] = str(e.filename)
    return reply


def rebuilt_error(reply: dict) -> Exception:
    """The exception a worker sent (:func:`error_reply`) as this process would have raised it: the
    same class, arguments, attributes and notes, if the class is a builtin or one of minifilm's
    already loaded here (looked up, never imported: a message cannot make this process load
    code); else a RuntimeError with the worker's one line."""
    module, kind = str(reply.get("module")), str(reply.get("kind"))
    home = sys.modules.get(module) if module == "builtins" or module.startswith("minifilm.") else None
    cls = getattr(home, kind, None) if home is not None and "." not in kind else None
    if not (isinstance(cls, type) and issubclass(cls, Exception)):
        return RuntimeError(reply.get("error", "a worker failed"))
    args = list(reply.get("args") or [])
    try:
        if issubclass(cls, OSError) and "filename" in reply:
            e = cls(*args[:2], reply["filename"])
        else:
            e = cls(*args)
    except Exception:  # noqa: BLE001 -- a constructor of its own (BVHError's): the arguments as made
        e = cls.__new__(cls)
        e.args = tuple(args)
    try:
        for k, v in (reply.get("attrs") or {}).items():
            setattr(e, k, v)
    except (AttributeError, TypeError):
        pass
    for note in reply.get("notes", []):
        e.add_note(str(note))
    return e


def serve(conn, setup: Callable[[], Any], job: Callable[[Any, dict], Any]) -> None:
    """A worker's loop (called by the target of its process): ``setup()`` makes its state once,
    then ``job(state, message)`` answers every job it is sent until the parent closes the pipe.
    Replies are JSON: {'ok': figures} or :func:`error_reply`; a job that returns
    :class:`WithBytes` sends {'ok': figures, 'bytes': size}, then the bytes. A job sent the same
    way (its JSON with 'bytes', then the bytes) gets them in its message as 'data'."""
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
            message = read_reply(conn)          # a job is sent as a reply is: JSON, then its bytes
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
    procs, conns = [], []
    try:
        with starting_workers():
            for w in range(n):
                mine, theirs = mp.Pipe()
                p = mp.Process(target=target, args=(*args, theirs), daemon=True, name=f"{name}-{w}")
                conns.append(mine)
                with _main_module_hidden():
                    p.start()
                theirs.close()
                procs.append(p)
    except BaseException:
        stop(procs, conns)
        raise
    return procs, conns


@contextlib.contextmanager
def starting_workers():
    """While worker processes are started: one BLAS thread in the environment (read by the
    workers' numpy when it loads) and SIGINT ignored (a worker started so keeps it ignored from its
    first instruction, so a Ctrl-C while it imports prints nothing from it); this process's
    environment and handler are back afterwards."""
    saved = {k: os.environ.get(k) for k in ONE_BLAS_THREAD}
    os.environ.update(ONE_BLAS_THREAD)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    try:
        yield
    finally:
        if main_thread:     # (None: a handler set outside Python; Python's own takes its place)
            signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def _main_module_hidden():
    """Start a worker without the caller's script. 'spawn' runs the script again in every worker
    (as ``__mp_main__``, so that a target defined there can be found); a script without an ``if
    __name__ == "__main__":`` guard would then build its data set again in each worker, or fail
    when that tries to start workers of its own. The targets here are minifilm's functions, which
    the workers import by name, so the script is not needed: while a worker starts, the script's
    module shows neither its file nor its module name (both put back at once)."""
    main = sys.modules.get("__main__")
    saved = {k: main.__dict__[k] for k in ("__file__", "__spec__") if main is not None and k in main.__dict__}
    try:
        if "__file__" in saved:
            del main.__file__
        if "__spec__" in saved:
            main.__spec__ = None
        yield
    finally:
        for k, v in saved.items():
            setattr(main, k, v)


def stop(procs, conns, at_once: bool = False) -> None:
    """Close the pipes, give the workers a moment to leave, terminate (then kill) any still running.
    ``at_once``: terminate them first (stopped or failed: what they are doing is not wanted)."""
    if at_once:
        for p in procs:
            if p.is_alive():
                p.terminate()
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


def read_reply(conn) -> dict:
    """A worker's next reply as :func:`serve` sends it: the JSON, and the arrays' bytes that follow
    it (:class:`WithBytes`) in 'data'; a worker reads a job sent the same way with it too.
    EOFError or OSError when the other side has gone."""
    reply = json.loads(conn.recv_bytes())
    if "bytes" in reply:
        reply["data"] = conn.recv_bytes()
    return reply


class WorkerGroup:
    """What a group of worker processes (``procs``, this side's ``conns``) has in common: their
    ids, a message to one and its reply, the one error for one that has died (``what``: the
    group's work, which the error names), and leaving a ``with`` block stops them (at once when it
    is left by an error)."""
    procs: list
    conns: list
    what = "workers"

    def __exit__(self, kind, error, trace) -> None:
        stop(self.procs, self.conns, at_once=kind is not None)

    @property
    def pids(self) -> list:
        """The workers' process ids."""
        return [p.pid for p in self.procs]

    def send(self, w: int, message: dict, doing: str) -> None:
        """Send worker w ``message`` as JSON; WorkerDied if it has gone."""
        try:
            self.conns[w].send_bytes(json.dumps(message).encode())
        except OSError:                     # its end of the pipe is closed: it has died
            raise self.died(w, doing) from None

    def read(self, w: int, doing: str) -> dict:
        """Worker w's next reply (:func:`read_reply`); WorkerDied if it has gone."""
        try:
            return read_reply(self.conns[w])
        except (EOFError, OSError):
            raise self.died(w, doing) from None

    def died(self, w: int, doing: str) -> WorkerDied:
        """The error for worker w, whose pipe is closed: how it ended, and what it was ``doing``."""
        proc = self.procs[w]
        return WorkerDied(f"{self.what}: worker {w} (process {proc.pid}) {how_it_ended(proc)} while {doing}")
