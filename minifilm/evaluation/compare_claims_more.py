"""The report's claim sections on interpolation (Figure 8), storage and run time (Table 2) and new
styles (Sec. 5.3.2 / Figure 11); see minifilm/evaluation/compare_claims.py for the others and the
verdict words."""
from __future__ import annotations

import numpy as np

from minifilm.baselines.variants import variant_parameter_counts
from minifilm.evaluation.compare_report_tools import fmt
from minifilm.evaluation.table2 import PAPER, time_variants


def _verdict(wins: int, total: int) -> str:
    if total == 0:
        return "not judged"
    return "holds" if wins == total else "partly" if wins > 0 else "does not hold"


def interpolation_claim(ctx, results, pairs) -> list:
    """Figure 8: one-hot holds the first style until the blend is nearly done, FiLM blends smoothly."""
    L = ["### Figure 8: interpolation between styles\n",
         "*Paper:* blending two styles, one-hot keeps the first style until the interpolation is nearly complete, "
         "FiLM moves smoothly through a continuous style space (BentForward to LeanBack).\n",
         "*Measures* (docs/compare_claims.md), from rollouts at blend weights 0, 0.1, .., 1: the pose statistics "
         "(mean and standard deviation over time of every normalised joint feature) of each weight's rollout; "
         "**max/mean** = the largest move of those statistics between neighbouring weights over the mean move "
         "(1 = every 10 % of the blend moves the pose as far; 10 = all of it in one step); **half-way share** = "
         "the share of the path walked by w = 0.5 (0.5 = even, near 0 = the first style held).\n",
         "*Rule:* for every pair and backbone with a FiLM and a one-hot variant, FiLM's max/mean is below "
         "one-hot's and its half-way share is nearer 0.5 (two comparisons each).\n"]
    L.append("| pair | variant | max/mean | half-way share | end-to-end distance | classifier score at w = 0.5 |")
    L.append("|---|---|---:|---:|---:|---:|")
    wins = total = 0
    for pair in pairs:
        found = {}
        for v, r in results.items():
            i = (r.get("interps") or {}).get(tuple(pair)) or (r.get("interp") if tuple(pair) == tuple(pairs[0]) else None)
            if i is None:
                continue
            if i.get("diverged"):
                L.append(f"| {pair[0]} -> {pair[1]} | {v} | diverged | | | |")
                continue
            found[v] = i["pose"]
            mid = float(np.interp(0.5, i["weights"], i["score"]))
            L.append(f"| {pair[0]} -> {pair[1]} | {v} | {fmt(i['pose']['max_over_mean'], 2)} | "
                     f"{fmt(i['pose']['first_half_share'], 2)} | {fmt(i['pose']['end_to_end'], 2)} | {mid:.2f} |")
        for backbone in ("PFNN", "MANN", "LPN"):
            f, o = found.get(f"{backbone} FiLM"), found.get(f"{backbone} one-hot")
            if f is None or o is None:
                continue
            total += 2
            wins += f["max_over_mean"] < o["max_over_mean"]
            wins += abs(f["first_half_share"] - 0.5) < abs(o["first_half_share"] - 0.5)
    return L + [f"\n*Verdict:* **{_verdict(wins, total)}** ({wins} of {total} comparisons go the paper's way).\n"]


def table2_figures(names, config, n_styles, frames=100, runs=3) -> dict:
    """Table 2 at this run's sizes: {variant: {'asn', 'smn', 'psr', 'ms', 'ms_sd'}} (ms per frame at
    batch 1 through the run-time network, minifilm/evaluation/table2.py, on this machine now)."""
    counts = {v: variant_parameter_counts(v, config, n_styles) for v in names}
    times = time_variants(list(names), config, frames=frames, runs=runs)
    return {v: dict(counts[v], ms=times[v][0], ms_sd=times[v][1]) for v in names}


def table2_claim(results, table) -> list:
    """Table 2: P.S.R. of FiLM is the smallest (LPN one-hot twice LPN FiLM's); the PFNN is the fastest."""
    L = ["### Table 2: parameters and run time\n",
         "*Paper:* FiLM needs few numbers per style at run time (its vectors are precomputed: P.S.R. 2048, half "
         "LPN one-hot's, far below Resad's), however large Ψ is; the PFNN is the fastest per frame, the LPN and "
         "MANN cost more.\n",
         "*Rule:* holds when LPN FiLM's P.S.R. is below LPN one-hot's and LPN Resad's, and PFNN FiLM's time per "
         "frame is below LPN FiLM's and MANN FiLM's (the variants run here; each comparison counts once).\n"]
    if not table:
        return L + ["*Verdict:* **not judged** (no Table 2 figures in this run).\n"]
    L.append("| variant | A.S.N. | S.M.N. | P.S.R. | ms / frame here | paper A.S.N. | paper S.M.N. | paper P.S.R. | "
             "paper ms |")
    L.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for v, t in table.items():
        p = PAPER[v]
        L.append(f"| {v} | {t['asn']:,} | {t['smn']:,} | {t['psr']:,} | {t['ms']:.3f} ± {t['ms_sd']:.3f} | "
                 f"{p[0]:,} | {p[1]:,} | {p[2]:,} | {p[3]:.2f} ± {p[4]:.2f} |")
    L.append("\nThe counts are those of the models trained here (their sizes and number of styles), not the "
             "paper's configuration (`minifilm table2` gives those); times are batch-1 predictions on this "
             "machine under its current load.")
    wins = total = 0
    for rival in ("LPN one-hot", "LPN Resad"):
        if "LPN FiLM" in table and rival in table:
            total += 1
            wins += table["LPN FiLM"]["psr"] < table[rival]["psr"]
    for rival in ("LPN FiLM", "MANN FiLM"):
        if "PFNN FiLM" in table and rival in table:
            total += 1
            wins += table["PFNN FiLM"]["ms"] < table[rival]["ms"]
    return L + [f"\n*Verdict:* **{_verdict(wins, total)}** ({wins} of {total} comparisons go the paper's way).\n"]


def new_style_claim(ctx, results, finetuned, table) -> list:
    """Sec. 5.3.2 / Figure 11: a new style by fine-tuning Ψ alone; others need retraining or a new adapter set.
    finetuned: {FiLM variant: compare_finetune.finetune_separation's result}."""
    held = ", ".join(ctx.holdouts)
    L = ["### Sec. 5.3.2 / Figure 11: a new style\n",
         "*Paper:* with FiLM a new style needs only Ψ fine-tuned on its data (the motion networks frozen); after "
         "it the new style's FiLM codes form a cluster of their own. One-hot would need every parameter retrained, "
         "residual adapters a further large set of parameters per style.\n",
         "*Rule:* for every FiLM variant fine-tuned here, two comparisons: fine-tuning lowers the held-out styles' "
         "test MSE, and raises the silhouette of their FiLM codes to above 0. Holds when every comparison goes "
         "the paper's way.\n"]
    L.append("| variant | what a new style needs | trained for it | stored per style | measured here |")
    L.append("|---|---|---:|---:|---|")
    for v, r in results.items():
        t = (table or {}).get(v, {})
        psr = f"{t['psr']:,}" if t else "n/a"
        if "FiLM" in v:
            ft = finetuned.get(v)
            measured = "not run" if ft is None else (
                f"{ft['steps']} steps, {ft['seconds']:.0f} s; held-out MSE {ft['before_new']['mse']:.4f} -> "
                f"{ft['after_new']['mse']:.4f}; silhouette {ft['separation']['before']['focus_silhouette']:.3f} -> "
                f"{ft['separation']['after']['focus_silhouette']:.3f}")
            L.append(f"| {v} | fine-tune Ψ only | {t['smn']:,} (Ψ) | {psr} |  {measured} |" if t else
                     f"| {v} | fine-tune Ψ only | n/a | n/a | {measured} |")
        elif "one-hot" in v:
            whole = f"{t['asn'] + t['smn']:,} (all)" if t else "all"
            L.append(f"| {v} | a new style id: retrain every parameter on all styles | {whole} | {psr} | "
                     f"a full training run: {r['steps']} steps, {r['seconds']:.0f} s here |")
        else:
            L.append(f"| {v} | a new adapter set trained (backbone frozen) | {psr} | {psr} | not run |")
    if not finetuned:
        return L + ["\n*Verdict:* **not judged** (needs a FiLM variant and a held-out style).\n"]
    wins = total = 0
    for v, ft in finetuned.items():
        b, a = ft["separation"]["before"]["focus_silhouette"], ft["separation"]["after"]["focus_silhouette"]
        wins += int(ft["after_new"]["mse"] < ft["before_new"]["mse"]) + int(a > b and a > 0)
        total += 2
    return L + [f"\nHeld out of training: {held} (per style and variant in the Figure 11 section).",
                f"\n*Verdict:* **{_verdict(wins, total)}** ({wins} of {total} comparisons go the paper's way).\n"]
