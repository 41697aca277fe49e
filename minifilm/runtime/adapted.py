"""Styles with an adapter of their own (minifilm/model/adapters.py), on the one inference path.

A style taught with an adapter is still a FiLM vector, plus a change of Φ that acts only while the
style is on. How much it is on travels with the style condition: every style's vector is its FiLM
numbers followed by one *share* per adapted style (A of them),

    cond = [γ1, β1, γ2, β2 | s_1 .. s_A]        (4H + A,)   s_a = 1 for adapted style a, else 0

so a style mix blends the shares with the same weights as the FiLM numbers (:class:`AdaptedLibrary`):
at a blend weight w of an adapted style its adapter's change is w times the whole change (the
change is linear in its share), a switch from or to it fades the change in or out with the FiLM
vector, and a mix of two adapted styles adds their weighted changes, each computed from the same
layer input. A row whose shares are all zero goes through Φ exactly as without adapters
(:class:`AdaptedNetwork`), bit for bit: the released styles, and every style of a mix that holds
no adapted style, move as they did before any adapter was taught.

PAPER: the paper's runtime conditions Φ on the FiLM vector alone (Sec. 4.4); the shares are this
package's addition for adapted styles.
"""
from __future__ import annotations

from typing import Dict, Mapping, Optional, Sequence

import numpy as np

from minifilm.model.adapters import StyleAdapter
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import StyleLibrary


class AdapterChange:
    """The adapters' change of Φ for a batch of rows (what :meth:`RuntimeNetwork.predict` takes as
    ``change``): adapters [StyleAdapter] * A, shares (B, A)."""

    def __init__(self, adapters: Sequence[StyleAdapter], shares: np.ndarray):
        self.parts = [(a, np.ascontiguousarray(shares[:, i])) for i, a in enumerate(adapters)
                      if np.any(shares[:, i] != 0)]

    def experts(self, layer, f, x, alpha):
        out = f
        for adapter, share in self.parts:
            out = out + adapter.experts_change(layer, x, alpha, share)
        return out

    def hidden(self, layer, h):
        out = h
        for adapter, share in self.parts:
            out = out + adapter.hidden_change(layer, h, share)
        return out


class AdaptedNetwork:
    """A :class:`RuntimeNetwork` (``base``) and the adapters of A of its styles, in the order of their
    shares in the condition. Everything else (statistics, sizes, ...) is the base network's."""

    def __init__(self, base: RuntimeNetwork, adapters: Sequence[StyleAdapter]):
        if base.film_dim is None:
            raise TypeError("AdaptedNetwork: adapters are taught to FiLM networks")
        sizes = [base.x_dim, base.hidden.hidden, base.hidden.hidden, base.z_dim]
        for a in adapters:
            if a.sizes != sizes or a.n_experts != base.n_experts:
                raise ValueError(f"AdaptedNetwork: an adapter for layers {a.sizes} and {a.n_experts} experts does "
                                 f"not fit this network ({sizes}, {base.n_experts} experts)")
        self.base = base
        self.adapters = [a if a.dtype == base.dtype else a.astype(base.dtype) for a in adapters]

    def __getattr__(self, name):            # stats, dtype, x_dim, z_dim, ...: the base network's
        if name == "base":
            raise AttributeError(name)
        return getattr(self.base, name)

    @property
    def film_dim(self) -> int:
        """The length of a style condition: the FiLM vector's 4H and one share per adapter."""
        return self.base.film_dim + len(self.adapters)

    def to_arrays(self) -> dict:
        """The base network's arrays: what the network is apart from the styles (the demo's
        calibration cache keys on it; an adapted style's own digest covers its adapter)."""
        return self.base.to_arrays()

    def predict(self, x_raw, p_raw, cond) -> np.ndarray:
        """Raw z (B, z_dim) from raw x (B, x_dim), p (B, phase_dim) and conditions (4H + A,) or (B, 4H + A)."""
        cond = np.asarray(cond)
        D, B = self.base.film_dim, len(x_raw)
        film = cond[..., :D]
        shares = np.broadcast_to(cond[..., D:], (B, len(self.adapters))).astype(self.base.dtype)
        on = np.any(shares != 0, axis=1)
        if not on.any():
            return self.base.predict(x_raw, p_raw, film)
        if on.all():
            return self.base.predict(x_raw, p_raw, film, change=AdapterChange(self.adapters, shares))
        out = self.base.predict(x_raw, p_raw, film)       # the rows without adapters: as always
        rows = np.flatnonzero(on)
        out[rows] = self.base.predict(np.asarray(x_raw)[rows], np.asarray(p_raw)[rows],
                                      film if film.ndim == 1 else film[rows],
                                      change=AdapterChange(self.adapters, shares[rows]))
        return out


class AdaptedLibrary(StyleLibrary):
    """Styles as conditions [FiLM | shares] (module docstring). ``films``: every style's FiLM vector;
    ``adapted``: the names of the styles with an adapter, in the order of their shares. A blend is
    computed part by part, so its FiLM part is bit for bit the blend of the FiLM vectors alone."""

    def __init__(self, films: StyleLibrary, adapted: Sequence[str], bits: Optional[Mapping[str, bytes]] = None):
        self.films, self.adapted = films, list(adapted)
        eye = np.eye(len(self.adapted), dtype=films.dtype)
        self.shares = StyleLibrary({n: eye[self.adapted.index(n)] if n in self.adapted
                                    else np.zeros(len(self.adapted), films.dtype) for n in films.names},
                                   dtype=films.dtype)
        super().__init__({n: np.concatenate([films[n], self.shares[n]]) for n in films.names}, dtype=films.dtype)
        self.run_id = films.run_id
        self._bits = dict(bits or {})

    def blend(self, weights) -> np.ndarray:
        return np.concatenate([self.films.blend(weights), self.shares.blend(weights)])

    def calibration_bits(self, name: str) -> bytes:
        """What a style's speed calibration depends on besides the network: its FiLM vector (as a
        library without adapters gives it) and, for an adapted style, its adapter's arrays."""
        return np.ascontiguousarray(self.films[name], np.float64).tobytes() + self._bits.get(name, b"")


def adapter_bits(adapter: StyleAdapter) -> bytes:
    """The bytes of an adapter's arrays (a fingerprint's input)."""
    return b"".join(np.ascontiguousarray(v).tobytes() for v in adapter.params.params.values())


def with_adapters(network: RuntimeNetwork, library: StyleLibrary, adapters: Mapping[str, StyleAdapter]):
    """-> (network, library) that apply ``adapters`` (style name -> adapter) while their style is on;
    the two given as they are when there is none."""
    if not adapters:
        return network, library
    names = [n for n in library.names if n in adapters]
    missing = sorted(set(adapters) - set(names))
    if missing:
        raise ValueError(f"with_adapters: adapters for styles the library does not hold: {missing}")
    bits: Dict[str, bytes] = {n: adapter_bits(adapters[n]) for n in names}
    return AdaptedNetwork(network, [adapters[n] for n in names]), AdaptedLibrary(library, names, bits)
