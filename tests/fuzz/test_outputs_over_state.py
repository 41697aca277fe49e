"""No output of any option replaces what a run, a made data set or a cache holds, and every
output's format is checked: the family through the command as a user runs it.

The writing options are not listed here: they are found in the commands' own parsers (an
argument type carrying ``output``, minifilm/cli/args.py), so a new option is covered the day it is
added, and a path option that is not marked either way fails :func:`test_every_path_option_is_marked`.
Each case exits 2 with one ``error:`` line and leaves the run folder byte for byte as it was."""
import importlib
import os
import pathlib
import shutil

import pytest

from minifilm import cli
from minifilm.dataset.manifest import MADE_BY, MotionFile, write_manifest
from in_process import minifilm_here
from test_names_and_outputs import one_error, tree

#: options that read a path (plain pathlib.Path type) rather than write one
PATH_READERS = {("finetune", "--run")}
#: option names that say an option writes
WRITER_WORDS = {"out", "gif", "html", "png", "mp4", "record", "animation", "markdown", "cache", "work"}


def parsers():
    """command -> its argparse parser, as ``minifilm COMMAND`` builds it."""
    out = {}
    for name, (module_name, _, _) in cli.COMMANDS.items():
        try:
            module = importlib.import_module(module_name)
        except ImportError as e:           # an optional extra missing: said, not hidden
            pytest.skip(f"{name}: {e}")
        parser = cli.Parser(prog=f"minifilm {name}")
        module.add_arguments(parser)
        out[name] = parser
    return out


def writer_options():
    """(command, flag, "file" or "folder", suffixes) of every writing option of every command."""
    found = []
    for name, parser in parsers().items():
        for action in parser._actions:
            kind = getattr(action.type, "output", None)
            if kind and action.option_strings:
                found.append((name, action.option_strings[0], kind, getattr(action.type, "suffixes", ())))
    return found


WRITERS = writer_options()
FILE_WRITERS = [w for w in WRITERS if w[2] == "file"]
FOLDER_WRITERS = [w for w in WRITERS if w[2] == "folder"]


def test_every_path_option_is_marked():
    """A path option is an input (recorded as one), a marked output, or a listed reader; an option
    named like an output is a marked output. So no writer escapes the families below."""
    for name, parser in parsers().items():
        for action in parser._actions:
            flag = action.option_strings[0] if action.option_strings else action.dest
            if action.type is pathlib.Path:
                assert (name, flag) in PATH_READERS, f"minifilm {name} {flag}: an unchecked path (type=Path)"
            if action.dest in WRITER_WORDS:
                assert getattr(action.type, "output", None), f"minifilm {name} {flag}: writes, but is not marked"
    assert len(FILE_WRITERS) >= 12 and len(FOLDER_WRITERS) >= 6, (FILE_WRITERS, FOLDER_WRITERS)


@pytest.fixture(autouse=True)
def in_a_temporary_folder(tmp_path, monkeypatch):
    """A command that wrongly succeeds writes its default outputs (motion.bvh, phases.png) into the
    working folder: let that be a temporary one, never the checkout."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="module")
def state(tiny_run, tmp_path_factory):
    """A run folder (whole, with data/, cache/, generated/), a data set folder made by minifilm,
    and the invocation of each command that the writing option is added to."""
    root = tmp_path_factory.mktemp("state")
    run = root / "run"
    shutil.copytree(tiny_run, run)
    data = root / "made"
    data.mkdir()
    shutil.copy(run / "data" / "Neutral_FW.bvh", data / "Old Man_FW.bvh")
    write_manifest([MotionFile(data / "Old Man_FW.bvh", "Old Man", "FW")], data / "manifest.csv")
    (data / "dataset.json").write_text(f'{{"made_by": "{MADE_BY}", "files": [{{"file": "Old Man_FW.bvh"}}]}}')
    clip = root / "clip.bvh"
    shutil.copy(run / "data" / "LeftHop_FW.bvh", clip)
    base = {"generate": ["generate", "--run", run, "--seconds", "0.5"], "view": ["view", clip],
            "phases": ["phases", clip], "demo": ["demo", "--run", run, "--record-seconds", "1"],
            "table2": ["table2", "--no-timing"], "train": ["train", "--quick"], "dataset": ["dataset", run / "data"],
            "compare": ["compare"], "retarget": ["retarget", clip, "--to", "cmu"],
            "finetune": ["finetune", "--run", run, "--name", "New", clip]}
    return run, data, base


def targets_for(suffixes, run, data, root):
    """(label, path) of the state files and state folders an output with ``suffixes`` could name."""
    out = []
    for suffix in suffixes:
        existing = [p for p in sorted(run.rglob("*")) if p.is_file() and p.suffix.lower() == suffix]
        out += [(f"existing {p.relative_to(run)}", p) for p in existing]
        out += [(f"new file in {d}/", run / d / f"new{suffix}") for d in ("data", "cache", "generated")]
        out += [(f"case variant {d}/", run / d.upper() / f"new{suffix}") for d in ("generated",)]
        out += [(f"case variant {p.name}", p.with_name(p.name.upper())) for p in existing if p.parent == run]
        if existing:
            link = root / f"link-to-{existing[0].name}"
            if not os.path.lexists(link):
                link.symlink_to(existing[0])
            out.append((f"link to {existing[0].relative_to(run)}", link))
        if suffix == ".bvh":
            out += [("a made data set's file", data / "Old Man_FW.bvh"), ("new file in a made data set", data / "n.bvh")]
    return out


def file_cases():
    cases = []
    for command, flag, _, suffixes in FILE_WRITERS:
        for label in ["state"] + [f"foreign {n}" for n in ("styles.npz", "starts.npz", "model.npz", "run.json")]:
            cases.append(pytest.param(command, flag, suffixes, label, id=f"{command} {flag} {label}"))
    return cases


@pytest.mark.parametrize("command,flag,suffixes,label", file_cases())
def test_no_file_output_replaces_state(state, command, flag, suffixes, label, capsys):
    run, data, base = state
    assert command in base, f"minifilm {command} writes {flag}: give it an invocation in state()"
    if label == "state":
        targets = targets_for(suffixes, run, data, run.parent)
    else:                                  # the cases: --gif R/starts.npz, --html R/styles.npz, ...
        targets = [(label, run / label.split()[1])]
    assert targets
    before, made = tree(run), tree(data)
    for what, target in targets:
        line = one_error(base[command] + [flag, target], capsys)
        assert target.name in line, (what, line)
        assert ("run folder" in line or "data set" in line or "also an input" in line
                or "is written here" in line or "extension" in line), (what, line)
        assert tree(run) == before and tree(data) == made, what


@pytest.mark.parametrize("command,flag", [pytest.param(c, f, id=f"{c} {f}") for c, f, _, _ in FOLDER_WRITERS])
@pytest.mark.parametrize("inside", ["data", "cache", "generated", "Generated", "generated/deeper"])
def test_no_folder_output_writes_into_state(state, command, flag, inside, capsys):
    run, _, base = state
    assert command in base, f"minifilm {command} writes {flag}: give it an invocation in state()"
    before = tree(run)
    line = one_error(base[command] + [flag, run / inside], capsys, "run folder")
    assert inside.split("/")[0] in line
    assert tree(run) == before


WRONG = (".png", ".gif", ".bvh", ".html", ".mp4", ".md", ".npz", ".json", ".txt", ".jpeg")


@pytest.mark.parametrize("command,flag,suffixes", [pytest.param(c, f, s, id=f"{c} {f}") for c, f, _, s in FILE_WRITERS])
def test_an_output_of_another_format_is_refused_when_parsed(state, command, flag, suffixes, tmp_path, capsys):
    _, _, base = state
    for suffix in WRONG:
        if suffix in suffixes:
            continue
        target = tmp_path / f"x{suffix}"
        line = one_error(base[command] + [flag, target], capsys, flag, suffix, suffixes[0])
        assert "is written here" in line or "extension" in line, line
        assert not target.exists()


def test_the_owners_still_write_their_state(state, tmp_path, capsys):
    """finetune adds a style to the run's styles.npz and starts.npz; the data set builder writes
    its cache into a cache folder; train replaces a run folder whole."""
    run, _, _ = state
    mine = tmp_path / "run"
    shutil.copytree(run, mine)
    code, out = minifilm_here(["finetune", "--run", mine, "--name", "Proud", "--steps", "2", mine / "data" / "Neutral_FW.bvh"],
                       capsys)
    assert code == 0, out.err[-800:]
    assert (mine / "model-Proud.npz").is_file()
    code, out = minifilm_here(["generate", "--run", mine, "--list-styles"], capsys)
    assert code == 0 and "Proud" in out.out.split(), out.err[-500:]
    code, out = minifilm_here(["dataset", mine / "data", "--cache", tmp_path / "cache", "--clip-seconds", "1"], capsys)
    assert code == 0 and list((tmp_path / "cache").glob("dataset-*.npz")), out.err[-500:]

