"""The documentation is executable: nothing in README.md or docs/ may rot.

* docs/features.md is exactly what scripts/gen_features_doc.py generates from the code's layout;
* every ```python snippet runs (in order, per file, sharing one namespace, in a scratch folder
  beside which ``../shared/data`` points at the real data). A snippet whose first line is
  ``# needs: shared data`` is skipped when that data is absent (the test fails instead in CI,
  repo_paths.need_data), and nothing after it may depend on it (it runs in a copy of the
  namespace);
* every shell command line (```bash blocks and inline `python ...` spans) names a script or
  module that exists and only options that script defines, and ``pip install -e ".[extra]"``
  names extras that setup.cfg defines (the commands themselves are run by CI: .ci/run and
  tests/pipeline/test_train_small.py);
* every reference ``path`` or ``path::name`` to the code (functions, classes, methods, tests)
  points at a file that exists and a name defined in it, and every relative Markdown link or
  image points at a file that exists (images under 200 KB);
* the README's first screen (60 lines) holds the set-up commands, the paper's sizes, the two
  pictures and a snippet of at most 15 lines, and that snippet, run as written, prints the output
  shown under it (numbers to one unit of their last digit).
"""
from __future__ import annotations

import ast
import configparser
import importlib.util
import os
import re
import shlex
from functools import lru_cache
from pathlib import Path

import pytest

from python_names import defined_names
from repo_paths import IN_CI, REPO_ROOT, SHARED_DATA, missing_data, need_data

DOCS = [REPO_ROOT / "README.md"] + sorted((REPO_ROOT / "docs").glob("*.md"))
NEEDS_DATA = "# needs: shared data"


def _rel(p: Path) -> str:
    return str(p.relative_to(REPO_ROOT))


# ---------------------------------------------------------------------------- markdown parsing
FENCE = re.compile(r"^```(\w*)[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)


def fenced_blocks(path: Path, lang: str):
    """[(line number, code)] of the fenced blocks of one language."""
    text = path.read_text(encoding="utf-8")
    return [(text.count("\n", 0, m.start()) + 1, m.group(2))
            for m in FENCE.finditer(text) if m.group(1) == lang]


def shell_commands(path: Path):
    """[(line, command)]: lines of ```bash blocks (continuations joined) and inline `python ...`
    / `pip ...` code spans."""
    out = []
    for line, code in fenced_blocks(path, "bash"):
        joined = re.sub(r"\\\n\s*", " ", code)
        for i, cmd in enumerate(joined.splitlines()):
            cmd = cmd.split(" #")[0].strip()
            if cmd and not cmd.startswith("#"):
                out.append((line + 1 + i, cmd))
    text = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), path.read_text(encoding="utf-8"))
    for m in re.finditer(r"`((?:python|pip|minifilm) [^`]+)`", text):
        out.append((text.count("\n", 0, m.start()) + 1, m.group(1)))
    return out


# ---------------------------------------------------------------------------- 1. features.md
def test_features_doc_is_generated_from_the_layout():
    spec = importlib.util.spec_from_file_location("gen_features_doc", REPO_ROOT / "scripts" / "gen_features_doc.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    committed = (REPO_ROOT / "docs" / "features.md").read_text(encoding="utf-8")
    assert committed == gen.render(), \
        "docs/features.md differs from the layout: run python scripts/gen_features_doc.py"


def test_features_doc_covers_every_column_once():
    """Independent of the generator's grouping: the index ranges of each table tile 0..size-1."""
    text = (REPO_ROOT / "docs" / "features.md").read_text(encoding="utf-8")
    sizes = {"x": 348, "p": 8, "z": 342, "y": 300}
    for section in re.split(r"^## ", text, flags=re.M)[1:]:
        key = section.split(" ", 1)[0]
        if key not in sizes:
            continue
        covered = []
        for a, b in re.findall(r"^\| (\d+)(?:–(\d+))? \|", section, flags=re.M):
            covered.extend(range(int(a), int(b or a) + 1))
        assert covered == list(range(sizes[key])), f"features.md section {key!r}"


# ---------------------------------------------------------------------------- 2. python snippets
def _run_snippets(path: Path, workdir: Path):
    ns = {"__name__": "__docs__"}
    ran = skipped = 0
    for line, code in fenced_blocks(path, "python"):
        needs_data = code.lstrip().startswith(NEEDS_DATA)
        if needs_data and not SHARED_DATA.is_dir():
            skipped += 1
            continue
        where = f"{_rel(path)}, python snippet at line {line}"
        try:
            exec(compile(code, where, "exec"), dict(ns) if needs_data else ns)
        except Exception as e:  # name the snippet, keep the traceback
            raise AssertionError(f"{where} failed: {type(e).__name__}: {e}") from e
        ran += 1
    return ran, skipped


@pytest.mark.parametrize("path", [p for p in DOCS if fenced_blocks(p, "python")], ids=_rel)
def test_python_snippets_run(path, tmp_path, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    if SHARED_DATA.is_dir():                       # ../shared/data from the scratch folder
        (tmp_path / "shared").mkdir()
        os.symlink(SHARED_DATA, tmp_path / "shared" / "data")
    monkeypatch.chdir(work)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    ran, skipped = _run_snippets(path, work)
    assert ran + skipped > 0
    if skipped:   # everything else ran and passed; say what could not run
        missing_data(SHARED_DATA, f"{_rel(path)}: {ran} snippet(s) ran and passed; {skipped} need the real data, which was")


# ---------------------------------------------------------------------------- 3. shell commands
@lru_cache(maxsize=None)
def script_options(path: Path) -> frozenset:
    """Every '--option' string literal of a script (argparse definitions)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return frozenset(n.value for n in ast.walk(tree)
                     if isinstance(n, ast.Constant) and isinstance(n.value, str)
                     and re.fullmatch(r"--[\w-]+", n.value))


def dispatched_options(source: Path) -> frozenset:
    """Options of the `minifilm` subcommands a script hands its arguments to
    (``main(["train"] + sys.argv[1:])``) or whose options it takes (``from minifilm.cli import train
    as options``, or ``from minifilm.cli.train import add_arguments`` as examples/train_small.py)."""
    out = set()
    text = source.read_text(encoding="utf-8")
    names = (re.findall(r"main\(\[[\"'](\w+)[\"']\]", text) + re.findall(r"from minifilm\.cli import (\w+) as \w+", text)
             + re.findall(r"from minifilm\.cli\.(\w+) import [^\n]*\badd_arguments\b", text))
    for name in names:
        out |= command_options(name) or set()
    return frozenset(out)


@lru_cache(maxsize=None)
def command_options(name: str):
    """The options of ``minifilm NAME`` (those its module's ``add_arguments`` defines, shared
    helpers included), None if no such subcommand."""
    import argparse
    import importlib
    from minifilm.cli import COMMANDS
    if name not in COMMANDS:
        return None
    parser = argparse.ArgumentParser()
    importlib.import_module(COMMANDS[name][0]).add_arguments(parser)
    return frozenset(s for s in parser._option_string_actions if s.startswith("--"))


def check_minifilm_command(words) -> str | None:
    """None if `minifilm SUBCOMMAND ...` names a subcommand and only options it defines."""
    if len(words) < 2 or words[1] in ("-h", "--help"):
        return None
    known = command_options(words[1])
    if known is None:
        return f"minifilm has no subcommand {words[1]!r}"
    bad = [a.split("=")[0] for a in words[2:] if a.startswith("--") and a.split("=")[0] not in known | {"--help"}]
    return f"minifilm {words[1]} has no option(s) {bad}" if bad else None


def setup_extras() -> set:
    cfg = configparser.ConfigParser()
    cfg.read(REPO_ROOT / "setup.cfg")
    return set(cfg["options.extras_require"]) if cfg.has_section("options.extras_require") else set()


def check_python_command(words) -> str | None:
    """None if `python ...` refers to things that exist, else what is wrong."""
    if len(words) >= 3 and words[1] == "-m":
        module, args = words[2], words[3:]
        spec = importlib.util.find_spec(module.split(".")[0])
        if spec is None:
            return f"module {module} not found"
        if module.startswith("minifilm"):
            spec = importlib.util.find_spec(module)
            if spec is None or spec.origin is None:
                return f"module {module} not found"
            source = Path(spec.origin)
        else:
            return None
    elif len(words) >= 2 and words[1].endswith(".py"):
        source, args = REPO_ROOT / words[1], words[2:]
        if not source.is_file():
            return f"script {words[1]} does not exist"
        try:
            compile(source.read_text(encoding="utf-8"), str(source), "exec")
        except SyntaxError as e:
            return f"script {words[1]} does not compile: {e}"
    else:
        return None
    known = script_options(source) | dispatched_options(source)
    bad = [a.split("=")[0] for a in args if a.startswith("--") and a.split("=")[0] not in known | {"--help"}]
    return f"{_rel(source)} has no option(s) {bad}" if bad else None


def check_command(cmd: str) -> list:
    problems = []
    for part in re.split(r"&&|;|\|", cmd):
        try:
            words = shlex.split(part)
        except ValueError as e:
            return [f"cannot parse: {e}"]
        if not words:
            continue
        if words[0] in ("python", "minifilm"):
            msg = check_python_command(words) if words[0] == "python" else check_minifilm_command(words)
            if msg:
                problems.append(msg)
        elif words[0] == "pip" and "-e" in words:
            target = words[words.index("-e") + 1]
            extras = re.findall(r"\[([\w,]+)\]", target)
            for extra in (extras[0].split(",") if extras else []):
                if extra not in setup_extras():
                    problems.append(f"setup.cfg defines no extra [{extra}]")
    return problems


def test_shell_commands_name_existing_scripts_and_options():
    problems, n = [], 0
    for path in DOCS:
        for line, cmd in shell_commands(path):
            n += 1
            problems += [f"{_rel(path)}:{line}: `{cmd}`: {p}" for p in check_command(cmd)]
    assert n > 0
    assert not problems, "\n".join(problems)


def test_the_command_checker_can_fail():
    assert check_command("python examples/train_small.py --quick") == []
    assert check_command("python examples/train_small.py --no-such-option")
    assert check_command("python examples/no_such_script.py")
    assert check_command('pip install -e ".[nonexistent]"')
    assert check_command("python -m minifilm.no_such_module --help")
    assert check_command("minifilm table2 --no-such-option")
    assert check_command("minifilm tabel2")
    assert check_command("minifilm table2 --no-timing") == []


# ---------------------------------------------------------------------------- 4. code references
REF = re.compile(r"`((?:minifilm|examples|benchmarks|studies|reports|scripts|tests|docs)/[\w/.-]+\.(?:py|md|png|csv))"
                 r"(?:::([\w.]+))?`")


def test_code_references_exist():
    problems, n = [], 0
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for m in REF.finditer(text):
            n += 1
            file, name = REPO_ROOT / m.group(1), m.group(2)
            line = text.count("\n", 0, m.start()) + 1
            if not file.exists():
                problems.append(f"{_rel(path)}:{line}: {m.group(1)} does not exist")
            elif name and name not in defined_names(file):
                problems.append(f"{_rel(path)}:{line}: {m.group(1)} defines no {name}")
    assert n > 0
    assert not problems, "\n".join(problems)


LINK = re.compile(r"\]\(([^)\s#]+)(?:#[^)]*)?\)")
#: largest size of a picture the docs show, bytes: a still, an animation (the repository stays small)
LIMITS = {".png": 200_000, ".gif": 1_500_000}


def test_relative_links_and_images_exist():
    problems, n = [], 0
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for m in LINK.finditer(text):
            target = m.group(1)
            if re.match(r"\w+:", target):          # http:, https:, mailto:
                continue
            n += 1
            file = (path.parent / target).resolve()
            line = text.count("\n", 0, m.start()) + 1
            if not file.is_file():
                problems.append(f"{_rel(path)}:{line}: link to {target}, which does not exist")
            elif file.suffix in LIMITS and file.stat().st_size > LIMITS[file.suffix]:
                problems.append(f"{_rel(path)}:{line}: {target} is over {LIMITS[file.suffix] // 1000} KB")
    assert n > 0
    assert not problems, "\n".join(problems)


# ---------------------------------------------------------------------------- 5. README examples
def test_readme_example_commands_run_in_miniature(tmp_path):
    """The commands and example scripts the README tells a newcomer to run, on tiny inputs (one
    process each, in parallel): make_synthetic -> minifilm phases / dataset and the phase and
    dataset walk-throughs; minifilm generate and generate_released.py if the released network is
    there. The main job is run by tests/pipeline/test_train_small.py, pytest by CI."""
    import subprocess
    import sys

    env = dict(os.environ, MPLBACKEND="Agg")
    py = [sys.executable]
    mf = py + ["-m", "minifilm"]
    syn = tmp_path / "syn"
    subprocess.run(py + ["examples/make_synthetic.py", str(syn), "--seconds", "3", "--styles",
                         "Limp", "--gaits", "FW"], cwd=REPO_ROOT, env=env, check=True,
                   capture_output=True, timeout=120)
    jobs = {"minifilm dataset": mf + ["dataset", str(syn), "--no-cache", "--clip-seconds", "1"],
            "build_dataset.py": py + ["examples/build_dataset.py", str(syn), "--cache", str(tmp_path / "cache"),
                                      "--clip-seconds", "1"]}
    if importlib.util.find_spec("matplotlib") is not None:      # the [viz] / [dev] extra
        jobs["minifilm phases"] = mf + ["phases", str(syn / "Limp_FW.bvh"), "--out", str(tmp_path / "phases.png")]
        jobs["plot_phases.py"] = py + ["examples/plot_phases.py", str(syn / "Limp_FW.bvh"), "--out",
                                       str(tmp_path / "phases2.png")]
    if not (SHARED_DATA / "released-lpn").is_dir() and IN_CI:    # a user's machine: run the rest
        missing_data(SHARED_DATA / "released-lpn", "the released network (for the README's generate commands)")
    if (SHARED_DATA / "released-lpn").is_dir():
        jobs["minifilm generate"] = mf + [
            "generate", "--params", str(SHARED_DATA / "released-lpn"), "--style", "Zombie", "--script", "figure8",
            "--seconds", "0.5", "--no-calibrate", "--out", str(tmp_path / "zombie.bvh")]
        jobs["generate_released.py"] = py + [
            "examples/generate_released.py", "--params", str(SHARED_DATA / "released-lpn"), "--style", "Old",
            "--seconds", "0.5", "--out", str(tmp_path / "old.bvh")]
    procs = {k: subprocess.Popen(cmd, cwd=REPO_ROOT, env=env, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True) for k, cmd in jobs.items()}
    failed = []
    for name, p in procs.items():
        out, err = p.communicate(timeout=300)
        if p.returncode != 0:
            failed.append(f"{name} exited {p.returncode}:\n{err[-2000:]}")
    assert not failed, "\n".join(failed)
    if "minifilm phases" in jobs:
        assert (tmp_path / "phases.png").stat().st_size > 0 and (tmp_path / "phases2.png").stat().st_size > 0
    if "minifilm generate" in jobs:
        from minifilm.motion.bvh import read_bvh
        assert read_bvh(tmp_path / "zombie.bvh").n_frames == 30
        assert read_bvh(tmp_path / "old.bvh").n_frames == 30


# ---------------------------------------------------------------------------- 6. the README's first screen
FIRST_SCREEN = 60        # lines a reader sees before scrolling
SNIPPET_LINES = 15
FIRST_SCREEN_HOLDS = ['pip install -e ".[viz]" && python examples/train_small.py',
                      'pip install -e ".[dev]" && python -m pytest -q',
                      "mpiexec -n 2 python examples/train_small.py", "4,935,928", "39,214,592", "707,420",
                      "docs/img/model_shapes.png", "docs/img/phase_pipeline_bandai_walk.png"]
NUMBER = re.compile(r"\d+(?:\.\d+)?")


def readme_snippet():
    """(line, code, shown output) of the README's first ```python block and the ```text block
    that follows it directly: the snippet a reader pastes and what it printed."""
    text = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    blocks = list(FENCE.finditer(text))
    i = next(i for i, m in enumerate(blocks) if m.group(1) == "python")
    code, shown = blocks[i], blocks[i + 1] if i + 1 < len(blocks) else None
    assert shown is not None and shown.group(1) == "text" and not text[code.end():shown.start()].strip(), \
        "README.md: the first python snippet must be followed directly by a ```text block of its output"
    return text.count("\n", 0, code.start()) + 1, code.group(2), shown.group(2)


def same_output(printed: str, shown: str) -> list:
    """What differs between printed and shown lines: the words and whole numbers exactly, every
    decimal number to one unit of its last digit shown. Why that tolerance: the rollout's float32 sums come out about 1e-8 apart
    between BLAS kernels and thread counts (measured: Haswell, SkylakeX and Zen kernels, 1 and 2
    threads), yet a value next to a rounding boundary can still round the other way on another CPU."""
    a, b = printed.strip().splitlines(), shown.strip().splitlines()
    if len(a) != len(b):
        return [f"{len(a)} lines printed, {len(b)} shown"]
    problems = []
    for got, want in zip(a, b):
        if NUMBER.sub("#", got) != NUMBER.sub("#", want):
            problems.append(f"printed {got!r}, shown {want!r}")
            continue
        for g, w in zip(NUMBER.findall(got), NUMBER.findall(want)):
            decimals = len(w.partition(".")[2])
            unit = 10.0 ** -decimals if decimals else 0.0       # a count (frames) is exact
            if abs(float(g) - float(w)) > unit * 1.001:
                problems.append(f"printed {g} where the README shows {w} (tolerance {unit:g}) in {want!r}")
    return problems


def test_the_first_screen_says_what_a_newcomer_needs():
    head = "\n".join((REPO_ROOT / "README.md").read_text(encoding="utf-8").splitlines()[:FIRST_SCREEN])
    missing = [s for s in FIRST_SCREEN_HOLDS if s not in head]
    assert not missing, f"README.md's first {FIRST_SCREEN} lines lack {missing}"
    line, code, shown = readme_snippet()
    n = len(code.splitlines())
    assert n <= SNIPPET_LINES, f"README.md's snippet (line {line}) has {n} lines, over {SNIPPET_LINES}"
    assert line + n + 2 + len(shown.splitlines()) + 1 <= FIRST_SCREEN, "the snippet and its output end below the first screen"


def test_the_readme_snippet_prints_what_the_readme_shows(tmp_path, monkeypatch, capsys):
    """The README's first snippet, as written, run in a folder of its own beside ../shared/data."""
    from minifilm.motion.bvh import read_bvh

    need_data(SHARED_DATA / "released-lpn", "the released network (the README's first snippet)")
    line, code, shown = readme_snippet()
    work = tmp_path / "work"
    work.mkdir()
    (tmp_path / "shared").mkdir()
    os.symlink(SHARED_DATA, tmp_path / "shared" / "data")
    monkeypatch.chdir(work)
    exec(compile(code, f"README.md, python snippet at line {line}", "exec"), {"__name__": "__readme__"})
    problems = same_output(capsys.readouterr().out, shown)
    assert not problems, "README.md's snippet printed something else than it shows:\n" + "\n".join(problems)
    written = list(work.glob("*.bvh"))
    assert len(written) == 1 and read_bvh(written[0]).n_frames > 0, written


def test_the_output_comparison_can_fail():
    shown = "120 frames -> zombie.bvh; hips 0.98-1.00 m, 0.78 m/s"
    assert same_output("120 frames -> zombie.bvh; hips 0.99-1.00 m, 0.77 m/s\n", shown) == []
    assert same_output("120 frames -> zombie.bvh; hips 0.98-1.00 m, 0.80 m/s", shown)      # a number off
    assert same_output("121 frames -> zombie.bvh; hips 0.98-1.00 m, 0.78 m/s", shown)      # an integer off
    assert same_output("120 frames -> walk.bvh; hips 0.98-1.00 m, 0.78 m/s", shown)        # a word off
    assert same_output(shown + "\nmore", shown)                                              # a line more
