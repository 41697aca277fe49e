"""The gradient checks of the style modulations other than FiLM (the baselines of the paper's Sec. 5:
minifilm/baselines/style_modulation.py, phase_function.py), rows of ``minifilm gradcheck`` like the
kit's (minifilm/evaluation/gradcheck_cases.py: every entry of every input and parameter against the
four-point stencil, the scalar ``L = Σ out ∘ r``). These layers are smooth in every input checked.
"""
from __future__ import annotations

import math

import numpy as np

from minifilm.baselines.phase_function import catmull_rom_weights
from minifilm.baselines.style_modulation import CPResidualAdapter, OneHotShift, ResidualAdapter
from minifilm.evaluation.gradcheck_cases import _rng, pair_result
from minifilm.evaluation.gradcheck_problem import Result, result_of
from minifilm.nn import functional as F
from minifilm.nn.gradcheck import compare_gradients


def _module_result(forward, backward, params, inputs: dict, rng) -> Result:
    """forward() -> out reading ``inputs`` and ``params``; backward(dout) -> {input: grad}."""
    params.zero_grad()
    out = forward()
    r = rng.standard_normal(out.shape)
    grads = backward(r)
    pairs = {k: (v, grads[k]) for k, v in inputs.items()}
    pairs.update({k: (params.params[k], params.grads[k].copy()) for k in params.names()})
    return result_of(compare_gradients(lambda: math.fsum((forward() * r).ravel().tolist()), pairs,
                                       scale=math.fsum(np.abs(out * r).ravel().tolist())))


STYLES = np.array([0, 2, 2, 0, 2])                   # a mixed batch; style 1 absent


def onehot(seed, blended=False):
    """Σ_k α_k E[k, s]: per style id, or (blended) for a soft one-hot vector (B, S)."""
    rng = _rng(seed, 40 + blended)
    m = OneHotShift(3, 3, 5, 8, rng, np.float64)
    alpha = rng.dirichlet(np.ones(3), size=len(STYLES))
    style = rng.dirichlet(np.ones(3), size=len(STYLES)) if blended else STYLES
    return _module_result(lambda: m.forward(style, alpha), lambda d: {"alpha": m.backward(d)}, m.params,
                          {"alpha": alpha}, rng)


def residual_adapter(seed):
    rng = _rng(seed, 42)
    m = ResidualAdapter(3, 5, rng, np.float64)
    m.params.data[...] = rng.standard_normal(m.params.size)
    h = rng.standard_normal((len(STYLES), 5))
    return _module_result(lambda: m.forward(h, STYLES), lambda d: {"h": m.backward(d)}, m.params, {"h": h}, rng)


def cp_adapter(seed):
    rng = _rng(seed, 43)
    m = CPResidualAdapter(3, 5, 4, rng, 4, np.float64)
    m.params.data[...] += rng.standard_normal(m.params.size)
    h = rng.standard_normal((len(STYLES), 5))
    w = catmull_rom_weights(rng.random(len(STYLES)))
    return _module_result(lambda: m.forward(h, STYLES, w), lambda d: {"h": m.backward(d)}, m.params, {"h": h}, rng)


def phase_function_layer(seed):
    """A PFNN layer W(φ) = Σ_k w_k(φ) W_k: gradients of the 4 control points (the phase is data)."""
    rng = _rng(seed, 44)
    w = catmull_rom_weights(np.concatenate([[0.0, 0.999], rng.random(3)]))   # a knot, a wrap-around
    inputs = (rng.standard_normal((5, 3)), w, rng.standard_normal((4, 3, 2)), rng.standard_normal((4, 2)))
    return pair_result(F.expert_linear_forward, F.expert_linear_backward, inputs, ("x", None, "W", "b"), rng)
