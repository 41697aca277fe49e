"""The gradient-check suite itself (minifilm/evaluation/gradcheck_table.py, ``minifilm gradcheck``):
it has a row for every backward pass, prints the table, fails loudly (exit code 1) when a
backward pass is wrong, and forces the FFT convolution when asked. The rows themselves run in
tests/nn/test_gradcheck.py, tests/model/test_model_gradcheck.py and
tests/baselines/test_baselines_gradcheck.py."""
import ast
import re
import subprocess
import sys

import pytest

from minifilm.evaluation import gradcheck_table as suite
from minifilm.nn import fast_conv
from minifilm.nn import functional as F
from repo_paths import REPO_ROOT

COVERED = {ref for case in suite.cases() for ref in case.covers}


def test_every_backward_pass_of_docs_backprop_has_a_row():
    """docs/backprop.md names the backward passes (and the code they rest on) as
    `path::name`: each one is covered by a row of the table."""
    text = (REPO_ROOT / "docs" / "backprop.md").read_text(encoding="utf-8")
    refs = {r for r in re.findall(r"`(minifilm/[\w/]+\.py::[\w.]+)`", text)
            if not r.startswith("minifilm/nn/gradcheck.py")}         # the method, not a backward pass
    assert len(refs) > 15
    assert not refs - COVERED, f"named in docs/backprop.md but in no row of the suite: {sorted(refs - COVERED)}"


def backward_passes():
    """Every *_backward function of the kit and the blocks, and every backward method of the
    networks and style modulations, as `path::name`."""
    out = []
    for rel in ("minifilm/nn/functional.py", "minifilm/nn/conv.py", "minifilm/nn/fast_conv.py",
                "minifilm/nn/fast_linear.py", "minifilm/model/blocks.py", "minifilm/model/adapters.py",
                "minifilm/train/adapter_fit.py"):
        tree = ast.parse((REPO_ROOT / rel).read_text(encoding="utf-8"))
        out += [f"{rel}::{n.name}" for n in tree.body if isinstance(n, ast.FunctionDef) and n.name.endswith("_backward")]
    for rel in ("minifilm/model/gating.py", "minifilm/model/motion_net.py", "minifilm/model/film_generator.py",
                "minifilm/model/style_model.py", "minifilm/baselines/style_modulation.py",
                "minifilm/baselines/expert_net.py", "minifilm/baselines/variants.py"):
        tree = ast.parse((REPO_ROOT / rel).read_text(encoding="utf-8"))
        out += [f"{rel}::{c.name}.{f.name}" for c in tree.body if isinstance(c, ast.ClassDef)
                for f in c.body if isinstance(f, ast.FunctionDef) and f.name.startswith("backward")]
    return out


def test_every_backward_pass_in_the_code_has_a_row():
    passes = backward_passes()
    assert "minifilm/nn/functional.py::layer_norm_backward" in passes and len(passes) > 25
    missing = [p for p in passes if p not in COVERED]
    assert not missing, f"backward passes without a row in the gradient-check table: {missing}"


def test_the_command_prints_the_table():
    proc = subprocess.run([sys.executable, "-m", "minifilm", "gradcheck", "--only", "layer norm (biased", "--seeds", "2"],
                          capture_output=True, text=True, timeout=120, cwd=REPO_ROOT)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("backward pass"))
    assert lines[head].split() == ["backward", "pass", "arrays", "entries", "seeds", "worst", "rel.", "error",
                                   "limit", "crossed", "pass"]
    row = lines[head + 2].split()
    assert row[:5] == ["layer", "norm", "(biased", "σ,", "ε"] and row[-1] == "yes" and row[-3] == "1e-07"
    assert float(row[-4]) < 1e-7 and row[-5] == "0-1"
    assert "1 of 1 checks passed" in proc.stdout


def test_a_wrong_backward_pass_fails_the_table_and_the_exit_code(monkeypatch):
    real = F.softmax_backward
    monkeypatch.setattr(F, "softmax_backward", lambda dout, cache: real(dout, cache) * (1 + 1e-6))
    printed = []
    assert suite.run(seeds=[0], only="softmax", out=printed.append) == 1
    text = "\n".join(printed)
    assert re.search(r"^softmax .* NO$", text, re.M) and "FAILED softmax: seed 0: x[" in text
    monkeypatch.setattr(F, "softmax_backward", real)
    assert suite.run(seeds=[0], only="softmax", out=printed.append) == 0


def test_a_check_that_raises_is_a_failed_row():
    case = suite.Case("raises", "kit", lambda seed: 1 / 0)
    row = suite.run_case(case, [0, 1])
    assert not row.passed and "ZeroDivisionError" in row.error
    assert "FAILED raises: seed 0: ZeroDivisionError" in suite.format_table([row], "backward pass")


def test_fft_convolutions_forces_the_fft_method_and_restores_the_choice():
    """The row 'Ψ, FFT convolutions' really runs both of Ψ's convolutions in the FFT form (the
    toy sizes would pick im2col), and only there."""
    from minifilm.evaluation import gradcheck_networks as nets
    choose = fast_conv._conv1d_method
    with suite.fft_convolutions():
        assert fast_conv._conv1d_method(1, 9, 3, 3, 3) == "fft"
        pr = nets.psi_problem(0)
        pr.run()
        assert [c.conv[0] for c in pr.model._caches[:2]] == ["fft", "fft"]
    assert fast_conv._conv1d_method is choose and choose(1, 9, 3, 3, 3) == "im2col"
    pr.run()
    assert [c.conv[0] for c in pr.model._caches[:2]] == ["im2col", "im2col"]


@pytest.mark.parametrize("group", ["kit", "block", "loss", "modulation", "network", "variant"])
def test_rows_have_covers_and_names_are_unique(group):
    rows = [c for c in suite.cases() if c.group == group]
    assert rows and all(c.covers for c in rows)
    names = [c.name for c in suite.cases()] + [c.name + " (float32)" for c in suite.float32_cases()]
    assert len(names) == len(set(names))


# ---- NaN or inf anywhere is a failure, at every entry point ------------------------------------
def _result(**errors):
    return suite.Result(errors, {k: 1 for k in errors}, worst="x[0]: analytic nan, numerical 1.0")


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_a_non_finite_error_fails_the_row_in_either_order(value):
    """A row whose seed gives NaN fails whether that seed comes first or after a good one, and
    whether the NaN is the first array's or a later one's (max() of a list with a NaN is
    order-dependent; the row's worst is then inf)."""
    good, bad_first, bad_last = _result(x=1e-9, W=2e-9), _result(x=value, W=1e-9), _result(x=1e-9, W=value)
    for seeds in ([good, bad_first], [bad_first, good], [good, bad_last], [bad_last, good], [bad_last]):
        row = suite.Row(suite.Case("r", "kit", None))
        for i, result in enumerate(seeds):
            row.add(i, result)
        assert not row.passed and row.worst == float("inf")
        assert "FAILED r: seed" in suite.format_table([row], "backward pass")
    empty = suite.Row(suite.Case("r", "kit", None))
    empty.add(0, suite.Result({}, {}))
    assert not empty.passed and "no array was checked" in empty.where


def nan_softmax(monkeypatch):
    real = F.softmax_backward

    def broken(dout, cache):
        dx = real(dout, cache)
        dx[0, 0] = float("nan")
        return dx
    monkeypatch.setattr(F, "softmax_backward", broken)


def test_a_nan_returning_backward_fails_the_table_the_command_and_the_pytest_check(monkeypatch, capsys):
    nan_softmax(monkeypatch)
    case = next(c for c in suite.cases() if c.name == "softmax")
    # the row
    row = suite.run_case(case, [0, 1])
    assert not row.passed and row.worst == float("inf") and "analytic nan" in row.where
    # the table and the exit code of suite.run
    printed = []
    assert suite.run(seeds=[0], only="softmax", out=printed.append) == 1
    assert re.search(r"^softmax .* inf .* NO$", "\n".join(printed), re.M)
    # the command (in this process, so the broken backward pass is the one it checks)
    from minifilm import cli
    with pytest.raises(SystemExit) as stop:
        cli.main(["gradcheck", "--only", "softmax", "--seeds", "1"])
    assert stop.value.code == 1
    assert re.search(r"^softmax .* NO$", capsys.readouterr().out, re.M)
    # the pytest suite's check (tests/gradcheck_report.py), which every gradient-check test calls
    import gradcheck_report
    saved = dict(gradcheck_report.ROWS)
    try:
        with pytest.raises(AssertionError, match=r"softmax, seed 0: inf"):
            gradcheck_report.check(case, 0)
    finally:
        gradcheck_report.ROWS.clear()
        gradcheck_report.ROWS.update(saved)


def test_a_nan_in_a_float32_backward_fails_its_row(monkeypatch):
    """The float32 table: a NaN in the float32 gradient (only) is a failure, not a NaN that
    compares False with the tolerance."""
    real = F.elu_backward

    def broken(dout, cache):
        dx = real(dout, cache)
        if dx.dtype == "float32":
            dx.flat[0] = float("nan")
        return dx
    monkeypatch.setattr(F, "elu_backward", broken)
    case = next(c for c in suite.float32_cases() if c.name == "Φ")
    row = suite.run_case(case, [0])
    assert not row.passed and row.worst == float("inf")


# ---- `python -m pytest -m gradcheck` runs every gradient check ---------------------------------
GRADIENT_CHECKS = {"numerical_gradient", "check_gradients", "check_pair", "compare_gradients", "gradient_check",
                   "check", "other"}      # the last two: tests/gradcheck_report.py's


def test_every_gradient_check_of_the_tests_carries_the_mark():
    """A test that computes numerical gradients (minifilm/nn/gradcheck.py, the companion's own
    check) or records a check in tests/gradcheck_report.py lives in a module named *gradcheck*
    (tests/conftest.py marks all of its tests) or is marked gradcheck itself."""
    unmarked, found = [], 0
    for path in sorted((REPO_ROOT / "tests").rglob("test_*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        imported = {a.asname or a.name for node in tree.body if isinstance(node, ast.ImportFrom)
                    and node.module in ("gradcheck_report", "minifilm.nn.gradcheck") for a in node.names}
        for node in tree.body:
            if not (isinstance(node, ast.FunctionDef) and node.name.startswith("test_")):
                continue
            calls = {c.func.id if isinstance(c.func, ast.Name) else c.func.attr for c in ast.walk(node)
                     if isinstance(c, ast.Call) and isinstance(c.func, (ast.Name, ast.Attribute))}
            uses = calls & GRADIENT_CHECKS & (imported | {"gradient_check"})
            if not uses:
                continue
            found += 1
            marked = "gradcheck" in path.name or any("mark.gradcheck" in ast.unparse(d) for d in node.decorator_list)
            if not marked:
                unmarked.append(f"{path.relative_to(REPO_ROOT)}::{node.name} ({', '.join(sorted(uses))})")
    assert found > 15
    assert not unmarked, f"gradient checks without the mark gradcheck: {unmarked}"
