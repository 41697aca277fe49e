"""The gradient-check suite against broken backward passes: a NaN, +inf or -inf in
one entry of a gradient, put into every backward pass of the kit, the blocks, the losses and the
style modulations at once, must fail every row of ``minifilm gradcheck`` (the rows' errors
become inf, never NaN, which would compare False with the limit and pass) and the pytest
suite's check (tests/gradcheck_report.py). The single-pair and command-level tests are in
tests/nn/test_gradcheck.py and tests/evaluation/test_gradcheck_suite.py."""
import functools
import sys

import numpy as np
import pytest

import gradcheck_report
from minifilm.baselines import style_modulation as modulation
from minifilm.evaluation import gradcheck_table as suite
from minifilm.model import blocks, losses
from minifilm.nn import conv, fast_conv, fast_linear
from minifilm.nn import functional as F

#: every network row would take ~30 s more; these cover each network class and the float32 table
NETWORK_ROWS = ("Ω gating network", "Φ motion network (Eq. 3)", "Ψ FiLM generator (Eq. 2)",
                "style model, shared clips", "LPN one-hot", "Φ")
ROWS = [c for c in suite.cases() if c.group in ("kit", "block", "loss", "modulation")]
ROWS += [c for c in suite.cases() + suite.float32_cases() if c.name in NETWORK_ROWS]


def poison(value, result):
    """``result`` (an array, or a tuple of them and numbers) with the middle entry of every
    non-empty float array set to ``value``."""
    if isinstance(result, np.ndarray) and result.dtype.kind == "f" and result.size:
        result = result.copy()
        result.flat[result.size // 2] = value
        return result
    if isinstance(result, tuple):
        return tuple(poison(value, r) for r in result)
    return result


def backward_passes():
    """Every function and method that returns a gradient: the pairs' *_backward, the losses,
    the style modulations' backward methods."""
    found = [getattr(m, n) for m in (F, conv, fast_conv, fast_linear, blocks) for n in dir(m) if n.endswith("_backward")]
    found += [losses.mse_loss, losses.bone_length_loss]
    return list({id(f): f for f in found}.values())


@pytest.fixture(params=[np.nan, np.inf, -np.inf], ids=["nan", "+inf", "-inf"])
def broken(request, monkeypatch):
    """Every backward pass poisoned, wherever a module holds it (modules that imported it by name
    included)."""
    value = request.param
    for original in backward_passes():
        wrapper = functools.wraps(original)(lambda *a, _f=original, **k: poison(value, _f(*a, **k)))
        for module in list(sys.modules.values()):
            if getattr(module, "__name__", "").startswith("minifilm"):
                for name, held in list(vars(module).items()):
                    if held is original:
                        monkeypatch.setattr(module, name, wrapper)
    for cls in (modulation.OneHotShift, modulation.ResidualAdapter, modulation.CPResidualAdapter):
        real = cls.backward
        monkeypatch.setattr(cls, "backward", lambda self, *a, _f=real, **k: poison(value, _f(self, *a, **k)))
    return value


@pytest.mark.filterwarnings("ignore:invalid value encountered")
@pytest.mark.parametrize("case", ROWS, ids=lambda c: f"{c.group}: {c.name}")
def test_a_broken_backward_pass_fails_every_row(broken, case, monkeypatch):
    if (case.group in ("network", "variant", "float32") or "conv1d" in case.name) and not np.isnan(broken):
        pytest.skip("the slower rows (networks, convolutions) run with NaN only")
    # the session's table must not show these poisoned runs: the rows record into a dict of
    # their own (a copy of the session's would still share, and so change, its Row objects)
    monkeypatch.setattr(gradcheck_report, "ROWS", {})
    row = suite.run_case(case, [0])
    assert not row.passed, f"{case.name} passed with a {broken} in its gradients"
    assert row.error is not None or row.worst == np.inf
    assert f"FAILED {case.name}: seed 0" in suite.format_table([row], "backward pass")
    if row.error is None:                 # the pytest suite's check fails it too
        with pytest.raises(AssertionError, match="seed 0: inf"):
            gradcheck_report.check(case, 0)
