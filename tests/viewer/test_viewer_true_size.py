"""`minifilm view` on real files of every layout: true size, foot contacts, titles inside their
panels, and --out writing the format its extension names."""
import os
import subprocess
import sys

import numpy as np
import pytest

from humanoid_rigs import CMU_CONVERSION_FROM_MB, CMU_CONVERSION_FROM_XIA, renamed_bvh
from minifilm.body.read import read_in_metres
from minifilm.body.units import standing_height
from minifilm.viewer import track_from_motion, track_with_contacts, write_gif
from viewer_helpers import synthetic_walker

LAYOUTS = ["100style/Neutral_FR_first3frames.bvh", "bandai2/dataset-2_walk_normal_001.bvh",
           "bandai2/dataset-2_run_active_002.bvh", "bvh/bandai1/dataset-1_walk-back_normal_001.bvh",
           "bvh/xia/neutral_01_000.bvh", "bvh/cmu/08_01_trimmed.bvh"]
RENAMED = {"cmu_conversion_of_xia.bvh": ("bvh/xia/neutral_01_000.bvh", CMU_CONVERSION_FROM_XIA),
           "cmu_conversion_of_08_01.bvh": ("bvh/cmu/08_01_trimmed.bvh", CMU_CONVERSION_FROM_MB)}


@pytest.fixture(params=LAYOUTS + sorted(RENAMED))
def real_file(request, shared_data, tmp_path):
    if request.param in RENAMED:
        source, mapping = RENAMED[request.param]
        return renamed_bvh(shared_data / source, tmp_path / request.param, mapping)
    return shared_data / request.param


def test_every_layout_is_drawn_at_its_true_size_with_contacts(real_file):
    track = track_with_contacts(real_file)
    motion, h, unit = read_in_metres(real_file)
    head = track.joint_names.index(motion.names[h.head])
    np.testing.assert_allclose(track.positions[:, head], motion.world()[0][:, h.head])   # what is drawn
    height = standing_height(motion.world()[0], h, motion.fps)
    assert 1.4 <= height <= 2.1, f"{real_file.name}: {height:.2f} m ({unit.how})"
    # and without any estimate of the head's top: the drawn body spans well over a metre
    extent = np.median(np.ptp(track.positions[:, :, 1], axis=1))
    assert 1.2 <= extent <= 2.1, extent
    if track.n_frames > 3:                                    # the 100STYLE header has 3 frames
        touching = track.in_contact()
        assert touching.shape[1] == 2 and touching.any(axis=0).all(), f"{real_file.name}: no contact on a foot"
        assert not touching.all(axis=0).any()                 # and each foot lifts off
    assert track.contact_joints.size == 2


def _inside(box, panel, w, h):
    x0, y0, x1, y1 = box
    c, r = panel
    return c * w <= x0 and x1 <= (c + 1) * w and r * h <= y0 and y1 <= (r + 1) * h


@pytest.mark.parametrize("size", [(240, 300), (120, 150)])
def test_titles_stay_inside_their_panels(tmp_path, size):
    walker = synthetic_walker(n_frames=20, fps=30.0)
    names = ["dataset-2_walk-turn-left_feminine_001", "dataset-2_walk-turn-right_exhausted_017",
             "a_third_very_long_name_that_used_to_be_cut_off_at_the_edge", "ok"]
    tracks = [track_from_motion(walker, name=n) for n in names]
    w, h = size
    r = write_gif(tracks, tmp_path / "titles.gif", size=size, seconds=0.2)
    assert len(r.titles) == 4
    for i, (shown, box) in enumerate(r.titles):
        assert _inside(box, (i, 0), w, h), (shown, box, i)
        assert box[2] - box[0] <= 0.94 * w + 1
    boxes = [b for _, b in r.titles]
    for a, b in zip(boxes, boxes[1:]):
        assert a[2] < b[0], "titles overlap"
    assert r.titles[3][0] == "ok"                                       # short names stay whole
    long_shown = r.titles[2][0]
    assert "\u2026" in long_shown and long_shown.startswith("a_") and long_shown.endswith("edge")


def minifilm(*args, env=None):
    return subprocess.run([sys.executable, "-m", "minifilm", *map(str, args)], capture_output=True, text=True,
                          timeout=600, env=env)


def test_view_out_writes_the_format_its_extension_names(shared_data, tmp_path):
    src = shared_data / "bvh/cmu/08_01_trimmed.bvh"
    proc = minifilm("view", src, "--out", tmp_path / "a.gif", "--out", tmp_path / "a.html", "--seconds", "0.3",
                    "--size", "80", "100")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "a.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    page = (tmp_path / "a.html").read_text(encoding="utf-8")
    assert page.lstrip().lower().startswith("<!doctype html") and "minifilmPlayer" in page
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gif", "a.html"]


@pytest.mark.parametrize("name", ["x.png", "x.bvh", "x"])
def test_view_out_refuses_an_unknown_extension_in_one_line(shared_data, tmp_path, name):
    proc = minifilm("view", shared_data / "bvh/cmu/08_01_trimmed.bvh", "--out", tmp_path / name)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") <= 2 and "--out writes the format its extension names" in proc.stderr
    assert ".gif" in proc.stderr and ".mp4" in proc.stderr and ".html" in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_view_out_follows_the_output_rules(shared_data, tmp_path):
    # an input may not be overwritten (files/output_targets.py), and two GIFs are one too many
    src = tmp_path / "walk.bvh"
    src.write_bytes((shared_data / "bvh/cmu/08_01_trimmed.bvh").read_bytes())
    before = src.read_bytes()
    (tmp_path / "folder.gif").mkdir()
    for args, words in ((["--out", tmp_path / "folder.gif"], "folder"),
                        (["--out", tmp_path / "a.gif", "--gif", tmp_path / "b.gif"], "two GIF outputs")):
        proc = minifilm("view", src, *args)
        assert proc.returncode == 2 and proc.stderr.startswith("error: ") and words in proc.stderr, proc.stderr
    assert src.read_bytes() == before and not (tmp_path / "a.gif").exists()


def test_view_out_mp4_without_ffmpeg_says_so(shared_data, tmp_path):
    (tmp_path / "bin").mkdir()
    env = dict(os.environ, PATH=str(tmp_path / "bin"))
    proc = minifilm("view", shared_data / "bvh/cmu/08_01_trimmed.bvh", "--out", tmp_path / "a.mp4", env=env)
    assert proc.returncode == 2 and "ffmpeg" in proc.stderr and "a.mp4" in proc.stderr
    assert not (tmp_path / "a.mp4").exists()


def test_view_says_which_unit_it_inferred(shared_data, tmp_path):
    renamed = renamed_bvh(shared_data / "bvh/xia/neutral_01_000.bvh", tmp_path / "renamed.bvh", CMU_CONVERSION_FROM_XIA)
    proc = minifilm("view", renamed, shared_data / "bvh/xia/neutral_01_000.bvh", "--out", tmp_path / "v.html")
    assert proc.returncode == 0, proc.stderr
    notes = [line for line in proc.stdout.splitlines() if "from its legs" in line]
    assert len(notes) == 1 and "renamed.bvh" in notes[0] and "CMU ASF units" in notes[0]   # known: no note
