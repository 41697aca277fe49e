"""The convergence section of the comparison's report: every variant's validation curve per seed,
one PNG, and whether each run is flat at the end (the rule of minifilm/evaluation/convergence.py)."""
from __future__ import annotations

from pathlib import Path

from minifilm.evaluation.convergence import TAIL_SHARE, TOLERANCE
from minifilm.viewer.deps import save_figure


def runs(results) -> list:
    """(variant, seed, curve) of every training run that recorded a validation curve."""
    return [(v, seed, c) for v, r in results.items() for seed, c in (r.get("curves") or {}).items()]


def draw_curves(plt, path: Path, results) -> bool:
    """One PNG: validation loss against steps, a colour per variant, a line style per seed (log y:
    the variants' losses differ in scale, each is read against its own start). False if no curves."""
    items = runs(results)
    if not items:
        return False
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    names = list(results)
    seeds = sorted({seed for _, seed, _ in items})
    styles = ["-", "--", ":", "-."]
    for v, seed, c in items:
        ax.plot(c["steps"], c["loss"], styles[seeds.index(seed) % 4], color=f"C{names.index(v) % 10}",
                marker=".", ms=3, label=f"{v} (seed {seed})")
    ax.set_yscale("log")
    ax.set_xlabel("training step")
    ax.set_ylabel("validation loss (MSE + BLL, own outputs)")
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    save_figure(fig, path, dpi=80)
    return True


def summary(results) -> dict:
    """{'n': runs judged, 'flat': runs flat at the end, 'falling': [(variant, seed)], 'unjudged': [...]}."""
    items = runs(results)
    return {"n": len(items), "flat": sum(c["flat"] is True for _, _, c in items),
            "falling": [(v, s) for v, s, c in items if c["flat"] is False],
            "unjudged": [(v, s) for v, s, c in items if c["flat"] is None]}


def section(results, image: str | None) -> list:
    """Markdown lines of the convergence section."""
    items = runs(results)
    L = ["## Convergence: validation curves\n"]
    if not items:
        return L + ["No validation curves were recorded.\n"]
    L.append(f"Rule: a run is **flat at the end** when the last {TAIL_SHARE:.0%} of its steps improved its "
             f"validation loss by less than {TOLERANCE:.0%} (the value at or before {1 - TAIL_SHARE:.0%} of the "
             "steps against the final one; a loss that rises at the end counts as flat). Validation loss = MSE + "
             "bone-length loss of the variant's own outputs on a fixed subset of the validation rows of the seen "
             "styles (the same frames for every run), recorded about every tenth of the budget; it compares a "
             "run with itself, not variants with each other (their outputs differ).\n")
    L.append("| variant | seed | steps | epochs | first | at 80 % | last | last 20 % improved | flat at end |")
    L.append("|---|---:|---:|---:|---:|---:|---:|---:|---|")
    for v, seed, c in items:
        k = c["steps"].index(c["from_step"]) if c.get("from_step") in c["steps"] else 0
        verdict = {True: "yes", False: "**no, still falling**", None: "not judged"}[c["flat"]]
        gain = "n/a" if c["flat"] is None else f"{100 * c['improvement']:.1f} %"
        L.append(f"| {v} | {seed} | {c['steps'][-1]} | {c['epochs']} | {c['loss'][0]:.4f} | {c['loss'][k]:.4f} | "
                 f"{c['loss'][-1]:.4f} | {gain} | {verdict} |")
    s = summary(results)
    L.append(f"\n**{s['flat']} of {s['n']} runs flat at the end.**"
             + (f" Still falling: {', '.join(f'{v} (seed {x})' for v, x in s['falling'])}: their figures below "
                "are not converged results (more steps, or --until-flat)." if s["falling"] else ""))
    if image:
        L.append(f"\n![validation curves]({image})\n")
    return L
