"""Seeded fuzzing of the BVH reader: truncated and corrupted versions of real files.

Every failure must be a ``BVHError`` naming the file and a line (never IndexError, KeyError, ...),
and every success must be self-consistent: the declared number of frames, finite arrays, proper
rotations, a valid hierarchy.
"""
import re

import numpy as np
import pytest

from minifilm.motion.bvh import BVHError, parse_bvh

from test_bvh import TINY

POOL = ["", "abc", "nan", "inf", "-inf", "1e999", "{", "}", "{}", "JOINT", "ROOT", "End", "Site", "OFFSET",
        "CHANNELS", "MOTION", "HIERARCHY", "Frames:", "Frame", "Time:", "Xrotation", "Yposition", "Qrotation",
        "3", "0", "-1", "7", "6", "1.5", "99999999999999999999", "\x00", "\u00e9", "0x10", "1_000", ".", "-",
        "+", "\t", "\r", "1e-400", "Hips"]


def shortened(text: str, frames: int) -> str:
    """The header of a real file with only its first ``frames`` frames (and a matching count)."""
    head, rest = re.split(r"(?im)^\s*frames\s*:.*$", text, maxsplit=1)
    lines = [line for line in rest.split("\n") if line.strip()]
    return head + f"Frames: {frames}\n" + "\n".join(lines[:frames + 1]) + "\n"


def mutate(text: str, rng: np.random.Generator) -> str:
    kind = rng.integers(7)
    lines = text.split("\n")
    if kind == 0:                                   # cut at a random offset
        return text[:rng.integers(len(text))]
    if kind == 1:                                   # replace a random token
        spans = [m.span() for m in re.finditer(r"\S+", text)]
        a, b = spans[rng.integers(len(spans))]
        new = POOL[rng.integers(len(POOL))] if rng.random() < 0.7 else text[slice(*spans[rng.integers(len(spans))])]
        return text[:a] + new + text[b:]
    if kind == 2:                                   # delete a line
        del lines[rng.integers(len(lines))]
    elif kind == 3:                                 # insert a garbage line
        words = [POOL[i] for i in rng.integers(len(POOL), size=rng.integers(1, 5))]
        lines.insert(rng.integers(len(lines) + 1), " ".join(words))
    elif kind == 4:                                 # duplicate a line
        i = rng.integers(len(lines))
        lines.insert(i, lines[i])
    elif kind == 5:                                 # swap two lines
        i, j = rng.integers(len(lines), size=2)
        lines[i], lines[j] = lines[j], lines[i]
    else:                                           # overwrite one character
        i = rng.integers(len(text))
        return text[:i] + "{}\t\r 0.-eXZabc\x00"[rng.integers(15)] + text[i + 1:]
    return "\n".join(lines)


def check_consistent(m, text: str) -> None:
    declared = re.findall(r"(?im)^\s*frames\s*:\s*(\d+)\s*$", text.split("MOTION")[-1])
    assert declared and m.n_frames == int(declared[0]) >= 1
    assert len(set(m.names)) == len(m.names) == len(m.channels) == m.offsets.shape[0]
    assert m.parents[0] == -1 and all(-1 <= p < j for j, p in enumerate(m.parents))
    for a in (m.offsets, m.rotations, m.translations):
        assert np.all(np.isfinite(a))
    RRt = m.rotations @ np.swapaxes(m.rotations, -1, -2)
    assert np.abs(RRt - np.eye(3)).max() < 1e-9
    assert np.all(np.isfinite(m.world()[0]))


def base_texts(root):
    texts = {"tiny": TINY, "100style": (root / "100style" / "Neutral_FR_first3frames.bvh").read_text()}
    for name, rel in [("bandai", "bandai2/dataset-2_walk_normal_001.bvh"),
                      ("xia", "bvh/xia/angry_13_000.bvh"), ("cmu", "bvh/cmu/08_01_trimmed.bvh")]:
        path = root / rel
        if not path.exists():
            path = sorted(root.glob(rel.split("/")[0] + "/**/*.bvh"))[0]
        texts[name] = shortened(path.read_text(), 4)
    return texts


@pytest.mark.parametrize("seed", [0, 1])
def test_fuzzed_files_fail_cleanly_or_read_consistently(shared_data, seed):
    rng = np.random.default_rng(seed)
    failures = successes = 0
    for name, text in base_texts(shared_data).items():
        check_consistent(parse_bvh(text, name), text)            # the unmutated base is valid
        for trial in range(150):
            mutated = text
            for _ in range(rng.integers(1, 4)):
                mutated = mutate(mutated, rng)
            source = f"{name}-fuzz-{seed}-{trial}.bvh"
            try:
                m = parse_bvh(mutated, source)
            except BVHError as err:
                failures += 1
                n_lines = len(re.split(r"\r\n|\r|\n", mutated))      # a bare CR ends a line too
                assert str(err).startswith(f"{source}, line "), str(err)
                assert err.line is not None and 1 <= err.line <= n_lines + 1, str(err)
                continue
            successes += 1
            check_consistent(m, mutated)
    # enough of both kinds for the checks above to mean something (a bare CR from the pool now
    # ends a line, which breaks a frame's value count: fewer mutants read than before)
    assert failures > 300 and successes >= 10, (failures, successes)


def test_byte_level_cuts_and_garbage_through_read_bvh(shared_data, tmp_path):
    """Files cut at random byte offsets or with random bytes spliced in (invalid UTF-8 included)."""
    from minifilm.motion.bvh import read_bvh

    rng = np.random.default_rng(7)
    data = shortened((shared_data / "100style" / "Neutral_FR_first3frames.bvh").read_text(), 3).encode()
    path = tmp_path / "bytes.bvh"
    for trial in range(60):
        if trial % 2 == 0:
            mutated = data[:rng.integers(len(data))]
        else:
            i = rng.integers(len(data))
            mutated = data[:i] + rng.integers(0, 256, size=rng.integers(1, 8), dtype=np.uint8).tobytes() + data[i:]
        path.write_bytes(mutated)
        try:
            m = read_bvh(path)
        except BVHError as err:
            assert str(err).startswith(f"{path}, line "), str(err)
            continue
        check_consistent(m, mutated.decode("utf-8", errors="replace"))
