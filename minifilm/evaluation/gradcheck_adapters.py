"""The gradient checks of a style's adapters (minifilm/model/adapters.py) and of Φ fitted with one
(minifilm/train/adapter_fit.py), rows of ``minifilm gradcheck`` like the others.

The two layers are polynomials in every input, so the pairs are checked at random points (the
kit's method: L = Σ out ∘ r, every entry of every input, the share included). Φ with an adapter
is checked whole on its training loss (MSE, float64, toy sizes, frozen experts, two styles' FiLM
vectors in one batch, a share per row): every entry of every adapter array, with the ELU inputs
kept MARGIN from 0 (FiLM's β shifted, layer by layer in forward order) and every layer-norm row
at σ >= SIGMA_MIN (the experts' biases shifted by a zero-mean pattern); a guard counts stencil
evaluations on which an ELU input changed sign.
"""
from __future__ import annotations

import math

import numpy as np

from minifilm.evaluation.gradcheck_cases import _rng, pair_result
from minifilm.evaluation.gradcheck_problem import MARGIN, SIGMA_MIN, result_of, shift_away
from minifilm.model import adapters as ad
from minifilm.nn import functional as F
from minifilm.nn.gradcheck import compare_gradients
from minifilm.train.adapter_fit import AdapterRows, FrozenPhi, adapted_phi_backward, adapted_phi_forward

SIZES, EXPERTS, BATCH = [6, 5, 5, 7], 3, 5


def residual_adapter(seed):
    """h + s (h A + a): gradients of h, A, a and the share s."""
    rng = _rng(seed, 60)
    H = 5
    inputs = (rng.standard_normal((BATCH, H)), rng.standard_normal((H, H)), rng.standard_normal(H),
              rng.uniform(0.1, 1.0, BATCH))
    return pair_result(ad.residual_adapter_forward, ad.residual_adapter_backward, inputs, ("h", "A", "a", "share"), rng)


def lowrank_experts(seed, rank=2):
    """s Σ_k α_k (x P_k) Q_k: gradients of x, α, P, Q and the share s."""
    rng = _rng(seed, 61 + rank)
    K, I, O = EXPERTS, 6, 4
    inputs = (rng.standard_normal((BATCH, I)), rng.dirichlet(np.ones(K), size=BATCH),
              rng.standard_normal((K, I, rank)), rng.standard_normal((K, rank, O)), rng.uniform(0.1, 1.0, BATCH))
    return pair_result(ad.lowrank_experts_forward, ad.lowrank_experts_backward, inputs,
                       ("x", "alpha", "P", "Q", "share"), rng)


def _conditioned(phi: FrozenPhi, rows: AdapterRows, films, adapter, share) -> None:
    """Shift the experts' biases (a zero-mean pattern, so every layer-norm row's σ >= SIGMA_MIN)
    and FiLM's β (every ELU input >= MARGIN from 0), layer by layer in forward order."""
    H = SIZES[1]
    pattern = np.linspace(-0.5, 0.5, H)
    for l in range(2):
        for _ in range(20):
            sigma = adapted_phi_forward(rows, films, phi, adapter, share)[1][l]["norm"][1]
            if sigma.min() >= SIGMA_MIN:
                break
            phi.experts[l][1][...] += pattern         # every expert alike: every row moves by it
            if l == 0:
                rows.f0[...] += pattern               # the first layer's output is computed once
        caches = adapted_phi_forward(rows, films, phi, adapter, share)[1]
        films[:, (2 * l + 1) * H:(2 * l + 2) * H] += shift_away(caches[l]["elu"][0], MARGIN)


def adapted_phi(seed, kind="residual"):
    """Φ with an adapter, the training loss (MSE) -> the adapter's arrays."""
    rng = _rng(seed, 70 + ad.KINDS.index(kind))
    K, (I, H, _, O) = EXPERTS, SIZES
    phi = FrozenPhi([(rng.standard_normal((K, a, b)) / math.sqrt(a), 0.3 * rng.standard_normal((K, b)))
                     for a, b in zip(SIZES[:-1], SIZES[1:])])
    x, alpha = rng.standard_normal((BATCH, I)), rng.dirichlet(np.ones(K), size=BATCH)
    rows = AdapterRows(x, alpha, F.expert_linear_forward(x, alpha, *phi.experts[0])[0],
                       rng.standard_normal((BATCH, O)), np.array([0, 1, 1, 0, 1]))
    films = 0.3 * rng.standard_normal((2, 4 * H))
    films[:, :H] += 1.0
    films[:, 2 * H:3 * H] += 1.0
    adapter = ad.StyleAdapter(kind, SIZES, K, rank=2, dtype=np.float64, rng=rng)
    adapter.params.data[...] += 0.3 * rng.standard_normal(adapter.params.size)
    share = rng.uniform(0.2, 1.0, BATCH)
    _conditioned(phi, rows, films, adapter, share)

    def loss():
        z, caches = adapted_phi_forward(rows, films, phi, adapter, share)
        return math.fsum(((z - rows.z) ** 2).ravel().tolist()) / rows.z.size, caches

    def sides(caches):
        return np.concatenate([(c["elu"][0] > 0).ravel() for c in caches[:2]])

    value, caches = loss()
    z = adapted_phi_forward(rows, films, phi, adapter, share)[0]
    adapter.params.zero_grad()
    adapted_phi_backward(2.0 * (z - rows.z) / z.size, caches, adapter)
    base, crossings = sides(caches), 0

    def f():
        nonlocal crossings
        v, c = loss()
        crossings += not np.array_equal(sides(c), base)
        return v

    pairs = {k: (adapter.params.params[k], adapter.params.grads[k].copy()) for k in adapter.params.names()}
    margin = float(min(np.abs(c["elu"][0]).min() for c in caches[:2]))
    return result_of(compare_gradients(f, pairs, scale=value), crossings, margin)
