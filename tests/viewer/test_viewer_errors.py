"""Bad input and unwritable outputs: one clear error, raised before rendering, nothing half-written."""
import sys
from pathlib import Path

import pytest

from minifilm.motion.bvh import BVHError
from minifilm.viewer import OutputPathError, track_from_motion, write_gif, write_html, write_mp4
from minifilm.viewer import gif as gif_module
from minifilm.viewer import mp4 as mp4_module
from minifilm.viewer.mp4 import FFmpegMissingError
from minifilm.viewer.render2d import PanelRenderer

from viewer_helpers import synthetic_walker

pytest.importorskip("matplotlib", reason="the GIF writer needs matplotlib (pip install 'minifilm[viz]')")
pytest.importorskip("PIL", reason="the GIF writer needs Pillow (pip install 'minifilm[viz]')")

WRITERS = {"gif": write_gif, "html": write_html}
SMALL = dict(size=(64, 80))


def _write(kind, tracks, path):
    return write_gif(tracks, path, **SMALL) if kind == "gif" else write_html(tracks, path)


def _unwritable(tmp_path):
    """(case, path) pairs that cannot be written."""
    a_file = tmp_path / "a_file.txt"
    a_file.write_text("x")
    (tmp_path / "a_folder.out").mkdir()
    cases = [("folder given as file", tmp_path / "a_folder.out"),
             ("parent is a file", a_file / "out.x")]
    if Path("/proc/self").is_dir():  # a read-only place even for root (chmod does not stop root)
        cases.append(("read-only", Path("/proc/minifilm-viewer-test.out")))
    return cases


def _single_line(error):
    assert "\n" not in str(error)
    return str(error)


@pytest.mark.parametrize("kind", WRITERS)
def test_unwritable_paths_fail_before_rendering(kind, tmp_path, walker, monkeypatch):
    calls = []
    monkeypatch.setattr(gif_module, "PanelRenderer", lambda *a, **k: calls.append(a))
    monkeypatch.setattr("minifilm.viewer.html.page_html", lambda *a, **k: calls.append(a))
    track = track_from_motion(walker)
    for case, path in _unwritable(tmp_path):
        with pytest.raises(OutputPathError) as info:
            _write(kind, track, path)
        assert str(path) in _single_line(info.value), case
    assert calls == []  # no rendering work was started
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file.txt", "a_folder.out"]


@pytest.mark.parametrize("kind", WRITERS)
def test_a_missing_output_folder_is_made(kind, tmp_path, walker):
    # as for BVH files and run folders: a new folder is not an error
    out = tmp_path / "new" / "deeper" / f"out.{kind}"
    _write(kind, track_from_motion(walker), out)
    assert out.is_file() and out.stat().st_size > 0
    assert [p.name for p in out.parent.iterdir()] == [out.name]  # no temporary left beside it


@pytest.mark.parametrize("kind", WRITERS)
def test_a_failure_while_rendering_leaves_no_file_and_keeps_the_old_one(kind, tmp_path, walker, monkeypatch):
    target = tmp_path / f"out.{kind}"
    target.write_text("the previous file")

    def broken(*args, **kwargs):
        raise RuntimeError("renderer crashed")
    if kind == "gif":
        real = PanelRenderer.render
        monkeypatch.setattr(PanelRenderer, "render", lambda self, k: real(self, k) if k < 3 else broken())
    else:
        monkeypatch.setattr("minifilm.viewer.html.page_html", broken)
    with pytest.raises(RuntimeError, match="renderer crashed"):
        _write(kind, track_from_motion(walker), target)
    assert target.read_text() == "the previous file"
    assert [p.name for p in tmp_path.iterdir()] == [target.name]  # no temporary file left


@pytest.mark.parametrize("kind", WRITERS)
def test_bad_bvh_files_and_empty_motions(kind, tmp_path):
    junk = tmp_path / "junk.bvh"
    junk.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n")
    out = tmp_path / f"out.{kind}"
    with pytest.raises(BVHError) as info:
        _write(kind, [junk], out)
    assert "junk.bvh, line 5" in _single_line(info.value)  # the reader names the file and line
    with pytest.raises(FileNotFoundError, match="missing.bvh"):
        _write(kind, [tmp_path / "missing.bvh"], out)
    with pytest.raises(ValueError, match="has no frames"):
        _write(kind, [synthetic_walker().slice(0, 0)], out)
    assert [p.name for p in tmp_path.iterdir()] == ["junk.bvh"]


def test_mp4_without_ffmpeg_says_so_and_points_to_gif(tmp_path, walker, monkeypatch):
    import matplotlib

    monkeypatch.setitem(matplotlib.rcParams, "animation.ffmpeg_path", str(tmp_path / "no-ffmpeg-here"))
    with pytest.raises(FFmpegMissingError) as info:
        write_mp4(track_from_motion(walker), tmp_path / "out.mp4", **SMALL)
    message = _single_line(info.value)
    assert "ffmpeg was not found" in message and "write_gif" in message and "out.mp4" in message
    assert list(tmp_path.iterdir()) == []


def test_mp4_with_ffmpeg(tmp_path, walker):
    from matplotlib.animation import FFMpegWriter

    if not FFMpegWriter.isAvailable():
        pytest.skip("ffmpeg is not on the PATH (the missing-ffmpeg error is tested above)")
    r = mp4_module.write_mp4(track_from_motion(walker), tmp_path / "out.mp4", **SMALL)
    data = (tmp_path / "out.mp4").read_bytes()
    assert data[4:8] == b"ftyp" and r.n_frames == 36


def test_missing_matplotlib_names_the_extra(tmp_path, walker, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # makes "import matplotlib" fail
    with pytest.raises(ImportError, match=r"pip install 'minifilm\[viz\]'"):
        write_gif(track_from_motion(walker), tmp_path / "out.gif")
    assert list(tmp_path.iterdir()) == []


def test_bad_arguments(tmp_path, walker):
    track = track_from_motion(walker)
    with pytest.raises(ValueError, match="fps or every, not both"):
        write_gif(track, tmp_path / "a.gif", fps=10, every=2)
    with pytest.raises(ValueError, match="panel size"):
        write_gif(track, tmp_path / "a.gif", size=(10, 10))
    assert list(tmp_path.iterdir()) == []
