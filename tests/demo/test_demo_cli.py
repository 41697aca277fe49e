"""``minifilm demo`` and ``python -m minifilm.demo``: help, one-line errors for bad input (exit 2),
a port that is taken, the recorded GIF, and the single BLAS thread of its frame loop."""
import socket
import subprocess
import sys

import pytest

pytest.importorskip("websockets", reason="the demo needs the websockets package")


def minifilm(*args, module=("-m", "minifilm", "demo"), timeout=120):
    return subprocess.run([sys.executable, *module, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.parametrize("module", [("-m", "minifilm", "demo"), ("-m", "minifilm.demo")])
def test_help_names_the_controls_and_options(module):
    proc = minifilm("--help", module=module)
    assert proc.returncode == 0, proc.stderr
    for text in ("--params", "--run", "--port", "--host", "--max-characters", "Q / E turn", "Shift runs"):
        assert text in proc.stdout


@pytest.mark.parametrize("argv", [["--params", "{missing}"], ["--run", "{missing}"], ["--run", "{run}", "--port", "70000"],
                                  ["--run", "{run}", "--port", "http"], ["--run", "{run}", "--max-characters", "0"],
                                  ["--run", "{run}", "--walk-speed", "nan"], ["--run", "{run}", "--style", "Ninja"],
                                  ["--run", "{run}", "--record", "{run}/run.json/demo.gif"],
                                  ["--run", "{run}", "--walk-speed", "3", "--run-speed", "1"],
                                  ["--run", "{run}", "--recalibrate", "--no-calibrate"], []])
def test_bad_input_is_one_line_and_exit_code_2(argv, tmp_path, tiny_run):
    proc = minifilm(*[a.format(missing=tmp_path / "missing", run=tiny_run) for a in argv])
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1, proc.stderr


def test_a_run_speed_below_the_walk_speed_is_refused_naming_both(tiny_run):
    proc = minifilm("--run", tiny_run, "--walk-speed", "3", "--run-speed", "1", "--port", "0")
    assert proc.returncode == 2 and "--run-speed 1" in proc.stderr and "--walk-speed 3" in proc.stderr, proc.stderr
    from minifilm.demo.character import DemoSettings
    with pytest.raises(ValueError, match="--run-speed 1 m/s"):
        DemoSettings(style="Neutral", walk_speed=3.0, run_speed=1.0)
    assert DemoSettings(style="Neutral", walk_speed=2.0, run_speed=2.0).run_speed == 2.0


def test_a_port_in_use_is_reported_in_one_line(tiny_run):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        proc = minifilm("--run", tiny_run, "--port", taken.getsockname()[1])
    assert proc.returncode == 2 and proc.stderr.startswith("error: cannot listen on 127.0.0.1:"), proc.stderr


def test_record_writes_a_gif_of_a_scripted_session(tiny_run, tmp_path):
    out = tmp_path / "demo.gif"
    proc = minifilm("--run", tiny_run, "--record", out, "--record-seconds", 1)
    assert proc.returncode == 0, proc.stderr
    Image = pytest.importorskip("PIL.Image")
    with Image.open(out) as gif:
        assert gif.n_frames == 12                  # 1 s at the GIF's 12 frames a second


def test_the_command_line_leaves_numpy_unloaded_so_the_frame_loop_gets_one_blas_thread():
    # minifilm demo sets OPENBLAS_NUM_THREADS=1 (cli COMMANDS) before importing its module; OpenBLAS reads
    # it once, when numpy is imported, so nothing the command line imports first may import numpy
    code = "import sys, minifilm.cli; sys.exit('numpy' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], timeout=60).returncode == 0
