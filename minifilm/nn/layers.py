"""Thin layer classes: each holds its weights and the last forward cache, and calls functional.py.

Every layer has
    ``params``, ``grads``: dicts with the same keys (e.g. "W", "b"); views into a
        :class:`~minifilm.nn.params.Parameters` buffer (``.parameters``), empty for layers
        without weights;
    ``forward(x, ..., train=False, rng=None) -> out`` (remembers what backward needs);
    ``backward(dout) -> dx`` (a tuple when the layer has several inputs); parameter gradients
        are ADDED to ``grads`` (``+=``), so call ``parameters.zero_grad()`` before each step.
A layer never changes its own weights; only the optimiser does.

Sharing one buffer: a network can lay out all its layers in ONE Parameters (so Adam is a few
vector operations) by collecting ``Layer.param_shapes(..., prefix="l0.")`` of every layer and
passing ``parameters=..., prefix="l0."`` to each constructor. Without ``parameters`` a layer makes
its own. With ``rng`` the weights are initialised (Glorot uniform, biases 0); without, they are
left as they are (zeros in a fresh buffer, e.g. before ``load_state_dict``).
"""
from __future__ import annotations

import numpy as np

from minifilm.nn import functional as F
from minifilm.nn.params import Parameters, init_uniform_fan


class Layer:
    """Base class: no weights, and the bookkeeping for the forward cache."""

    def __init__(self):
        self.parameters: Parameters | None = None
        self.params: dict[str, np.ndarray] = {}
        self.grads: dict[str, np.ndarray] = {}
        self._cache = None
        self._work: dict = {}   # big scratch buffers reused from call to call (functional._scratch)

    def _bind(self, shapes: dict, parameters: Parameters | None, prefix: str, dtype) -> None:
        """Point ``params``/``grads`` at views of ``parameters`` (a new buffer when None)."""
        if parameters is None:
            parameters = Parameters({prefix + n: s for n, s in shapes.items()}, dtype=dtype)
        for name, shape in shapes.items():
            key = prefix + name
            if key not in parameters:
                raise KeyError(f"{type(self).__name__}: parameters have no {key!r} "
                               f"(have {parameters.names()})")
            if parameters.shapes[key] != tuple(shape):
                raise ValueError(f"{type(self).__name__}: {key!r} is {parameters.shapes[key]} in "
                                 f"the parameters, expected {tuple(shape)}")
            self.params[name] = parameters.params[key]
            self.grads[name] = parameters.grads[key]
        self.parameters = parameters

    def _take_cache(self):
        if self._cache is None:
            raise RuntimeError(f"{type(self).__name__}.backward called before forward")
        return self._cache

    def __repr__(self) -> str:
        shapes = ", ".join(f"{n}{p.shape}" for n, p in self.params.items())
        return f"{type(self).__name__}({shapes})"


class Linear(Layer):
    """``y = x W + b``; W (in, out), b (out,). x: (B, in) -> (B, out)."""

    @staticmethod
    def param_shapes(in_dim: int, out_dim: int, prefix: str = "") -> dict:
        return {prefix + "W": (in_dim, out_dim), prefix + "b": (out_dim,)}

    def __init__(self, in_dim: int, out_dim: int, rng: np.random.Generator | None = None,
                 dtype=np.float32, parameters: Parameters | None = None, prefix: str = ""):
        super().__init__()
        self._bind(self.param_shapes(in_dim, out_dim), parameters, prefix, dtype)
        if rng is not None:
            init_uniform_fan(self.params["W"], in_dim, out_dim, rng)
            self.params["b"][...] = 0

    def forward(self, x, train=False, rng=None):
        out, self._cache = F.linear_forward(x, self.params["W"], self.params["b"])
        return out

    def backward(self, dout):
        dx, dW, db = F.linear_backward(dout, self._take_cache(), work=self._work)
        self.grads["W"] += dW
        self.grads["b"] += db
        return dx


class ExpertLinear(Layer):
    """K expert linear layers blended per sample by alpha (B, K) (Sec. 4.1; the layers of Phi).

    W (K, in, out), b (K, out). ``forward(x (B, in), alpha (B, K)) -> (B, out)``;
    ``backward(dout) -> (dx, dalpha)``. Each expert is initialised like the original:
    uniform in +-sqrt(6 / (in + out)).
    """

    @staticmethod
    def param_shapes(n_experts: int, in_dim: int, out_dim: int, prefix: str = "") -> dict:
        return {prefix + "W": (n_experts, in_dim, out_dim), prefix + "b": (n_experts, out_dim)}

    def __init__(self, n_experts: int, in_dim: int, out_dim: int,
                 rng: np.random.Generator | None = None, dtype=np.float32,
                 parameters: Parameters | None = None, prefix: str = ""):
        super().__init__()
        self._bind(self.param_shapes(n_experts, in_dim, out_dim), parameters, prefix, dtype)
        if rng is not None:
            init_uniform_fan(self.params["W"], in_dim, out_dim, rng)
            self.params["b"][...] = 0

    def forward(self, x, alpha, train=False, rng=None):
        out, self._cache = F.expert_linear_forward(x, alpha, self.params["W"], self.params["b"])
        return out

    def backward(self, dout):
        dx, dalpha, dW, db = F.expert_linear_backward(dout, self._take_cache())
        self.grads["W"] += dW
        self.grads["b"] += db
        return dx, dalpha


class Conv1d(Layer):
    """1-D convolution over time, 'same' zero padding, stride 1. x (B, T, C) -> (B, T, F).

    W (k, C, F) with k odd, b (F,). Glorot uniform with fan_in = k*C, fan_out = k*F.
    """

    @staticmethod
    def param_shapes(in_channels: int, filters: int, kernel_size: int, prefix: str = "") -> dict:
        return {prefix + "W": (kernel_size, in_channels, filters), prefix + "b": (filters,)}

    def __init__(self, in_channels: int, filters: int, kernel_size: int,
                 rng: np.random.Generator | None = None, dtype=np.float32,
                 parameters: Parameters | None = None, prefix: str = ""):
        super().__init__()
        if kernel_size % 2 != 1:
            raise ValueError(f"Conv1d: kernel_size must be odd for 'same' padding, got {kernel_size}")
        self._bind(self.param_shapes(in_channels, filters, kernel_size), parameters, prefix, dtype)
        if rng is not None:
            init_uniform_fan(self.params["W"], kernel_size * in_channels, kernel_size * filters, rng)
            self.params["b"][...] = 0

    def forward(self, x, train=False, rng=None):
        out, self._cache = F.conv1d_forward(x, self.params["W"], self.params["b"], work=self._work)
        return out

    def backward(self, dout):
        dx, dW, db = F.conv1d_backward(dout, self._take_cache())
        self.grads["W"] += dW
        self.grads["b"] += db
        return dx


class ELU(Layer):
    """ELU with alpha = 1."""

    def forward(self, x, train=False, rng=None):
        out, self._cache = F.elu_forward(x)
        return out

    def backward(self, dout):
        return F.elu_backward(dout, self._take_cache())


class ReLU(Layer):
    """max(x, 0)."""

    def forward(self, x, train=False, rng=None):
        out, self._cache = F.relu_forward(x)
        return out

    def backward(self, dout):
        return F.relu_backward(dout, self._take_cache())


class Softmax(Layer):
    """Softmax over the last axis (max-subtracted)."""

    def forward(self, x, train=False, rng=None):
        out, self._cache = F.softmax_forward(x)
        return out

    def backward(self, dout):
        return F.softmax_backward(dout, self._take_cache())


class LayerNorm(Layer):
    """Layer norm over the last axis without affine: (x - mu) / (sigma + eps).

    Training convention (default): unbiased std, eps 1e-6. The original runtime: unbiased=False,
    eps=0.0 (original-pipeline §10.2).
    """

    def __init__(self, unbiased: bool = True, eps: float = 1e-6):
        super().__init__()
        self.unbiased, self.eps = unbiased, eps

    def forward(self, x, train=False, rng=None):
        out, self._cache = F.layer_norm_forward(x, self.unbiased, self.eps)
        return out

    def backward(self, dout):
        return F.layer_norm_backward(dout, self._take_cache())


class FiLM(Layer):
    """``gamma * h + beta`` with per-sample gamma, beta (B, H) (Eq. 3). backward -> (dh, dgamma, dbeta)."""

    def forward(self, h, gamma, beta, train=False, rng=None):
        out, self._cache = F.film_forward(h, gamma, beta)
        return out

    def backward(self, dout):
        return F.film_backward(dout, self._take_cache())


class Dropout(Layer):
    """Inverted dropout with rate p; identity unless ``train=True``.

    In training pass ``rng`` (a Generator) or a fixed boolean keep-``mask`` of x's shape.
    """

    def __init__(self, p: float):
        super().__init__()
        if not 0.0 <= p < 1.0:
            raise ValueError(f"Dropout: p must be in [0, 1), got {p}")
        self.p = p

    def forward(self, x, train=False, rng=None, mask=None):
        out, cache = F.dropout_forward(x, self.p, rng=rng, mask=mask, train=train)
        self._cache = ("dropout", cache)   # cache is None in eval mode; keep "forward ran" visible
        return out

    def backward(self, dout):
        return F.dropout_backward(dout, self._take_cache()[1])


class MaxPool1d(Layer):
    """Max pooling over time, size 2, stride 2: (B, T, C) -> (B, T // 2, C); odd T drops the last frame."""

    def forward(self, x, train=False, rng=None):
        out, self._cache = F.max_pool1d_forward(x)
        return out

    def backward(self, dout):
        return F.max_pool1d_backward(dout, self._take_cache())
