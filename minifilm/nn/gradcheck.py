"""Numerical gradient checks: trust every backward pass by comparing it with centred differences.

Use in float64 only (in float32 the differences drown in rounding). Typical use on a forward /
backward pair of your own::

    rng = np.random.default_rng(0)
    errors = check_pair(linear_forward, linear_backward, (x, W, b), rng, names=("x", "W", "b"))
    assert max(errors.values()) < 1e-7            # {'x': 3e-11, 'W': 1e-11, 'b': 2e-12}

or, for anything else (a whole network, a loss), build a scalar function and the analytic pairs::

    errors = check_gradients(lambda: loss_of(x, W), {"x": (x, dx), "W": (W, dW)})

Precision: the error is relative per entry, so an entry whose true gradient is tiny next to the
loss can exceed 1e-7 from rounding alone (the two-point stencil's rounding error is about
1e-16 |f| / h). ``order=4, h=1e-4`` cuts that by ~100x and is what minifilm's own tests use.
"""
from __future__ import annotations

import math
from typing import Callable, Optional, Sequence

import numpy as np


def rel_error(a: np.ndarray, b: np.ndarray) -> float:
    """Largest elementwise relative error ``|a - b| / max(1e-8, |a| + |b|)`` (as in CS231n).

    The 1e-8 floor avoids 0 / 0 where both gradients are exactly zero (e.g. dropped units).
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"rel_error: shapes differ, {a.shape} vs {b.shape}")
    if a.size == 0:
        return 0.0
    return float(np.max(np.abs(a - b) / np.maximum(1e-8, np.abs(a) + np.abs(b))))


def numerical_gradient(f: Callable[[], float], x: np.ndarray, h: float = 1e-6,
                       order: int = 2) -> np.ndarray:
    """Centred-difference gradient of the scalar ``f()`` with respect to the array ``x``.

    ``x`` must be the very array ``f`` reads (a parameter view, an input array): each entry is
    moved in place, ``f`` is called, and the entry is restored exactly. Returns x's shape.

    order=2: (f(x + h) - f(x - h)) / 2h; truncation error ~h^2, rounding ~1e-16 |f| / h.
    order=4: (8 (f(x + h) - f(x - h)) - (f(x + 2h) - f(x - 2h))) / 12h; truncation ~h^4, so a
        larger h (about 1e-4) is allowed and the rounding error drops by 100x. Use it when a check
        at 1e-7 trips on entries whose true gradient is tiny (the elementwise relative error
        divides by |a| + |b|); keep inputs 2h away from kinks.
    """
    if order not in (2, 4):
        raise ValueError(f"numerical_gradient: order must be 2 or 4, got {order}")
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


def check_gradients(f: Callable[[], float], pairs: dict[str, tuple], h: float = 1e-6,
                    order: int = 2) -> dict[str, float]:
    """Compare analytic gradients with numerical ones.

    Args:
        f: the scalar function (reads the arrays below; called 2 * size times per array).
        pairs: ``{name: (array, analytic_gradient)}``; each array is perturbed in place.
        h, order: step and stencil of :func:`numerical_gradient`.
    Returns:
        ``{name: rel_error(analytic, numerical)}``.
    """
    errors = {}
    for name, (x, analytic) in pairs.items():
        analytic = np.array(analytic, dtype=np.float64)   # copy: f may overwrite shared buffers
        if analytic.shape != x.shape:
            raise ValueError(f"check_gradients: analytic gradient for {name!r} is {analytic.shape}, "
                             f"the array is {x.shape}")
        errors[name] = rel_error(analytic, numerical_gradient(f, x, h, order))
    return errors


def check_pair(forward: Callable, backward: Callable, inputs: Sequence[np.ndarray], rng: np.random.Generator,
               names: Optional[Sequence[str]] = None, h: float = 1e-4, order: int = 4,
               **forward_kwargs) -> dict[str, float]:
    """Check a forward/backward pair (functional.py, the model's blocks) for every input.

    ``out, cache = forward(*inputs, **forward_kwargs)`` and ``backward(dout, cache)`` returning
    dL/d(input) for the inputs in order (a tuple when there are several; ``None`` for an input
    without a gradient, e.g. a kept-out first layer's data). The scalar checked is
    L = sum(out * r) for a fixed random r, so the whole Jacobian is exercised; it is summed exactly
    (math.fsum), so outputs a perturbation does not touch cancel exactly between f(x + h) and
    f(x - h). Inputs must be float64; fix any randomness (dropout masks) in ``forward_kwargs``.
    Returns ``{name: rel_error}`` for every input that has a gradient (names default to
    ``input0``, ``input1``, ...).
    """
    out, cache = forward(*inputs, **forward_kwargs)
    r = rng.standard_normal(np.shape(out))

    def loss() -> float:
        return math.fsum((forward(*inputs, **forward_kwargs)[0] * r).ravel().tolist())

    grads = backward(r, cache)
    grads = grads if isinstance(grads, tuple) else (grads,)
    if len(grads) < len(inputs):
        raise ValueError(f"check_pair: backward returned {len(grads)} gradients for {len(inputs)} inputs")
    names = list(names) if names is not None else [f"input{i}" for i in range(len(inputs))]
    pairs = {name: (x, g) for name, x, g in zip(names, inputs, grads) if g is not None}
    return check_gradients(loss, pairs, h, order)
