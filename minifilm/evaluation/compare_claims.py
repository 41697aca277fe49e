"""The report's per-claim sections (docs/compare_claims.md): for each claim of the paper's Sec. 5, its
statement in short, this run's figures and a verdict computed from them by a stated rule.

Verdicts: **holds** (every comparison the rule makes goes the paper's way), **partly** (some do, or
the main one does and a secondary one does not), **does not hold** (none do), **not judged** (the
run lacks the variants or styles the claim needs). Each section is built by one function returning
markdown lines; :func:`claim_sections` puts them together.
"""
from __future__ import annotations

import numpy as np

from minifilm.evaluation.compare_claims_more import interpolation_claim, new_style_claim, table2_claim
from minifilm.evaluation.compare_report_tools import fmt, seed_summary

#: styles of 100STYLE whose arms cycle on their own, not with the feet (no single global phase, Sec. 5.1.1)
NO_GLOBAL_PHASE = ("PendulumHands", "Swimming", "SwingArmsRound", "WhirlArms", "Flapping", "Waving", "BeatChest")
#: hands moving less than this share of the data's amplitude count as 'stuck'
STUCK = 0.5


def verdict(wins: int, total: int) -> str:
    """holds (all), partly (some), does not hold (none), not judged (nothing to compare)."""
    if total == 0:
        return "not judged"
    return "holds" if wins == total else "partly" if wins > 0 else "does not hold"


def _mean(values):
    v = [x for x in values if x is not None and np.isfinite(x)]
    return float(np.mean(v)) if v else float("nan")


def figure10_claim(ctx, results) -> list:
    """Figure 10: the FiLM variants have the lowest test MSE and BLL; LPN Resad worse than PFNN Resad."""
    summ = {v: seed_summary(r) for v, r in results.items()}
    film = [v for v in results if "FiLM" in v]
    other = [v for v in results if "FiLM" not in v]
    L = ["### Figure 10: test errors\n",
         "*Paper:* every FiLM variant has a lower test error (MSE and bone-length loss) than every one-hot and "
         "residual-adapter variant; PFNN Resad beats LPN Resad (the phase-dependent adapter helps).\n",
         "*Rule:* holds when the worst FiLM variant's mean over the seeds is below the best other variant's, for "
         "MSE and for BLL (two comparisons); per style, the share of styles whose lowest MSE is a FiLM variant.\n"]
    if not (film and other):
        return L + ["*Verdict:* **not judged** (needs FiLM and non-FiLM variants).\n"]
    wins, lines = 0, []
    for key in ("mse", "bll"):
        worst_film = max(film, key=lambda v: summ[v][key])
        best_other = min(other, key=lambda v: summ[v][key])
        ok = summ[worst_film][key] < summ[best_other][key]
        wins += ok
        lines.append(f"- {key.upper()}: worst FiLM {worst_film} {summ[worst_film][key]:.4f} against best other "
                     f"{best_other} {summ[best_other][key]:.4f}: {'yes' if ok else 'no'}")
    per_style = [min(results, key=lambda v: summ[v]["per_style"][s]) for s in ctx.seen]
    share = float(np.mean(["FiLM" in v for v in per_style])) if per_style else float("nan")
    lines.append(f"- per style: the lowest MSE is a FiLM variant's on {share:.0%} of the {len(per_style)} seen "
                 f"styles (FiLM variants are {len(film)} of {len(results)}: {len(film) / len(results):.0%} by chance)")
    if "PFNN Resad" in summ and "LPN Resad" in summ:
        p, q = summ["PFNN Resad"]["mse"], summ["LPN Resad"]["mse"]
        lines.append(f"- PFNN Resad {p:.4f} against LPN Resad {q:.4f} (MSE): {'PFNN lower' if p < q else 'LPN lower'}")
    return L + lines + [f"\n*Verdict:* **{verdict(wins, 2)}** ({wins} of 2 comparisons go the paper's way).\n"]


def no_phase_claim(ctx, results, released=None) -> list:
    """Sec. 5.1.1 / Figures 5, 9: the PFNN and MANN get the arms stuck where the LPN does not."""
    styles = [s for s in NO_GLOBAL_PHASE if s in ctx.seen]
    L = ["### Sec. 5.1.1 / Figures 5 and 9: styles without a single global phase\n",
         "*Paper:* in styles whose arms do not cycle with the feet, the PFNN (global phase from foot contacts) and "
         "the MANN (end-effector velocities) get the hands and arms 'stuck' in an average pose; the LPN (a local "
         "phase per limb) does not.\n",
         "*Measure:* hand amplitude ratio = the hands' motion amplitude in the generated motion over the data's "
         "(docs/compare_claims.md: per 1 s window, the norm of the per-axis standard deviation of each hand's "
         f"root-local position). 1 = as much arm motion as the data; below {STUCK} = stuck.\n",
         "*Rule:* for every such style and every modulation (FiLM, one-hot, Resad) with an LPN and a PFNN or MANN "
         "variant, the LPN's ratio is closer to 1 (|log ratio| smaller) than each other backbone's.\n"]
    if not styles:
        return L + [f"*Verdict:* **not judged** (none of {', '.join(NO_GLOBAL_PHASE)} is a seen style).\n"]
    names = [v for v in results if not results[v]["rollout"]["diverged"]]
    L.append("| variant | " + " | ".join(styles) + " |")
    L.append("|---|" + "---:|" * len(styles))
    ratio = {}
    for v in names:
        hands = results[v]["rollout"].get("hands", {})
        ratio[v] = {s: hands.get(s, float("nan")) / ctx.data_hands[s] if ctx.data_hands.get(s) else float("nan")
                    for s in styles}
        L.append(f"| {v} | " + " | ".join(fmt(ratio[v][s], 2) + (" (stuck)" if ratio[v][s] < STUCK else "")
                                        for s in styles) + " |")
    if released and "rollout" in released and not released["rollout"]["diverged"]:
        hands = released["rollout"].get("hands", {})      # a reference row: not part of the verdict
        L.append("| released network | " + " | ".join(
            fmt(hands[s] / ctx.data_hands[s], 2) if s in hands and ctx.data_hands.get(s) else "n/a"
            for s in styles) + " |")
    L.append("| data amplitude (m) | " + " | ".join(fmt(ctx.data_hands.get(s), 3) for s in styles) + " |")
    wins = total = 0
    for mod in ("FiLM", "one-hot", "Resad"):
        lpn = f"LPN {mod}"
        rivals = [f"{b} {mod}" for b in ("PFNN", "MANN") if f"{b} {mod}" in ratio]
        if lpn not in ratio:
            continue
        for s in styles:
            for r in rivals:
                a, b = abs(np.log(ratio[lpn][s])), abs(np.log(ratio[r][s]))
                if np.isfinite(a) and np.isfinite(b):
                    total += 1
                    wins += a < b
    return L + [f"\n*Verdict:* **{verdict(wins, total)}** (the LPN's arms closer to the data's in {wins} of "
                f"{total} comparisons; diverged variants are left out).\n"]


def capacity_claim(ctx, results) -> list:
    """Sec. 5.1.2 / Figure 7: one-hot and Resad lack capacity (ArmsAboveHead's clavicles), and one-hot
    models some styles as another."""
    L = ["### Sec. 5.1.2 / Figure 7: capacity with many styles\n",
         "*Paper:* one-hot and residual adapters only shift one hidden layer, FiLM scales and shifts all of them: "
         "with many styles the lower capacity shows as artifacts (ArmsAboveHead's clavicles are poorly modelled "
         "by LPN one-hot and LPN Resad, not by LPN FiLM), and one-hot can model some styles as another style.\n",
         "*Measures:* the clavicle error = one-step MSE (normalised units) of the predicted next-frame positions "
         "of the collar and shoulder joints on ArmsAboveHead's test frames (mean over the seeds); styles taken for "
         "another = seen styles whose generated motion the classifier assigns to one other style more often than "
         "to itself.\n",
         "*Rule:* holds when LPN FiLM's clavicle error is below both LPN one-hot's and LPN Resad's, and LPN "
         "one-hot has more styles taken for another than LPN FiLM (three comparisons).\n"]
    clav = {v: _mean([e.get("clavicle") for e in r.get("seed_errors") or [r["errors"]]]) for v, r in results.items()}
    have = any(np.isfinite(x) for x in clav.values())
    L.append("| variant | ArmsAboveHead clavicle error | styles taken for another | most often mistaken (for, share) |")
    L.append("|---|---:|---:|---|")
    mistaken = {}
    for v, r in results.items():
        tf = r["rollout"].get("taken_for") or {}
        bad = sorted((x for x in tf.items() if x[1]["mistaken"]), key=lambda x: -x[1]["other_share"])
        mistaken[v] = len(bad) if tf else None
        worst = ", ".join(f"{s} as {d['other']} ({d['other_share']:.0%})" for s, d in bad[:4]) or "none"
        n = "diverged" if r["rollout"]["diverged"] else f"{len(bad)} of {len(tf)}"
        L.append(f"| {v} | {fmt(clav[v])} | {n} | {worst if tf else ''} |")
    wins = total = 0
    if have and "LPN FiLM" in clav:
        for v in ("LPN one-hot", "LPN Resad"):
            if v in clav and np.isfinite(clav[v]):
                total += 1
                wins += clav["LPN FiLM"] < clav[v]
    if mistaken.get("LPN FiLM") is not None and mistaken.get("LPN one-hot") is not None:
        total += 1
        wins += mistaken["LPN one-hot"] > mistaken["LPN FiLM"]
    note = "" if have else " ArmsAboveHead is not a seen style: no clavicle figures."
    return L + [f"\n*Verdict:* **{verdict(wins, total)}** ({wins} of {total} comparisons go the paper's way).{note}\n"]


def claim_sections(ctx, results, ft, meta) -> list:
    """Every claim's section, in the paper's order."""
    L = ["## The paper's claims, one by one\n",
         "Each claim: the paper's statement in short, the figures of this run and a verdict by the stated rule. "
         "Definitions: docs/compare_claims.md. Read every verdict with the convergence section above: a run "
         "still falling at the end is not a converged result.\n"]
    for part in (figure10_claim(ctx, results), no_phase_claim(ctx, results, meta.get("released")),
                 capacity_claim(ctx, results),
                 interpolation_claim(ctx, results, meta.get("pairs") or [meta["interpolate"]]),
                 table2_claim(results, meta.get("table2")), new_style_claim(ctx, results, meta.get("finetuned") or ({"LPN FiLM": ft} if ft else {}),
                                 meta.get("table2"))):
        L.extend(part)
    return L
