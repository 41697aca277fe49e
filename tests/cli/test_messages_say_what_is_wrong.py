"""Messages that said something wrong or nothing: each now names what was given and what is needed.

phases' frame range ("between 10.0 s and None s"), phases --style with a name that changes
nothing, empty style names in generate (taken for no style, then "--blend needs --style2"),
strafe's speed cap (silent), a too-short fine-tuning clip (the minimum stated as what the clip
had), and the memory of generate / view (estimated before allocating, refused over --max-memory).
"""
import numpy as np
import pytest
from in_process import minifilm_here

from minifilm.cli.generate import STRAFE_TOP_SPEED, script_speed
from minifilm.cli.memory import VIEW_BYTES_PER_JOINT_FRAME, check_memory
from minifilm.cli.phases import frames_shown, hop_style
from minifilm.errors import InputError
from minifilm.pipeline.new_style import shortest_clip_frames, too_short
from repo_paths import SHARED_DATA


# ---- phases -------------------------------------------------------------------------------------
def test_a_range_after_the_end_names_the_end_not_none():
    t = np.arange(120) / 60.0
    with pytest.raises(ValueError) as e:
        frames_shown(t, 10.0, None, "walk.bvh")
    text = str(e.value)
    assert "None" not in text and "from 10 s to the end" in text and "walk.bvh lasts 1.98 s" in text
    with pytest.raises(ValueError, match="between 5 s and 6 s: walk.bvh lasts 1.98 s"):
        frames_shown(t, 5.0, 6.0, "walk.bvh")


def test_a_stop_before_the_start_is_refused_as_such():
    with pytest.raises(ValueError, match="--stop 1 s comes before --start 2 s"):
        frames_shown(np.arange(600) / 60.0, 2.0, 1.0, "walk.bvh")


def test_a_range_inside_the_file_keeps_its_frames():
    keep = frames_shown(np.arange(120) / 60.0, 0.5, 1.0, "walk.bvh")
    assert keep.sum() == 31 and keep[30] and keep[60] and not keep[61]


@pytest.mark.parametrize("given,name", [("LeftHop", "LeftHop"), ("righthop", "RightHop"), (" LEFTHOP ", "LeftHop")])
def test_the_hop_styles_are_taken_in_any_case(given, name):
    assert hop_style(given) == name


@pytest.mark.parametrize("bad", ["Nope", "Neutral", "", "Left Hop"])
def test_phases_refuses_a_style_that_would_change_nothing(tmp_path, capsys, bad):
    bvh = tmp_path / "walk.bvh"
    bvh.write_text("HIERARCHY\n")                      # never read: the option is refused first
    code, (_, err) = minifilm_here(["phases", bvh, "--style", bad, "--out", tmp_path / "p.png"], capsys)
    assert code == 2 and "only LeftHop and RightHop change how phases are labelled" in err, err
    assert not (tmp_path / "p.png").exists()


# ---- generate -----------------------------------------------------------------------------------
@pytest.mark.parametrize("option", ["--style", "--style2", "--style3", "--switch-to"])
@pytest.mark.parametrize("empty", ["", "  "])
def test_an_empty_style_name_is_refused_by_its_option(tmp_path, capsys, option, empty):
    code, (_, err) = minifilm_here(["generate", "--params", tmp_path, option, empty, "--blend", "0.3",
                                    "--out", tmp_path / "o.bvh"], capsys)
    assert code == 2 and f"argument {option}" in err and "not an empty string" in err, err
    assert "needs --style2" not in err


def test_strafe_says_when_it_caps_the_speed(capsys):
    assert script_speed("strafe", 2.5) == STRAFE_TOP_SPEED
    out = capsys.readouterr().out
    assert "--speed 2.5 is capped to 1 m/s" in out and "strafe" in out


@pytest.mark.parametrize("script,speed", [("strafe", 0.8), ("strafe", 1.0), ("figure8", 2.5)])
def test_other_speeds_are_walked_as_asked_without_a_note(capsys, script, speed):
    assert script_speed(script, speed) == speed
    assert capsys.readouterr().out == ""


# ---- finetune's clip ----------------------------------------------------------------------------
@pytest.mark.parametrize("fps", [30.0, 60.0])
def test_a_too_short_clip_is_told_the_real_minimum(fps):
    window = int(2 * fps)
    assert shortest_clip_frames(2.0, fps) == window + 1
    text = too_short(window, 2.0, fps)
    assert f"at least {window + 1} frames" in text and f"the file has {window} (2.000 s)" in text
    assert f"({(window + 1) / fps:.3f} s" in text                 # more than the window, said so


# ---- memory -------------------------------------------------------------------------------------
def test_check_memory_names_the_estimate_and_the_option():
    check_memory(2**30, 2.0, "x", "less")                            # under the limit: nothing
    with pytest.raises(InputError) as e:
        check_memory(4.4 * 2**30, 2.0, "--seconds 3600", "generate fewer seconds")
    text = str(e.value)
    assert "about 4.4 GiB" in text and "limit of 2 GiB (--max-memory 2)" in text and "--max-memory 5" in text


def test_view_refuses_a_file_too_long_for_the_limit_before_reading_it(tmp_path, capsys):
    frames = 2 * 3600 * 60                                              # two hours at 60 fps
    bvh = tmp_path / "long.bvh"
    bvh.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition Yposition Zposition\n"
                   "  End Site\n  {\n    OFFSET 0 1 0\n  }\n}\nMOTION\n"
                   f"Frames: {frames}\nFrame Time: 0.0166667\n0 0 0\n")   # the frames are not there
    code, (_, err) = minifilm_here(["view", bvh, "--html", tmp_path / "v.html", "--max-memory", "0.1"], capsys)
    need = frames * 2 * VIEW_BYTES_PER_JOINT_FRAME / 2**30
    assert code == 2 and f"({frames:,} frames) would need about {need:.3g} GiB" in err, err
    assert "--max-memory" in err and not (tmp_path / "v.html").exists()


def test_generate_refuses_an_hour_over_the_limit_before_rolling_out(tmp_path, capsys):
    released = SHARED_DATA / "released-lpn"
    if not (released / "Xmean.bin").exists():
        pytest.skip("the released network is not in the shared data folder")
    code, (out, err) = minifilm_here(["generate", "--params", released, "--seconds", 3600, "--max-memory", 1,
                                      "--no-calibrate", "--out", tmp_path / "o.bvh"], capsys)
    assert code == 2 and "--seconds 3600 (216,000 frames) would need about" in err, err
    assert "limit of 1 GiB (--max-memory 1)" in err and not (tmp_path / "o.bvh").exists()
