"""Fuzz family 4: a run is never lost or mixed.

``minifilm train`` into a folder that holds a run is stopped at points spread over its work (while
the data is made, while it trains, while it generates; one of them at a random moment of a seeded
generator): by SIGINT (Ctrl-C), SIGTERM and SIGKILL. Afterwards the earlier run loads and generates
exactly as before, and no temporary is left where a user looks (a killed process's hidden
temporary is removed by the next command writing the folder). Two commands writing one folder:
the second is refused, naming the first's process. (A map's workers stopped with their command:
tests/test_maps.py and tests/dataset/test_build_workers.py.)"""
import hashlib
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from child_process import Child, minifilm_argv

from minifilm.pipeline.run_folder import RunFolder

TRAIN = ["train", "--quick", "--styles", "Neutral,LeftHop", "--gaits", "FW", "--seconds", "6", "--epochs", "3",
         "--generate-seconds", "1"]


def fingerprint(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and "cache" not in p.parts}


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
    with Child(minifilm_argv(*TRAIN, "--out", old_run)) as proc:
        if isinstance(when, str):
            proc.until(when, start=True)
        else:
            time.sleep(when)
        proc.send_signal(sig)
        rest = proc.end(timeout=600)
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
    with Child(minifilm_argv(*TRAIN, "--out", old_run)) as first:
        first.until("[data]", start=True)
        r = subprocess.run([sys.executable, "-m", "minifilm", *TRAIN, "--out", str(old_run)], capture_output=True,
                           text=True, timeout=600)
        assert r.returncode == 2 and f"in use by process {first.pid}" in r.stderr, r.stderr[-500:]
        out = first.end(timeout=900)
    assert first.returncode == 0, out[-800:]
    generates(old_run, tmp_path)


def test_two_finetunes_of_one_run_the_second_is_refused(old_run, tmp_path):
    clip = old_run / "data" / "Neutral_FW.bvh"
    with Child(minifilm_argv("finetune", "--run", old_run, "--name", "First", "--steps", "3000", clip)) as first:
        first.until("[finetune] teaching", start=True)
        r = subprocess.run([sys.executable, "-m", "minifilm", "finetune", "--run", str(old_run), "--name", "Second",
                            "--steps", "5", str(clip)], capture_output=True, text=True, timeout=600)
        out = first.end(timeout=900)
    assert first.returncode == 0, out[-800:]
    assert r.returncode == 2 and f"in use by process {first.pid}" in r.stderr, r.stderr[-500:]
    assert "First" in RunFolder.load(old_run).styles()
