"""Fuzz family: BVH text as other writers and encodings produce it.

Frame Time is a number spelled as the motion's numbers are (ASCII digits only: Python's float()
alone takes ``0.01_6`` and digits of other scripts); a file that starts with MOTION says it has no
HIERARCHY; the header survey (``bvh_header``) counts the joints the parser reads however the
hierarchy is laid out (one line, tabs, blank lines), so the memory estimate sees them; joint names
in Windows-1252 are read as the characters they are, bytes that are no text are refused naming the
line.

Cases: 10 digit scripts x 4 spellings of Frame Time, 12 underscore placements, 8 accepted
spellings; 6 MOTION-first files; 120 random hierarchies x 3 layouts; every defined Windows-1252
byte 0x80-0xFF in a joint name (123) and the 5 undefined ones."""
import numpy as np
import pytest

from harness import outcome
from minifilm.motion.bvh import BVHError, bvh_header, read_bvh

HIERARCHY = ("HIERARCHY\nROOT Hips\n{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation "
             "Yrotation\n\tJOINT Spine\n\t{\n\t\tOFFSET 0 10 0\n\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
             "\t\tEnd Site\n\t\t{\n\t\t\tOFFSET 0 10 0\n\t\t}\n\t}\n}\n")
FRAME = "0 90 0 0 0 0 0 0 0\n"

#: zero and one of digit scripts float() reads
SCRIPTS = {"Arabic-Indic": 0x660, "Extended Arabic-Indic": 0x6F0, "Devanagari": 0x966, "Bengali": 0x9E6,
           "Thai": 0xE50, "Fullwidth": 0xFF10, "Tibetan": 0xF20, "Myanmar": 0x1040, "Khmer": 0x17E0,
           "Mathematical bold": 0x1D7CE}


def _file(tmp_path, text, name="f.bvh", encoding="utf-8"):
    path = tmp_path / name
    path.write_bytes(text.encode(encoding) if isinstance(text, str) else text)
    return path


def _refused(path, *mentions):
    for reader in (read_bvh, bvh_header):
        _, error = outcome(lambda: reader(path), BVHError, mentions=(str(path),) + mentions)
        assert error is not None, f"{reader.__name__} accepted {path.read_bytes()[-60:]!r}"
    return error


def _digits(text, zero):
    return "".join(chr(zero + int(c)) if c.isdigit() else c for c in text)


@pytest.mark.parametrize("script", sorted(SCRIPTS))
def test_frame_time_in_other_scripts_is_refused(tmp_path, script):
    for spelling in ("0.0166667", ".008333", "1e-2", "0.033"):
        path = _file(tmp_path, f"{HIERARCHY}MOTION\nFrames: 1\nFrame Time: {_digits(spelling, SCRIPTS[script])}\n{FRAME}")
        assert "Frame Time" in str(_refused(path))


def test_frame_time_with_underscores_is_refused(tmp_path):
    text = "0.0166667"
    for k in range(1, len(text)):
        if text[k - 1] == "." or text[k] == ".":
            continue
        path = _file(tmp_path, f"{HIERARCHY}MOTION\nFrames: 1\nFrame Time: {text[:k]}_{text[k:]}\n{FRAME}")
        _refused(path, "Frame Time")
    for spelling in ("0.01_6", "1_0e-2", "_0.016", "0.016_"):
        _refused(_file(tmp_path, f"{HIERARCHY}MOTION\nFrames: 1\nFrame Time: {spelling}\n{FRAME}"), "Frame Time")


@pytest.mark.parametrize("spelling, fps", [("0.0166667", 60.0), (".0083333", 120.0), ("1e-2", 100.0), ("+0.04", 25.0),
                                           ("3.3333E-2", 30.0), ("0.033333 ", 30.0), ("0.0166667\t", 60.0),
                                           ("1.6666667e-02", 60.0)])
def test_frame_time_as_writers_spell_it_is_read(tmp_path, spelling, fps):
    path = _file(tmp_path, f"{HIERARCHY}MOTION\nFrames: 1\nFrame Time: {spelling}\n{FRAME}")
    assert read_bvh(path).fps == pytest.approx(fps, rel=1e-4)
    assert 1 / bvh_header(path)[1] == pytest.approx(fps, rel=1e-4)


@pytest.mark.parametrize("text", ["MOTION\nFrames: 1\nFrame Time: 0.01\n0 0 0\n", "\n\nMOTION\nFrames: 1\n",
                                  "motion\nFrames: 1\nFrame Time: 0.01\n", "\ufeffMOTION\nFrames: 1\nFrame Time: 0.01\n",
                                  "  \tMOTION\r\nFrames: 1\r\nFrame Time: 0.01\r\n", "MOTION\n"])
def test_a_file_starting_with_motion_says_it_has_no_hierarchy(tmp_path, text):
    error = _refused(_file(tmp_path, text))
    assert "no HIERARCHY" in str(error) and "found no text" not in str(error)


def _random_hierarchy(rng):
    """A random tree of 2-30 joints (End Sites at the leaves) as BVH hierarchy text; its joint count."""
    n = int(rng.integers(2, 31))
    parents = [-1] + [int(rng.integers(0, j)) for j in range(1, n)]
    children = {j: [c for c in range(n) if parents[c] == j] for j in range(n)}

    def block(j, depth):
        kind = "ROOT" if j == 0 else "JOINT"
        channels = "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" if j == 0 else \
            "CHANNELS 3 Zrotation Xrotation Yrotation"
        inner = [f"OFFSET {rng.uniform(-5, 5):.3f} {rng.uniform(1, 9):.3f} 0", channels]
        for c in children[j]:
            inner.append(block(c, depth + 1))
        if not children[j]:
            inner.append("End Site\n{\nOFFSET 0 1 0\n}")
        return f"{kind} j{j}\n{{\n" + "\n".join(inner) + "\n}"
    leaves = sum(1 for j in range(n) if not children[j])
    channels = 6 + 3 * (n - 1)
    return "HIERARCHY\n" + block(0, 0) + "\n", n + leaves, channels


def test_the_header_counts_the_joints_the_parser_reads_in_any_layout(tmp_path):
    rng = np.random.default_rng(7)
    for i in range(120):
        text, joints, channels = _random_hierarchy(rng)
        frame = " ".join(["0"] * channels) + "\n"
        for layout, hier in (("lines", text), ("one line", " ".join(text.split()) + "\n"),
                             ("tabs and blanks", text.replace("\n", "\n\n\t"))):
            path = _file(tmp_path, f"{hier}MOTION\nFrames: 2\nFrame Time: 0.01\n{frame}{frame}")
            assert bvh_header(path) == (2, 0.01, joints), (i, layout)
            assert len(read_bvh(path).names) == joints, (i, layout)


def test_windows_1252_joint_names_are_read_as_their_characters(tmp_path):
    defined = []
    for b in range(0x80, 0x100):
        try:
            defined.append((b, bytes([b]).decode("cp1252")))
        except UnicodeDecodeError:
            continue
    assert len(defined) == 123
    for b, char in defined:
        if char.isspace() or char in "{}":
            continue                                    # (a no-break space would split the name)
        raw = (HIERARCHY + f"MOTION\nFrames: 1\nFrame Time: 0.01\n{FRAME}").encode("ascii").replace(
            b"JOINT Spine", b"JOINT Sp" + bytes([b]) + b"ine")
        path = _file(tmp_path, raw)
        if not char.isprintable():                      # the soft hyphen: refused as any invisible name
            _refused(path, "joint name")
            continue
        names = read_bvh(path).names
        assert names[1] == f"Sp{char}ine" and "\ufffd" not in "".join(names), hex(b)
        assert bvh_header(path)[2] == 3


def test_bytes_that_are_no_text_are_refused_naming_the_line(tmp_path):
    for b in (0x81, 0x8D, 0x8F, 0x90, 0x9D):             # undefined in Windows-1252, invalid alone in UTF-8
        raw = (HIERARCHY + f"MOTION\nFrames: 1\nFrame Time: 0.01\n{FRAME}").encode("ascii").replace(
            b"ROOT Hips", b"ROOT Hips" + bytes([b]))
        error = _refused(_file(tmp_path, raw), f"0x{b:02X}", "line 2")
        assert "UTF-8" in str(error)


def test_a_binary_file_is_named_as_not_a_bvh_file(tmp_path):
    """A checkpoint, an archive or a picture passed as a BVH file: said to be binary data, not
    sent to save itself as UTF-8."""
    import io
    import numpy as np
    buffer = io.BytesIO()
    np.savez(buffer, weights=np.arange(1000.0))                  # a .npz (a zip of .npy files)
    error = _refused(_file(tmp_path, buffer.getvalue()), "not a BVH file", "binary data")
    assert "UTF-8" not in str(error)


def test_utf8_names_stay_utf8(tmp_path):
    text = HIERARCHY.replace("Spine", "Wirbelsäule_脊椎") + f"MOTION\nFrames: 1\nFrame Time: 0.01\n{FRAME}"
    assert read_bvh(_file(tmp_path, text)).names[1] == "Wirbelsäule_脊椎"
