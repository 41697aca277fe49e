"""Example scripts report bad input in one line (minifilm.cli.run) and keep tracebacks for bugs."""
import subprocess
import sys
from pathlib import Path

import pytest

from minifilm.cli import run
from minifilm.motion.bvh import BVHError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_input_errors_become_one_line_and_exit_code_2(capsys):
    def main():
        raise BVHError("walk.bvh", 7, "expected 'OFFSET'")
    with pytest.raises(SystemExit) as stop:
        run(main)
    assert stop.value.code == 2
    assert capsys.readouterr().err == "error: walk.bvh, line 7: expected 'OFFSET'\n"


def test_bugs_keep_their_traceback():
    def main():
        raise IndexError("a bug, not bad input")
    with pytest.raises(IndexError):
        run(main)


def test_return_code_passes_through():
    with pytest.raises(SystemExit) as stop:
        run(lambda: 3)
    assert stop.value.code == 3


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
