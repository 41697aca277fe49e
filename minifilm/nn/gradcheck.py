"""Numerical gradient checks: trust every backward pass by comparing it with centred differences.

One method for everything minifilm checks (the kit's pairs, the model's blocks, the losses, Ω,
Φ, Ψ, the style model, the comparison variants; ``minifilm gradcheck`` prints them all): the
**four-point centred difference** in float64,

    f'(x) ≈ (8 (f(x + h) − f(x − h)) − (f(x + 2h) − f(x − 2h))) / 12h        h = H = 3e-4

for every entry of every array, compared with the analytic gradient by the elementwise relative
error ``|a − b| / max(1e-8, |a| + |b|)``, which must stay below LIMIT = 1e-7 wherever the function
is smooth, with the scalar normalised to SCALE = 1e-4 (below). On a forward / backward pair::

    rng = np.random.default_rng(0)
    errors = check_pair(linear_forward, linear_backward, (x, W, b), rng, names=("x", "W", "b"))
    assert passed(errors)                          # e.g. {'x': 3e-11, 'W': 1e-11, 'b': 2e-12}

or, for anything else (a whole network, a loss), a scalar function and the analytic pairs::

    errors = check_gradients(lambda: loss_of(x, W), {"x": (x, dx), "W": (W, dW)}, scale=S)

Why these numbers. The numerical derivative has two errors: truncation, ~h^4 f^(5) / 30 for the
four-point stencil (~h^2 f^(3) / 6 for the two-point one), and rounding, ~1.5 ε S / h, where S
is the size of the numbers f adds up (ε = 2.2e-16). A small network's fifth derivatives reach
~1e3 S per unit step, which puts the best h near 3e-4, where both are ≈ 1e-13 S. Measured on
the whole style model (seeds 0-4, normalised as below): four-point 2e-8 / 9e-9 / 3e-9 at
h = 1e-4 / 3e-4 / 1e-3; two-point at its best (h = 1e-5 to 3e-5) 1.7e-7, so it cannot reach 1e-7.

The relative error is per entry, so an entry whose true gradient is tiny next to S (a sum over
samples whose terms cancel; a nearly saturated unit) measures rounding, not the backward pass:
un-normalised, entries of ~1e-7 S fail 1e-7 however exact the gradient. The floor of rel_error
makes it absolute below |a| + |b| = 1e-8 (|a − b| <= 1e-15 passes). So ``scale=S`` multiplies f
and the analytic gradients by SCALE / S: the rounding (≈ 1e-16) then sits 10x under that
absolute tolerance, every entry above 5e-5 S is checked relatively to 1e-7, and the smaller
ones (about 1 % of a network's non-zero entries) absolutely, to 1e-11 S, which is as precisely as
any finite difference can measure them.

A larger h is not better either: the stencil spans ±2h, and every kink it crosses (ReLU / ELU at
0, where ELU's *second* derivative jumps, which spoils any high-order stencil; a max-pool tie;
|·| at 0) costs an error of order h, and a layer-norm row with a small σ (σ = 0 is a kink) has
huge high derivatives. So checks keep their inputs far from those points
(minifilm/evaluation/gradcheck_problem.py explains how) rather than loosening the limit.

Use float64 only: in float32 the differences drown in rounding (compare float32 backward passes
with float64 ones instead, as the suite does).

NaN or inf anywhere is a failure. An entry where either gradient is not finite (a backward pass
that returns NaN, a forward pass that overflows inside the stencil) has the error ``inf``, never
NaN: NaN compares False with everything, so ``max(errors.values()) < LIMIT`` or ``worst <= limit``
would let it through depending on the order of the arrays. :func:`worst_error` and
:func:`passed` read a dict of errors the same way (no errors at all: nothing was checked, a
failure too); the suite's rows, its table and the tests all go through them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional, Sequence

import numpy as np

#: the suite's step, stencil and limit (see the module docstring)
H = 3e-4
ORDER = 4
LIMIT = 1e-7
SCALE = 1e-4


def rel_error(a: np.ndarray, b: np.ndarray) -> float:
    """Largest elementwise relative error ``|a - b| / max(1e-8, |a| + |b|)`` (as in CS231n).

    The 1e-8 floor avoids 0 / 0 where both gradients are exactly zero (e.g. dropped units).
    ``inf`` when any entry of either is NaN or inf.
    """
    return float(np.max(rel_errors(a, b))) if np.size(a) else 0.0


def rel_errors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The elementwise relative errors of :func:`rel_error`, one per entry (``inf`` where either
    entry is not finite)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"rel_error: shapes differ, {a.shape} vs {b.shape}")
    with np.errstate(invalid="ignore"):
        errs = np.abs(a - b) / np.maximum(1e-8, np.abs(a) + np.abs(b))
    errs[~(np.isfinite(a) & np.isfinite(b))] = np.inf
    return errs


def worst_error(errors) -> float:
    """The largest of a check's errors (a dict ``{name: error}`` or any iterable of numbers), a
    NaN or inf among them counting as ``inf``; ``inf`` too when there are none (nothing was
    checked). Unlike ``max``, the answer does not depend on the order of the values."""
    values = [float(e) for e in (errors.values() if isinstance(errors, dict) else errors)]
    return max((v if math.isfinite(v) else math.inf for v in values), default=math.inf)


def passed(errors, limit: float = LIMIT) -> bool:
    """True when every error of a check is finite and below ``limit`` (see :func:`worst_error`)."""
    return worst_error(errors) < limit


def _check_step(h, where: str) -> float:
    """h as a float, or a ValueError naming ``where``: the stencil needs a finite step > 0."""
    ok = isinstance(h, (int, float, np.integer, np.floating)) and not isinstance(h, bool)
    if not (ok and math.isfinite(h) and h > 0):
        raise ValueError(f"{where}: h must be a finite step > 0, got {h!r}")
    return float(h)


def numerical_gradient(f: Callable[[], float], x: np.ndarray, h: float = H,
                       order: int = ORDER) -> np.ndarray:
    """Centred-difference gradient of the scalar ``f()`` with respect to the array ``x``.

    ``x`` must be the very array ``f`` reads (a parameter view, an input array): each entry is
    moved in place, ``f`` is called, and the entry is restored exactly. Returns x's shape.

    order=4 (the default): (8 (f(x + h) - f(x - h)) - (f(x + 2h) - f(x - 2h))) / 12h,
        truncation ~h^4, rounding ~1.5 δ / h (δ: rounding error of f); keep inputs 2h from kinks.
    order=2: (f(x + h) - f(x - h)) / 2h; truncation ~h^2, rounding ~δ / h (shown for comparison:
        at h = 1e-6 it cannot reach 1e-7 on entries under ~1e-3 of the loss's scale).
    """
    if order not in (2, 4):
        raise ValueError(f"numerical_gradient: order must be 2 or 4, got {order}")
    h = _check_step(h, "numerical_gradient")
    if not isinstance(x, np.ndarray) or x.dtype != np.float64:
        raise TypeError("numerical_gradient: x must be a float64 ndarray (centred differences with "
                        f"h={h} are meaningless in lower precision), got "
                        f"{getattr(x, 'dtype', type(x).__name__)}")
    grad = np.zeros_like(x)
    for i in np.ndindex(x.shape):
        old = x[i]
        x[i] = old + h
        f_plus = float(f())
        x[i] = old - h
        f_minus = float(f())
        if order == 2:
            grad[i] = (f_plus - f_minus) / (2 * h)
        else:
            x[i] = old + 2 * h
            f_plus2 = float(f())
            x[i] = old - 2 * h
            f_minus2 = float(f())
            grad[i] = (8 * (f_plus - f_minus) - (f_plus2 - f_minus2)) / (12 * h)
        x[i] = old
    return grad


@dataclass
class Comparison:
    """One array's check: the worst elementwise relative error, where it is, and both gradients."""

    error: float
    entries: int
    worst: tuple
    analytic: np.ndarray
    numerical: np.ndarray


def compare_gradients(f: Callable[[], float], pairs: dict, h: float = H, order: int = ORDER,
                      scale: Optional[float] = None) -> dict:
    """Like :func:`check_gradients`, with the details: ``{name: Comparison}`` (the gradients
    compared, i.e. multiplied by ``SCALE / scale`` when ``scale`` is given)."""
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"check_gradients: scale must be a finite number > 0 (the size of f's terms), got {scale!r}")
    h = _check_step(h, "check_gradients")
    k = 1.0 if scale is None else SCALE / scale
    g = f if scale is None else (lambda: k * float(f()))
    out = {}
    for name, (x, analytic) in pairs.items():
        analytic = k * np.array(analytic, dtype=np.float64)   # a copy: f may overwrite shared buffers
        if analytic.shape != x.shape:
            raise ValueError(f"check_gradients: analytic gradient for {name!r} is {analytic.shape}, "
                             f"the array is {x.shape}")
        numerical = numerical_gradient(g, x, h, order)
        errs = rel_errors(analytic, numerical)
        worst = np.unravel_index(int(np.argmax(errs)), errs.shape) if errs.size else ()
        out[name] = Comparison(float(errs.max()) if errs.size else 0.0, int(x.size), tuple(int(i) for i in worst),
                               analytic, numerical)
    return out


def check_gradients(f: Callable[[], float], pairs: dict, h: float = H, order: int = ORDER,
                    scale: Optional[float] = None) -> dict:
    """Compare analytic gradients with numerical ones.

    Args:
        f: the scalar function (reads the arrays below; called 4 * size times per array).
        pairs: ``{name: (array, analytic_gradient)}``; each array is perturbed in place.
        h, order: step and stencil of :func:`numerical_gradient` (the suite's H and ORDER).
        scale: the size of the numbers f adds up at the current point (the sum of the absolute
            values of its terms); f and the gradients are then multiplied by SCALE / scale
            before they are compared (see "Why these numbers" above). None: compared as given.
    Returns:
        ``{name: rel_error(analytic, numerical)}``; ``inf`` for an array where either gradient
        has a NaN or inf (read them with :func:`passed`).
    """
    return {name: c.error for name, c in compare_gradients(f, pairs, h, order, scale).items()}


def pair_loss(forward: Callable, inputs: Sequence[np.ndarray], r: np.ndarray, **forward_kwargs):
    """The scalar of :func:`check_pair`: ``L = sum(forward(*inputs)[0] * r)``, summed exactly
    (NaN when an output is not finite, which fails the check)."""
    def loss() -> float:
        terms = (forward(*inputs, **forward_kwargs)[0] * r).ravel()
        return math.fsum(terms.tolist()) if np.all(np.isfinite(terms)) else math.nan
    return loss


def check_pair(forward: Callable, backward: Callable, inputs: Sequence[np.ndarray], rng: np.random.Generator,
               names: Optional[Sequence[str]] = None, h: float = H, order: int = ORDER,
               **forward_kwargs) -> dict:
    """Check a forward/backward pair (functional.py, the model's blocks) for every input.

    ``out, cache = forward(*inputs, **forward_kwargs)`` and ``backward(dout, cache)`` returning
    dL/d(input) for the inputs in order (a tuple when there are several; ``None`` for an input
    without a gradient, e.g. a kept-out first layer's data). The scalar checked is
    L = sum(out * r) for a fixed random r, so the whole Jacobian is exercised; it is summed exactly
    (math.fsum), so outputs a perturbation does not touch cancel exactly between f(x + h) and
    f(x - h), and normalised with scale = sum|out * r| (see the module docstring). Inputs must be
    float64; fix any randomness (dropout masks) in ``forward_kwargs``.
    Returns ``{name: rel_error}`` for every input that has a gradient (names default to
    ``input0``, ``input1``, ...); ``inf`` where a gradient or the output is not finite.
    A backward pass that returns a gradient of the wrong shape is a ValueError.
    """
    out, cache = forward(*inputs, **forward_kwargs)
    r = rng.standard_normal(np.shape(out))
    grads = backward(r, cache)
    grads = grads if isinstance(grads, tuple) else (grads,)
    if len(grads) < len(inputs):
        raise ValueError(f"check_pair: backward returned {len(grads)} gradients for {len(inputs)} inputs")
    names = list(names) if names is not None else [f"input{i}" for i in range(len(inputs))]
    pairs = {name: (x, g) for name, x, g in zip(names, inputs, grads) if g is not None}
    finite = bool(np.all(np.isfinite(out)))        # a non-finite output: unnormalised, it fails below
    scale = (math.fsum(np.abs(out * r).ravel().tolist()) or None) if finite else None
    return check_gradients(pair_loss(forward, inputs, r, **forward_kwargs), pairs, h, order, scale)
