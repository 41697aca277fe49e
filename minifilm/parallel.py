"""Maps on every core: one function applied to many items (files, walks, styles, variants) by the
worker processes of concurrent.futures or any executor with its interface (mpi4py.futures' under
mpiexec). ``workers``: None (every usable core), a whole number >= 1, or an Executor (used as given,
not shut down; ``executor()`` keeps a pool for several maps); one worker or item: the plain loop.
Results come in the items' order; an item's error is raised here as itself (pickled back) with a
note naming the item; a dead worker is one ChildProcessError naming the first item not done; Ctrl-C
or an error kills the workers, which ignore SIGINT. Workers are fresh Pythons ('spawn': a script
that maps needs ``if __name__ == "__main__":``), one BLAS thread each (threads of several processes
on shared cores take turns: walks took 6x the CPU so).
"""
import contextlib
import multiprocessing
import os
import signal
import threading
from concurrent.futures import BrokenExecutor, Executor, ProcessPoolExecutor

ONE_BLAS_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}   #: read as numpy loads


def worker_count(workers, jobs: int) -> int:
    """The processes ``workers`` (None or a whole number >= 1) means for ``jobs`` items: at most one each."""
    if workers is None:
        workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    elif isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a whole number >= 1, None (every core) or an Executor, not {workers!r}")
    return max(1, min(workers, jobs))


@contextlib.contextmanager
def executor(workers=None, jobs: int = 1):
    """The Executor given, None (one worker: map with workers=1), or a pool, terminated on an exception."""
    if isinstance(workers, Executor) or worker_count(workers, jobs) == 1:
        yield workers if isinstance(workers, Executor) else None
        return
    pool = ProcessPoolExecutor(worker_count(workers, jobs), mp_context=multiprocessing.get_context("spawn"))
    try:
        yield pool
    except BaseException:
        _end_workers(pool)
        raise
    finally:
        pool.shutdown(cancel_futures=True)


def _end_workers(pool: ProcessPoolExecutor) -> None:
    """Kill the pool's workers now (Ctrl-C, or an item's error), so that shutdown does not wait for
    their items. A worker killed while it was sending a result leaves half a message in the pool's
    results pipe, and the pool's own thread would wait for the rest for ever, and shutdown with it
    (seen: 1 Ctrl-C in 6). Once the workers are gone this process holds the pipe's last writing
    end: closing it turns that wait into an end of file, which the pool takes as broken, and cleans
    up after. (The standard library closes its call queue's end the same way when a pool breaks.)"""
    workers = list(pool._processes.values())        # (Python 3.14: pool.kill_workers())
    for p in workers:
        p.kill()            # (not terminate: a worker ignores SIGTERM when this process was started so)
    for p in workers:
        p.join(30)
    pool._result_queue._writer.close()


def map_in_order(fn, items, workers=None, doing: str = "doing", name=str, done=lambda i, result: None) -> list:
    """[fn(item) for item in items] on ``workers``; an error is noted "(while {doing} {name(item)})".
    ``done(i, result)``: called here for each result in the items' order (progress, collecting)."""
    items, results = list(items), []
    with executor(workers, len(items)) as pool:
        futures = [] if pool is None else _submit(pool, fn, items)
        for i, item in enumerate(items):
            try:
                results.append(futures[i].result() if futures else fn(item))
            except BrokenExecutor:
                raise ChildProcessError(f"a worker process ended abruptly while {doing} {name(item)} or a later item") from None
            except Exception as e:
                if isinstance(workers, Executor):   # a given pool goes on: drop the items not started.
                    for f in futures:               # (Our own is killed on the way out; a future
                        f.cancel()                  # cancelled here would then trip its thread.)
                if name(item) not in str(e):
                    e.add_note(f"(while {doing} {name(item)})")
                raise
            done(i, results[-1])
    return results


def _submit(pool, fn, items) -> list:
    """Submit every item; workers started meanwhile inherit one BLAS thread and SIGINT ignored (kept by Python)."""
    saved, main = dict(os.environ), threading.current_thread() is threading.main_thread()
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    os.environ.update(ONE_BLAS_THREAD)
    try:
        return [pool.submit(fn, item) for item in items]
    finally:
        os.environ.update({k: v for k, v in saved.items() if k in ONE_BLAS_THREAD})    # as they were
        for k in set(ONE_BLAS_THREAD) - set(saved):
            del os.environ[k]
        if main:
            signal.signal(signal.SIGINT, signal.default_int_handler if handler is None else handler)
