"""Read and write the original authors' released network (docs/original-code.md §10.1).

The released LPN + FiLM network (github.com/ianxmason/local-phases, Unity demo parameters) is a
folder of little-endian float32 files:

    Xmean, Xstd (x_dim)  Ymean, Ystd (z_dim)  GT_Xmean, GT_Xstd (phase_dim)   normalisation
    wc{l}_w (out, in), wc{l}_b (out)          gating Ω, l = 0, 1, 2
    cp{l}_a{e} (out, in), cp{l}_b{e} (out)    expert e of layer l of Φ
    Style_{sss}_{scale1,shift1,scale2,shift2} FiLM γ1, β1, γ2, β2 of style sss (hidden each)
    styles.txt                                "sss Name" per line (optional here)

Matrices are row-major (out, in); minifilm stores (in, out) and experts (K, in, out), so every
weight is transposed here and only here. All sizes are read from the files, so other sizes of
the same architecture load too. The FiLM generator Ψ is not released: the loaded StyleModel
has Ω and Φ only and runs from the style vectors (Sec. 4.4).

Deviation from the demo: the Unity runtime copies FiLM parameters starting at hidden unit 1, so
unit 0 gets γ = β = 0 in both layers (docs/original-code.md §10.2, a bug). We apply the stored
vectors from unit 0.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from minifilm.dataset.stats import NormStats
from minifilm.errors import InputError
from minifilm.files import atomic_directory, check_name, check_regular, read_regular_bytes
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import UnknownStyleError

FILM_PARTS = ("scale1", "shift1", "scale2", "shift2")   # γ1, β1, γ2, β2: the order of Eq. (2)
_STYLE_FILE = re.compile(r"^Style_(\d{3})_scale1\.bin$")


class ReleasedFormatError(InputError):
    """A released-parameter folder is missing a file or has a file of the wrong size."""


class StyleVectors(dict):
    """name -> FiLM vector, in file order; an unknown name is an UnknownStyleError listing the
    known ones (a KeyError and an InputError), not a bare KeyError."""

    def __missing__(self, name):
        raise UnknownStyleError(f"style {name!r} is not one of the released network's {len(self)} styles; "
                                f"known styles: {', '.join(self)}")


@dataclass
class ReleasedNetwork:
    """model: StyleModel with Ω and Φ (no Ψ); stats: normalisation; styles: name -> (4H,) FiLM
    vector, in file order (names from styles.txt, else the 3-digit id).

    ``network`` is the model on the one inference path with the demo's layer norm (biased σ,
    no eps, docs/original-code.md §10.2): what the runtime controller drives.
    """

    model: StyleModel
    stats: NormStats
    styles: dict

    def __post_init__(self):
        self.network = RuntimeNetwork.from_model(self.model, self.stats, runtime_layer_norm=True,
                                                 dtype=self.model.dtype)

    def predict(self, X, L, film):
        """One frame (docs/original-code.md §10.2 steps 1-6): X (x_dim,) raw input, L (phase_dim,)
        raw local phases, film (4H,) -> Y (z_dim,) raw output."""
        return self.network.predict(np.asarray(X)[None], np.asarray(L)[None], film)[0]


def _n_floats(path: Path) -> int:
    if not os.path.lexists(path):
        raise ReleasedFormatError(f"released network: missing file {path}")
    size = check_regular(path, "released network: file", ReleasedFormatError).st_size
    if size % 4:
        raise ReleasedFormatError(f"released network: {path} has {size} bytes, not a whole number of float32")
    return size // 4


def _read(directory: Path, name: str, shape) -> np.ndarray:
    path = directory / f"{name}.bin"
    n = _n_floats(path)
    expected = int(np.prod(shape))
    if n != expected:
        raise ReleasedFormatError(f"released network: {path} holds {n} float32, expected {expected} "
                                  f"(shape {tuple(shape)})")
    raw = read_regular_bytes(path, "released network: file", 4 * expected, ReleasedFormatError)
    if len(raw) != 4 * expected:                   # changed since its size was read
        raise ReleasedFormatError(f"released network: {path} changed while being read")
    values = np.frombuffer(raw, dtype="<f4").reshape(shape).copy()
    if not np.all(np.isfinite(values)):
        bad = np.flatnonzero(~np.isfinite(values.ravel()))
        raise ReleasedFormatError(f"released network: {path} holds {len(bad)} non-finite value(s) (first at "
                                  f"float {bad[0]}); the file is corrupt")
    return values


def _read_style_names(directory: Path) -> dict:
    path = directory / "styles.txt"
    names, taken = {}, set()
    if not os.path.lexists(path):
        return names
    try:
        text = read_regular_bytes(path, "released network: style list", 1 << 20, ReleasedFormatError).decode("utf-8")
    except UnicodeDecodeError as e:
        raise ReleasedFormatError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        parts = line.split(maxsplit=1)
        if len(parts) != 2 or not re.fullmatch(r"[0-9]{3}", parts[0]):
            raise ReleasedFormatError(f"{path}, line {lineno}: expected 'sss Name', got {line[:80]!r}")
        sid, name = parts[0], check_name(parts[1].strip(), f"{path}, line {lineno}", ReleasedFormatError)
        if sid in names:
            raise ReleasedFormatError(f"{path}, line {lineno}: style id {sid} is named twice "
                                      f"({names[sid]!r} and {name!r})")
        if name in taken:
            raise ReleasedFormatError(f"{path}, line {lineno}: the name {name!r} is given to two style ids")
        if not (directory / f"Style_{sid}_scale1.bin").is_file():
            raise ReleasedFormatError(f"{path}, line {lineno}: names style {sid} ({name!r}), but there is no "
                                      f"Style_{sid}_scale1.bin (nor its other three files)")
        names[sid] = name
        taken.add(name)
    return names


def infer_config(directory) -> ModelConfig:
    """The ModelConfig of a released folder: Φ/Ω sizes from the files, Ψ sizes of the paper."""
    d = Path(directory)
    if not d.is_dir():
        raise ReleasedFormatError(f"released network: {d} is not a directory")
    hidden = _n_floats(d / "cp0_b0.bin")
    n_experts = _n_floats(d / "wc2_b.bin")
    try:        # ModelConfig refuses absurd sizes before anything is allocated
        return replace(ModelConfig.paper(), x_dim=_n_floats(d / "Xmean.bin"), z_dim=_n_floats(d / "Ymean.bin"),
                       phase_dim=_n_floats(d / "GT_Xmean.bin"), n_experts=n_experts, hidden=hidden,
                       gating_hidden=_n_floats(d / "wc0_b.bin"))
    except ValueError as e:
        raise ReleasedFormatError(f"released network {d}: its file sizes describe an impossible network ({e})") from None


def load_released(directory, dtype=np.float32) -> ReleasedNetwork:
    """Load a released folder into Ω + Φ, normalisation statistics and a style dict."""
    d = Path(directory)
    cfg = infer_config(d)
    model = StyleModel(cfg, np.random.default_rng(0), dtype=dtype, with_film_generator=False)
    arrays = dict(x_mean=_read(d, "Xmean", (cfg.x_dim,)), x_std=_read(d, "Xstd", (cfg.x_dim,)),
                  z_mean=_read(d, "Ymean", (cfg.z_dim,)), z_std=_read(d, "Ystd", (cfg.z_dim,)),
                  p_mean=_read(d, "GT_Xmean", (cfg.phase_dim,)), p_std=_read(d, "GT_Xstd", (cfg.phase_dim,)))
    try:
        stats = NormStats(**arrays)
    except ValueError as e:   # e.g. a zero standard deviation: name the file, not the field
        files = {"x_mean": "Xmean", "x_std": "Xstd", "z_mean": "Ymean", "z_std": "Ystd", "p_mean": "GT_Xmean",
                 "p_std": "GT_Xstd"}
        named = next((f"{b}.bin" for k, b in files.items() if k in str(e)), "the statistics files")
        raise ReleasedFormatError(f"released network {d}: {named}: {e}") from None

    G = model.gating.params.params
    for l in range(3):
        out_dim, in_dim = G[f"W{l}"].shape[1], G[f"W{l}"].shape[0]
        G[f"W{l}"][...] = _read(d, f"wc{l}_w", (out_dim, in_dim)).T
        G[f"b{l}"][...] = _read(d, f"wc{l}_b", (out_dim,))
    M = model.motion.params.params
    for l in range(3):
        K, in_dim, out_dim = M[f"W{l}"].shape
        for e in range(K):
            M[f"W{l}"][e] = _read(d, f"cp{l}_a{e}", (out_dim, in_dim)).T   # (out, in) -> (in, out)
            M[f"b{l}"][e] = _read(d, f"cp{l}_b{e}", (out_dim,))

    names = _read_style_names(d)
    styles = StyleVectors()
    ids = sorted(m.group(1) for f in d.iterdir() if (m := _STYLE_FILE.match(f.name)))
    for sid in ids:
        film = np.concatenate([_read(d, f"Style_{sid}_{part}", (cfg.hidden,)) for part in FILM_PARTS])
        name = names.get(sid, sid)
        if name in styles:
            raise ReleasedFormatError(f"released network: two styles are called {name!r} in {d} (an unnamed "
                                      "style file's id is also the name of another style in styles.txt)")
        styles[name] = film.astype(dtype)
    if not styles:
        raise ReleasedFormatError(f"released network: {d} has no style (Style_<sss>_scale1.bin ...)")
    return ReleasedNetwork(model=model, stats=stats, styles=styles)


def _write(directory: Path, name: str, array) -> None:
    np.ascontiguousarray(array, dtype="<f4").tofile(directory / f"{name}.bin")


def write_released(model: StyleModel, stats: NormStats, styles: dict, directory) -> None:
    """Write Ω + Φ, the statistics and the styles in the released layout (inverse of load_released).

    styles: name -> (4H,) FiLM vector; style files are numbered 000, 001, ... in dict order, and
    styles.txt lists every name that is not just its own 3-digit id. The folder is written whole
    and atomically (minifilm.files.atomic_directory): an existing folder of that name is replaced,
    so no file of an earlier, larger set of styles survives, and a failure leaves it as it was.
    """
    H = model.config.hidden
    if not 1 <= len(styles) <= 1000:
        raise InputError(f"write_released: {len(styles)} styles; the layout numbers them 000-999")
    for name, film in styles.items():           # check everything before writing anything
        check_name(name, "write_released: style name")
        if np.shape(film) != (4 * H,) or not np.all(np.isfinite(film)):
            raise InputError(f"write_released: style {name!r} has shape {np.shape(film)}, expected ({4 * H},) "
                             "finite numbers")
    with atomic_directory(directory, "released network folder",
                          replaceable=lambda n: n.endswith(".bin") or n == "styles.txt") as d:
        for name, arr in (("Xmean", stats.x_mean), ("Xstd", stats.x_std), ("Ymean", stats.z_mean),
                          ("Ystd", stats.z_std), ("GT_Xmean", stats.p_mean), ("GT_Xstd", stats.p_std)):
            _write(d, name, arr)
        G = model.gating.params.params
        for l in range(3):
            _write(d, f"wc{l}_w", G[f"W{l}"].T)
            _write(d, f"wc{l}_b", G[f"b{l}"])
        M = model.motion.params.params
        for l in range(3):
            for e in range(M[f"W{l}"].shape[0]):
                _write(d, f"cp{l}_a{e}", M[f"W{l}"][e].T)
                _write(d, f"cp{l}_b{e}", M[f"b{l}"][e])
        lines = []
        for i, (name, film) in enumerate(styles.items()):
            sid = f"{i:03d}"
            film = np.asarray(film)
            for k, part in enumerate(FILM_PARTS):
                _write(d, f"Style_{sid}_{part}", film[k * H:(k + 1) * H])
            if name != sid:
                lines.append(f"{sid} {name}\n")
        if lines:
            (d / "styles.txt").write_text("".join(lines))
