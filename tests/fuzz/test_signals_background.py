"""Stopping a command that was started from a background shell.

A shell script that runs ``minifilm train ... &`` (no job control in a script) or runs it after
``trap '' INT`` starts the command with SIGINT (and after ``trap '' TERM``, SIGTERM) *ignored*, and
Python then installs no KeyboardInterrupt handler of its own: Ctrl-C or ``kill -INT`` was lost,
``train`` ran to its end and replaced the earlier run. Every command now installs its stop handlers itself.

The family: the commands a user stops (``train`` at each stage, ``finetune``, ``demo``) started with
the dispositions a parent can leave (SIGINT ignored, SIGINT and SIGTERM ignored, both default) --
each set explicitly in the child, none assumed from the test's own process -- then stopped by
SIGINT or SIGTERM once they print that they are working. Each ends with 130 / 143 and its one
line, no traceback, and an earlier run in the folder stays exactly as it was. One case goes through
a real ``sh`` that starts the command in the background (``cmd &``), as the report's reproduction
did. Cases: 14 subprocess stops + 2 in-process checks of the handlers.
"""
import hashlib
import os
import shutil
import signal
import subprocess
import sys

import pytest
from child_process import Child, minifilm_argv

from minifilm import cli

TRAIN = ["train", "--quick", "--styles", "Neutral,LeftHop", "--gaits", "FW", "--seconds", "6", "--epochs", "3",
         "--generate-seconds", "1"]

#: the dispositions a parent may leave: (SIGINT's, SIGTERM's)
INHERITED = {"int-ignored": ("SIG_IGN", "SIG_DFL"),
             "int-term-ignored": ("SIG_IGN", "SIG_IGN"),
             "defaults": ("SIG_DFL", "SIG_DFL")}
EXIT = {signal.SIGINT: (130, "interrupted"), signal.SIGTERM: (143, "terminated")}


def fingerprint(folder):
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and "cache" not in p.parts}


def start(argv, inherited) -> Child:
    """``python -m minifilm ARGV`` with SIGINT / SIGTERM set to ``inherited`` when it starts."""
    return Child(minifilm_argv(*argv), signals=INHERITED[inherited])


def stop_and_check(proc: Child, sig):
    proc.send_signal(sig)
    rest = proc.end(timeout=600)
    code, line = EXIT[sig]
    assert proc.returncode == code, rest[-1500:]
    assert line in rest and "Traceback" not in rest, rest[-1500:]


@pytest.fixture
def old_run(tiny_run, tmp_path):
    (tmp_path / "runs").mkdir()
    return shutil.copytree(tiny_run, tmp_path / "runs" / "run")


TRAIN_CASES = [("int-ignored", "[dataset]", signal.SIGINT), ("int-ignored", "[train]", signal.SIGINT),
               ("int-ignored", "[generate]", signal.SIGINT), ("int-ignored", "[train]", signal.SIGTERM),
               ("int-term-ignored", "[dataset]", signal.SIGINT), ("int-term-ignored", "[train]", signal.SIGTERM),
               ("defaults", "[train]", signal.SIGINT), ("defaults", "[dataset]", signal.SIGTERM)]


@pytest.mark.parametrize("inherited,marker,sig", TRAIN_CASES,
                         ids=[f"{i}-{m.strip('[]')}-{s.name}" for i, m, s in TRAIN_CASES])
def test_train_stops_and_keeps_the_earlier_run(old_run, inherited, marker, sig):
    before = fingerprint(old_run)
    with start(TRAIN + ["--out", old_run], inherited) as proc:
        proc.until(marker)
        stop_and_check(proc, sig)
    assert fingerprint(old_run) == before
    assert sorted(p.name for p in old_run.parent.iterdir() if not p.name.endswith(".lock")) == ["run"]


@pytest.mark.parametrize("inherited,sig", [("int-ignored", signal.SIGINT), ("int-term-ignored", signal.SIGTERM),
                                           ("defaults", signal.SIGINT)])
def test_finetune_stops_and_leaves_the_style_library(old_run, inherited, sig):
    before = fingerprint(old_run)
    with start(["finetune", "--run", old_run, "--name", "Late", "--steps", "100000",
                old_run / "data" / "Neutral_FW.bvh"], inherited) as proc:
        proc.until("[finetune] teaching")
        stop_and_check(proc, sig)
    assert fingerprint(old_run) == before


@pytest.mark.parametrize("inherited", ["int-ignored", "int-term-ignored"])
def test_demo_stops_on_ctrl_c(tiny_run, inherited):
    """The demo's own handlers (its event loop's) are installed whatever it inherited; it ends cleanly."""
    pytest.importorskip("websockets")
    with start(["demo", "--run", tiny_run, "--port", "0", "--no-calibrate"], inherited) as proc:
        proc.until("http://")
        proc.send_signal(signal.SIGINT)
        printed = proc.end(timeout=120)
    assert proc.returncode in (0, 130), printed[-1500:]
    assert "Traceback" not in printed, printed[-1500:]


def test_a_background_job_of_a_shell_stops_on_sigint(old_run):
    """The reproduction: a non-interactive ``sh`` runs the command with ``&`` (SIGINT ignored in it)."""
    before = fingerprint(old_run)
    argv = " ".join(f"'{a}'" for a in minifilm_argv(*TRAIN, "--out", old_run))
    with Child([shutil.which("sh"), "-c", f"{argv} & echo pid $!; wait $!"], signals=("SIG_DFL", "SIG_DFL")) as shell:
        seen = shell.until("[train]")
        os.kill(int(seen.split("pid ", 1)[1].split()[0]), signal.SIGINT)
        printed = shell.end(timeout=600)
    assert shell.returncode == 130, printed[-1500:]
    assert "interrupted" in printed and "Traceback" not in printed, printed[-1500:]
    assert fingerprint(old_run) == before


def test_run_command_installs_the_stop_handlers_and_gives_back_the_old_ones():
    if signal.getsignal(signal.SIGINT) is None:
        pytest.skip("this process's SIGINT handler was not set from Python")
    saved = signal.signal(signal.SIGINT, signal.SIG_IGN), signal.getsignal(signal.SIGTERM)
    seen = {}

    def command():
        seen["int"], seen["term"] = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
        return 0
    try:
        with pytest.raises(SystemExit) as stop:
            cli.run_command(command)
        assert stop.value.code == 0
        assert seen["int"] is signal.default_int_handler and seen["term"] is cli._terminate
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN        # given back
    finally:
        signal.signal(signal.SIGINT, saved[0])


def test_ctrl_c_inside_a_command_with_sigint_ignored_is_exit_130(capsys):
    saved = signal.signal(signal.SIGINT, signal.SIG_IGN)

    def command():
        signal.raise_signal(signal.SIGINT)      # the user's Ctrl-C, delivered to this process
        return 0                                # not reached: the signal raises KeyboardInterrupt
    try:
        with pytest.raises(SystemExit) as stop:
            cli.run_command(command)
        assert stop.value.code == 130 and "interrupted" in capsys.readouterr().err
    finally:
        signal.signal(signal.SIGINT, saved)


def test_a_stop_prints_one_line_even_when_it_left_an_object_half_made():
    """Ctrl-C while an object is being made (np.load's ZipFile, say) can leave one whose __del__
    fails; its "Exception ignored ... Traceback" must not follow the stop's one line."""
    code = ("import sys\n"
            "from minifilm.cli import report_errors\n"
            "class HalfMade:\n"
            "    def __del__(self):\n"
            "        raise AttributeError('no attribute _writing')\n"
            "def main():\n"
            "    held = [HalfMade()]\n"
            "    raise KeyboardInterrupt\n"
            "report_errors(main)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.strip() == "interrupted", proc.stderr
