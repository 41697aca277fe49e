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


def test_view_without_an_output_writes_view_html(two_files, tmp_path):
    proc = minifilm("view", two_files[0], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "view.html").stat().st_size > 100_000          # three.js is inlined


@pytest.mark.parametrize("case", ["missing", "not_bvh", "folder_out", "missing_folder"])
def test_view_bad_input_is_one_line_and_writes_nothing(two_files, tmp_path, case):
    a, _ = two_files
    junk = tmp_path / "junk.bvh"
    junk.write_text("this is not a BVH file\n")
    args = {"missing": [tmp_path / "nope.bvh", "--gif", tmp_path / "o.gif"],
            "not_bvh": [junk, "--gif", tmp_path / "o.gif"],
            "folder_out": [a, "--gif", tmp_path],
            "missing_folder": [a, "--html", tmp_path / "no" / "such" / "folder" / "o.html"]}[case]
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
