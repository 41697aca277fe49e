"""The package's shape, kept by reading every module's imports (ast): imports go one way, down the
data flow, and sit at the top of their file unless a comment says why not.

    errors, files, parallel   shared by every layer: input errors, the file system, maps on every core
    nn, motion           the bottom: the kit and the motion data know nothing of each other
    phases, features, synthetic     -> motion (and each other, downwards)
    body                 -> phases, synthetic, motion: which joint is the hips, a foot, a hand, found
                            once per file (roles, rig, unit), and retargeting onto a rig with them
    dataset              -> body, phases, features, motion
    model                -> nn
    train                -> model, dataset
    runtime, viewer      -> model, features, motion, dataset
    baselines, evaluation   the comparison of Sec. 5: nothing in the core imports them
    pipeline, cli        whole jobs and the command: they may import everything (cli imports pipeline)
    demo                 the live demo, an application like pipeline (its __main__ hands over to cli)
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from repo_paths import REPO_ROOT

PACKAGE = REPO_ROOT / "minifilm"

#: what each part of the package may import from minifilm (besides itself), and why
ALLOWED = {
    "errors": set(),
    "files": {"errors"},
    "parallel": set(),
    "nn": set(),
    "motion": {"errors", "files"},
    "phases": {"errors", "motion", "files"},
    "features": {"errors", "motion", "files"},
    "body": {"errors", "motion", "phases", "synthetic", "files"},
    "synthetic": {"errors", "motion", "files"},
    "dataset": {"errors", "body", "motion", "phases", "features", "files", "parallel"},
    "model": {"nn"},
    "train": {"errors", "model", "nn", "dataset", "files"},
    "runtime": {"errors", "model", "nn", "features", "motion", "dataset", "files"},
    "viewer": {"errors", "body", "motion", "phases", "features", "runtime", "dataset", "files"},
    "baselines": {"errors", "model", "nn", "dataset", "features", "runtime", "files"},
    "evaluation": {"errors", "baselines", "model", "nn", "dataset", "features", "body", "motion", "phases", "synthetic",
                   "train", "runtime", "viewer", "files", "parallel"},
    "pipeline": {"errors", "evaluation", "baselines", "model", "nn", "dataset", "features", "body", "motion", "phases",
                 "synthetic", "train", "runtime", "viewer", "files", "parallel"},
    "demo": {"errors", "cli", "pipeline", "runtime", "viewer", "motion", "features", "dataset", "synthetic", "files"},
    "cli": {"errors", "demo", "pipeline", "evaluation", "baselines", "model", "nn", "dataset", "features", "body", "motion",
            "phases", "synthetic", "train", "runtime", "viewer", "files", "parallel"},
    "__main__": {"cli"},
}
CORE = {"errors", "files", "parallel", "nn", "motion", "body", "phases", "features", "synthetic", "dataset", "model",
        "train", "runtime", "viewer"}
COMPARISON = {"baselines", "evaluation"}


def part_of(module_path: Path) -> str:
    """'nn' for minifilm/nn/functional.py, 'files' for minifilm/files/atomic.py."""
    rel = module_path.relative_to(PACKAGE)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def minifilm_imports(tree: ast.AST):
    """(line, imported part, node) for every import of a minifilm module."""
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for name in names[:1] if isinstance(node, ast.ImportFrom) else names:
            parts = name.split(".")
            if parts[0] == "minifilm" and len(parts) > 1:
                yield node.lineno, parts[1], node


MODULES = sorted(p for p in PACKAGE.rglob("*.py"))


def test_every_part_has_a_rule():
    parts = {part_of(p) for p in MODULES if p.name != "__init__.py" or p.parent != PACKAGE}
    assert parts - {"__init__"} <= set(ALLOWED), f"parts without an import rule: {parts - set(ALLOWED)}"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(REPO_ROOT)))
def test_imports_go_one_way(path):
    if path == PACKAGE / "__init__.py":
        return
    part = part_of(path)
    tree = ast.parse(path.read_text(encoding="utf-8"))
    problems = []
    for line, target, _ in minifilm_imports(tree):
        if target == part:
            continue
        if part in CORE and target in COMPARISON:
            problems.append(f"line {line}: the core ({part}) imports the comparison ({target}); the comparison "
                            "builds on the core, never the other way (hand the core a builder instead)")
        elif target not in ALLOWED[part]:
            problems.append(f"line {line}: {part} imports {target}, but {part} may import only "
                            f"{sorted(ALLOWED[part]) or 'nothing of minifilm'} (the data flow goes one way)")
    assert not problems, f"{path.relative_to(REPO_ROOT)}:\n" + "\n".join(problems)


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(REPO_ROOT)))
def test_imports_are_at_the_top_unless_a_comment_says_why(path):
    lines = path.read_text(encoding="utf-8").split("\n")
    tree = ast.parse("\n".join(lines))
    top = {id(n) for n in tree.body}
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
            if not explained(lines, node.lineno):
                problems.append(f"line {node.lineno}: `{lines[node.lineno - 1].strip()}` inside a function or "
                                "block, with no comment saying why it is not at the top")
    assert not problems, f"{path.relative_to(REPO_ROOT)}:\n" + "\n".join(problems)


def explained(lines, lineno: int) -> bool:
    """An inner import is explained by a comment on its own line, or on the lines just above it:
    the group of imports it belongs to and the one statement before that group."""
    k = lineno - 1
    if "#" in lines[k]:
        return True
    k -= 1
    while k >= 0 and lines[k].strip().startswith(("import ", "from ", "#")):
        if "#" in lines[k]:
            return True
        k -= 1
    return k >= 0 and "#" in lines[k]


def test_the_rules_can_fail(tmp_path):
    """The checks above see a wrong-way import and an unexplained inner import."""
    src = "from minifilm.baselines.variants import build_variant\n\ndef f():\n    import numpy\n"
    tree = ast.parse(src)
    found = [(line, target) for line, target, _ in minifilm_imports(tree)]
    assert found == [(1, "baselines")] and "baselines" not in ALLOWED["runtime"]
    inner = [n for n in ast.walk(tree) if isinstance(n, ast.Import) and n not in tree.body]
    assert inner and "#" not in src.split("\n")[inner[0].lineno - 1]


# ---- no circles: following imports from any module never leads back to it -------------------------
def module_name(path: Path) -> str:
    """'minifilm.demo.record' for minifilm/demo/record.py, 'minifilm.files' for its __init__.py."""
    parts = list(path.relative_to(REPO_ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def module_graph() -> dict:
    """{module: the minifilm modules it imports}, every import (inside functions too: an import
    put off until it runs is still a dependency). ``from minifilm.demo import record``
    is an edge to that module, ``from minifilm.files import atomic_write_text`` to the package."""
    names = {module_name(p): p for p in MODULES}
    graph = {}
    for name, path in names.items():
        out = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                out |= {f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in names else node.module
                        for a in node.names}
            elif isinstance(node, ast.Import):
                out |= {a.name for a in node.names}
        graph[name] = {m for m in out if m in names and m != name}
    return graph


def circles(graph: dict) -> list:
    """The strongly connected parts of ``graph`` with more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while not part or part[-1] != v:
                part.append(stack.pop())
                on_stack.discard(part[-1])
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def test_the_import_graph_has_no_circle():
    found = circles(module_graph())
    assert not found, "modules that import each other, directly or round a circle:\n" + "\n".join(
        " <-> ".join(part) for part in found)


def test_the_circle_finder_can_fail():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a", "e"}, "e": {"d"}, "f": set()}
    assert circles(graph) == [["a", "b", "c"], ["d", "e"]]
    assert circles({"a": {"b"}, "b": set()}) == []
