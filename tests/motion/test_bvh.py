"""Tests for minifilm.motion.bvh: reading against independent computations, round trips, clear errors."""
import os
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from minifilm.motion.bvh import BVHError, parse_bvh, read_bvh
from minifilm.motion.bvh_write import format_bvh, write_bvh
from minifilm.motion.motion import Motion
from minifilm.body.rig import detect_skeleton

# Line numbers matter: the error tests below refer to them.
TINY = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Chest
  {
    OFFSET 0 10 0
    CHANNELS 3 Xrotation Zrotation Yrotation
    End Site
    {
      OFFSET 0 20 0
    }
  }
  JOINT LeftLeg
  {
    OFFSET 5 -10 0
    CHANNELS 6 Xposition Yposition Zposition Yrotation Zrotation Xrotation
    End Site
    {
      OFFSET 0 -40 0
    }
  }
}
MOTION
Frames: 2
Frame Time: .0083333
1 90 2 10 20 30 5 -6 7 4 -11 0 40 50 60
3 91 4 0 0 0 0 0 90 5 -10 0 0 0 0
"""


def deg(order, angles):
    return Rotation.from_euler(order, angles, degrees=True).as_matrix()


def test_tiny_file_by_hand():
    m = parse_bvh(TINY, "tiny.bvh")
    assert m.names == ["Hips", "Chest", "ChestSite", "LeftLeg", "LeftLegSite"]
    assert m.parents.tolist() == [-1, 0, 1, 0, 3]
    assert m.channels[1] == ("Xrotation", "Zrotation", "Yrotation") and m.channels[2] == ()
    assert m.n_frames == 2 and m.frame_time == pytest.approx(0.0083333) and round(m.fps) == 120
    np.testing.assert_allclose(m.offsets[3], [0.05, -0.1, 0])
    # frame 0, computed independently with SciPy (capital letters = intrinsic = BVH order)
    R_hips = deg("ZXY", [10, 20, 30])
    R_chest = deg("XZY", [5, -6, 7])
    R_leg = deg("YZX", [40, 50, 60])
    np.testing.assert_allclose(m.rotations[0, 0], R_hips, atol=1e-12)
    np.testing.assert_allclose(m.rotations[0, 1], R_chest, atol=1e-12)
    np.testing.assert_allclose(m.rotations[0, 3], R_leg, atol=1e-12)
    np.testing.assert_allclose(m.rotations[0, 2], np.eye(3))
    # position channels replace the offset (LeftLeg), joints without them use the offset (Chest)
    np.testing.assert_allclose(m.translations[0, 0], [0.01, 0.90, 0.02])
    np.testing.assert_allclose(m.translations[0, 3], [0.04, -0.11, 0.0])
    np.testing.assert_allclose(m.translations[:, 1], [[0, 0.1, 0]] * 2)
    P, _ = m.world()
    hips = np.array([0.01, 0.90, 0.02])
    np.testing.assert_allclose(P[0, 2], hips + R_hips @ [0, 0.1, 0] + R_hips @ R_chest @ [0, 0.2, 0], atol=1e-12)
    np.testing.assert_allclose(P[0, 4], hips + R_hips @ [0.04, -0.11, 0] + R_hips @ R_leg @ [0, -0.4, 0],
                               atol=1e-12)
    # scale argument
    m1 = parse_bvh(TINY, "tiny.bvh", scale=1.0)
    np.testing.assert_allclose(m1.translations, m.translations * 100)


def test_zero_position_channels_are_not_replaced_by_the_offset():
    """We deliberately drop the original's quirk (all-zero position channels -> OFFSET)."""
    text = TINY.replace("OFFSET 5 -10 0", "OFFSET 5 -10 3").replace("4 -11 0 40", "0 0 0 40")
    m = parse_bvh(text)
    np.testing.assert_allclose(m.translations[0, 3], [0, 0, 0])
    np.testing.assert_allclose(m.offsets[3], [0.05, -0.10, 0.03])


def test_crlf_tabs_case_and_blank_lines_read_the_same():
    base = parse_bvh(TINY)
    variant = TINY.replace("  ", "\t").replace("End Site", "end site").replace("MOTION", "MOTION\n")
    variant = variant.replace("Frame Time: .0083333", "Frame Time:\t.0083333").replace("\n", "\r\n")
    variant = variant.replace("ROOT Hips\r\n{", "ROOT Hips {")
    m = parse_bvh(variant)
    assert m.names == base.names and m.channels == base.channels
    np.testing.assert_allclose(m.rotations, base.rotations)
    np.testing.assert_allclose(m.translations, base.translations)


def test_style100_header_file(shared_data):
    path = shared_data / "100style" / "Neutral_FR_first3frames.bvh"
    m = read_bvh(path)
    assert m.n_joints == 28 and m.n_frames == 3
    assert [m.names[i] for i in (7, 12, 17, 22, 27)] == ["HeadSite", "RightWristSite", "LeftWristSite",
                                                         "RightToeSite", "LeftToeSite"]
    first = [float(x) for x in path.read_text().split("Frame Time:")[1].split("\n")[1].split()]
    np.testing.assert_allclose(m.translations[0, 0], np.array(first[:3]) * 0.01)
    np.testing.assert_allclose(m.rotations[0, 0], deg("YXZ", first[3:6]), atol=1e-12)
    np.testing.assert_allclose(m.rotations[0, 1], deg("YXZ", first[6:9]), atol=1e-12)
    assert 0.9 < m.world()[0][0, 0, 1] < 1.05


def test_bandai_every_joint_has_six_channels(shared_data):
    path = sorted((shared_data / "bandai2").glob("dataset-2_walk_*.bvh"))[0]
    m = read_bvh(path)
    text = path.read_text()
    rows = np.array([[float(v) for v in line.split()]
                     for line in text.split("Frame Time:")[1].strip().split("\n")[1:]])
    chans = [c for c in m.channels if c]
    assert len(chans) == 22 and all(len(c) == 6 for c in chans)
    assert m.names[0] == "joint_Root" and m.names[1] == "Hips"
    np.testing.assert_allclose(m.translations[:, 1], rows[:, 6:9] * 0.01)          # Hips position channels
    np.testing.assert_allclose(m.rotations[:, 1], deg("ZXY", rows[:, 9:12]), atol=1e-12)
    assert m.frame_time == pytest.approx(1 / 30, rel=1e-5)


def test_bandai1_root_translation_on_either_joint_moves_the_hips(shared_data):
    for path in sorted((shared_data / "bvh" / "bandai1").glob("dataset-1_walk_*.bvh")):
        m = read_bvh(path)
        hips = m.world()[0][:, m.index("Hips")]
        travel = np.linalg.norm((hips[-1] - hips[0])[[0, 2]])
        assert travel > 1.0, path.name


def data_files(root):
    return sorted(root.rglob("*.bvh"))


def test_round_trip_every_shared_file(shared_data):
    """read -> write -> read: world positions within 1e-4 m, local rotation matrices within 1e-4."""
    files = data_files(shared_data)
    assert len(files) > 10
    for path in files:
        m = read_bvh(path)
        scale = detect_skeleton(m).bvh_scale
        if scale != 0.01:
            m = read_bvh(path, scale=scale)
        back = parse_bvh(format_bvh(m, scale=scale), "round-trip", scale=scale)
        assert back.names == m.names and back.channels == m.channels, path.name
        assert back.parents.tolist() == m.parents.tolist() and back.frame_time == pytest.approx(m.frame_time)
        np.testing.assert_allclose(back.offsets, m.offsets, atol=1e-6)
        assert np.abs(back.rotations - m.rotations).max() < 1e-4, path.name
        assert np.abs(back.world()[0] - m.world()[0]).max() < 1e-4, path.name


def test_write_bvh_to_disk_and_atomicity(tmp_path):
    m = parse_bvh(TINY)
    out = tmp_path / "out.bvh"
    write_bvh(m, out)
    back = read_bvh(out)
    np.testing.assert_allclose(back.world()[0], m.world()[0], atol=1e-9)
    assert "CHANNELS 3 Xrotation Zrotation Yrotation" in out.read_text()
    before = out.read_text()
    # Chest has no position channels: a moving translation can't be written; the old file survives.
    bad_t = m.translations.copy()
    bad_t[1, 1] += 0.5
    bad = Motion(m.names, m.parents, m.offsets, m.channels, m.rotations, bad_t, m.frame_time, "bad")
    with pytest.raises(ValueError, match="Chest"):
        write_bvh(bad, out)
    assert out.read_text() == before
    assert sorted(os.listdir(tmp_path)) == ["out.bvh"]


def test_write_joint_with_unusual_rotation_channels():
    m = parse_bvh(TINY.replace("CHANNELS 3 Xrotation Zrotation Yrotation", "CHANNELS 1 Zrotation")
                  .replace("5 -6 7", "-6").replace("0 0 90", "90"))
    np.testing.assert_allclose(m.rotations[1, 1], deg("Z", 90), atol=1e-12)
    back = parse_bvh(format_bvh(m))
    assert back.channels[1] == ("Zrotation", "Xrotation", "Yrotation")
    np.testing.assert_allclose(back.rotations, m.rotations, atol=1e-9)


# ------------------------------------------------------------------ errors

def lines_replaced(text, lineno, new):
    lines = text.split("\n")
    if new is None:
        del lines[lineno - 1]
    else:
        lines[lineno - 1] = new
    return "\n".join(lines)


ERROR_CASES = {
    "missing HIERARCHY": (lines_replaced(TINY, 1, None), 1, "HIERARCHY"),
    "missing MOTION": (lines_replaced(TINY, 25, None), 25, "MOTION"),
    "missing closing brace": (lines_replaced(TINY, 24, None), 24, "unbalanced braces"),
    "extra closing brace": (lines_replaced(TINY, 24, "}\n}"), 25, "unbalanced braces"),
    "missing opening brace": (lines_replaced(TINY, 7, None), 7, "'{'"),
    "unknown channel": (lines_replaced(TINY, 9, "CHANNELS 3 Xrotation Zrotation Wrotation"), 9, "Wrotation"),
    "CHANNELS count too high": (lines_replaced(TINY, 9, "CHANNELS 4 Xrotation Zrotation Yrotation"), 9, "CHANNELS 4"),
    "CHANNELS count too low": (lines_replaced(TINY, 9, "CHANNELS 2 Xrotation Zrotation Yrotation"), 9, "more channel"),
    "CHANNELS count not a number": (lines_replaced(TINY, 9, "CHANNELS x Xrotation"), 9, "channel count"),
    "missing OFFSET": (lines_replaced(TINY, 8, None), None, "OFFSET"),
    "bad OFFSET": (lines_replaced(TINY, 8, "OFFSET 0 1e999 0"), 8, "finite"),
    "duplicate joint": (TINY.replace("JOINT LeftLeg", "JOINT Chest"), 15, "duplicate"),
    "too few values": (lines_replaced(TINY, 28, "1 90 2 10 20 30 5 -6 7 4 -11 0 40 50"), 28, "expected 15 values"),
    "too many values": (lines_replaced(TINY, 29, "3 91 4 0 0 0 0 0 90 5 -10 0 0 0 0 0"), 29, "found 16"),
    "non-numeric": (lines_replaced(TINY, 28, "1 90 2 10 abc 30 5 -6 7 4 -11 0 40 50 60"), 28, "'abc'"),
    "nan": (lines_replaced(TINY, 29, "3 91 4 0 0 0 0 0 90 5 -10 0 nan 0 0"), 29, "finite"),
    "inf": (lines_replaced(TINY, 28, "1 90 2 10 20 30 5 -6 7 4 -11 0 40 50 inf"), 28, "finite"),
    "fewer frames than declared": (TINY.replace("Frames: 2", "Frames: 3"), None, "ends after 2"),
    "more frames than declared": (TINY.replace("Frames: 2", "Frames: 1"), 29, "more data"),
    "zero frames": (TINY.split("Frames")[0] + "Frames: 0\nFrame Time: 0.01\n", 26, "at least one frame"),
    "missing Frames": (lines_replaced(TINY, 26, None), 26, "Frames:"),
    "missing Frame Time": (lines_replaced(TINY, 27, None), 27, "Frame Time"),
    "zero Frame Time": (lines_replaced(TINY, 27, "Frame Time: 0"), 27, "Frame Time"),
    "empty file": ("", 1, "HIERARCHY"),
    "ends in hierarchy": (TINY[:TINY.index("JOINT LeftLeg")], None, "unbalanced braces"),
}


@pytest.mark.parametrize("case", list(ERROR_CASES))
def test_malformed_input_gives_bvh_error_with_file_and_line(case):
    text, line, words = ERROR_CASES[case]
    with pytest.raises(BVHError) as err:
        parse_bvh(text, "broken.bvh")
    message = str(err.value)
    assert isinstance(err.value, ValueError)
    assert message.startswith("broken.bvh, line "), message
    assert words in message, message
    if line is not None:
        assert err.value.line == line, message


def test_error_names_the_file_on_disk(tmp_path):
    path = tmp_path / "cut.bvh"
    path.write_text(TINY[:-40])
    with pytest.raises(BVHError, match=re.escape(str(path)) + r", line \d+"):
        read_bvh(path)
