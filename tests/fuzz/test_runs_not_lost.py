"""Fuzz family 4: a run is never lost or mixed.

``minifilm train`` into a folder that holds a run is stopped at points spread over its work (while
the data is made, while it trains, while it generates; one of them at a random moment of a seeded
generator): by SIGINT (Ctrl-C), SIGTERM and SIGKILL. Afterwards the earlier run loads and generates
exactly as before, and no temporary is left where a user looks (a killed process's hidden
temporary is removed by the next command writing the folder). Training with worker processes
(--workers 2), stopped by SIGINT or SIGTERM, or with a worker killed mid-run: one message, no
worker left running, no shared-memory segment left in /dev/shm, the earlier run kept. Two commands
writing one folder: the second is refused, naming the first's process. ``minifilm dataset --workers
2`` stopped while its workers label (SIGINT, SIGTERM, Ctrl-C to the group, SIGKILL): no worker
left running, no cache written. ``minifilm finetune --params`` stopped while a worker shares its
walks, or with that worker killed: no worker left running, no style pack written. ``minifilm dataset
--from-released --workers 2`` stopped while its workers drive the network (SIGINT, SIGTERM, Ctrl-C
to the group), or with a worker killed: no worker left running, no data set folder."""
import hashlib
import os
import re
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from minifilm.pipeline.run_folder import RunFolder

TRAIN = ["train", "--quick", "--styles", "Neutral,LeftHop", "--gaits", "FW", "--seconds", "6", "--epochs", "3",
         "--generate-seconds", "1"]


def fingerprint(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and "cache" not in p.parts}


def start(argv, **kw):
    return subprocess.Popen([sys.executable, "-u", "-m", "minifilm", *map(str, argv)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, **kw)


def wait_for(proc, marker: str, timeout: float = 600.0) -> str:
    """Read the process's output until a line starting with ``marker``; returns what was read."""
    seen, t0 = [], time.monotonic()
    while time.monotonic() - t0 < timeout:
        line = proc.stdout.readline()
        if not line:
            break
        seen.append(line)
        if line.startswith(marker):
            return "".join(seen)
    raise AssertionError(f"no {marker!r} line in:\n{''.join(seen)[-2000:]}")


def generates(folder: Path, tmp: Path) -> None:
    r = subprocess.run([sys.executable, "-m", "minifilm", "generate", "--run", str(folder), "--seconds", "0.5",
                        "--out", str(tmp / "check.bvh")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-800:]


@pytest.fixture
def old_run(tiny_run, tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    shutil.copytree(tiny_run, runs / "run")
    return runs / "run"


STOPS = [("[dataset]", signal.SIGINT), ("[train]", signal.SIGTERM), ("[generate]", signal.SIGINT),
         ("[dataset]", signal.SIGKILL), ("[train]", signal.SIGKILL), ("[generate]", signal.SIGKILL),
         (random.Random(24).uniform(1.0, 8.0), signal.SIGKILL)]


@pytest.mark.parametrize("when,sig", STOPS, ids=[f"{w if isinstance(w, str) else f'{w:.1f}s'}-{s.name}" for w, s in STOPS])
def test_a_stopped_training_keeps_the_earlier_run(old_run, tmp_path, when, sig):
    before = fingerprint(old_run)
    proc = start(TRAIN + ["--out", old_run])
    if isinstance(when, str):
        wait_for(proc, when)
    else:
        time.sleep(when)
    proc.send_signal(sig)
    rest, _ = proc.communicate(timeout=600)
    if sig != signal.SIGKILL:
        assert proc.returncode in (130, 143), rest[-800:]
        assert "Traceback" not in rest
    after = fingerprint(old_run)
    if after != before:
        # Only a finished run may take the earlier one's place: a kill at a random time can come after
        # the job's last step (its pictures, "[view]") and the exchange of the folders that follows it.
        assert sig == signal.SIGKILL and not isinstance(when, str) and "[view]" in rest, rest[-800:]
        assert sorted(after) == sorted(before)             # a whole run, not a mix of two
    RunFolder.load(old_run).styles()
    generates(old_run, tmp_path)
    visible = sorted(p.name for p in old_run.parent.iterdir() if not p.name.startswith("."))
    assert visible == ["run"], visible
    hidden = [p.name for p in old_run.parent.iterdir() if p.name.startswith(".") and not p.name.endswith(".lock")]
    if sig != signal.SIGKILL:
        assert hidden == [], hidden                        # cleaned up by the command itself
    else:                                                  # the next writer removes a dead one's
        r = subprocess.run([sys.executable, "-m", "minifilm", *TRAIN, "--epochs", "1", "--out", str(old_run)],
                           capture_output=True, text=True, timeout=900)
        assert r.returncode == 0, r.stdout[-800:] + r.stderr[-800:]
        assert [p.name for p in old_run.parent.iterdir() if p.name.startswith(".") and not p.name.endswith(".lock")] == []
        generates(old_run, tmp_path)


def test_two_trainings_into_one_folder_the_second_is_refused(old_run, tmp_path):
    first = start(TRAIN + ["--out", old_run])
    wait_for(first, "[data]")
    r = subprocess.run([sys.executable, "-m", "minifilm", *TRAIN, "--out", str(old_run)], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 2 and f"in use by process {first.pid}" in r.stderr, r.stderr[-500:]
    out, _ = first.communicate(timeout=900)
    assert first.returncode == 0, out[-800:]
    generates(old_run, tmp_path)


def test_two_finetunes_of_one_run_the_second_is_refused(old_run, tmp_path):
    clip = old_run / "data" / "Neutral_FW.bvh"
    first = start(["finetune", "--run", old_run, "--name", "First", "--steps", "3000", clip])
    wait_for(first, "[finetune] teaching")
    r = subprocess.run([sys.executable, "-m", "minifilm", "finetune", "--run", str(old_run), "--name", "Second",
                        "--steps", "5", str(clip)], capture_output=True, text=True, timeout=600)
    out, _ = first.communicate(timeout=900)
    assert first.returncode == 0, out[-800:]
    assert r.returncode == 2 and f"in use by process {first.pid}" in r.stderr, r.stderr[-500:]
    assert "First" in RunFolder.load(old_run).styles()


def worker_ids(text: str) -> list:
    found = re.search(r"(\d+) worker processes \(ids ([\d, ]+)\)", text)
    assert found, text[-800:]
    return [int(pid) for pid in found.group(2).split(",")]


def running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    status = Path(f"/proc/{pid}/status")
    return not (status.exists() and "zombie" in status.read_text().lower())


WORKER_STOPS = [("parent", signal.SIGINT), ("parent", signal.SIGTERM), ("group", signal.SIGINT),
                ("worker", signal.SIGKILL), ("worker", signal.SIGTERM)]


@pytest.mark.parametrize("who,sig", WORKER_STOPS, ids=[f"{w}-{s.name}" for w, s in WORKER_STOPS])
def test_a_stopped_training_with_workers_leaves_no_process_no_shared_memory(old_run, tmp_path, who, sig):
    before = fingerprint(old_run)
    # "group": Ctrl-C in a terminal, SIGINT to the job and its workers at once (own session here)
    proc = start(TRAIN + ["--workers", "2", "--epochs", "400", "--out", old_run], start_new_session=who == "group")
    seen = wait_for(proc, "    2 worker processes")
    pids = worker_ids(seen)
    wait_for(proc, "        1 ")                            # an epoch done: the workers are mid-run
    if who == "group":
        os.killpg(proc.pid, sig)
    else:
        proc.send_signal(sig) if who == "parent" else os.kill(pids[1], sig)
    rest, _ = proc.communicate(timeout=600)
    if who in ("parent", "group"):
        assert proc.returncode == (130 if sig == signal.SIGINT else 143), rest[-800:]
    else:                                                  # one line naming the worker and the signal
        assert proc.returncode == 2, rest[-800:]
        assert re.search(rf"error: training stopped: worker 1 \(process {pids[1]}\) was killed by {sig.name}", rest), rest[-800:]
    assert "Traceback" not in rest, rest[-2000:]
    assert not [pid for pid in pids if running(pid)]
    assert not list(Path("/dev/shm").glob(f"minifilm_{proc.pid}_*"))
    assert fingerprint(old_run) == before
    visible = sorted(p.name for p in old_run.parent.iterdir() if not p.name.startswith("."))
    hidden = [p.name for p in old_run.parent.iterdir() if p.name.startswith(".") and not p.name.endswith(".lock")]
    assert (visible, hidden) == (["run"], [])
    generates(old_run, tmp_path)


@pytest.fixture(scope="module")
def bvh_folder(tmp_path_factory):
    """16 synthetic files, 4 s each: a couple of seconds of labelling for two workers."""
    from minifilm.synthetic.generator import write_dataset
    folder = tmp_path_factory.mktemp("bvh")
    write_dataset(folder, styles=["Neutral", "LeftHop", "Limp", "Drunk"], gaits=["FW", "BW", "FR", "SW"], seconds=4.0,
                  truth=False)
    return folder


DATASET_STOPS = [("parent", signal.SIGINT), ("parent", signal.SIGTERM), ("group", signal.SIGINT),
                 ("parent", signal.SIGKILL)]


@pytest.mark.parametrize("who,sig", DATASET_STOPS, ids=[f"{w}-{s.name}" for w, s in DATASET_STOPS])
def test_a_stopped_dataset_build_with_workers_leaves_no_process_and_no_cache(bvh_folder, tmp_path, who, sig):
    cache = tmp_path / "cache"
    proc = start(["dataset", bvh_folder, "--workers", "2", "--cache", cache], start_new_session=who == "group")
    pids = worker_ids(wait_for(proc, "[dataset] 16 files in 2 worker processes"))
    wait_for(proc, "[dataset] 1/16 files")                 # the first file is back, the workers are at others
    if who == "group":
        os.killpg(proc.pid, sig)
    else:
        proc.send_signal(sig)
    rest, _ = proc.communicate(timeout=600)
    assert proc.returncode == {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGKILL: -9}[sig], rest[-800:]
    assert "Traceback" not in rest, rest[-2000:]
    if sig == signal.SIGKILL:           # the workers are told by the kernel (PR_SET_PDEATHSIG) and end
        deadline = time.monotonic() + 30
        while [pid for pid in pids if running(pid)] and time.monotonic() < deadline:
            time.sleep(0.1)
    assert not [pid for pid in pids if running(pid)]
    assert not cache.exists() or list(cache.iterdir()) == []   # no cache, whole or half


FINETUNE_STOPS = [("parent", signal.SIGINT), ("parent", signal.SIGTERM), ("worker", signal.SIGKILL)]


def stop_while_refining(argv, marker: str, who: str, sig, killed_while: str = "walking") -> None:
    """Start ``argv`` (finetune with one walk worker), stop it once ``marker`` is printed -- the
    parent by ``sig``, or the worker killed -- and check the exit: 130 / 143, or 2 with one line
    naming the worker (killed while ``killed_while``, a regular expression); no traceback, no
    process and no shared memory left."""
    proc = start(argv)
    seen = wait_for(proc, marker)
    pids = [int(p) for p in re.search(r"\(ids ([\d, ]+)\)", seen).group(1).split(",")]
    assert len(pids) == 1
    proc.send_signal(sig) if who == "parent" else os.kill(pids[0], sig)
    rest, _ = proc.communicate(timeout=600)
    if who == "parent":
        assert proc.returncode == (130 if sig == signal.SIGINT else 143), rest[-800:]
    else:
        assert proc.returncode == 2, rest[-800:]
        assert re.search(rf"walks: worker 0 \(process {pids[0]}\) was killed by SIGKILL while {killed_while}",
                         rest), rest[-800:]
    assert "Traceback" not in rest, rest[-2000:]
    assert not running(pids[0])
    assert not list(Path("/dev/shm").glob(f"minifilm_{proc.pid}_*"))      # the walks' shared weights


@pytest.mark.parametrize("who,sig", FINETUNE_STOPS, ids=[f"{w}-{s.name}" for w, s in FINETUNE_STOPS])
def test_a_stopped_teaching_with_a_walk_worker_leaves_no_process_and_no_pack(shared_data, tmp_path, who, sig):
    pack = tmp_path / "pack"
    clip = shared_data / "bandai2" / "dataset-2_walk_elderly_001.bvh"
    stop_while_refining(["finetune", "--params", shared_data / "released-lpn", "--name", "Taught", "--out", pack,
                         "--steps", "20", "--motion-rounds", "50", "--workers", "2", "--adapter", "off", clip],
                        "refining by motion", who, sig)         # (an adapter would be fitted instead of refining)
    assert not pack.exists()


@pytest.mark.parametrize("who,sig", FINETUNE_STOPS, ids=[f"{w}-{s.name}" for w, s in FINETUNE_STOPS])
def test_a_stopped_run_refinement_with_a_walk_worker_leaves_no_process_and_the_run_as_it_was(
        old_run, tmp_path, who, sig):
    """finetune --run --motion-rounds with a walk worker, stopped while it refines: the run folder
    is as it was (no new style, no checkpoint), no process and no shared memory is left."""
    before = fingerprint(old_run)
    # (the refinement's first line comes as its pool starts: the worker may not have walked yet)
    stop_while_refining(["finetune", "--run", old_run, "--name", "Taught", "--steps", "20", "--motion-rounds", "50",
                         "--workers", "2", old_run / "data" / "Neutral_FW.bvh"],
                        "[finetune] refining by motion", who, sig, killed_while="(starting|walking)")
    assert fingerprint(old_run) == before


RELEASED_STOPS = [("parent", signal.SIGINT), ("parent", signal.SIGTERM), ("group", signal.SIGINT),
                  ("worker", signal.SIGKILL)]


@pytest.mark.parametrize("who,sig", RELEASED_STOPS, ids=[f"{w}-{s.name}" for w, s in RELEASED_STOPS])
def test_a_stopped_released_data_set_with_workers_leaves_no_process_and_no_folder(shared_data, tmp_path, who, sig):
    out = tmp_path / "made"
    proc = start(["dataset", "--from-released", shared_data / "released-lpn", "--out", out, "--workers", "2",
                  "--styles", "Neutral", "Zombie", "Aeroplane", "Chicken", "--seconds-per-style", "0.5"],
                 start_new_session=who == "group")
    pids = worker_ids(wait_for(proc, "4 styles in 2 worker processes"))
    wait_for(proc, "speed calibration of 4 styles")      # calibrated: the workers drive the gaits
    if who == "group":
        os.killpg(proc.pid, sig)
    else:
        proc.send_signal(sig) if who == "parent" else os.kill(pids[1], sig)
    rest, _ = proc.communicate(timeout=600)
    if who == "worker":                                   # one line naming the worker and the signal
        assert proc.returncode == 2, rest[-800:]
        assert re.search(rf"error: from-released: worker 1 \(process {pids[1]}\) was killed by SIGKILL while "
                         r"driving gait", rest), rest[-800:]
    else:
        assert proc.returncode == (130 if sig == signal.SIGINT else 143), rest[-800:]
    assert "Traceback" not in rest, rest[-2000:]
    assert not [pid for pid in pids if running(pid)]
    assert list(tmp_path.iterdir()) == []                 # no folder, no temporary beside it
