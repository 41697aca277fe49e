"""Fuzzing real BVH files (four skeletons from ../shared/data) through reading, labelling and features.

Each case is a real file, cut to 40 frames, with one hostile or careless edit: numbers that are
NaN, infinite, 1e308 or just large; frame times of 0, 1e-9 or 100 s; wrong frame counts; other line
endings; a byte-order mark; broken structure. The file must either read, label and featurise into
finite arrays at a sane frame rate, or fail with one error line naming the file.
"""
import re

import numpy as np
import pytest
from harness import outcome

from minifilm.errors import MAX_FPS, MIN_FPS, InputError
from minifilm.features.compute import frame_features
from minifilm.motion.bvh import read_bvh
from minifilm.body.rig import detect_skeleton
from minifilm.phases.label import label

SOURCES = {
    "bandai": "bandai2/dataset-2_walk_normal_001.bvh",
    "cmu": "bvh/cmu/08_01_trimmed.bvh",
    "xia": "bvh/xia/angry_13_000.bvh",
    "100style": "100style/Neutral_FR_first3frames.bvh",
}
FRAMES = 40
NUMBERS = ["nan", "NaN", "inf", "-inf", "1e308", "-1e308", "1e999", "1e7", "-2e6", "1e-400", "0x10", "1_0",
           "", "--1", "1e", ".", "+", "9" * 400]
FRAME_TIMES = ["0", "-0.0333", "1e-9", "100", "nan", "inf", "0.0009", "1.5", "1", "0.001", "abc", "0.0333 0.1"]
FRAME_COUNTS = ["0", "-1", "39", "41", "1000000000000", "1e3", "40.0", "abc"]


def cut(text: str, frames: int = FRAMES) -> str:
    head, rest = re.split(r"(?im)^\s*frames\s*:.*$", text, maxsplit=1)
    lines = [line for line in rest.split("\n") if line.strip()]
    n = min(frames, len(lines) - 1)
    return head + f"Frames: {n}\n" + "\n".join(lines[:n + 1]) + "\n"


def edits(rng):
    """(name, function text -> text) for every deterministic edit, then seeded random ones."""
    out = []
    for v in FRAME_TIMES:
        out.append((f"frame time {v}", lambda t, v=v: re.sub(r"(?im)^(\s*frame\s+time\s*:).*$", rf"\g<1> {v}", t)))
    for v in FRAME_COUNTS:
        out.append((f"frames {v}", lambda t, v=v: re.sub(r"(?im)^(\s*frames\s*:).*$", rf"\g<1> {v}", t)))
    out += [
        ("CR line ends", lambda t: t.replace("\n", "\r")),
        ("CRLF line ends", lambda t: t.replace("\n", "\r\n")),
        ("byte-order mark", lambda t: "\ufeff" + t),
        ("tabs for spaces", lambda t: t.replace(" ", "\t")),
        ("no final newline", lambda t: t.rstrip("\n")),
        ("empty", lambda t: ""),
        ("header only", lambda t: t.split("MOTION")[0]),
        ("no hierarchy", lambda t: "MOTION" + t.split("MOTION")[1]),
        ("binary", lambda t: "\x00\x01\x02" * 50),
        ("a joint renamed as its sibling", lambda t: _rename_second_joint(t)),
        ("one channel count +1", lambda t: re.sub(r"CHANNELS (\d)", lambda m: f"CHANNELS {int(m.group(1)) + 1}", t, 1)),
        ("offset 1e308", lambda t: re.sub(r"OFFSET\s+\S+", "OFFSET 1e308", t, 1)),
        ("offset nan", lambda t: re.sub(r"OFFSET\s+\S+", "OFFSET nan", t, 1)),
        ("closing brace removed", lambda t: t.replace("}", "", 1)),
        ("extra closing brace", lambda t: t.replace("MOTION", "}\nMOTION", 1)),
    ]
    data_line = lambda t: len(t.split("MOTION")[0].split("\n")) + 3
    for k in range(40):                            # one number of a frame replaced
        v = NUMBERS[k % len(NUMBERS)]
        out.append((f"value {v!r} #{k}", lambda t, v=v, s=int(rng.integers(1 << 30)): _replace_value(t, v, s, data_line(t))))
    for k in range(20):                            # the file cut at a random byte
        out.append((f"truncated #{k}", lambda t, s=int(rng.integers(1 << 30)): t[:np.random.default_rng(s).integers(len(t))]))
    return out


def _rename_second_joint(text: str) -> str:
    names = re.findall(r"(?m)^\s*(?:ROOT|JOINT)\s+(\S+)", text)
    return re.sub(rf"(JOINT\s+){re.escape(names[2])}\b", rf"\g<1>{names[1]}", text, 1) if len(names) > 2 else text


def _replace_value(text: str, value: str, seed: int, first_data_line: int) -> str:
    rng = np.random.default_rng(seed)
    lines = text.split("\n")
    data = [i for i in range(first_data_line - 1, len(lines)) if lines[i].strip()]
    i = data[rng.integers(len(data))]
    parts = lines[i].split()
    parts[rng.integers(len(parts))] = value
    lines[i] = " ".join(parts)
    return "\n".join(lines)


def cases():
    rng = np.random.default_rng(19)
    out = []
    for skeleton in ("bandai", "cmu"):
        out += [(skeleton, name, fn) for name, fn in edits(rng)]
    for skeleton in ("xia", "100style"):         # a sample of the edits on the other two skeletons
        picked = edits(rng)
        out += [(skeleton, picked[i][0], picked[i][1]) for i in rng.choice(len(picked), 12, replace=False)]
    return out


CASES = cases()


@pytest.mark.parametrize("skeleton,name,edit", CASES, ids=[f"{s}: {n}" for s, n, _ in CASES])
def test_a_mutated_real_file_reads_cleanly_or_fails_with_one_line(shared_data, tmp_path, skeleton, name, edit):
    text = edit(cut((shared_data / SOURCES[skeleton]).read_text()))
    path = tmp_path / "fuzzed.bvh"
    path.write_bytes(text.encode("utf-8", errors="surrogatepass"))
    motion, error = outcome(lambda: read_bvh(path), InputError, mentions=[path])
    if error is not None:
        return
    assert MIN_FPS <= motion.fps <= MAX_FPS
    assert np.all(np.isfinite(motion.rotations)) and np.all(np.isfinite(motion.translations))
    assert np.all(np.isfinite(motion.world()[0]))

    def featurise():
        sk = detect_skeleton(motion)
        labels = label(motion, sk, "fuzz")
        return frame_features(motion, sk, labels.vectors, labels.contacts, fps=motion.fps)

    rows, error = outcome(featurise, ValueError)
    if error is None:
        for a in (rows.x, rows.p, rows.z):
            assert np.all(np.isfinite(a))


def test_there_are_enough_cases():
    assert len(CASES) >= 150
