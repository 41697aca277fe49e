"""The project's size budgets, in one place, so they hold themselves: a cap that nothing checks drifts.

    README.md                          <= 300 lines  (the first screen; the rest lives in docs/)
    benchmarks/README.md               <= 300 lines  (today's figures, one table each with its command;
                                                      how a decision was reached goes to reports/)
    examples/minifilm_in_one_file.py   <= 850 lines, none over 100 characters (the whole method)
    every module of minifilm/          <= 400 lines  (one idea a file)
"""
from pathlib import Path

import pytest

from repo_paths import REPO_ROOT

BUDGETS = {"README.md": 300, "benchmarks/README.md": 300, "examples/minifilm_in_one_file.py": 850}
MODULE_LINES = 400
COMPANION_WIDTH = 100


def lines(path: Path) -> list:
    return path.read_text(encoding="utf-8").splitlines()


@pytest.mark.parametrize("name", list(BUDGETS))
def test_each_document_keeps_its_budget(name):
    n = len(lines(REPO_ROOT / name))
    assert n <= BUDGETS[name], f"{name} has {n} lines, over its budget of {BUDGETS[name]}"


def test_no_module_of_the_package_is_over_400_lines():
    long = {p.relative_to(REPO_ROOT).as_posix(): n for p in sorted((REPO_ROOT / "minifilm").rglob("*.py"))
            if (n := len(lines(p))) > MODULE_LINES}
    assert not long, f"modules over {MODULE_LINES} lines (split them by idea): {long}"


def test_no_line_of_the_companion_is_over_100_characters():
    wide = [i + 1 for i, line in enumerate(lines(REPO_ROOT / "examples" / "minifilm_in_one_file.py"))
            if len(line) > COMPANION_WIDTH]
    assert not wide, f"examples/minifilm_in_one_file.py: lines over {COMPANION_WIDTH} characters: {wide}"


def test_the_budgets_can_fail(tmp_path):
    probe = tmp_path / "long.md"
    probe.write_text("x\n" * 301, encoding="utf-8")
    assert len(lines(probe)) > BUDGETS["README.md"]
