"""The names a Python file defines, read from its syntax tree, for the tests that check that
every reference to a module's function or class in the repository's text points at something real."""
from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path


@lru_cache(maxsize=None)
def defined_names(path: Path, imported: bool = False) -> frozenset:
    """Top-level functions, classes and assignments, ``Class.method`` and ``Class.attribute``; with
    ``imported``, also the names the file imports (a module may re-export them)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
            if isinstance(node, ast.ClassDef):
                names.update(f"{node.name}.{n}" for n in _class_members(node))
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            names.update(_assigned(node))
        elif imported and isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return frozenset(names)


def _assigned(node) -> list:
    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
    return [t.id for t in targets if isinstance(t, ast.Name)]


def _class_members(node: ast.ClassDef) -> list:
    members = []
    for sub in node.body:
        if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)):
            members.append(sub.name)
        elif isinstance(sub, (ast.AnnAssign, ast.Assign)):
            members.extend(_assigned(sub))
    return members
