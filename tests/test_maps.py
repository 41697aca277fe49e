"""Maps on worker processes (minifilm/parallel.py), as a user relies on them: the results of one
process, in the items' order; an item's error raised as itself, naming the item; a killed worker
one message; Ctrl-C a clean stop with no worker left running."""
import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from minifilm.errors import DataError
from minifilm.motion.bvh import BVHError
from minifilm.parallel import executor, map_in_order, worker_count
from repo_paths import REPO_ROOT


# ---- what the workers run (module-level: a spawned worker imports them by name) -------------------
def a_number(seed: int) -> float:
    """A float made of a few hundred thousand operations (a matrix product and a sum)."""
    a = np.random.default_rng(seed).normal(size=(64, 64))
    return float(np.linalg.norm(a @ a.T) + seed)


def slow_first(i: int) -> int:
    """Item 0 takes longest, so the workers finish out of order."""
    time.sleep(0.3 if i == 0 else 0.0)
    return i * i


def fails_on_two(i: int) -> int:
    if i == 2:
        raise DataError("bad frame 7")
    return i


def bad_bvh(name: str):
    raise BVHError(name, 12, "expected a number, found 'x'")


def blas_threads(i: int):
    return os.environ.get("OPENBLAS_NUM_THREADS"), os.environ.get("OMP_NUM_THREADS")


def killed_on_zero(i: int) -> int:
    if i == 0:
        os.kill(os.getpid(), signal.SIGKILL)
    return i


# ---- the tests ----------------------------------------------------------------------------------
def test_two_workers_give_the_results_of_one_process_in_order():
    one = map_in_order(a_number, range(6), workers=1)
    two = map_in_order(a_number, range(6), workers=2)
    assert multiprocessing.active_children() == []            # the workers are gone
    # not bit for bit: a worker may sum in another order (another BLAS kernel, thread count, CPU).
    # Each number is sums of products, the longest of 4,096 terms: reordered, a sum of n terms moves
    # by at most about n * 1.1e-16 relative (5e-13 here); 1e-10 leaves room, and a wrong or
    # swapped result (numbers tens apart) fails it
    np.testing.assert_allclose(two, one, rtol=1e-10)
    assert one == [a_number(i) for i in range(6)]             # (the plain loop is the loop)


def test_results_and_the_done_calls_come_in_the_items_order():
    seen = []
    got = map_in_order(slow_first, range(5), workers=2, done=lambda i, r: seen.append((i, r)))
    assert got == [0, 1, 4, 9, 16]
    assert seen == list(enumerate(got))


def test_a_workers_error_is_raised_as_itself_with_the_item_named():
    for workers in (1, 2):
        with pytest.raises(DataError, match="bad frame 7") as info:
            map_in_order(fails_on_two, range(4), workers=workers, doing="labelling", name=lambda i: f"file {i}")
        assert info.value.__notes__ == ["(while labelling file 2)"]
        assert multiprocessing.active_children() == []
    with pytest.raises(BVHError) as info:                     # a constructor of its own: pickled as it is
        map_in_order(bad_bvh, ["a.bvh", "b.bvh"], workers=2)
    assert (info.value.source, info.value.line) == ("a.bvh", 12)
    assert str(info.value) == "a.bvh, line 12: expected a number, found 'x'"
    assert not hasattr(info.value, "__notes__")               # its message names the item already


def test_an_error_with_many_items_queued_ends_the_pool_without_tripping_its_thread(monkeypatch):
    """The pool's own thread marks the items still queued as failed when its workers are killed;
    an item cancelled by the map before that made the thread die of InvalidStateError (in a script,
    15 maps of 40 items in 15) before it had cleaned up its pipes."""
    tripped = []
    monkeypatch.setattr(threading, "excepthook", lambda args: tripped.append(args.exc_type.__name__))
    for _ in range(3):
        with pytest.raises(DataError, match="bad frame 7"):
            map_in_order(fails_on_two, range(40), workers=2)
        assert multiprocessing.active_children() == []
    assert tripped == []


def test_a_killed_worker_ends_the_map_with_one_message_naming_the_item():
    with pytest.raises(ChildProcessError, match="ended abruptly while doing 0 or a later item"):
        map_in_order(killed_on_zero, range(4), workers=2)
    assert multiprocessing.active_children() == []


def test_workers_run_one_blas_thread_and_this_process_keeps_its_own(monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "3")
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert map_in_order(blas_threads, range(2), workers=2) == [("1", "1")] * 2
    assert blas_threads(0) == ("3", None)


def test_an_executor_given_is_used_as_given_and_left_open():
    with ThreadPoolExecutor(2) as given:
        assert map_in_order(slow_first, range(4), workers=given) == [0, 1, 4, 9]
        with executor(given, 4) as pool:
            assert pool is given
        assert given.submit(slow_first, 3).result() == 9      # not shut down


def test_worker_counts():
    assert worker_count(3, 2) == 2 and worker_count(1, 5) == 1 and worker_count(4, 0) == 1
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert worker_count(None, 10**6) == cores and worker_count(None, 1) == 1
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="workers must be a whole number >= 1"):
            worker_count(bad, 4)
    with executor(1, 10) as pool, executor(4, 1) as alone:
        assert pool is None and alone is None                  # the plain loop: nothing started


STOPPED = textwrap.dedent('''
    import os, signal, sys, time
    from pathlib import Path
    from minifilm.parallel import map_in_order

    def wait(job):
        folder, i = job
        Path(folder, f"{i}.{os.getpid()}.started").write_text("")
        if i == 0:
            time.sleep(600)         # the other worker does the rest, then waits for work

    if __name__ == "__main__":
        signal.signal(signal.SIGINT, signal.default_int_handler)   # (a shell in the background ignores it)
        try:
            map_in_order(wait, [(sys.argv[1], i) for i in range(4)], workers=2)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(130)
''')


def running(pid: int) -> bool:
    """Whether process ``pid`` still runs (a zombie, ended but not yet waited for, does not)."""
    try:
        return "zombie" not in Path(f"/proc/{pid}/status").read_text().lower()
    except FileNotFoundError:
        return False


def ignores_sigint(pid: int) -> bool:
    """Whether process ``pid`` ignores SIGINT (its SigIgn mask in /proc): a worker then prints
    nothing on Ctrl-C, wherever it is (an interrupted worker would print a traceback, often before
    the parent stops it)."""
    mask = next(line for line in Path(f"/proc/{pid}/status").read_text().splitlines() if line.startswith("SigIgn:"))
    return bool(int(mask.split()[1], 16) & (1 << (signal.SIGINT - 1)))


def wait_until(what, seconds: float = 120.0):
    """Poll ``what()`` until it is true (at most ``seconds``: how long to wait, not a timing)."""
    deadline = time.monotonic() + seconds
    while not what() and time.monotonic() < deadline:
        time.sleep(0.05)
    return what()


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="POSIX signals, and /proc to see the workers")
@pytest.mark.parametrize("who", ["group", "parent"])
def test_ctrl_c_stops_the_map_cleanly_and_leaves_no_worker(tmp_path, who):
    """"group": Ctrl-C in a terminal, SIGINT to the whole job at once; "parent": ``kill -INT``.
    One worker is busy, the other waits for work (where an interrupt would print a traceback)."""
    script = tmp_path / "stopped_map"         # (a script, named without a suffix)
    script.write_text(STOPPED)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO_ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
    try:
        assert wait_until(lambda: len(list(tmp_path.glob("*.started"))) == 4), "the workers never started"
        pids = {int(p.name.split(".")[1]) for p in tmp_path.glob("*.started")}
        assert len(pids) == 2 and all(ignores_sigint(pid) for pid in pids)
        if who == "group":
            os.killpg(proc.pid, signal.SIGINT)
        else:
            proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130 and out == "interrupted\n", err[-2000:]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-2000:]
    assert wait_until(lambda: not any(running(pid) for pid in pids), 30), "a worker is still running"


HALF_SENT = textwrap.dedent('''
    import gc, signal, sys, time
    from multiprocessing.queues import SimpleQueue
    from pathlib import Path
    from minifilm.parallel import map_in_order

    def half_sent(folder):
        """What a worker killed while it sends a result leaves: half a message in the pool's
        results pipe (the header says 1000 bytes; 4 came). Then it waits to be killed."""
        [results] = [q for q in gc.get_objects() if isinstance(q, SimpleQueue)]
        results._writer._send((1000).to_bytes(4, "big") + b"half")
        Path(folder, "sent").write_text("")
        time.sleep(600)

    if __name__ == "__main__":
        signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            map_in_order(half_sent, [sys.argv[1]] * 2, workers=2)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(130)
''')


def test_ctrl_c_ends_the_map_when_a_killed_worker_left_half_a_result(tmp_path):
    """The pool's own thread reads a result as one message; the rest of one a killed worker was
    sending never comes. Ctrl-C must still end the map (it waited for ever: 1 Ctrl-C in 6 of a
    data set's labelling, on a loaded machine)."""
    script = tmp_path / "half_sent"
    script.write_text(HALF_SENT)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO_ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
    try:
        assert wait_until(lambda: (tmp_path / "sent").exists()), "no worker sent its half"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)                # (a hang guard, not a timing)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130 and out == "interrupted\n", err[-2000:]
