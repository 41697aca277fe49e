"""Table 2 of the paper (Sec. 5.2.1): storage and run time of the seven variants.

    minifilm table2 [--no-timing] [--markdown PATH] [--runs 5] [--frames 200] [--styles 95]

Parameter counts come from the shapes alone (minifilm.baselines.variants.variant_parameter_counts)
in the paper's configuration: A.S.N. (animation synthesis network: Φ, plus Ω where there is
one), S.M.N. (style modulation network: the one-hot rows, the adapters or Ψ) and P.S.R. (numbers
needed per style at run time). Each is compared with the paper's number.

Run time: the time to compute the next frame at batch 1 through the one inference path
(minifilm.runtime.network.RuntimeNetwork via minifilm.baselines.runtime.variant_network, float32,
FiLM vectors precomputed as at run time, Sec. 4.4), averaged over `frames` frames; five such runs
give mean ± std, as in the paper. Every variant runs the same code (one (I, K·O) matrix product
per expert layer), so the ratios compare architectures, not implementations. Absolute times depend on this machine and its load.
"""
from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Optional

import numpy as np

from minifilm.baselines.runtime import variant_network
from minifilm.baselines.variants import VARIANTS, backbone_config, build_variant, variant_parameter_counts
from minifilm.dataset.stats import NormStats
from minifilm.files import atomic_write_text, check_writable
from minifilm.model.config import ModelConfig

#: The paper's Table 2: A.S.N., S.M.N., P.S.R., run time (ms, mean, std).
PAPER = {
    "PFNN one-hot": (2_436_380, 194_560, 2048, 0.78, 0.01),
    "LPN one-hot": (4_935_928, 389_120, 4096, 4.11, 0.02),
    "PFNN Resad": (2_436_380, 2_978_440, 31_352, 0.92, 0.01),
    "LPN Resad": (4_935_928, 24_952_320, 262_656, 4.78, 0.06),
    "PFNN FiLM": (2_436_380, 35_668_530, 2048, 1.37, 0.02),
    "MANN FiLM": (4_870_392, 35_668_530, 2048, 4.48, 0.04),
    "LPN FiLM": (4_935_928, 35_668_530, 2048, 4.53, 0.04),
}

FILM_NOTE = ("✗ in the FiLM rows is Ψ, the FiLM generator (their S.M.N.): the architecture the paper describes "
             "(two conv1d layers of 256 filters of width 25 over 240 frames x 300 features, max-pool 2 "
             "after each, dense 2048, dense 4 x 512) has 1,920,256 + 1,638,656 + 31,459,328 + 4,196,352 "
             "= 39,214,592 parameters, as the original code builds it; the paper's 35,668,530 matches no "
             "reading of that architecture (see minifilm/model/film_generator.py), so we keep the "
             "architecture and report our count. It is not needed at run time (P.S.R. = 2048).")


def parameter_rows(config: ModelConfig, n_styles: int) -> list:
    """[(name, ours {'asn','smn','psr'}, paper (asn, smn, psr))] in Table 2's order."""
    return [(name, variant_parameter_counts(name, config, n_styles), PAPER[name][:3]) for name in VARIANTS]


def _timing_inputs(name, config, frames, rng):
    """The run-time network of variant `name` (no Ψ) and `frames` inputs for it."""
    model = build_variant(name, config, rng, with_film_generator=False)
    for ps in model.parameter_sets():                        # adapters start at zero: make them do work
        ps.data[:] = (0.02 * rng.standard_normal(ps.size)).astype(ps.data.dtype)
    cb = backbone_config(model.backbone, config)
    x = rng.standard_normal((frames, cb.x_dim)).astype(np.float32)
    if cb.phase_dim == 1:
        p = (np.arange(frames) / 60.0 % 1.0)[:, None].astype(np.float32)   # a phase advancing at 1 Hz
    else:
        p = rng.standard_normal((frames, cb.phase_dim)).astype(np.float32)
    style = rng.standard_normal(config.film_dim).astype(np.float32) if model.modulation == "film" else np.array([7])
    network = variant_network(model, NormStats.identity(cb.x_dim, cb.z_dim, cb.phase_dim))
    return network, x, p, style


def time_variants(names, config, frames=200, runs=5, seed=0) -> dict:
    """name -> (mean, std) over `runs` of the mean ms per frame of batch-1 prediction.

    The runs are interleaved (run 1 of every variant, then run 2, ...), so that changes in the
    machine's load fall on all variants alike and the ratios stay meaningful.
    """
    rng = np.random.default_rng(seed)
    setups = {name: _timing_inputs(name, config, frames, rng) for name in names}
    per_run = {name: [] for name in names}
    for network, x, p, style in setups.values():
        network.predict(x[:1], p[:1], style)                 # warm up
    for _ in range(runs):
        for name, (network, x, p, style) in setups.items():
            t0 = time.perf_counter()
            for f in range(frames):
                network.predict(x[f:f + 1], p[f:f + 1], style)
            per_run[name].append(1e3 * (time.perf_counter() - t0) / frames)
    return {name: (float(np.mean(v)), float(np.std(v))) for name, v in per_run.items()}


def _fmt(n):
    return f"{n:,}"


def build_table(config, n_styles, timings=None) -> list:
    """Rows of strings: model, A.S.N., S.M.N., P.S.R. (ours, with the paper's where they differ),
    match marks for the three counts, run time in the paper and here."""
    rows = []
    for name, ours, paper in parameter_rows(config, n_styles):
        cells, marks = [name], []
        for key, want in zip(("asn", "smn", "psr"), paper):
            got = ours[key]
            cells.append(_fmt(got) if got == want else f"{_fmt(got)} (paper {_fmt(want)})")
            marks.append("✓" if got == want else "✗")
        cells.append(" ".join(marks))
        mean, std = PAPER[name][3:]
        cells.append(f"{mean:.2f} ± {std:.2f}")
        if timings is not None:
            cells.append("{:.2f} ± {:.2f}".format(*timings[name]))
        rows.append(cells)
    return rows


HEADER = ["Model", "A.S.N.", "S.M.N.", "P.S.R.", "match A/S/P", "paper ms", "ms here"]


def as_text(rows, header) -> str:
    widths = [max(len(r[i]) for r in rows + [header]) for i in range(len(header))]
    line = lambda r: "  ".join(c.ljust(w) for c, w in zip(r, widths))   # noqa: E731
    return "\n".join([line(header), line(["-" * w for w in widths])] + [line(r) for r in rows])


def as_markdown(rows, header, notes) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out) + "\n\n" + "\n\n".join(notes) + "\n"


def report(markdown: Optional[Path] = None, runs: int = 5, frames: int = 200, styles: int = 95,
           timing: bool = True) -> int:
    """Print Table 2 (and write it as markdown to ``markdown``): counts for ``styles`` training
    styles and, with ``timing``, the batch-1 time per frame over ``runs`` runs of ``frames``."""
    if markdown:
        check_writable(markdown, "--markdown")
    config = ModelConfig.paper()
    timings = None
    if timing:
        timings = time_variants(VARIANTS, config, frames=frames, runs=runs)
    header = HEADER if timings is not None else HEADER[:-1]
    rows = build_table(config, styles, timings)
    notes = [FILM_NOTE]
    if timings is not None:
        notes.append(f"Run time: batch-1 `RuntimeNetwork.predict` in float32 with NumPy, mean ± std over {runs} "
                     f"runs of {frames} frames each, on this machine (2 shared cores); the paper's "
                     "numbers are from its own (C#/Unity) runtime. Runs are interleaved across the "
                     "variants; compare the ratios between rows (the machine's load moves the absolute "
                     f"times). BLAS threads: OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')} "
                     "(`minifilm table2` uses 1 unless told otherwise).")
    print(as_text(rows, header))
    print()
    for n in notes:
        print(n)
    if markdown:
        atomic_write_text(markdown, "## Table 2: storage and run time\n\n" + as_markdown(rows, header, notes))
        print(f"\nwrote {markdown}")
    return 0
