"""Bad names and outputs (the fuzz families 1-3 and 7), through the command as a user runs it: names from data never
become paths or reach the terminal raw, an output never replaces a special file, a read-only file
or one of the command's inputs, a special file is never read, a header cannot ask for more than
its file justifies, and every message is one line naming the file.

Each case exits with code 2 and one ``error:`` line, leaves its files as they were and writes
nothing outside its folder. Special files (FIFOs, sockets, device nodes) are made in the test's
own folder: nothing points at /dev for writing."""
import os
import shutil
import stat
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest
from in_process import minifilm_here

from minifilm.files import atomic_savez
from minifilm.motion.bvh import BVHError, parse_bvh
from minifilm.runtime.style_library import StyleLibrary, StyleLibraryError


def one_error(argv, capsys, *mentions):
    """Run ``minifilm argv``: exit 2, one error line naming every one of ``mentions``, no
    escape character or traceback on the terminal; returns the line."""
    code, out = minifilm_here(argv, capsys)
    errors = [line for line in out.err.splitlines() if line.startswith("error:")]
    assert code == 2 and len(errors) == 1, (code, out.err[-600:])
    assert "Traceback" not in out.err and "\x1b" not in out.err + out.out
    for m in mentions:
        assert str(m) in errors[0], errors[0]
    return errors[0]


def tree(folder):
    """path -> (mode, contents) of every file and folder under ``folder`` (other tests' FIFOs and
    sockets may lie beside: they are listed, never read)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        mode = os.lstat(p).st_mode
        out[str(p.relative_to(folder))] = (mode, p.read_bytes() if stat.S_ISREG(mode) else b"")
    return out


# ---- 1. names from data --------------------------------------------------------------------------
@pytest.mark.parametrize("style", ["../../../X", "/abs/path/X", "\x1b[2Jerror: all fine", "a\\b", "x" * 80])
def test_a_manifest_style_that_is_not_a_name_is_refused(run, tmp_path, capsys, style):
    # the test looks only at its own folder: the work lies five folders down in it, so that
    # wherever the name's "../../../" would lead from the output folder is still inside it
    work = tmp_path.joinpath(*"abcde")
    work.mkdir(parents=True)
    manifest = work / "data.csv"
    text = f"file,style,gait\n{run / 'data' / 'Neutral_FW.bvh'},Neutral,FW\n{run / 'data' / 'LeftHop_FW.bvh'},{style!s},FW\n"
    manifest.write_text(text)
    before = tree(tmp_path)
    one_error(["train", "--data", manifest, "--out", work / "out", "--quick"], capsys, "data.csv", "line 3")
    assert tree(tmp_path) == before and not (work / "out").exists()


def test_a_style_library_with_an_escape_sequence_is_refused(run, capsys):
    lib = StyleLibrary.load(run / "styles.npz")
    films = np.stack([lib[n] for n in lib.names])
    atomic_savez(run / "styles.npz", {"names": np.array(["\x1b[2JNeutral", "LeftHop"]), "films": films})
    one_error(["generate", "--run", run, "--list-styles"], capsys, "styles.npz", "control")
    with pytest.raises(StyleLibraryError, match=r"'\\x1b\[2JNeutral'"):
        StyleLibrary.load(run / "styles.npz")


@pytest.mark.parametrize("name", ["\x1b[31mred", "../up", "a/b", "tab\tname", " space"])
def test_finetune_names_follow_the_one_rule(run, capsys, name):
    before = tree(run)
    one_error(["finetune", "--run", run, "--name", name, run / "data" / "Neutral_FW.bvh"], capsys, "--name")
    assert tree(run) == before


def test_a_released_style_list_naming_a_path_is_refused(shared_data, tmp_path, capsys):
    folder = tmp_path / "released"
    folder.mkdir()
    for p in (shared_data / "released-lpn").iterdir():
        (folder / p.name).symlink_to(p)
    (folder / "styles.txt").unlink()
    (folder / "styles.txt").write_text("000 ../../etc/X\n")
    one_error(["generate", "--params", folder, "--list-styles"], capsys, "styles.txt", "line 1")


# ---- 2. what an output may replace -------------------------------------------------------------
def test_outputs_never_replace_special_files(run, tmp_path, capsys):
    fifo = tmp_path / "fifo.bvh"
    os.mkfifo(fifo)
    one_error(["generate", "--run", run, "--seconds", "1", "--out", fifo], capsys, "fifo.bvh", "FIFO")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    try:
        os.mknod(tmp_path / "null", stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, OSError):
        return                                   # device nodes need root
    one_error(["generate", "--run", run, "--seconds", "1", "--out", tmp_path / "null"], capsys, "character device")
    one_error(["view", run / "data" / "Neutral_FW.bvh", "--gif", tmp_path / "null"], capsys, "character device")
    assert stat.S_ISCHR(os.lstat(tmp_path / "null").st_mode)


def test_a_read_only_output_is_refused_and_a_link_is_followed(run, tmp_path, capsys):
    protected = tmp_path / "protected.bvh"
    protected.write_text("mine")
    os.chmod(protected, 0o444)
    one_error(["generate", "--run", run, "--seconds", "1", "--out", protected], capsys, "read-only")
    assert protected.read_text() == "mine"
    real, link = tmp_path / "real.bvh", tmp_path / "link.bvh"
    real.write_text("old")
    link.symlink_to(real)
    code, out = minifilm_here(["generate", "--run", run, "--seconds", "0.5", "--out", link], capsys)
    assert code == 0, out.err[-500:]
    assert link.is_symlink() and real.read_text().startswith("HIERARCHY")


def test_an_output_that_is_an_input_is_refused_before_the_work(run, tmp_path, capsys):
    a = tmp_path / "a.bvh"
    shutil.copy(run / "data" / "Neutral_FW.bvh", a)
    original = a.read_bytes()
    one_error(["view", a, "--html", a], capsys, "a.bvh", ".html")          # the format, found first
    (tmp_path / "a.html").symlink_to(a)                                     # an HTML name leading to the input
    one_error(["view", a, "--html", tmp_path / "a.html"], capsys, "a.html", "also an input")
    one_error(["generate", "--run", run, "--seconds", "1", "--skeleton-bvh", a, "--out", a], capsys, "also an input")
    one_error(["generate", "--run", run, "--seconds", "1", "--out", run / "skeleton.bvh"], capsys, "skeleton.bvh",
              "also an input")
    assert a.read_bytes() == original


def test_a_run_folder_may_not_swallow_its_own_data(run, tmp_path, capsys):
    data = tmp_path / "mydata"
    shutil.copytree(run / "data", data)
    before = tree(data)
    one_error(["train", "--data", data, "--out", data, "--quick"], capsys, "holds an input")
    one_error(["train", "--data", data, "--out", tmp_path, "--quick"], capsys, "holds an input")
    assert tree(data) == before


def test_a_png_output_with_another_suffix_is_refused_before_the_work(run, capsys):
    one_error(["phases", run / "data" / "Neutral_FW.bvh", "--out", "p.txt"], capsys, "p.txt", ".png")


# ---- 3. special files and sizes --------------------------------------------------------------
@pytest.mark.parametrize("command", ["view", "phases", "skeleton", "finetune", "data folder"])
def test_a_fifo_is_never_read(run, tmp_path, command):
    """In a process of its own with a timeout: before, each of these hung for ever."""
    folder = tmp_path / "data"
    folder.mkdir()
    fifo = folder / "Neutral_FW.bvh"
    os.mkfifo(fifo)
    argv = {"view": ["view", fifo, "--gif", tmp_path / "v.gif"],
            "phases": ["phases", fifo, "--out", tmp_path / "p.png"],
            "skeleton": ["generate", "--run", run, "--seconds", "1", "--skeleton-bvh", fifo, "--out", tmp_path / "o.bvh"],
            "finetune": ["finetune", "--run", run, "--name", "New", fifo],
            "data folder": ["train", "--data", folder, "--out", tmp_path / "t", "--quick"]}[command]
    r = subprocess.run([sys.executable, "-m", "minifilm", *map(str, argv)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr[-500:]
    assert "FIFO" in r.stderr and "Neutral_FW.bvh" in r.stderr and r.stderr.count("error:") == 1


def test_devices_are_never_read(tmp_path, capsys):
    one_error(["view", "/dev/zero", "--gif", tmp_path / "v.gif"], capsys, "/dev/zero", "character device")
    one_error(["phases", "/dev/urandom", "--out", tmp_path / "p.png"], capsys, "/dev/urandom", "character device")


def header(n_joints, channels=""):
    """A hierarchy of a root and ``n_joints - 1`` joints in one chain."""
    text = ["HIERARCHY", "ROOT Hips", "{", "OFFSET 0 0 0", "CHANNELS 3 Xposition Yposition Zposition"]
    for i in range(n_joints - 1):
        text += [f"JOINT j{i}", "{", "OFFSET 0 1 0"] + ([channels] if channels else [])
    text += ["}"] * n_joints
    return "\n".join(text) + "\n"


def test_a_header_cannot_ask_for_more_memory_than_its_file_justifies():
    text = header(6000) + "MOTION\nFrames: 6000\nFrame Time: 0.01\n" + "0 0 0\n" * 6000
    tracemalloc.start()
    try:
        with pytest.raises(BVHError, match="6,000 joints and 6,000 frames"):
            parse_bvh(text, source="huge.bvh")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 200 << 20, f"{peak / 2**20:.0f} MiB before the refusal"


def test_checks_stay_linear_in_the_number_of_joints_and_styles(tmp_path):
    """Each took minutes with a list lookup (10k joints 3.5 s, 100k styles over 120 s); a process
    of its own gives the whole case 120 s."""
    code = f"""
import numpy as np
from minifilm.motion.bvh import parse_bvh, BVHError
from minifilm.runtime.style_library import StyleLibrary, StyleLibraryError
from minifilm.files import atomic_savez
import sys
sys.path[:0] = [{str(os.path.dirname(__file__))!r}, {str(os.path.dirname(os.path.dirname(__file__)))!r}]  # its folder and tests/
from test_names_and_outputs import header
m = parse_bvh(header(100_000) + "MOTION\\nFrames: 1\\nFrame Time: 0.01\\n0 0 0\\n", source="wide.bvh")
assert m.n_joints >= 100_000
names = np.array([f"s{{i}}" for i in range(100_000)])
atomic_savez({str(tmp_path / 'lib.npz')!r}, {{"names": names, "films": np.zeros((100_000, 4), np.float32)}})
assert len(StyleLibrary.load({str(tmp_path / 'lib.npz')!r})) == 100_000
names[-1] = "s0"
atomic_savez({str(tmp_path / 'lib.npz')!r}, {{"names": names, "films": np.zeros((100_000, 4), np.float32)}})
try:
    StyleLibrary.load({str(tmp_path / 'lib.npz')!r})
    raise SystemExit("duplicates were not found")
except StyleLibraryError as e:
    assert "'s0'" in str(e)
print("ok")
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.strip() == "ok", r.stderr[-800:]


# ---- 7. messages -------------------------------------------------------------------------------
def test_deeply_nested_json_is_one_line(run, capsys):
    (run / "run.json").write_text("[" * 50_000 + "]" * 50_000)
    one_error(["generate", "--run", run, "--list-styles"], capsys, "run.json", "nested too deeply")


def test_a_boolean_frame_rate_is_not_one_frame_per_second(run, capsys):
    import json
    meta = json.loads((run / "run.json").read_text())
    meta["fps"] = True
    (run / "run.json").write_text(json.dumps(meta))
    one_error(["generate", "--run", run, "--list-styles"], capsys, "run.json", "fps True")


def test_a_huge_csv_field_is_one_line(run, tmp_path, capsys):
    manifest = tmp_path / "data.csv"
    manifest.write_text(f"file,style,gait\n{run / 'data' / 'Neutral_FW.bvh'},{'N' * 200_000},FW\n")
    one_error(["train", "--data", manifest, "--out", tmp_path / "out", "--quick"], capsys, "data.csv", "line")


def test_a_fifo_in_a_manifest_is_named_as_one(run, tmp_path, capsys):
    os.mkfifo(tmp_path / "pipe.bvh")
    manifest = tmp_path / "data.csv"
    manifest.write_text(f"file,style,gait\n{tmp_path / 'pipe.bvh'},Neutral,FW\n")
    one_error(["train", "--data", manifest, "--out", tmp_path / "out", "--quick"], capsys, "pipe.bvh", "FIFO")


def test_a_file_given_as_a_data_folder_says_so(run, tmp_path, capsys):
    one_error(["train", "--data", run / "run.json", "--out", tmp_path / "out", "--quick"], capsys,
              "run.json", "is a file, not a folder")


@pytest.mark.parametrize("change,expect", [
    (lambda t: t.replace("Frames: ", "Frames: " + "9" * 5000, 1), "Frames"),
    (lambda t: t.replace("Frames: ", "Frames: \u0661\u0662", 1), "Frames"),
    (lambda t: _first_value(t, "1_0"), "1_0"),
    (lambda t: _first_value(t, "\u0661\u0662"), "\u0661"),
    (lambda t: t.replace("OFFSET 0", "OFFSET 1_0", 1) if "OFFSET 0" in t else t.replace("OFFSET", "OFFSET 1_0", 1),
     "1_0"),
])
def test_numbers_in_a_bvh_are_ascii_decimals(run, tmp_path, capsys, change, expect):
    bad = tmp_path / "bad.bvh"
    bad.write_text(change((run / "data" / "Neutral_FW.bvh").read_text()), encoding="utf-8")
    line = one_error(["phases", bad, "--out", tmp_path / "p.png"], capsys, "bad.bvh", "line")
    assert expect in line or repr(expect)[1:-1] in line
    assert not (tmp_path / "p.png").exists()


def _first_value(text: str, value: str) -> str:
    head, frames = text.split("Frame Time:", 1)
    time_line, data = frames.split("\n", 1)
    first, rest = data.split("\n", 1)
    return head + "Frame Time:" + time_line + "\n" + " ".join([value] + first.split()[1:]) + "\n" + rest


def test_train_never_replaces_a_folder_of_other_files(tmp_path, capsys):
    home = tmp_path / "project"
    home.mkdir()
    (home / "notes.txt").write_text("mine")
    one_error(["train", "--quick", "--out", home], capsys, "notes.txt", "new or empty folder")
    assert sorted(p.name for p in home.iterdir()) == ["notes.txt"]


def test_a_deeply_nested_checkpoint_configuration_is_one_line(run, capsys):
    with np.load(run / "model.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["meta.json"] = np.array("[" * 50_000 + "]" * 50_000)
    atomic_savez(run / "model.npz", arrays)
    one_error(["generate", "--run", run, "--seconds", "1", "--out", run.parent / "o.bvh"], capsys,
              "model.npz", "nested too deeply")
