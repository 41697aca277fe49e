"""Two inputs never share one output: names are compared after they are made safe for a file
system (minifilm/files/names.py), case-folded and NFC-normalised as macOS and Windows compare
them, in every command that names files after inputs or styles (retarget, finetune's
checkpoints, dataset --from-released, the demo's recordings).

The pure family draws thousands of lists of hostile names (unsafe punctuation, reserved device
names in any case, dots and spaces at the ends, scripts whose case folding changes length,
combining characters); the command families put such pairs through the command."""
import json
import random
import shutil
import unicodedata

import pytest

from minifilm.dataset.manifest import MADE_BY, MotionFile, scan_folder, write_manifest
from minifilm.files import file_name, file_names, same_file_key, shared_file_names
from minifilm.files.names import _UNSAFE, _WINDOWS_RESERVED
from minifilm.pipeline.from_released import previous_output, style_file_names
from in_process import minifilm_here
from test_names_and_outputs import one_error, tree

PIECES = ["a", "b", "A", "B", "_", ":", "?", "*", "<", ">", "|", '"', " ", ".", "-", "+", "é", "e\u0301", "ß", "SS",
          "İ", "i", "Σ", "ς", "σ", "ﬀ", "ff", "Ａ", "日本", "CON", "con", "Nul", "com1", "LPT9", "aux.txt", "prn.", "x."]
N_LISTS = 3000


def hostile_names(rng: random.Random, n: int):
    names = []
    for _ in range(n):
        name = "".join(rng.choice(PIECES) for _ in range(rng.randint(1, 4)))
        names.append(name)
    return names


def is_safe_file_name(made: str) -> bool:
    return (bool(made) and not _UNSAFE.search(made) and made[0] not in ". " and made.rstrip(" .") == made
            and made.split(".")[0].upper() not in _WINDOWS_RESERVED)


def test_file_names_are_safe_and_distinct_on_every_disk():
    rng = random.Random(0)
    tried = 0
    for _ in range(N_LISTS):
        names = hostile_names(rng, rng.randint(2, 6))
        made = file_names(names)
        assert set(made) == set(names)
        keys = [same_file_key(made[n]) for n in dict.fromkeys(names)]
        assert len(set(keys)) == len(keys), (names, made)
        for n in names:
            assert is_safe_file_name(file_name(n)), (n, file_name(n))
            # a numbered name is its safe name with -k; a safe name keeps itself when no earlier
            # safe name takes it
            assert made[n] == file_name(n) or made[n].startswith(file_name(n) + "-"), (n, made[n])
        tried += 1
    assert tried == N_LISTS


def test_shared_file_names_finds_exactly_the_collisions():
    rng = random.Random(1)
    for _ in range(N_LISTS):
        names = hostile_names(rng, rng.randint(2, 6))
        groups = shared_file_names(names)
        by_key = {}
        for n in names:
            by_key.setdefault(same_file_key(file_name(n)), []).append(n)
        expected = sorted(sorted(g) for g in by_key.values() if len(g) > 1)
        assert sorted(sorted(g) for _, g in groups) == expected, names
        for made, group in groups:
            assert all(same_file_key(file_name(n)) == same_file_key(made) for n in group)


# ---- retarget -----------------------------------------------------------------------------------
PAIRS = [("a:b", "a_b"), ("a?b", "a*b"), ("a:b", "a?b"), ("Neutral", "neutral"), ("caf\u00e9", "cafe\u0301"),
         ("CON", "_CON"), ("x.", "x_"), ("stra\u00dfe", "STRASSE"), ("Old Man", "OLD MAN"), ("a|b", "A_B")]


@pytest.mark.parametrize("first,second", PAIRS)
def test_retarget_refuses_two_sources_meeting_in_one_output(tiny_run, tmp_path, capsys, first, second):
    sources = tmp_path / "in"
    sources.mkdir()
    for i, name in enumerate((first, second)):
        folder = sources / str(i)            # own folders: on this disk they may be one name
        folder.mkdir()
        shutil.copy(tiny_run / "data" / "Neutral_FW.bvh", folder / f"{name}.bvh")
    files = [sources / "0" / f"{first}.bvh", sources / "1" / f"{second}.bvh"]
    out = tmp_path / "out"
    line = one_error(["retarget", *files, "--to", "100style", "--out", out], capsys, "would all be written to",
                     str(out))
    assert f"{file_name(first)}.bvh" in line or f"{file_name(second)}.bvh" in line, line
    assert not out.exists()


# ---- finetune's checkpoints -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def taught(tiny_run, tmp_path_factory):
    """A run that has learnt the style 'A:B' (checkpoint model-A_B.npz)."""
    run = tmp_path_factory.mktemp("taught") / "run"
    shutil.copytree(tiny_run, run)
    from minifilm.pipeline.new_style import teach_style
    teach_style(run, "A:B", [run / "data" / "Neutral_FW.bvh"], steps=2, log=lambda m: None)
    return run


@pytest.mark.parametrize("name", ["A_B", "A?B", "a:b", "a_b", "A*B", "neutral", "LEFTHOP", "lefthop"])
def test_finetune_refuses_a_name_whose_checkpoint_is_another_style_s(taught, tmp_path, capsys, name):
    run = tmp_path / "run"
    shutil.copytree(taught, run)
    before = tree(run)
    line = one_error(["finetune", "--run", run, "--name", name, "--steps", "2", run / "data" / "Neutral_FW.bvh"],
                     capsys, "--name", "would be the file of the style")
    assert tree(run) == before, line


def test_finetune_replaces_its_own_style_and_keeps_the_run_whole(taught, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(taught, run)
    code, out = minifilm_here(["finetune", "--run", run, "--name", "A:B", "--replace", "--steps", "2",
                        run / "data" / "Neutral_FW.bvh"], capsys)
    assert code == 0, out.err[-600:]
    code, out = minifilm_here(["generate", "--run", run, "--list-styles"], capsys)
    assert code == 0 and "A:B" in out.out.split(), out


# ---- dataset --from-released ------------------------------------------------------------------------
ODD_STYLES = ["Old_Man", "A*B?", "A_B_", "neutral_", "Neutral_", "Old Man", "a:b", "a_b", "\u00dcn\u00ef"]


def test_a_made_data_set_is_read_back_with_every_style(tiny_run, tmp_path):
    """The files of styles whose names are not <Style>_<Gait> material: each its own file, and the
    folder read by its manifest gives every style back under its true name."""
    stems = style_file_names(ODD_STYLES)
    assert len({same_file_key(s) for s in stems.values()}) == len(ODD_STYLES)
    assert stems["A_B_"] == "A_B_" and stems["a_b"] == "a_b"          # a safe name keeps itself
    folder = tmp_path / "made"
    folder.mkdir()
    files = []
    for style in ODD_STYLES:
        path = folder / f"{stems[style]}_FW.bvh"
        shutil.copy(tiny_run / "data" / "Neutral_FW.bvh", path)
        files.append(MotionFile(path, style, "FW"))
    write_manifest(files, folder / "manifest.csv")
    (folder / "dataset.json").write_text(json.dumps({"made_by": MADE_BY, "files": [
        {"file": f.path.name, "style": f.style} for f in files]}))
    assert sorted(f.style for f in scan_folder(folder)) == sorted(ODD_STYLES)
    assert previous_output(folder) == {f.path.name for f in files} | {"manifest.csv", "dataset.json"}
    (folder / "dataset.json").write_text(json.dumps({"made_by": "somebody", "files": []}))
    assert previous_output(folder) == set()


@pytest.mark.parametrize("seconds", ["1e-9", "0.1", "0.49"])
def test_seconds_per_style_too_short_for_train_is_refused_up_front(shared_data, tmp_path, capsys, seconds):
    one_error(["dataset", "--from-released", shared_data / "released-lpn", "--out", tmp_path / "d",
               "--seconds-per-style", seconds], capsys, "--seconds-per-style", "at least 0.5 s")
    assert not (tmp_path / "d").exists()


def test_the_demo_s_recording_is_named_by_the_one_rule():
    from minifilm.demo.record import _file_name
    for title in ["Neutral + 0.5 Old", "../../x", "CON", "a:b?c", "", "   "]:
        made = _file_name(title)
        assert is_safe_file_name(made) and "/" not in made, (title, made)
    assert unicodedata.normalize("NFC", _file_name("caf\u00e9")) == "caf\u00e9"
