"""No reference a reader cannot follow (tests/test_docs.py checks README and docs/): every file path, ``path::name``, dotted ``minifilm.x.y`` name, Sphinx ``:func:`` / ``:class:`` /
``:meth:`` name and ``§`` section cited in the repository's code, docstrings, comments and docs
must exist in the repository.

* paths: ``minifilm/…``, ``tests/…``, ``docs/…``, ``benchmarks/…``, ``examples/…``, ``scripts/…`` from
  the repository root; a shorter one (``nn/optim.py``, ``conv.py``) relative to the citing file's
  folder or to ``minifilm/``;
* ``::name``: a function, class, ``Class.method`` or module-level assignment of that file;
* ``§N.M``: a section of docs/original-code.md;
* a file that says its paths are "as of commit <hash>" (a dated report about code since replaced)
  may cite files of that commit (``git show <hash>:<path>`` opens them);
* and nothing a reader cannot open at all: no issue numbers ("issue 27", "(issue 8)": the repository
  has no tracker a reader can see), no work sessions or helpers, no absolute machine paths
  (``/work/…``, ``/home/…``, ``/tmp/…``): a repository's text says what it means in its own words.
"""
from __future__ import annotations

import ast
import re
import subprocess
from functools import lru_cache
from pathlib import Path

import pytest

from python_names import defined_names
from repo_paths import REPO_ROOT

ROOTS = ("minifilm", "tests", "docs", "benchmarks", "studies", "reports", "examples", "scripts")
SUFFIXES = (".py", ".md", ".js", ".html", ".css")
ORIGINAL = REPO_ROOT / "docs" / "original-code.md"
#: files of other projects cited by name: CS231n's assignment code, nanoGPT, the authors' repository
#: (docs/original-code.md names its files)
EXTERNAL = {"layers.py", "fast_layers.py", "layer_utils.py", "gradient_check.py", "model.py", "train.py",
            "Bll.py", "LPN.py", "Data_Loader.py", "Normalize_Data_Subset.py"}
PACKAGES = {p.name for p in (REPO_ROOT / "minifilm").iterdir() if p.is_dir()}

PATH = re.compile(r"(?<![\w/.-])((?:[\w-]+/)*[\w-]+\.(?:py|md|png|csv|js|html|css))(?![\w])(?:::([A-Za-z_][\w.]*\w))?")
DOTTED = re.compile(r"(?<![\w./-])(minifilm(?:\.\w+)+)")
ROLE = re.compile(r":(?:func|class|meth):`~?([\w.]+)`")
SECTION = re.compile(r"()§\s?(\d+(?:\.\d+)*)")
#: what no reader can open: an issue number, a work session or helper, a machine's absolute path
UNFOLLOWABLE = {
    "an issue number": re.compile(r"\bissues?[\s#-]*\d+", re.IGNORECASE),
    "a work session": re.compile(r"\b(?:other|previous|this|that|first|second|earlier|later|same)\s+"
                                 r"sessions?\b|\bsessions'", re.IGNORECASE),
    "a helper": re.compile(r"\bhelpers?'|\bother helpers\b", re.IGNORECASE),
    "a machine's absolute path": re.compile(r"(?<![\w.~])/(?:work|home|Users|tmp|root|mnt)/\w"),
}


def repo_files():
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"], cwd=REPO_ROOT,
                            capture_output=True, text=True).stdout.split()
    files = [REPO_ROOT / f for f in listed if f.endswith(SUFFIXES) and f.split("/")[0] in ROOTS + ("README.md",)]
    return [f for f in files if f.is_file() and "vendor" not in f.parts]


def resolve_path(ref: str, citing: Path):
    """The file a path reference means; None if there is none; "skip" for what is not ours to
    check (another project's file, an output path such as runs/train_small/model.npz)."""
    first = ref.split("/")[0]
    if first in ROOTS or ref == "README.md":
        return REPO_ROOT / ref if (REPO_ROOT / ref).exists() else None
    for base in (citing.parent, REPO_ROOT / "minifilm", REPO_ROOT):
        if (base / ref).exists():
            return base / ref
    if "/" in ref:
        return None if first in PACKAGES else "skip"
    if ref in EXTERNAL or not ref.endswith(".py"):
        return "skip"                             # another project's file, or an output (phases.png)
    hits = [p for root in ROOTS for p in (REPO_ROOT / root).rglob(ref)]
    return hits[0] if hits else None


def resolve_dotted(ref: str):
    """'minifilm.a.b.name' -> None if it exists, else what is missing."""
    parts = ref.split(".")
    for i in range(len(parts), 0, -1):
        base = REPO_ROOT.joinpath(*parts[:i])
        module = base.with_suffix(".py") if base.with_suffix(".py").is_file() else base / "__init__.py"
        if module.is_file():
            rest = ".".join(parts[i:])
            if not rest or rest in defined_names(module, imported=True):
                return None
            return f"{module.relative_to(REPO_ROOT)} defines no {rest}"
    return f"no module {ref}"


@lru_cache(maxsize=None)
def original_sections() -> frozenset:
    text = ORIGINAL.read_text(encoding="utf-8")
    heads = re.findall(r"(?m)^#{2,4} (\d+(?:\.\d+)*)\.? ", text)
    items = re.findall(r"(?m)^\*\*(\d+(?:\.\d+)+) ", text)
    return frozenset(heads + items)


AS_OF = re.compile(r"\bas of commit ([0-9a-f]{7,40})\b", re.IGNORECASE)


@lru_cache(maxsize=None)
def existed_at(commit: str, ref: str) -> bool:
    """Whether ``ref`` (a path from the repository root) is a file of ``commit``; True when this
    clone does not have the commit at all (a shallow clone cannot tell)."""
    def git(*args):
        return subprocess.run(["git", *args], cwd=REPO_ROOT, capture_output=True).returncode == 0
    return git("cat-file", "-e", f"{commit}:{ref}") or not git("cat-file", "-e", f"{commit}^{{commit}}")


def problems_in(path: Path) -> list:
    text = path.read_text(encoding="utf-8")
    rel = path.relative_to(REPO_ROOT).as_posix()
    as_of = AS_OF.search(text)
    out = []

    def where(m):
        return f"{rel}:{text.count(chr(10), 0, m.start()) + 1}"

    for m in PATH.finditer(text):
        ref, name = m.group(1), m.group(2)
        if ref.startswith(("http", "www")) or "{" in ref or ref.endswith(".min.js"):
            continue
        if "no_such" in ref:                      # the negative examples of the checkers' own tests
            continue
        target = resolve_path(ref, path)
        if target is None and as_of and existed_at(as_of.group(1), ref):
            continue                              # a file of the commit the text is about
        if target is None:
            out.append(f"{where(m)}: {ref} does not exist")
        elif target != "skip" and name and target.suffix == ".py" and name not in defined_names(target, imported=True):
            out.append(f"{where(m)}: {ref} defines no {name}")
    if path.suffix == ".py":
        for m in DOTTED.finditer(text):
            if m.group(1).endswith("_") or text[max(0, m.start() - 11):m.start()] == "getLogger(\"" \
                    or "no_such" in m.group(1):
                continue                                 # a name pattern (expert_linear_*), a logger
            msg = resolve_dotted(m.group(1).rstrip("."))
            if msg:
                out.append(f"{where(m)}: {m.group(1)}: {msg}")
        own = defined_names(path, imported=True) | {n.name for n in ast.walk(ast.parse(text)) if isinstance(n, ast.FunctionDef)}
        for m in ROLE.finditer(text):
            ref = m.group(1)
            if ref.startswith("minifilm."):
                msg = resolve_dotted(ref)
                if msg:
                    out.append(f"{where(m)}: {ref}: {msg}")
            elif ref.split(".")[0] not in own and ref not in own and not ref.startswith(("np.", "numpy.")):
                out.append(f"{where(m)}: :{ref}: is neither defined nor imported here")
    for m in SECTION.finditer(text):
        if m.group(1):
            continue
        if path == ORIGINAL or m.group(2) not in original_sections():
            if path != ORIGINAL or m.group(2) not in original_sections():
                out.append(f"{where(m)}: §{m.group(2)} is not a section of docs/original-code.md")
    return out


def test_every_reference_in_the_repository_exists():
    files = [f for f in repo_files() if f != Path(__file__).resolve()]   # this file's text is examples
    assert len(files) > 150 and ORIGINAL in files
    problems = [p for f in files for p in problems_in(f)]
    assert not problems, f"{len(problems)} references point nowhere:\n" + "\n".join(problems)


def test_the_reference_checker_can_fail(tmp_path):
    bad = REPO_ROOT / "tests" / "_reference_probe.py"        # read only through problems_in
    text = ('"""See minifilm/nn/absent.py, minifilm/nn/optim.py::NoSuchName, nn/optim.py::Adam, '
            'minifilm.nn.optim.Nope, :func:`_scratch`, §99.9 and §12.3."""\n')
    try:
        bad.write_text(text, encoding="utf-8")
        found = problems_in(bad)
    finally:
        bad.unlink()
    joined = "\n".join(found)
    assert "absent.py does not exist" in joined and "defines no NoSuchName" in joined
    assert "Nope" in joined and "_scratch" in joined and "§99.9" in joined
    assert "Adam" not in joined and "§12.3" not in joined and len(found) == 5


def test_a_text_as_of_a_commit_may_cite_that_commit_s_files_only():
    probe = REPO_ROOT / "tests" / "_reference_probe_as_of.md"      # read only through problems_in
    commit = "2e18e45"                  # the last commit with the project's own worker processes
    if subprocess.run(["git", "cat-file", "-e", f"{commit}^{{commit}}"], cwd=REPO_ROOT).returncode:
        pytest.skip(f"this clone does not have commit {commit} (a shallow clone)")
    try:
        probe.write_text(f"As of commit {commit}: minifilm/train/parallel.py, minifilm/train/never_was.py\n",
                         encoding="utf-8")
        found = problems_in(probe)
    finally:
        probe.unlink()
    assert len(found) == 1 and "never_was.py does not exist" in found[0], found


@pytest.mark.parametrize("section", ["0.3", "1.1", "2", "3.3", "4.8", "10.2", "12.3", "12.17", "13.1"])
def test_the_original_code_document_has_the_cited_sections(section):
    assert section in original_sections()


def unfollowable(text: str) -> list:
    """Each issue number, work session, helper or machine path in ``text``: (line, kind, match)."""
    return [(text.count("\n", 0, m.start()) + 1, kind, m.group(0))
            for kind, pattern in UNFOLLOWABLE.items() for m in pattern.finditer(text)]


def test_no_issue_numbers_sessions_or_machine_paths_in_the_repository():
    files = [f for f in repo_files() if f != Path(__file__).resolve()]   # this file's text is examples
    assert len(files) > 150
    found = [f"{f.relative_to(REPO_ROOT)}:{line}: {kind} ({text!r})"
             for f in files for line, kind, text in unfollowable(f.read_text(encoding="utf-8"))]
    assert not found, f"{len(found)} places a reader cannot follow:\n" + "\n".join(found)


def test_the_unfollowable_checker_can_fail():
    text = ("As issue 27 asked (issue 8), measured in the previous session with other helpers' jobs,\n"
            "data in /work/shared/data and /tmp/run; a scripted session, /proc/self/status, issues.\n")
    kinds = [kind for _, kind, _ in unfollowable(text)]
    assert kinds.count("an issue number") == 2 and kinds.count("a work session") == 1
    assert kinds.count("a helper") == 1 and kinds.count("a machine's absolute path") == 2
    assert len(kinds) == 6
