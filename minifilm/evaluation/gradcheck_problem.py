"""How a network is set up for a gradient check, and how the check runs (used by the suite).

A :class:`Problem` is a toy-sized float64 network in training mode with every dropout mask
fixed, its inputs, and a scalar objective; :func:`check_problem` perturbs every entry of every
input and parameter array (minifilm.nn.gradcheck, four-point stencil) and :func:`float32_errors`
runs the same backward pass in float32. Before the check the set-up keeps the stencil away from
every point where the network is not smooth, or nearly not, instead of loosening the limit:

* ELU and ReLU inputs (ELU's second derivative jumps at 0, which spoils a four-point stencil as
  much as ReLU's kink): after a forward pass the inputs of each one are read from the network's
  caches, in forward order, and the bias of each unit is shifted by the smallest amount that
  puts all its rows at least MARGIN = 0.05 from 0 (≈ 170 h; a step of ±2h moves a pre-activation
  by at most a few h here). For Φ's ELUs that bias is FiLM's β, as Ψ emits it or as it is fed in;
* layer norm: its k-th derivative grows like 1/σ^k (σ = 0 is a kink), so a row whose σ is small
  (a toy layer whose inputs were mostly dropped) turns the stencil's h^4 truncation into a visible
  error; the experts' biases get the smallest multiple of a fixed zero-mean pattern that gives
  every row σ >= SIGMA_MIN = 0.5;
* max-pool ties (a kink of the maximum): the clips whose pairs come within MARGIN of a tie are
  redrawn (biases cannot separate two frames of the same unit), and the shifts are redone;
* the bone-length loss (|·| at 0, ‖·‖ at a zero-length bone): the target rows are redrawn until
  every bone's length differs from the prediction's by MARGIN.

And the check must not be vacuous: dropout masks that cut an array off from the output (in a toy
Ψ, all of a seed's few live ReLU units dropped: every gradient of Ψ and the clip is then exactly
0 on both sides, and "passes") are drawn again (:meth:`Problem.prepare`).

Then the side of every kink is recorded (ELU / ReLU sign, the winner of every max-pool pair,
the sign of every bone's length error, non-zero predicted bones) and compared on every
evaluation of the stencil: ``crossings`` counts evaluations on which any changed, and must be 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, List, Optional

import numpy as np

from minifilm.model.film_generator import FilmGenerator
from minifilm.model.gating import GatingNetwork
from minifilm.model.losses import bone_list, bone_length_loss, mse_loss
from minifilm.model.motion_net import MotionNetwork
from minifilm.nn.gradcheck import compare_gradients

MARGIN = 0.05
SIGMA_MIN = 0.5
NO_SIDES = np.zeros(0, bool)
#: toy skeleton of the whole-model check: 4 joints at output columns 2..13, chain 0-1-2 and 0-3
#: (joint 0 has two children, so the loss's scatter-add is exercised)
PARENTS = np.array([-1, 0, 1, 0])
POS_IDX = 2 + np.arange(12).reshape(4, 3)


# ---- kinks and near-singular points ---------------------------------------------------------
class Site:
    """An ELU or ReLU: ``pre()`` is its input (..., units) after a forward pass, ``shift(d)`` adds
    d (units,) to the bias that moves every row of each unit alike. :meth:`fix` moves every row
    at least ``margin`` from 0 with the smallest shift (``live``: a ReLU, kept alive, shift_away)."""

    def __init__(self, pre: Callable[[], np.ndarray], shift: Callable[[np.ndarray], None], live: bool = False):
        self.pre, self.shift, self.live = pre, shift, live

    def fix(self, margin: float) -> None:
        self.shift(shift_away(self.pre(), margin, self.live))

    def sides(self) -> np.ndarray:
        return (self.pre() > 0).ravel()

    def margin(self) -> float:
        return float(np.abs(self.pre()).min())


class NormSite(Site):
    """A layer norm: ``pre()`` is its input rows (B, H), ``shift(d)`` adds d (H,) to every row
    (to the biases of all experts). Its derivatives grow like 1/σ^k, so a row with a small σ is
    a near-singular point for a high-order stencil (σ = 0 is a kink): :meth:`fix` adds the
    smallest multiple of a fixed zero-mean pattern that gives every row σ >= SIGMA_MIN."""

    def fix(self, margin: float) -> None:
        rows = self.pre()
        u = np.linspace(-1.0, 1.0, rows.shape[-1])
        for c in (0.0, 0.25, -0.25, 0.5, -0.5, 1.0, -1.0, 2.0, -2.0, 4.0, -4.0):
            if np.std(rows + c * u, axis=-1, ddof=1).min() >= SIGMA_MIN:
                self.shift(c * u)
                return
        raise RuntimeError("NormSite: no shift gives every layer-norm row sigma >= SIGMA_MIN")

    def sides(self) -> np.ndarray:
        return NO_SIDES

    def margin(self) -> float:
        return np.inf                   # not a kink; sigma_min() reports it

    def sigma_min(self) -> float:
        return float(np.std(self.pre(), axis=-1, ddof=1).min())


def _add(a: np.ndarray, d: np.ndarray) -> None:
    a += d                                      # in place: a is a view into a parameter buffer


def shift_away(values: np.ndarray, margin: float, live: bool = False) -> np.ndarray:
    """d (units,): for each unit (last axis) the smallest |d| with every |values + d| >= margin,
    among the shifts that keep a row on each side of 0 where there was one (so both branches of
    the unit stay exercised and no ReLU unit is shifted dead), else the smallest of all.
    ``live`` (a ReLU): first of all leave a row above 0 in every unit, even if no row is then
    left below it: a dead unit's weights are checked vacuously, and in a toy Ψ the few units of
    a layer can all be dead, cutting Ψ off from the output whatever the dropout masks."""
    v = values.reshape(-1, values.shape[-1])
    d = np.zeros(v.shape[1])
    for u in range(v.shape[1]):
        col = v[:, u]
        cands = np.concatenate([[0.0], -col - 1.25 * margin, -col + 1.25 * margin])
        cands = cands[np.argsort(np.abs(cands), kind="stable")]
        ok = [c for c in cands if np.all(np.abs(col + c) >= margin)]
        sides = [c for c in ok if (col + c > 0).any() >= (col > 0).any() and (col + c < 0).any() >= (col < 0).any()]
        if live:                                    # alive first; both sides when it can have them
            sides = [c for c in sides if (col + c > 0).any()] or [c for c in ok if (col + c > 0).any()]
        d[u] = (sides or ok)[0]
    return d


def gating_sites(net: GatingNetwork) -> List[Site]:
    return [Site(lambda l=l: net._caches[l].act[0], lambda d, l=l: _add(net.params.params[f"b{l}"], d))
            for l in range(2)]


def film_generator_sites(net: FilmGenerator) -> List[Site]:
    P = net.params.params
    return [Site(lambda: net._caches[0].relu, lambda d: _add(P["conv0_b"], d), live=True),
            Site(lambda: net._caches[1].relu, lambda d: _add(P["conv1_b"], d), live=True),
            Site(lambda: net._caches[3].act, lambda d: _add(P["dense0_b"], d), live=True)]


def motion_sites(net: MotionNetwork, beta: Callable[[int], np.ndarray]) -> List[Site]:
    """Φ's two Eq. (3) blocks: the layer norm's input (shifted through the experts' biases), then
    the ELU's (shifted through FiLM's β; ``beta(i)`` is the array of layer i's β (..., H))."""
    P = net.params.params
    out = []
    for i in range(2):
        out.append(NormSite(lambda i=i: net._caches[i].norm[0], lambda d, i=i: _add(P[f"b{i}"], d)))
        out.append(Site(lambda i=i: net._caches[i].elu[0], lambda d, i=i: _add(beta(i), d)))
    return out


def expert_net_sites(net) -> List[Site]:
    """The ELUs of the variants' Φ without FiLM; shifting every expert's bias by d shifts the
    blend by d (the blend weights sum to 1)."""
    return [Site(lambda l=l: net._caches[l][1][0], lambda d, l=l: _add(net.params.params[f"b{l}"], d))
            for l in range(2)]


def pool_sides(net: FilmGenerator) -> List[np.ndarray]:
    """Which frame wins each max-pool pair of Ψ (both-zero pairs stay 'first' unless a ReLU flips)."""
    return [net._caches[0].pool[1], net._caches[1].pool[1]]


def pool_gaps(net: FilmGenerator) -> np.ndarray:
    """(clips,) the smallest gap, per clip, between the two frames of a max-pool pair whose
    maximum is positive (a tie is a kink of the maximum)."""
    gaps = []
    for c in net._caches[:2]:
        r = np.maximum(c.relu, 0)
        T2 = r.shape[1] // 2
        even, odd = r[:, 0:2 * T2:2], r[:, 1:2 * T2:2]
        gap = np.where(np.maximum(even, odd) > 0, np.abs(even - odd), np.inf)
        gaps.append(gap.reshape(len(gap), -1).min(axis=1))
    return np.minimum(*gaps)


def bone_lengths(out, target, mean, std):
    """Bone lengths (N, bones) in metres of the prediction and the target (Eq. 6)."""
    par, child = bone_list(PARENTS)
    sd, mu = std[POS_IDX], mean[POS_IDX]
    lengths = []
    for z in (out, target):
        pos = z[:, POS_IDX] * sd + mu
        lengths.append(np.linalg.norm(pos[:, par] - pos[:, child], axis=-1))
    return lengths


# ---- objectives ---------------------------------------------------------------------------
def projection(r: np.ndarray):
    """L = sum(out * r), summed exactly: every output weighted by an O(1) random number."""
    def objective(out):
        terms = (out * r).ravel().tolist()
        return math.fsum(terms), r, NO_SIDES, math.fsum(map(abs, terms))
    return objective


def training_objective(target, mean, std):
    """Eq. (5)-(7): L = MSE + bone-length loss of the toy skeleton (POS_IDX, PARENTS)."""
    def objective(out):
        m, d1 = mse_loss(out, target)
        b, d2 = bone_length_loss(out, target, POS_IDX, PARENTS, mean, std)
        hat, true = bone_lengths(out, target, mean, std)
        return m + b, d1 + d2, np.concatenate([(true > hat).ravel(), (hat > 0).ravel()]), m + b
    return objective


def bll_target(out, rng, mean, std, margin=MARGIN):
    """A random target whose every bone length differs from the prediction's by >= margin."""
    target = rng.standard_normal(out.shape)
    for b in range(len(out)):
        while True:
            hat, true = bone_lengths(out[b:b + 1], target[b:b + 1], mean, std)
            if np.abs(true - hat).min() >= margin:
                break
            target[b] = rng.standard_normal(out.shape[1])
    return target


# ---- the problem --------------------------------------------------------------------------
@dataclass
class Problem:
    """One network's check, built in float64 for one seed.

    forward(model, inputs) -> out with the dropout masks of ``masks`` (the dict the forward
    reads); draw_masks() -> new masks (a training pass with ``rng``); backward(model, dout) ->
    {input: gradient}; objective(out) -> (value, dout, kink sides of the loss, scale);
    nets(model) -> {label: Parameters} in a fixed order; make(dtype) -> a fresh model of the same
    architecture (the float32 comparison copies ``model``'s parameters into it). sites: the
    ELUs, ReLUs and layer norms in forward order; psi: the FilmGenerator whose max-pool pairs are
    kept from ties by redrawing rows of ``inputs['clip']`` (None: no Ψ in this forward pass).
    """

    model: object
    make: Callable
    nets: Callable
    inputs: dict
    forward: Callable
    backward: Callable
    rng: np.random.Generator
    masks: dict
    draw_masks: Callable
    sites: List[Site] = field(default_factory=list)
    psi: Optional[FilmGenerator] = None
    objective: Optional[Callable] = None
    loss_margin: Callable = lambda out: np.inf

    def run(self, model=None, inputs=None):
        return self.forward(self.model if model is None else model, self.inputs if inputs is None else inputs)

    def prepare(self) -> "Problem":
        """Draw the dropout masks and condition. Masks that cut an array off from the output (a
        toy layer whose few live units were all dropped: its check would be vacuous) are drawn
        again."""
        for _ in range(20):
            self.masks.clear()
            self.masks.update(self.draw_masks())
            self.condition()
            if self.connected():
                return self
        raise RuntimeError("Problem.prepare: no dropout masks left every array connected")

    def condition(self) -> None:
        """Move every kink MARGIN from the inputs of its switch and every layer-norm row to
        σ >= SIGMA_MIN (biases, forward order), redrawing clips with a near max-pool tie."""
        for _ in range(100):
            for site in self.sites:
                self.run()
                site.fix(MARGIN)
            self.run()
            bad = [] if self.psi is None else np.flatnonzero(pool_gaps(self.psi) < MARGIN)
            if not len(bad):
                return
            clip = self.inputs["clip"]
            clip[bad] = self.rng.standard_normal(clip[bad].shape)
        raise RuntimeError("Problem.condition: could not keep the max-pool pairs away from ties")

    def connected(self) -> bool:
        """Every input and parameter array gets a non-zero gradient from a random projection
        (FloatingPointError when one is not finite)."""
        nets = self.nets(self.model)
        for ps in nets.values():
            ps.zero_grad()
        out = self.run()
        grads = self.backward(self.model, np.random.default_rng(0).standard_normal(out.shape))
        arrays = {**grads, **{f"{label}.{n}": ps.grads[n] for label, ps in nets.items() for n in ps.names()}}
        bad = [name for name, g in arrays.items() if not np.all(np.isfinite(g))]
        if bad:                         # a broken backward pass: no mask can fix it, so say so
            raise FloatingPointError(f"the backward pass gave non-finite gradients (NaN or inf) of {', '.join(bad)}")
        return all(np.abs(g).max() > 0 for g in arrays.values())

    def sides(self, loss_sides) -> np.ndarray:
        """Which side of every kink each input is on (compared on every stencil evaluation)."""
        parts = [s.sides() for s in self.sites]
        if self.psi is not None:
            parts += [p.ravel() for p in pool_sides(self.psi)]
        return np.concatenate(parts + [loss_sides])

    def margin(self, out) -> float:
        """Smallest distance of an input of a kink from its switching point (after a forward)."""
        m = [s.margin() for s in self.sites] + [self.loss_margin(out)]
        if self.psi is not None:
            m.append(float(pool_gaps(self.psi).min()))
        return float(min(m))

    def sigma_min(self) -> float:
        """Smallest layer-norm σ of a row (inf without layer norm)."""
        return min([s.sigma_min() for s in self.sites if isinstance(s, NormSite)] + [np.inf])


# ---- running a problem ----------------------------------------------------------------------
@dataclass
class Result:
    """One check on one seed: the worst relative error and the entries of each array, the
    evaluations that crossed a kink, and the smallest distance of a kink from its switch."""

    errors: dict
    entries: dict
    crossings: int = 0
    margin: float = np.inf
    worst: str = ""


def result_of(comparisons: dict, crossings: int = 0, margin: float = np.inf) -> Result:
    if not comparisons:
        return Result({}, {}, crossings, margin, "no array was checked")
    name = max(comparisons, key=lambda k: comparisons[k].error)    # errors are never NaN (inf instead)
    c = comparisons[name]
    where = f"{name}{list(c.worst)}: analytic {c.analytic[c.worst]:.3e}, numerical {c.numerical[c.worst]:.3e}"
    return Result({k: v.error for k, v in comparisons.items()}, {k: v.entries for k, v in comparisons.items()},
                  crossings, margin, where)


def problem_pairs(pr: Problem, model=None, inputs=None, dout=None):
    """(output, objective value, dout, loss sides, scale, {array: (array, gradient)}) after one
    forward and backward pass (parameter gradients zeroed first; ``dout`` given: the incoming
    gradient instead of the objective's)."""
    model = pr.model if model is None else model
    inputs = pr.inputs if inputs is None else inputs
    nets = pr.nets(model)
    for ps in nets.values():
        ps.zero_grad()
    out = pr.forward(model, inputs)
    value, d, loss_sides, scale = pr.objective(out)
    dout = d if dout is None else dout
    grads = pr.backward(model, dout)
    pairs = {name: (a, grads[name]) for name, a in inputs.items()}
    for label, ps in nets.items():
        for name in ps.names():
            pairs[f"{label}.{name}"] = (ps.params[name], ps.grads[name])
    return out, value, dout, loss_sides, scale, pairs


def check_problem(pr: Problem) -> Result:
    """Every entry of every input and parameter array against the four-point stencil, the
    objective normalised (minifilm.nn.gradcheck), with the kink guard."""
    out, _, _, loss_sides, scale, pairs = problem_pairs(pr)
    pairs = {k: (a, g.copy()) for k, (a, g) in pairs.items()}
    base, margin = pr.sides(loss_sides), pr.margin(out)
    crossings = 0

    def f():
        nonlocal crossings
        value, _, sides, _ = pr.objective(pr.run())
        crossings += not np.array_equal(pr.sides(sides), base)
        return value

    return result_of(compare_gradients(f, pairs, scale=scale), crossings, margin)


def float32_errors(pr: Problem) -> Result:
    """The same backward pass (same parameters, inputs, masks and incoming gradient) in float32
    against float64: per array max|g32 − g64| / max|g64|. Raises if float32 does not stay float32."""
    _, _, dout, _, _, pairs64 = problem_pairs(pr)
    pairs64 = {k: g.copy() for k, (_, g) in pairs64.items()}
    model = pr.make(np.float32)
    for a, b in zip(pr.nets(pr.model).values(), pr.nets(model).values()):
        b.data[...] = a.data
    out, _, _, _, _, pairs32 = problem_pairs(pr, model, {k: v.astype(np.float32) for k, v in pr.inputs.items()},
                                             dout=dout.astype(np.float32))
    errors = {}
    for k, g64 in pairs64.items():
        g32 = pairs32[k][1]
        if out.dtype != np.float32 or g32.dtype != np.float32:
            raise TypeError(f"float32 check: {k} came out as {g32.dtype} (output {out.dtype})")
        with np.errstate(invalid="ignore", over="ignore"):
            diff = float(np.max(np.abs(g32.astype(np.float64) - g64)) / max(float(np.max(np.abs(g64))), 1e-300))
        finite = np.all(np.isfinite(g32)) and np.all(np.isfinite(g64))
        errors[k] = diff if finite and math.isfinite(diff) else math.inf      # NaN / inf: a failure
    worst = max(errors, key=errors.get)
    return Result(errors, {k: int(g.size) for k, g in pairs64.items()}, worst=f"{worst}: {errors[worst]:.1e}")
