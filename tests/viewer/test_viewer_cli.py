"""`minifilm view`, and the pictures other commands write with the viewer: `minifilm phases
--animation`, `minifilm generate --gif --html`."""
import subprocess
import sys

import numpy as np
import pytest

from minifilm.motion.bvh_write import write_bvh
from viewer_helpers import synthetic_walker


def minifilm(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "minifilm", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


@pytest.fixture
def two_files(tmp_path):
    a, b = tmp_path / "walk_a.bvh", tmp_path / "walk_b.bvh"
    m = synthetic_walker()
    write_bvh(m, a)
    write_bvh(m.slice(0, m.n_frames // 2), b)
    return a, b


def test_view_writes_a_gif_and_an_html_player(two_files, tmp_path):
    from PIL import Image
    a, b = two_files
    proc = minifilm("view", a, b, "--gif", tmp_path / "v.gif", "--html", tmp_path / "v.html", "--seconds", "1",
                    "--size", "120", "150")
    assert proc.returncode == 0, proc.stderr
    with Image.open(tmp_path / "v.gif") as im:
        assert im.size == (240, 150)                       # two 120 x 150 panels side by side
        n = im.n_frames
    fps = float(proc.stdout.split(" frames at ")[1].split(" fps")[0])
    assert n == round(fps * 1.0)
    html = (tmp_path / "v.html").read_text(encoding="utf-8")
    assert "minifilmPlayer" in html and "walk_a" in html and "walk_b" in html


def test_view_reports_the_frames_it_wrote_and_makes_missing_folders(two_files, tmp_path):
    from PIL import Image
    out = tmp_path / "new" / "folder" / "v.gif"
    proc = minifilm("view", *two_files, "--gif", out, "--seconds", "0.5", "--size", "64", "80")
    assert proc.returncode == 0, proc.stderr
    with Image.open(out) as im:
        n = im.n_frames
    assert f"({n} frames at " in proc.stdout, proc.stdout


def _empty_path_env(tmp_path):
    import os
    (tmp_path / "empty-bin").mkdir()
    return dict(os.environ, PATH=str(tmp_path / "empty-bin"))  # no ffmpeg (python is called by full path)


def test_view_mp4_without_ffmpeg_is_one_line_before_any_output(two_files, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.run([sys.executable, "-m", "minifilm", "view", str(two_files[0]), "--gif", str(out / "a.gif"),
                           "--html", str(out / "a.html"), "--mp4", str(out / "a.mp4")], capture_output=True,
                          text=True, timeout=300, env=_empty_path_env(tmp_path))
    assert proc.returncode == 2, proc.stdout
    assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1, proc.stderr
    assert "ffmpeg was not found" in proc.stderr and "--gif" in proc.stderr and "a.mp4" in proc.stderr
    assert list(out.iterdir()) == []                              # not even the GIF or the page


@pytest.mark.parametrize("command", ["view", "phases"])
def test_a_missing_drawing_package_is_one_line_before_any_work(two_files, tmp_path, command):
    # in a process of its own where "import PIL" fails, as without Pillow (matplotlib, which needs
    # it, is not imported yet there; blocking it in this process would leave matplotlib half-loaded)
    out = tmp_path / "out"
    out.mkdir()
    args = {"view": ["view", str(two_files[0]), "--html", str(out / "a.html"), "--gif", str(out / "a.gif")],
            "phases": ["phases", str(two_files[0]), "--out", str(out / "p.png"), "--animation", str(out / "p.gif")]}
    code = ("import sys; sys.modules['PIL'] = sys.modules['PIL.Image'] = None; "
            f"from minifilm.cli import main; main({args[command]!r})")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    err = proc.stderr
    assert proc.returncode == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert "Pillow" in err and "minifilm[viz]" in err
    assert list(out.iterdir()) == []


def test_view_without_an_output_writes_view_html(two_files, tmp_path):
    proc = minifilm("view", two_files[0], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "view.html").stat().st_size > 100_000          # three.js is inlined


@pytest.mark.parametrize("case", ["missing", "not_bvh", "folder_out", "parent_is_a_file", "second_output_bad"])
def test_view_bad_input_is_one_line_and_writes_nothing(two_files, tmp_path, case):
    a, _ = two_files
    junk = tmp_path / "junk.bvh"
    junk.write_text("this is not a BVH file\n")
    args = {"missing": [tmp_path / "nope.bvh", "--gif", tmp_path / "o.gif"],
            "not_bvh": [junk, "--gif", tmp_path / "o.gif"],
            "folder_out": [a, "--gif", tmp_path],
            "parent_is_a_file": [a, "--html", junk / "o.html"],
            # the first output is fine, the second is not: nothing is written at all
            "second_output_bad": [a, "--html", tmp_path / "ok.html", "--gif", junk / "o.gif"]}[case]
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = minifilm("view", *args)
    assert proc.returncode == 2, proc.stdout
    assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before      # nothing half-written, no debris


def test_phases_animation_beside_the_plot(two_files, tmp_path, shared_data):
    from PIL import Image
    walk = shared_data / "bandai2" / "dataset-2_walk_normal_001.bvh"
    proc = minifilm("phases", walk, "--out", tmp_path / "p.png", "--animation", tmp_path / "p.gif", "--stop", "1")
    assert proc.returncode == 0, proc.stderr
    with Image.open(tmp_path / "p.gif") as im:
        assert im.n_frames == 31                           # 0 .. 1 s at 30 fps
    assert (tmp_path / "p.png").stat().st_size > 0


def test_generate_writes_gif_and_html_of_the_rollout(tmp_path, shared_data):
    from PIL import Image
    proc = minifilm("generate", "--params", shared_data / "released-lpn", "--style", "Old", "--seconds", "1",
                    "--no-calibrate", "--out", tmp_path / "o.bvh", "--gif", tmp_path / "o.gif",
                    "--html", tmp_path / "o.html")
    assert proc.returncode == 0, proc.stderr
    with Image.open(tmp_path / "o.gif") as im:
        frames = [np.asarray(im.convert("L")) for _ in range(2) if not im.seek(im.tell() + 5)]
        assert im.n_frames == 30                           # 60 fps capped to 30 for GIF players
    assert len({f.tobytes() for f in frames}) > 1
    assert "Old" in (tmp_path / "o.html").read_text(encoding="utf-8")


def test_files_of_one_name_from_two_folders_get_panels_told_apart():
    from minifilm.cli.view import panel_names
    assert panel_names(["a/walk.bvh", "b/walk.bvh", "c/run.bvh"]) == ["a/walk", "b/walk", "run"]
    assert panel_names(["walk.bvh"]) == ["walk"]
