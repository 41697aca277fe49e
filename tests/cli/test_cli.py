"""The `minifilm` command: its subcommands, one-line errors for bad input (exit 2), tracebacks for
bugs, and the examples that go through the same error reporting."""
import subprocess
import sys
from pathlib import Path

import pytest

from minifilm import cli
from minifilm.motion.bvh import BVHError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def minifilm(*args, cwd=None, timeout=300):
    """Run ``python -m minifilm ARGS`` (the console command's module) and return the result."""
    return subprocess.run([sys.executable, "-m", "minifilm", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


def test_help_lists_every_command_with_one_line():
    proc = minifilm("--help")
    assert proc.returncode == 0
    for name, (_, text, _) in cli.COMMANDS.items():
        assert f"  {name}" in proc.stdout and text in proc.stdout
    assert set(cli.COMMANDS) >= {"train", "phases", "dataset", "generate", "finetune", "table2", "compare"}


def test_unknown_command_is_named():
    proc = minifilm("tabel2")
    assert proc.returncode == 2 and "tabel2" in proc.stderr


@pytest.mark.parametrize("name", list(cli.COMMANDS))
def test_every_command_has_help(name):
    proc = minifilm(name, "--help")
    assert proc.returncode == 0, proc.stderr
    assert f"minifilm {name}" in proc.stdout


def test_input_errors_become_one_line_and_exit_code_2(capsys):
    def main():
        raise BVHError("walk.bvh", 7, "expected 'OFFSET'")
    with pytest.raises(SystemExit) as stop:
        cli.report_errors(main)
    assert stop.value.code == 2
    assert capsys.readouterr().err == "error: walk.bvh, line 7: expected 'OFFSET'\n"


def test_bugs_keep_their_traceback():
    def main():
        raise IndexError("a bug, not bad input")
    with pytest.raises(IndexError):
        cli.report_errors(main)


def test_return_code_passes_through():
    with pytest.raises(SystemExit) as stop:
        cli.report_errors(lambda: 3)
    assert stop.value.code == 3


@pytest.mark.parametrize("argv", [["phases", "{bad}"], ["dataset", "{missing}"],
                                  ["generate", "--params", "{missing}", "--seconds", "1"],
                                  ["generate", "--run", "{missing}", "--seconds", "1"],
                                  ["finetune", "--run", "{missing}", "--name", "X", "{bad}"],
                                  ["generate", "--params", "{missing}", "--seconds", "nan"],
                                  ["generate", "--params", "{missing}", "--blend", "1000"],
                                  ["phases", "{bad}", "--start", "-1"]])
def test_commands_report_bad_input_in_one_line(tmp_path, argv):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n")
    proc = minifilm(*[a.format(bad=bad, missing=tmp_path / "missing") for a in argv], cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1, proc.stderr


@pytest.mark.parametrize("argv", [["plot_phases.py", "{bad}"], ["build_dataset.py", "{missing}"],
                                  ["generate_released.py", "--params", "{missing}", "--seconds", "1"]])
def test_example_scripts_report_bad_input_in_one_line(tmp_path, argv):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n")
    args = [a.format(bad=bad, missing=tmp_path / "missing") for a in argv]
    proc = subprocess.run([sys.executable, str(EXAMPLES / args[0])] + args[1:], capture_output=True,
                          text=True, cwd=tmp_path, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error: ") and "Traceback" not in proc.stderr


def test_the_dataset_command_says_when_a_split_is_empty(tmp_path, capsys):
    """One file per style split by whole files leaves nothing to validate or test on: `train`
    refuses such a data set, and `dataset` says so too (its build still succeeds)."""
    from minifilm.synthetic.generator import default_dataset, write_dataset
    write_dataset(tmp_path / "data", default_dataset(styles=["Neutral", "Limp"], gaits=["FW"], seconds=2.0, seed=1))
    with pytest.raises(SystemExit) as done:
        cli.main(["dataset", str(tmp_path / "data"), "--split-files", "--no-cache", "--workers", "1"])
    assert done.value.code == 0
    assert "note: the val and test split(s) have no frames" in capsys.readouterr().out


@pytest.mark.parametrize("stop, code, said", [(KeyboardInterrupt, 130, "interrupted"),
                                               (cli.Terminated, 143, "terminated")])
def test_a_stop_that_a_read_error_hid_ends_as_the_stop(capsys, monkeypatch, stop, code, said):
    """Ctrl-C cuts a checkpoint's read short, closing its file then fails (EBADF) and the reader
    reports the file as unreadable: the command still ends as interrupted, not as bad input."""
    import sys
    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)    # a stop quiets it: put it back after
    def main():
        try:
            try:
                raise stop()
            except BaseException:
                raise OSError(9, "Bad file descriptor")
        except OSError as e:
            raise ValueError(f"checkpoint model.npz: not a readable .npz archive ({e})") from None
    with pytest.raises(SystemExit) as done:
        cli.report_errors(main)
    assert done.value.code == code and capsys.readouterr().err.strip() == said


def test_an_input_error_without_a_stop_behind_it_is_still_one_error_line(capsys):
    def main():
        raise ValueError("model.npz: not a readable .npz archive")
    with pytest.raises(SystemExit) as done:
        cli.report_errors(main)
    assert done.value.code == 2 and capsys.readouterr().err.strip() == "error: model.npz: not a readable .npz archive"
