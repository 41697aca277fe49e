"""The networks' building blocks: forward/backward "sandwiches" of the kit's pairs, with named caches.

Ω, Φ and Ψ are stacks of a few kinds of layer. Each kind is written here once, in the style of
CS231n's ``layer_utils.py``: ``out, cache = block_forward(...)`` chains the kit's functional pairs
(``minifilm.nn.functional``) and ``block_backward(dout, cache)`` runs them in reverse, one line per
step, so the networks read as a list of blocks and their backward passes as the same list reversed.

    dense_forward        dropout -> x W + b -> activation              Ω's layers, Ψ's dense layers
    expert_forward       dropout -> Σ_k α_k (x W_k + b_k)               Φ's output layer (Sec. 4.1)
    film_block_forward   dropout -> experts -> layer norm -> FiLM -> ELU   Φ's hidden layers, Eq. (3)
    conv_block_forward   conv1d -> ReLU -> max-pool 2                   Ψ's convolutions, Eq. (2)

Shapes: x (B, I); W (I, O) or experts (K, I, O); α (B, K); γ, β (B, H) or (H,); clips (B, T, C).
Dropout comes from a :class:`~minifilm.model.dropout.Dropout` of the current pass, at a named site.
Ψ's blocks run the fast forms of the convolution and of the dense weight gradient
(minifilm/nn/fast_conv.py, minifilm/nn/fast_linear.py), tested equal to the plain pairs.
"""
from __future__ import annotations

from typing import NamedTuple, Optional

from minifilm.model.dropout import Dropout
from minifilm.nn import functional as F
from minifilm.nn.fast_conv import conv1d_fast_backward, conv1d_fast_forward
from minifilm.nn.fast_linear import linear_fast_backward

ACTIVATIONS = {"elu": (F.elu_forward, F.elu_backward), "relu": (F.relu_forward, F.relu_backward),
               "softmax": (F.softmax_forward, F.softmax_backward)}


# ---- dense: dropout -> linear -> activation -------------------------------------------------
class DenseCache(NamedTuple):
    drop: object
    linear: tuple
    act: object
    activation: Optional[str]


def dense_forward(x, W, b, activation: Optional[str] = None, drop: Optional[Dropout] = None,
                  site: str = ""):
    """``act(dropout(x) W + b)``: x (B, I), W (I, O), b (O,) -> (B, O). ``activation`` is
    'elu', 'relu', 'softmax' or None; without ``drop`` there is no dropout."""
    c_drop = None
    if drop is not None:
        x, c_drop = drop.forward(x, site)
    h, c_lin = F.linear_forward(x, W, b)
    c_act = None
    if activation is not None:
        h, c_act = ACTIVATIONS[activation][0](h)
    return h, DenseCache(c_drop, c_lin, c_act, activation)


def dense_backward(dout, cache: DenseCache, work: Optional[dict] = None):
    """-> dx (B, I), dW (I, O), db (O,). With ``work`` (Ψ's dense layers) dW is computed into the
    layer's reused buffer (:func:`~minifilm.nn.fast_linear.linear_fast_backward`)."""
    if cache.activation is not None:
        dout = ACTIVATIONS[cache.activation][1](dout, cache.act)
    if work is None:
        dx, dW, db = F.linear_backward(dout, cache.linear)
    else:
        dx, dW, db = linear_fast_backward(dout, cache.linear, work)
    return F.dropout_backward(dx, cache.drop), dW, db


# ---- gated experts: dropout -> Σ_k α_k (x W_k + b_k) -----------------------------------------
class ExpertCache(NamedTuple):
    drop: object
    experts: tuple


def expert_forward(x, alpha, W, b, drop: Dropout, site: str):
    """``Σ_k α_k (dropout(x) W_k + b_k)``: x (B, I), α (B, K), W (K, I, O), b (K, O) -> (B, O)."""
    x, c_drop = drop.forward(x, site)
    h, c_exp = F.expert_linear_forward(x, alpha, W, b)
    return h, ExpertCache(c_drop, c_exp)


def expert_backward(dout, cache: ExpertCache):
    """-> dx (B, I), dα (B, K), dW (K, I, O), db (K, O)."""
    dx, dalpha, dW, db = F.expert_linear_backward(dout, cache.experts)
    return F.dropout_backward(dx, cache.drop), dalpha, dW, db


# ---- Eq. (3): h = ELU(γ ∘ LN(Σ_k α_k (x W_k + b_k)) + β) ------------------------------------
class FilmBlockCache(NamedTuple):
    drop: object
    experts: tuple
    norm: tuple
    film: tuple
    elu: tuple


def film_block_forward(x, alpha, W, b, gamma, beta, drop: Dropout, site: str,
                       ln_unbiased: bool = True, ln_eps: float = 1e-6):
    """One hidden layer of Φ, Eq. (3): x (B, I), α (B, K), W (K, I, O), b (K, O), γ, β (B, O).

    The layer norm has no parameters of its own (FiLM's γ, β play that role); ``ln_unbiased`` and
    ``ln_eps`` choose its convention (see ``functional.layer_norm_forward``).
    """
    x, c_drop = drop.forward(x, site)
    f, c_exp = F.expert_linear_forward(x, alpha, W, b)                  # F(i)
    n, c_norm = F.layer_norm_forward(f, unbiased=ln_unbiased, eps=ln_eps)  # (F − μ) / σ
    m, c_film = F.film_forward(n, gamma, beta)                           # γ ∘ · + β
    h, c_elu = F.elu_forward(m)                                         # h(i)
    return h, FilmBlockCache(c_drop, c_exp, c_norm, c_film, c_elu)


def film_block_backward(dout, cache: FilmBlockCache):
    """-> dx (B, I), dα (B, K), dW (K, I, O), db (K, O), dγ, dβ (B, O)."""
    dm = F.elu_backward(dout, cache.elu)
    dn, dgamma, dbeta = F.film_backward(dm, cache.film)
    df = F.layer_norm_backward(dn, cache.norm)
    dx, dalpha, dW, db = F.expert_linear_backward(df, cache.experts)
    return F.dropout_backward(dx, cache.drop), dalpha, dW, db, dgamma, dbeta


# ---- Ψ's convolutions: conv1d -> ReLU -> max-pool 2 ------------------------------------------
class ConvBlockCache(NamedTuple):
    conv: tuple
    relu: object
    pool: tuple


def conv_block_forward(x, W, b, work: Optional[dict] = None):
    """x (B, T, C), W (k, C, F), b (F,) -> (B, T // 2, F). ``work``: the layer's reused buffers."""
    h, c_conv = conv1d_fast_forward(x, W, b, work=work)      # conv.py's conv1d, fast (fast_conv.py)
    h, c_relu = F.relu_forward(h)
    h, c_pool = F.max_pool1d_forward(h)
    return h, ConvBlockCache(c_conv, c_relu, c_pool)


def conv_block_backward(dout, cache: ConvBlockCache, need_dx: bool = True):
    """-> dx (B, T, C) (None when ``need_dx`` is False), dW (k, C, F), db (F,)."""
    dh = F.max_pool1d_backward(dout, cache.pool)
    dh = F.relu_backward(dh, cache.relu)
    return conv1d_fast_backward(dh, cache.conv, need_dx=need_dx)
