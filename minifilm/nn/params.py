"""Parameters: every named weight array of a network as a view into ONE flat buffer.

Why one buffer: at small batch sizes an optimiser step over dozens of separate arrays costs more
than the forward pass. With all weights in ``data`` (N,) and all gradients in ``grad`` (N,), one
Adam step is a handful of vector operations (optim.py; in place, fast_optim.py), while layers still read and
write named arrays: ``params["W"]`` is a reshaped view into ``data``, ``grads["W"]`` into ``grad``.

Also here: initialisers that fill an array in place from an explicit ``np.random.Generator``.
"""
from __future__ import annotations

import math

import numpy as np


class Parameters:
    """Named arrays stored in one flat buffer.

    Args:
        shapes: ``{name: shape}``, in the order the arrays are laid out in the buffer.
        dtype: float32 for training, float64 for gradient checks.

    Attributes:
        data (N,), grad (N,): the flat buffers (weights start at zero; use the init_* helpers).
        params[name], grads[name]: views into ``data`` and ``grad`` with the given shapes.
        trainable: when False, the optimiser leaves this set alone (freezing, Sec. 5.3.2).
        size: N, the total number of numbers.
    """

    def __init__(self, shapes: dict[str, tuple], dtype=np.float32):
        self.shapes = {}
        for name, shape in shapes.items():
            shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(int(n) for n in shape)
            if any(n < 0 for n in shape):
                raise ValueError(f"Parameters: negative size in shape {shape} of {name!r}")
            self.shapes[name] = shape
        self.dtype = np.dtype(dtype)
        if self.dtype.kind != "f":
            raise ValueError(f"Parameters: dtype must be floating point, got {self.dtype}")
        self.size = sum(math.prod(s) for s in self.shapes.values())
        self.data = np.zeros(self.size, dtype=self.dtype)
        self.grad = np.zeros(self.size, dtype=self.dtype)
        self.params: dict[str, np.ndarray] = {}
        self.grads: dict[str, np.ndarray] = {}
        self.slices: dict[str, slice] = {}
        start = 0
        for name, shape in self.shapes.items():
            stop = start + math.prod(shape)
            self.slices[name] = slice(start, stop)
            self.params[name] = self.data[start:stop].reshape(shape)   # views, never copies
            self.grads[name] = self.grad[start:stop].reshape(shape)
            start = stop
        self.trainable = True

    def bind(self, data: np.ndarray, grad: np.ndarray) -> None:
        """Move the set onto the given flat buffers (N,) of its dtype, e.g. a view into one gradient
        buffer shared by several sets (minifilm/train/mpi.py sums it across MPI ranks in one call):
        the current values are copied into ``data`` and ``grad``, and ``params`` / ``grads`` become
        views into them."""
        for name, buf in (("data", data), ("grad", grad)):
            if buf.shape != (self.size,) or buf.dtype != self.dtype:
                raise ValueError(f"Parameters.bind: {name} must be ({self.size},) {self.dtype}, "
                                 f"got {buf.shape} {buf.dtype}")
        data[...] = self.data
        grad[...] = self.grad
        self.data, self.grad = data, grad
        for name, shape in self.shapes.items():
            self.params[name] = data[self.slices[name]].reshape(shape)
            self.grads[name] = grad[self.slices[name]].reshape(shape)

    def __repr__(self) -> str:
        inner = ", ".join(f"{n}{s}" for n, s in self.shapes.items())
        return f"Parameters({inner}; size={self.size}, {self.dtype}, trainable={self.trainable})"

    def __contains__(self, name: str) -> bool:
        return name in self.params

    def __getitem__(self, name: str) -> np.ndarray:
        return self.params[name]

    def names(self) -> list[str]:
        return list(self.shapes)

    def zero_grad(self) -> None:
        """Set every gradient to zero in place (the views stay valid)."""
        self.grad.fill(0)

    def state_dict(self) -> dict[str, np.ndarray]:
        """``{name: copy of the array}``, ready for ``np.savez``."""
        return {name: p.copy() for name, p in self.params.items()}

    def load_state_dict(self, state: dict, strict: bool = False) -> None:
        """Copy arrays from ``state`` into the buffer (cast to this set's dtype).

        Raises KeyError naming any missing names, ValueError naming any shape mismatch; with
        ``strict=True`` names in ``state`` that this set does not have are an error too.
        """
        missing = [n for n in self.params if n not in state]
        if missing:
            raise KeyError(f"Parameters.load_state_dict: missing {missing} "
                           f"(have {sorted(state)[:10]}{'...' if len(state) > 10 else ''})")
        if strict:
            extra = [n for n in state if n not in self.params]
            if extra:
                raise KeyError(f"Parameters.load_state_dict: unexpected names {extra}")
        for name, p in self.params.items():
            value = np.asarray(state[name])
            if value.shape != p.shape:
                raise ValueError(f"Parameters.load_state_dict: {name!r} has shape {value.shape}, "
                                 f"expected {p.shape}")
        for name, p in self.params.items():   # only write once everything is known to fit
            p[...] = state[name]

    def astype(self, dtype) -> "Parameters":
        """A copy in another dtype (same names, values, gradients and ``trainable`` flag)."""
        other = Parameters(self.shapes, dtype=dtype)
        other.data[...] = self.data
        other.grad[...] = self.grad
        other.trainable = self.trainable
        return other


# --------------------------------------------------------------------------------------------
# Initialisers: fill an array in place (a view into Parameters.data) and return it.
# --------------------------------------------------------------------------------------------
def init_uniform_fan(a: np.ndarray, fan_in: int, fan_out: int, rng: np.random.Generator) -> np.ndarray:
    """Glorot/Xavier uniform: U(-r, r) with r = sqrt(6 / (fan_in + fan_out)).

    The original initialises every expert matrix this way, with fan_in, fan_out the layer's input
    and output sizes (not counting the K experts).
    """
    r = math.sqrt(6.0 / (fan_in + fan_out))
    a[...] = rng.uniform(-r, r, size=a.shape)
    return a


def init_he_normal(a: np.ndarray, fan_in: int, rng: np.random.Generator) -> np.ndarray:
    """He normal: N(0, 2 / fan_in), suited to ReLU-like layers."""
    a[...] = rng.standard_normal(a.shape) * math.sqrt(2.0 / fan_in)
    return a


def init_constant(a: np.ndarray, value: float = 0.0) -> np.ndarray:
    """Fill with a constant (biases: 0; FiLM scales: 1)."""
    a[...] = value
    return a
