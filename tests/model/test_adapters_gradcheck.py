"""Gradient checks of a taught style's adapters (minifilm/model/adapters.py) and of Φ fitted with
one (minifilm/train/adapter_fit.py): the rows of ``minifilm gradcheck``'s "adapter" group, one
(row, seed) per test, float64, every entry, relative error below 1e-7 (the suite's method)."""
import numpy as np
import pytest

from gradcheck_report import check
from minifilm.evaluation import gradcheck_adapters as rows
from minifilm.evaluation.gradcheck_table import SEEDS, cases
from minifilm.model import adapters as ad
from minifilm.nn.gradcheck import worst_error

ADAPTER_ROWS = [c for c in cases() if c.group == "adapter"]


def test_there_is_a_row_for_each_layer_and_for_phi_with_each_kind():
    names = " / ".join(c.name for c in ADAPTER_ROWS)
    assert len(ADAPTER_ROWS) == 5 and "residual adapter" in names and "low-rank" in names
    assert sum(c.name.startswith("Φ with") for c in ADAPTER_ROWS) == 2


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", ADAPTER_ROWS, ids=lambda c: c.name)
def test_adapter_gradients(case, seed):
    check(case, seed)


@pytest.mark.parametrize("kind", ad.KINDS)
def test_a_wrong_adapter_backward_fails_its_row(monkeypatch, kind):
    """The whole-Φ check sees one array's gradient off by one part in a million."""
    if kind == "residual":
        real = ad.residual_adapter_backward
        monkeypatch.setattr("minifilm.train.adapter_fit.residual_adapter_backward",
                            lambda d, c: (lambda g: (g[0], g[1] * (1 + 1e-6), g[2], g[3]))(real(d, c)))
    else:
        real = ad.lowrank_experts_backward
        monkeypatch.setattr("minifilm.train.adapter_fit.lowrank_experts_backward",
                            lambda d, c: (lambda g: (g[0], g[1], g[2], g[3] * (1 + 1e-6), g[4]))(real(d, c)))
    result = rows.adapted_phi(0, kind)
    assert worst_error(result.errors) > 1e-7


def test_the_whole_phi_check_is_not_vacuous():
    """Every adapter array gets a gradient that is not zero, and no ELU input sits near its kink."""
    for kind in ad.KINDS:
        result = rows.adapted_phi(1, kind)
        assert result.crossings == 0 and result.margin >= 0.05
        assert set(result.errors) == set(ad.adapter_shapes(kind, rows.SIZES, rows.EXPERTS, 2))


def test_adapters_start_as_the_identity():
    """A new adapter changes nothing (A, a, Q zero), whatever the share."""
    rng = np.random.default_rng(0)
    x, alpha, share = rng.standard_normal((4, 6)), rng.dirichlet(np.ones(3), 4), rng.random(4)
    low = ad.StyleAdapter("lowrank", [6, 5, 5, 7], 3, rank=2, dtype=np.float64, rng=rng)
    res = ad.StyleAdapter("residual", [6, 5, 5, 7], 3, dtype=np.float64)
    assert np.abs(low.params.params["P0"]).max() > 0
    assert np.array_equal(low.experts_change(0, x, alpha, share), np.zeros((4, 5)))
    assert np.array_equal(res.hidden_change(0, x[:, :5], share), np.zeros((4, 5)))
