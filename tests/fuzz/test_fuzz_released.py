"""Fuzzing a copy of the authors' released network folder (../shared/data/released-lpn).

Each case is the real folder (its files linked, not copied) with one file missing, cut, padded,
forged to gigabytes, holding a NaN, or with a broken ``styles.txt``. It must load with exactly the
original's weights and styles (only the style names may follow a documented fallback), or fail with
one error line naming the folder or file: never NaN, a wrong style under a right name, or a huge
allocation.
"""
import os

import numpy as np
import pytest
from harness import outcome

from minifilm.errors import InputError
from minifilm.runtime.released import load_released

RNG = np.random.default_rng(1919)
WEIGHTS = ["cp0_a3", "cp1_b5", "cp2_a7", "wc0_w", "wc2_b", "Xstd", "Ymean", "GT_Xstd", "Style_007_shift2",
           "Style_042_scale1"]


def _bytes_edit(name, fn):
    return lambda d: (d / f"{name}.bin").write_bytes(fn((d / f"{name}.bin").read_bytes()))


def _set_float(name, value, seed):
    def edit(d):
        a = np.fromfile(d / f"{name}.bin", dtype="<f4")
        a[np.random.default_rng(seed).integers(len(a))] = value
        a.tofile(d / f"{name}.bin")
    return edit


def _styles_txt(fn):
    return lambda d: (d / "styles.txt").write_text(fn((d / "styles.txt").read_text()))


def _sparse(name, n_bytes):
    def edit(d):
        with open(d / f"{name}.bin", "wb") as f:
            f.truncate(n_bytes)                  # a sparse file: gigabytes that take no disk
    return edit


# (name, edit(folder), what a clean load must equal: "same" weights and names, "ids" (names fall
# back to the style ids), or None when only an error is acceptable)
CASES = []
for w in WEIGHTS:
    CASES.append((f"{w} missing", lambda d, w=w: (d / f"{w}.bin").unlink(), None))
    CASES.append((f"{w} one float short", _bytes_edit(w, lambda b: b[:-4]), None))
    CASES.append((f"{w} one byte short", _bytes_edit(w, lambda b: b[:-1]), None))
    CASES.append((f"{w} one float long", _bytes_edit(w, lambda b: b + b"\0\0\0\0"), None))
    CASES.append((f"NaN in {w}", _set_float(w, np.nan, int(RNG.integers(1 << 30))), None))
    CASES.append((f"-inf in {w}", _set_float(w, -np.inf, int(RNG.integers(1 << 30))), None))
CASES += [
    ("cp0_b0 forged to 4 GB (hidden 10^9)", _sparse("cp0_b0", 4 * 10**9), None),
    ("wc2_b forged to 400 MB (10^8 experts)", _sparse("wc2_b", 4 * 10**8), None),
    ("Xmean forged to 1 GB", _sparse("Xmean", 10**9), None),
    ("a weight file is a folder", lambda d: ((d / "wc1_b.bin").unlink(), (d / "wc1_b.bin").mkdir()), None),
    ("styles.txt missing", lambda d: (d / "styles.txt").unlink(), "ids"),
    ("styles.txt empty", _styles_txt(lambda t: ""), "ids"),
    ("styles.txt with CRLF", _styles_txt(lambda t: t.replace("\n", "\r\n")), "same"),
    ("styles.txt with blank lines and spaces", _styles_txt(lambda t: "\n\n" + t.replace(" ", "   ")), "same"),
    ("styles.txt line twice", _styles_txt(lambda t: t + t.splitlines()[3] + "\n"), None),
    ("styles.txt a name twice", _styles_txt(lambda t: t.replace("001 Akimbo", "001 Aeroplane")), None),
    ("styles.txt names a style without files", _styles_txt(lambda t: t + "777 Ghost\n"), None),
    ("styles.txt garbage line", _styles_txt(lambda t: t + "this is not a style\n"), None),
    ("styles.txt binary", lambda d: (d / "styles.txt").write_bytes(b"\xff\xfe\x00garbage"), None),
    ("an unnamed style whose id is another's name", _styles_txt(
        lambda t: "\n".join(line for line in t.replace("001 Akimbo", "001 042").splitlines()
                            if not line.startswith("042 "))), None),
    ("one style's files all missing", lambda d: [p.unlink() for p in d.glob("Style_013_*.bin")], "fewer"),
    ("an unknown file", lambda d: (d / "notes.txt").write_text("hello"), "same"),
    ("no style at all", lambda d: [p.unlink() for p in d.glob("Style_*.bin")], None),
]


@pytest.fixture(scope="module")
def reference(shared_data):
    return load_released(shared_data / "released-lpn")


#: every file an edit writes to: these are real copies in each case's folder, the rest are links
WRITTEN = {f"{w}.bin" for w in WEIGHTS} | {"cp0_b0.bin", "wc2_b.bin", "Xmean.bin", "wc1_b.bin", "styles.txt"}


def linked_copy(src, dst):
    """``src`` as a folder of links to its files, except the ones an edit may write (copied), so
    the shared data is never written through a link."""
    dst.mkdir()
    for p in src.iterdir():
        if p.name in WRITTEN:
            (dst / p.name).write_bytes(p.read_bytes())
        else:
            os.symlink(p, dst / p.name)
    return dst


@pytest.fixture(scope="module", autouse=True)
def shared_files_unchanged(shared_data):
    """The cases write only to copies: the shared files' sizes and times are the same after."""
    files = sorted((shared_data / "released-lpn").iterdir())
    before = [(p.name, p.stat().st_size, p.stat().st_mtime_ns) for p in files]
    yield
    assert [(p.name, p.stat().st_size, p.stat().st_mtime_ns) for p in files] == before


@pytest.mark.parametrize("name,edit,expect", CASES, ids=[c[0] for c in CASES])
def test_mutated_released_folder(shared_data, reference, tmp_path, name, edit, expect):
    folder = linked_copy(shared_data / "released-lpn", tmp_path / "released")
    edit(folder)
    net, error = outcome(lambda: load_released(folder), InputError, mentions=[folder])
    if error is not None:
        return
    assert expect is not None, f"{name}: loaded"
    ref_films = list(reference.styles.values())
    films = list(net.styles.values())
    for a in net.model.motion.params.params.values():
        assert np.all(np.isfinite(a))
    if expect == "fewer":
        assert len(films) == len(ref_films) - 1
        return
    for a, b in zip(films, ref_films):
        np.testing.assert_array_equal(a, b)
    if expect == "same":
        assert list(net.styles) == list(reference.styles)
    else:
        assert list(net.styles) == [f"{i:03d}" for i in range(len(films))]
    x = np.zeros((1, net.network.x_dim), np.float32)
    z = net.network.predict(x, np.zeros((1, 8)), films[0])
    np.testing.assert_array_equal(z, reference.network.predict(x, np.zeros((1, 8)), ref_films[0]))


def test_there_are_enough_cases():
    assert len(CASES) >= 70
