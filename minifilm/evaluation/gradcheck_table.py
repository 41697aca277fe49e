"""The gradient-check suite: every backward pass of minifilm checked numerically, as one table.

    minifilm gradcheck [--seeds 5] [--only TEXT]      (tests/*/test_*gradcheck*.py run the same)

One row per backward pass (docs/backprop.md lists them): the kit's pairs, the model's blocks,
the losses with their degenerate branches, each style modulation on its own, a taught style's
adapters (the two layers, and Φ fitted with each: minifilm/evaluation/gradcheck_adapters.py),
Ω, Φ, Ψ (also with the FFT convolution), the style model (per-sample clips, shared clips, one
FiLM vector for the batch) and the seven comparison variants, every one on seeds 0-4. Each row says how many arrays
and entries one seed perturbs, the worst elementwise relative error over all of them and all
seeds, its limit, the stencil evaluations that crossed a kink (must be 0) and whether it passed.
A second table runs the networks' backward passes in float32 against float64.

The method (minifilm/nn/gradcheck.py): the four-point centred difference in float64 with
h = 3e-4, every entry of every array, the elementwise relative error |a − b| / max(1e-8, |a| + |b|)
below 1e-7, the objective normalised to a scale of 1e-4. Why those numbers:

* truncation ~ h^4 f^(5) / 30 and rounding ~ 1.5 ε S / h (S: the size of the numbers the scalar
  adds up; ε = 2.2e-16). The toy networks' fifth derivatives reach ~1e3 S per unit step (a
  parameter feeds a chain of layers), which puts the best h near 3e-4: both errors ≈ 1e-13 S;
* the relative error is relative above |a| + |b| = 1e-8 and absolute below (|a − b| < 1e-15). An
  entry whose true gradient is tiny next to S (by cancellation: a sum over samples of terms of
  both signs) cannot be measured relatively by any finite difference, only to the rounding
  level. So every objective is multiplied by SCALE / S = 1e-4 / S (S = Σ|terms| at the checked
  point; for a loss, the loss): the rounding (≈ 1e-16) then sits 10x under the absolute
  tolerance, entries above 5e-5 S are checked relatively to 1e-7 and the rest (about 1 % of the
  non-zero entries of a network) absolutely, to 1e-11 S. Without the normalisation, entries of
  ~1e-7 S failed on some seeds by rounding alone (reproduce with ``scale=None``);
* no stencil may cross a kink: inputs are kept MARGIN = 0.05 ≈ 170 h away from every ELU / ReLU
  switch, max-pool tie and |·| / ‖·‖ zero, and layer-norm rows at σ >= 0.5 (a small σ makes the
  fifth derivative huge), by shifting biases after measuring the pre-activations and redrawing
  clips or targets (minifilm/evaluation/gradcheck_problem.py). A guard compares the side of every
  kink on every evaluation and the row fails if one changed.

Two rows sit on a kink on purpose and say why the stencil still measures the gradient the code
takes: the layer norm of a constant row (h = 1e-14, error bound (2/3) c h / ε ≈ 3e-9) and the
bone-length loss's degenerate bones (the loss is even along every perturbed coordinate, so the
symmetric stencil measures the code's subgradient 0 exactly). Their limit is the same 1e-7.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import partial
from typing import Callable, List, Optional, Sequence

from minifilm.baselines.variants import SPECS, VARIANTS
from minifilm.evaluation import gradcheck_adapters as adapters
from minifilm.evaluation import gradcheck_baselines as baselines
from minifilm.evaluation import gradcheck_cases as kit
from minifilm.evaluation import gradcheck_networks as nets
from minifilm.evaluation.gradcheck_problem import Result, check_problem, float32_errors
from minifilm.nn import fast_conv
from minifilm.nn.gradcheck import H, LIMIT, worst_error

SEEDS = tuple(range(5))
FUN, CONV, BLOCKS, LOSSES = "minifilm/nn/functional.py", "minifilm/nn/conv.py", "minifilm/model/blocks.py", \
    "minifilm/model/losses.py"
FAST_CONV = "minifilm/nn/fast_conv.py"
MOD, PFNN = "minifilm/baselines/style_modulation.py", "minifilm/baselines/phase_function.py"
ADAPT, ADAPT_FIT = "minifilm/model/adapters.py", "minifilm/train/adapter_fit.py"


def _pair(path, name):
    return (f"{path}::{name}_forward", f"{path}::{name}_backward")


@dataclass(frozen=True)
class Case:
    """One row: ``check(seed) -> Result``; ``covers``: the code it checks (``path::name``)."""

    name: str
    group: str
    check: Callable[[int], Result]
    covers: tuple = ()
    limit: float = LIMIT
    note: str = ""


class fft_convolutions:
    """Within this context every conv1d of Ψ takes the "fft" method (the one the paper-size Ψ
    trains with), whatever the sizes; outside it, the usual choice (fast_conv._conv1d_method)."""

    def __enter__(self):
        self._choose = fast_conv._conv1d_method
        fast_conv._conv1d_method = lambda *sizes: "fft"

    def __exit__(self, *exc):
        fast_conv._conv1d_method = self._choose


def _with_fft(build: Callable[[int], "nets.Problem"], check: Callable) -> Callable:
    def run(seed):
        with fft_convolutions():
            return check(build(seed))
    return run


def _network(build):
    return lambda seed: check_problem(build(seed))


STYLE = "minifilm/model/style_model.py::StyleModel"


def cases() -> List[Case]:
    """Every row of the table, in the order of docs/backprop.md (kit, blocks, losses, style
    modulation, a taught style's adapters, networks, variants)."""
    K = "kit"
    rows = [
        Case("linear", K, kit.linear, _pair(FUN, "linear")),
        Case("ELU", K, kit.elu, _pair(FUN, "elu")),
        Case("ReLU", K, kit.relu, _pair(FUN, "relu")),
        Case("softmax", K, kit.softmax, _pair(FUN, "softmax")),
        Case("layer norm (unbiased σ, ε = 1e-6)", K, kit.layer_norm, _pair(FUN, "layer_norm")),
        Case("layer norm (biased σ, ε = 0)", K, partial(kit.layer_norm, unbiased=False, eps=0.0), _pair(FUN, "layer_norm")),
        Case("layer norm, constant row (σ = 0)", K, kit.layer_norm_constant_row, _pair(FUN, "layer_norm"),
             note=f"on the kink; h = {kit.CONSTANT_ROW_H:g}"),
        Case("FiLM (per-sample γ, β)", K, kit.film, _pair(FUN, "film")),
        Case("FiLM (γ, β shared by the batch)", K, partial(kit.film, per_sample=False), _pair(FUN, "film")),
        Case("dropout (fixed mask)", K, kit.dropout, _pair(FUN, "dropout")),
        Case("gated experts, blended weights (plain form)", K, kit.expert_blend, _pair(FUN, "expert_blend")),
        Case("gated experts (batch 1)", K, partial(kit.expert_linear, batch=1), _pair(FUN, "expert_linear")),
        Case("gated experts (batch 4)", K, kit.expert_linear, _pair(FUN, "expert_linear")),
        Case("gather (shared clips)", K, kit.gather, _pair(FUN, "gather")),
        Case("conv1d, im2col (k 1-7, T 3-7)", K, kit.conv1d, _pair(CONV, "conv1d") + (f"{CONV}::im2col",)),
        Case("conv1d, FFT (k 3-25, T 6-16)", K, partial(kit.conv1d, method="fft"),
             _pair(FAST_CONV, "conv1d_fast") + _pair(FAST_CONV, "_conv1d_fft") + (f"{FAST_CONV}::_fft_bases",)),
        Case("max-pool 2 (T 6, 7)", K, kit.max_pool, _pair(CONV, "max_pool1d")),
        Case("dense block (dropout, ELU)", "block", kit.dense_block, _pair(BLOCKS, "dense")),
        Case("expert block (dropout)", "block", kit.expert_block, _pair(BLOCKS, "expert")),
        Case("Eq. 3 block (experts, LN, FiLM, ELU)", "block", kit.film_block, _pair(BLOCKS, "film_block")),
        Case("conv block (conv1d, ReLU, max-pool)", "block", kit.conv_block,       # the fast conv, as Ψ runs it
             _pair(BLOCKS, "conv_block") + _pair(FAST_CONV, "conv1d_fast")
             + (f"{FAST_CONV}::_im2col", f"{FAST_CONV}::_conv1d_method")),
        Case("MSE (Eq. 5)", "loss", kit.mse, (f"{LOSSES}::mse_loss",)),
        Case("bone-length loss (Eq. 6-7)", "loss", kit.bll, (f"{LOSSES}::bone_length_loss",)),
        Case("bone-length loss, |ℓ − ℓ̂| = 0", "loss", partial(kit.bll, degenerate="equal"),
             (f"{LOSSES}::bone_length_loss",), note="on the kink; exact by symmetry"),
        Case("bone-length loss, zero-length predicted bone", "loss", partial(kit.bll, degenerate="zero-pred"),
             (f"{LOSSES}::bone_length_loss",), note="on the kink; exact by symmetry"),
        Case("bone-length loss, zero-length target bone", "loss", partial(kit.bll, degenerate="zero-target"),
             (f"{LOSSES}::bone_length_loss",)),
        Case("one-hot style rows (ids)", "modulation", baselines.onehot, (f"{MOD}::OneHotShift", f"{MOD}::OneHotShift.backward")),
        Case("one-hot style rows (blended)", "modulation", partial(baselines.onehot, blended=True),
             (f"{MOD}::OneHotShift", f"{MOD}::OneHotShift.backward")),
        Case("residual adapter (LPN Resad)", "modulation", baselines.residual_adapter,
             (f"{MOD}::ResidualAdapter", f"{MOD}::ResidualAdapter.backward")),
        Case("CP residual adapter (PFNN Resad)", "modulation", baselines.cp_adapter,
             (f"{MOD}::CPResidualAdapter", f"{MOD}::CPResidualAdapter.backward")),
        Case("PFNN phase-function layer", "modulation", baselines.phase_function_layer,
             (f"{PFNN}::PhaseFunction", f"{PFNN}::catmull_rom_weights")),
        Case("taught style's residual adapter (share)", "adapter", adapters.residual_adapter,
             _pair(ADAPT, "residual_adapter")),
        Case("taught style's low-rank expert update, rank 2", "adapter", adapters.lowrank_experts,
             _pair(ADAPT, "lowrank_experts")),
        Case("taught style's low-rank expert update, rank 4", "adapter", partial(adapters.lowrank_experts, rank=4),
             _pair(ADAPT, "lowrank_experts")),
        Case("Φ with a residual adapter, MSE", "adapter", adapters.adapted_phi, _pair(ADAPT_FIT, "adapted_phi")),
        Case("Φ with low-rank expert updates, MSE", "adapter", partial(adapters.adapted_phi, kind="lowrank"),
             _pair(ADAPT_FIT, "adapted_phi")),
        Case("Ω gating network", "network", _network(nets.omega_problem),
             ("minifilm/model/gating.py::GatingNetwork.forward", "minifilm/model/gating.py::GatingNetwork.backward")),
        Case("Φ motion network (Eq. 3)", "network", _network(nets.phi_problem),
             ("minifilm/model/motion_net.py::MotionNetwork.forward", "minifilm/model/motion_net.py::MotionNetwork.backward",
              "minifilm/model/motion_net.py::split_film")),
        Case("Ψ FiLM generator (Eq. 2)", "network", _network(nets.psi_problem),
             ("minifilm/model/film_generator.py::FilmGenerator.forward",
              "minifilm/model/film_generator.py::FilmGenerator.backward",
              "minifilm/nn/fast_linear.py::linear_fast_backward")),
        Case("Ψ, FFT convolutions", "network", _with_fft(nets.psi_problem, check_problem),
             ("minifilm/model/film_generator.py::FilmGenerator.backward", f"{FAST_CONV}::_conv1d_fft_backward")),
        Case("style model, MSE + BLL (Eq. 4-7)", "network", _network(nets.style_model_problem),
             (f"{STYLE}.forward", f"{STYLE}.backward")),
        Case("style model, shared clips", "network", _network(partial(nets.style_model_problem, form="shared-clip")),
             (f"{STYLE}.forward", f"{STYLE}.backward")),
        Case("style model, one FiLM vector", "network", _network(partial(nets.style_model_problem, form="film-vector")),
             (f"{STYLE}.forward_with_film", f"{STYLE}.backward_with_film")),
    ]
    variant = "minifilm/baselines/variants.py::VariantModel"
    for name in VARIANTS:
        backbone, modulation = SPECS[name]
        covers = ("minifilm/baselines/variants.py::build_variant",
                  f"{STYLE}.backward" if name == "LPN FiLM" else f"{variant}.backward")
        if modulation == "film" and name != "LPN FiLM":
            covers += (f"{variant}.backward_with_film",)
        elif modulation != "film":
            covers += ("minifilm/baselines/expert_net.py::ExpertNetwork.backward",)
        rows.append(Case(name, "variant", _network(partial(nets.variant_problem, name)), covers))
    return rows


#: the float32 comparison: max|g32 − g64| / max|g64| per array must stay under this, ≈ 250 float32
#: epsilons (1.2e-7); the worst of any network (wide sizes) over seeds 0-29 was 7.3e-6 (MANN FiLM)
FLOAT32_TOLERANCE = 3e-5


def float32_cases() -> List[Case]:
    """The networks' backward passes in float32 against float64 (same parameters, inputs, masks
    and incoming gradient); ``limit``: FLOAT32_TOLERANCE."""
    def f32(build, fft=False, **kw):            # the wide networks (gradcheck_networks.toy_config)
        build = partial(build, wide=True, **kw)
        return _with_fft(build, float32_errors) if fft else (lambda seed: float32_errors(build(seed)))
    rows = [Case("Ω", "float32", f32(nets.omega_problem)), Case("Φ", "float32", f32(nets.phi_problem)),
            Case("Ψ", "float32", f32(nets.psi_problem)), Case("Ψ, FFT convolutions", "float32", f32(nets.psi_problem, True)),
            Case("style model", "float32", f32(nets.style_model_problem)),
            Case("style model, shared clips", "float32", f32(nets.style_model_problem, form="shared-clip")),
            Case("style model, one FiLM vector", "float32", f32(nets.style_model_problem, form="film-vector"))]
    rows += [Case(name, "float32", f32(partial(nets.variant_problem, name))) for name in VARIANTS]
    return [Case(c.name, c.group, c.check, limit=FLOAT32_TOLERANCE) for c in rows]


# ---- running and reporting ------------------------------------------------------------------
@dataclass
class Row:
    """A case over its seeds."""

    case: Case
    seeds: list = field(default_factory=list)
    arrays: int = 0
    entries: int = 0
    worst: float = 0.0
    where: str = ""
    crossings: int = 0
    seconds: float = 0.0
    error: Optional[str] = None

    @property
    def passed(self) -> bool:
        """Every seed ran, no kink was crossed and the worst error is finite and within the limit
        (a NaN or inf error is a failure, see minifilm.nn.gradcheck.worst_error)."""
        return (self.error is None and self.crossings == 0 and bool(self.seeds)
                and math.isfinite(self.worst) and self.worst <= self.case.limit)

    def add(self, seed: int, result: Result) -> None:
        """Record one seed's result; a NaN or inf error (or none at all) makes the row's worst inf."""
        self.seeds.append(seed)
        self.arrays = max(self.arrays, len(result.errors))
        self.entries = max(self.entries, sum(result.entries.values()))
        self.crossings += result.crossings
        e = worst_error(result.errors)
        if e > self.worst or not self.where:
            where = result.worst if result.errors else "no array was checked"
            self.worst, self.where = e, f"seed {seed}: {where}"


def run_case(case: Case, seeds: Sequence[int] = SEEDS) -> Row:
    row = Row(case)
    t = time.perf_counter()
    for seed in seeds:
        try:
            row.add(seed, case.check(seed))
        except Exception as e:          # a broken backward pass may also raise: report, go on
            row.error = f"seed {seed}: {type(e).__name__}: {e}"
            break
    row.seconds = time.perf_counter() - t
    return row


def _span(seeds) -> str:
    seeds = sorted(seeds)
    return "-" if not seeds else str(seeds[0]) if len(seeds) == 1 else f"{seeds[0]}-{seeds[-1]}"


def format_table(rows: Sequence[Row], title: str, error_name: str = "worst rel. error") -> str:
    """The table: one line per row, then the worst entry of every row that failed."""
    w = max([len(title)] + [len(r.case.name) for r in rows])
    head = f"{title:<{w}}  arrays  entries  seeds  {error_name:>16}  limit    crossed  pass"
    lines = [head, "-" * len(head)]
    for r in rows:
        seeds = _span(r.seeds)
        crossed = "-" if r.case.group == "float32" else str(r.crossings)
        lines.append(f"{r.case.name:<{w}}  {r.arrays:>6}  {r.entries:>7}  {seeds:>5}  {r.worst:>16.1e}  "
                     f"{r.case.limit:<7.0e}  {crossed:>7}  {'yes' if r.passed else 'NO'}"
                     + (f"   ({r.case.note})" if r.case.note else ""))
    for r in rows:
        if not r.passed:
            lines.append(f"  FAILED {r.case.name}: {r.error or r.where}")
    return "\n".join(lines)


def run(seeds: Sequence[int] = SEEDS, only: Optional[str] = None, out=print) -> int:
    """Run the suite, print both tables, return 0 if every row passed, else 1."""
    t = time.perf_counter()
    pick = [c for c in cases() if not only or only.lower() in c.name.lower()]
    pick32 = [c for c in float32_cases() if not only or only.lower() in c.name.lower()]
    if not pick and not pick32:
        raise ValueError(f"gradcheck: no row's name contains {only!r} (the rows: {', '.join(c.name for c in cases())})")
    out(f"Every backward pass against the four-point centred difference in float64 (h = {H:.0e}, every "
        f"entry,\nobjective normalised to 1e-4; minifilm/evaluation/gradcheck_table.py explains), seeds "
        f"{_span(seeds)}:\n")
    rows = [run_case(c, seeds) for c in pick]
    out(format_table(rows, "backward pass"))
    rows32 = [run_case(c, seeds) for c in pick32]
    if rows32:
        out("\nfloat32 backward passes against float64: max|g32 − g64| / max|g64| per array\n")
        out(format_table(rows32, "network (float32)", "worst rel. diff."))
    bad = [r for r in rows + rows32 if not r.passed]
    out(f"\n{len(rows) + len(rows32) - len(bad)} of {len(rows) + len(rows32)} checks passed "
        f"in {time.perf_counter() - t:.1f} s")
    return 1 if bad else 0
