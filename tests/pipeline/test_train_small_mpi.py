"""The main job under ``mpiexec -n 2`` (minifilm/train/mpi.py), for real: rank 0 alone prints and
writes the run folder; a rank killed mid-epoch, or Ctrl-C, ends the whole job with the earlier run
folder as it was."""
import os
import shutil
import signal
import subprocess
import sys
import uuid
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mpi4py", reason="the mpi extra (mpi4py, mpich) is not installed")
MPIEXEC = shutil.which("mpiexec")
pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="no mpiexec on the PATH (pip install -e '.[mpi]')")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "train_small.py"
MINI = ["--quick", "--styles", "Neutral,LeftHop", "--gaits", "FW", "--seconds", "6", "--generate-seconds", "0.5"]
#: how long a job that should end may take before the test calls it hung (not a speed target)
HANG = 120


def start(args, tmp_path, log_name="log.txt"):
    """``mpiexec -n 2 python examples/train_small.py ARGS`` in the background, its output to a file;
    (process, log path, marker): the marker is in every rank's environment, to find the ranks."""
    marker = uuid.uuid4().hex
    # TMPDIR: temporary files of the job (and of mpiexec, where it honours it) go to the test's folder
    env = dict(os.environ, MINIFILM_TEST_JOB=marker, OPENBLAS_NUM_THREADS="1", TMPDIR=str(tmp_path))
    log = tmp_path / log_name
    with open(log, "wb") as out:
        proc = subprocess.Popen([MPIEXEC, "-n", "2", sys.executable, str(EXAMPLE), *args], cwd=tmp_path,
                                env=env, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=True)
    return proc, log, marker


def rank_pid(marker, rank):
    """The process id of rank ``rank`` of the job with ``marker`` (from /proc), or None."""
    for entry in Path("/proc").iterdir():
        try:
            env = (entry / "environ").read_bytes().split(b"\0")
        except (OSError, ValueError):
            continue
        if f"MINIFILM_TEST_JOB={marker}".encode() in env and f"PMI_RANK={rank}".encode() in env:
            return int(entry.name)
    return None


def wait_for(log, text, proc):
    """Wait until the job's output holds ``text`` (a hang guard of HANG seconds, not a timing)."""
    import time
    deadline = time.monotonic() + HANG
    while text not in log.read_text(errors="replace"):
        assert proc.poll() is None, log.read_text(errors="replace")
        assert time.monotonic() < deadline, f"no {text!r} in:\n{log.read_text(errors='replace')}"
        time.sleep(0.2)


def gone_or_hung(condition):
    """Wait until ``condition()`` holds: a rank killed by mpiexec may outlive it by a moment (a hang
    guard of HANG seconds, not a timing)."""
    import time
    deadline = time.monotonic() + HANG
    while not condition():
        assert time.monotonic() < deadline, "a rank is still running"
        time.sleep(0.2)


def snapshot(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def mpi_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mpi_run")
    proc, log, _ = start([*MINI, "--epochs", "1", "--out", "run"], folder)
    assert proc.wait(timeout=600) == 0, log.read_text()
    return folder, log.read_text()


def test_two_ranks_make_one_run_folder_and_print_once(mpi_run):
    folder, printed = mpi_run
    assert "training in 2 MPI ranks" in printed
    for line in ("[train] checkpoint", "[test] MSE per style", "[style]", "[done]"):
        assert printed.count(line) == 1, line               # rank 0 alone prints
    assert sorted(p.name for p in folder.iterdir()) == ["log.txt", "run"]     # nothing stray, no lock left
    run = folder / "run"
    for name in ("model.npz", "styles.npz", "starts.npz", "run.json", "loss_curve.png",
                 "generated/Neutral.bvh", "generated/LeftHop.bvh", "generated/styles.gif"):
        assert (run / name).is_file(), name
    from minifilm.train.checkpoint import load_checkpoint
    meta, arrays = load_checkpoint(run / "model.npz")
    assert meta["epoch"] == 1 and all(np.all(np.isfinite(a)) for a in arrays.values() if a.dtype.kind == "f")


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="finds the ranks through /proc")
@pytest.mark.parametrize("how", ["a rank killed", "Ctrl-C"])
def test_a_stopped_job_ends_every_rank_and_keeps_the_earlier_run(mpi_run, tmp_path, how):
    folder, _ = mpi_run
    shutil.copytree(folder / "run", tmp_path / "run")
    before = snapshot(tmp_path / "run")
    proc, log, marker = start([*MINI, "--epochs", "500", "--out", "run"], tmp_path, "log2.txt")
    try:
        wait_for(log, "    epoch  train MSE", proc)            # rank 0 is training
        pids = [rank_pid(marker, 0), rank_pid(marker, 1)]
        assert None not in pids
        if how == "a rank killed":
            os.kill(pids[1], signal.SIGKILL)
        else:
            os.killpg(proc.pid, signal.SIGINT)                # the terminal's Ctrl-C, to mpiexec's group
                                                              # (it passes it on to the ranks)
        code = proc.wait(timeout=HANG)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert code != 0
    gone_or_hung(lambda: rank_pid(marker, 0) is None and rank_pid(marker, 1) is None)   # no rank left running
    if how == "a rank killed":
        assert str(pids[1]) in log.read_text(errors="replace")              # mpiexec names it
    assert snapshot(tmp_path / "run") == before                              # the earlier run, whole
