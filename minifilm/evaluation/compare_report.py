"""The markdown report and PNG plots of `minifilm compare` (minifilm/evaluation/compare.py)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from minifilm.evaluation import compare_convergence, compare_finetune
from minifilm.evaluation.compare_claims import claim_sections
from minifilm.evaluation.compare_report_tools import fmt, report_name, seed_summary
from minifilm.files import atomic_write_text
from minifilm.viewer.deps import pyplot, save_figure

PHASE_STYLES = ("Swimming", "PendulumHands", "LeftHop")


_fmt = fmt


def command_options(a) -> str:
    """The options of the run beyond data and budget, as they would be typed (paths left out)."""
    out = []
    for flag, value in (("--styles", ",".join(a.styles) if a.styles else None), ("--holdout", a.holdout),
                        ("--interpolate", a.interpolate), ("--max-steps", getattr(a, "max_steps", None)),
                        ("--rollout-seconds", a.rollout_seconds if a.rollout_seconds != 10.0 else None),
                        ("--fps", a.fps if a.fps != 30.0 else None),
                        ("--variants", getattr(a, "variants", None)),
                        ("--lr", a.lr if a.lr != 1e-3 else None),
                        ("--batch-size", a.batch_size if a.batch_size != 32 else None),
                        ("--seed", a.seed if a.seed != 0 else None)):
        if value is not None:
            text = str(value)
            out.append(f"{flag} '{text}'" if any(c in text for c in " ;,") else f"{flag} {text}")
    if getattr(a, "extra_seeds", [1]) != [1]:
        out.append("--extra-seeds '" + ",".join(map(str, a.extra_seeds)) + "'")
    for flag, on in (("--until-flat", getattr(a, "until_flat", False)), ("--split-files", a.split_files),
                     ("--tiny", a.tiny)):
        if on:
            out.append(flag)
    return "".join(" " + x for x in out)


def _plots(out: Path, name: str, ctx, results, ft) -> dict:
    """Draw the PNGs; returns {key: file name} (empty without matplotlib)."""
    try:
        plt = pyplot()
    except ImportError:
        return {}
    files = {}
    names = list(results)
    # Figure 10: test MSE and BLL per variant
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    summ = {v: seed_summary(results[v]) for v in names}
    for ax, key in zip(axes, ("mse", "bll")):
        vals = [summ[v][key] for v in names]
        err = [summ[v][key + "_sd"] if summ[v]["n"] > 1 else 0.0 for v in names]
        ax.bar(range(len(names)), vals, yerr=err, capsize=3, color=[f"C{i}" for i in range(len(names))])
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels(names, rotation=30, ha="right", fontsize=8)
        ax.set_title(f"test {key.upper()} (seen styles; mean, sd over {summ[names[0]]['n']} seeds)", fontsize=9)
    fig.tight_layout()
    files["errors"] = f"compare_{name}_errors.png"
    save_figure(fig, out / files["errors"], dpi=80)
    curves = f"compare_{name}_validation.png"
    if compare_convergence.draw_curves(plt, out / curves, results):
        files["curves"] = curves
    # Figure 8: style score along the blend weight
    interp = [v for v in names if "interp" in results[v] and not results[v]["interp"].get("diverged")]
    if interp:
        fig, ax = plt.subplots(figsize=(6, 4))
        for i, v in enumerate(interp):
            r = results[v]["interp"]
            ax.plot(r["weights"], r["score"], "-o" if "FiLM" in v else "--s", ms=3, label=v)
        ax.plot([0, 1], [0, 1], ":", color="gray", lw=1)
        ax.set_xlabel("blend weight w (0 = style A, 1 = style B)")
        ax.set_ylabel("classifier P(B) / (P(A) + P(B))")
        ax.legend(fontsize=7)
        fig.tight_layout()
        files["interp"] = f"compare_{name}_interpolation.png"
        save_figure(fig, out / files["interp"], dpi=80)
    # Figure 11: FiLM codes before / after fine-tuning
    if ft is not None:
        styles = ctx.seen + ctx.holdouts
        fig, axes = plt.subplots(1, 2, figsize=(10, 4.5))
        draw_film_codes(axes, ft["separation"], ft["labels"], styles, ctx.holdouts)
        fig.tight_layout()
        files["film"] = f"compare_{name}_film_codes.png"
        save_figure(fig, out / files["film"], dpi=80)
    return files


def claims(ctx, results, ft) -> list:
    """The paper's claims, each with a verdict computed from the numbers of this run."""
    out = []
    summ = {v: seed_summary(r) for v, r in results.items()}
    mse = {v: summ[v]["mse"] for v in results}
    film = [v for v in mse if "FiLM" in v]
    other = [v for v in mse if "FiLM" not in v]
    if film and other:
        best_other = min(other, key=mse.get)
        best = min(mse, key=mse.get)
        sds = [summ[v]["mse_sd"] for v in summ if summ[v]["n"] > 1]
        if max(mse[v] for v in film) < mse[best_other]:
            verdict = "holds"
        elif best in film:
            verdict = "partly holds (the lowest is a FiLM variant, but not every FiLM variant beats every other)"
        else:
            verdict = "does not hold"
        out.append(f"FiLM variants have the lowest test error: **{verdict}** "
                   f"(lowest overall: {best} {mse[best]:.4f}; FiLM variants "
                   + ", ".join(f"{v} {mse[v]:.4f}" for v in film)
                   + f"; best non-FiLM {best_other} {mse[best_other]:.4f}; means over {summ[best]['n']} seed(s)"
                   + (f", seed-to-seed sd {min(sds):.4f} to {max(sds):.4f})." if sds else "; one seed)."))
    phase = [s for s in PHASE_STYLES if s in ctx.seen]
    trio = [v for v in ("LPN FiLM", "PFNN FiLM", "MANN FiLM") if v in results]
    if phase and "LPN FiLM" in results and len(trio) > 1:
        parts, wins = [], 0
        for s in phase:
            e = {v: summ[v]["per_style"][s] for v in trio}
            win = e["LPN FiLM"] < min(e[v] for v in trio if v != "LPN FiLM")
            wins += win
            parts.append(f"{s}: " + ", ".join(f"{v.split()[0]} {e[v]:.4f}" for v in trio))
        out.append(f"LPN beats PFNN and MANN (all with FiLM) on styles whose limbs have different phase cycles: "
                   f"**LPN lowest on {wins} of {len(phase)}** ({'; '.join(parts)}).")
    if ft is not None:
        b, a = ft["separation"]["before"]["focus_silhouette"], ft["separation"]["after"]["focus_silhouette"]
        holds = a > b and a > 0
        out.append(f"Fine-tuning Ψ alone makes an unseen style separable: **{'holds' if holds else 'does not hold'}** "
                   f"(LPN FiLM, silhouette of the FiLM codes of {', '.join(ctx.holdouts)} {b:.3f} -> {a:.3f}; "
                   "all styles "
                   f"{ft['separation']['before']['silhouette']:.3f} -> {ft['separation']['after']['silhouette']:.3f}).")
    return out


def write_report(out: Path, name: str, ctx, results, ft, meta) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    files = _plots(out, name, ctx, results, ft)
    a, ds = ctx.args, ctx.ds
    L = []
    w = L.append
    w(f"# Comparison of the variants on {name} data (Figure 10, style metrics)\n")
    shown = report_name(a.data)
    w(f"Generated by `OPENBLAS_NUM_THREADS=1 minifilm compare --data {shown} --budget-steps "
      f"{a.budget_steps} --finetune-steps {a.finetune_steps}" + command_options(a)
      + f"` in {meta['total_seconds'] / 60:.1f} min on a shared 2-core machine.\n")
    w("## Setup\n")
    w(f"- Data: {name}, {len(ds.styles)} styles at {ds.fps:g} fps ({len(ds.train)} training frames); held out of "
      f"training: **{', '.join(ctx.holdouts)}**; seen: {', '.join(ctx.seen)}. Normalisation statistics from the seen styles only.")
    w(f"- Budget, {'before --until-flat' if getattr(a, 'until_flat', False) else 'identical'} for every variant: **{meta['epochs']} epoch(s) x {meta['steps_per_epoch']} style-balanced "
      f"minibatches of {a.batch_size} = {meta['epochs'] * meta['steps_per_epoch']} Adam steps** (lr {a.lr:g}, "
      f"dropout {meta['sizes']['dropout']}), asked for: {a.budget_steps}. Small models: hidden "
      f"{meta['sizes']['hidden']}, {meta['sizes']['n_experts']} experts, Ψ conv {meta['sizes']['conv_filters']} "
      f"filters / dense {meta['sizes']['film_dense']}, "
      f"clips {a.clip_seconds:g} s. The paper trained 90 epochs: whether this budget is enough is judged by "
      f"the validation curves below."
      + (f" With --until-flat every run went on in whole epochs while its validation loss still fell, up to "
         f"{a.max_steps or 4 * meta['epochs'] * meta['steps_per_epoch']} steps: the steps of each run are in the "
         "convergence table, so the budgets are no longer identical." if getattr(a, "until_flat", False) else ""))
    w("- Test errors are on held-out test frames of the seen styles, over the 324 motion outputs (trajectory and "
      "joints) that every variant predicts (the LPN's phase outputs and the PFNN's phase update are left out so the "
      "numbers are comparable), normalised units, each style weighted equally. BLL = bone-length loss (Eq. 6-7), m.")
    w(f"- Rollouts: {a.rollout_seconds:g} s per seen style along a figure-eight (1.3 m/s commanded) with "
      "`minifilm.runtime.controller.Controller`; every variant is driven through `compare_tools.VariantRuntime` (PFNN: global "
      "phase advanced by its predicted update; MANN: end-effector velocities; one-hot / Resad: style ids; FiLM: the "
      "mean Ψ(clip) over the style's training clips). The first second (mean start pose) is dropped.")
    ci = ctx.clf_info
    w(f"- Style classifier (`minifilm.evaluation.style_classifier`): MLP (64 ReLU units) on the mean and std over "
      f"{ci['window']}-frame windows of the normalised clip features; trained on {ci['n_train']} windows of the "
      f"training rows (all {len(ds.styles)} styles); **ceiling = accuracy on {ci['n_heldout']} windows of held-out "
      f"real rows: {ci['heldout_acc']:.3f}** (training accuracy {ci['train_acc']:.3f}).\n")
    L.extend(compare_convergence.section(results, files.get("curves")))
    w("## Figure 10: test error\n")
    n_seeds = seed_summary(next(iter(results.values())))["n"]
    seeds = ", ".join(str(x) for x in [a.seed] + list(getattr(a, "extra_seeds", [])))
    w(f"Mean ± sample std over {n_seeds} model seed(s) ({seeds}; same data, different initialisation and batch "
      f"order); rollouts and everything below use the model of seed {a.seed}.\n")
    w("| variant | parameters | test MSE | test BLL | final train loss (seed " + str(a.seed) + ") | train time |")
    w("|---|---:|---:|---:|---:|---:|")
    pm = lambda m, sd: f"{m:.4f}" + (f" ± {sd:.4f}" if np.isfinite(sd) else "")   # noqa: E731
    for v, r in results.items():
        e = seed_summary(r)
        w(f"| {v} | {r['params']:,} | {pm(e['mse'], e['mse_sd'])} | {pm(e['bll'], e['bll_sd'])} | "
          f"{r['final_train_loss']:.4f} | {r['seconds']:.0f} s |")
    if "errors" in files:
        w(f"\n![test errors]({files['errors']})\n")
    w("Test MSE per seen style (mean over the seeds; the lowest in bold):\n")
    summ = {v: seed_summary(r) for v, r in results.items()}
    w("| style | " + " | ".join(results) + " |")
    w("|---|" + "---:|" * len(results))
    for s in ctx.seen:
        best = min(results, key=lambda v: summ[v]["per_style"][s])
        w(f"| {s} | " + " | ".join((f"**{summ[v]['per_style'][s]:.4f}**" if v == best else
                                   f"{summ[v]['per_style'][s]:.4f}") for v in results) + " |")
    w("\n## Generated motion: style recognition, foot sliding, bone lengths\n")
    w(f"Classifier ceiling on real held-out rows: **{ci['heldout_acc']:.3f}** (chance {1 / len(ds.styles):.3f}).\n")
    w("Foot sliding twice: while the network's own contact label is on (m/s), and by the field's "
      "height-based definition (cm/s while a toe is within 1 cm of the floor, docs/metrics.md). "
      "Path and direction errors: the root against the commanded velocities integrated.\n")
    fid = getattr(ctx, "fid", None)
    if fid:
        w("FID-like: the squared Fréchet distance between all rollout windows of all seen styles and all real "
          "held-out windows of those styles, in the style space of their real training windows (docs/metrics.md); "
          f"real held-out windows against real training windows read **{_fmt(fid['real_to_real'], 2)}**, the floor "
          "a generator moving exactly like the data would reach.\n")
    w("| variant | style accuracy | FID-like | foot sliding (m/s) | foot sliding, height (cm/s) | path error (m) | "
      "direction error (°) | bone-length cv mean | bone-length cv max | root speed (m/s) |")
    w("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    rel = meta.get("released")
    rows = [(v, r["rollout"]) for v, r in results.items()]
    if rel and "rollout" in rel:
        rows.append((f"released network ({len(rel['styles'])} styles)", rel["rollout"]))
    for v, q in rows:
        w(f"| {v} | diverged | | | | | | | | |" if q["diverged"] else
          f"| {v} | {q['accuracy']:.3f} | {_fmt(q.get('fid'), 2)} | {_fmt(q['foot_sliding'], 3)} | "
          f"{_fmt(q.get('foot_sliding_cm_s'), 1)} | {_fmt(q.get('path_error'), 2)} | "
          f"{_fmt(q.get('direction_error'), 1)} | {_fmt(q['bone_cv_mean'])} | {_fmt(q['bone_cv_max'])} | "
          f"{_fmt(q['speed'], 2)} |")
    if rel and "rollout" in rel:
        w(f"\nThe released network ({rel['source']}, named by {rel['named_by']}) is driven along the same "
          "figure-eight for the same seconds, without calibration or foot locking like the variants, at its own "
          "60 fps, thinned to the data's rate before it is measured.")
    elif rel:
        w(f"\nThe released network's row is missing: {rel['skipped']}.")
    w("\nStyle accuracy per seen style (fraction of rollout windows classified as the commanded style):\n")
    alive = [v for v, r in results.items() if not r["rollout"]["diverged"]]
    w("| style | " + " | ".join(alive) + " |")          # a row per style: 100 styles stay readable
    w("|---|" + "---:|" * len(alive))
    for s in ctx.seen:
        w(f"| {s} | " + " | ".join(f"{results[v]['rollout']['per_style'][s]:.2f}" for v in alive) + " |")
    pa, pb = meta["interpolate"]
    w(f"\n## Figure 8: interpolation {pa} -> {pb}\n")
    w(f"Score = P({pb}) / (P({pa}) + P({pb})) of the classifier, averaged over the windows of a "
      f"{a.rollout_seconds:g} s rollout, at 11 blend weights. FiLM blends the two styles' FiLM vectors, one-hot "
      "blends the one-hot vectors (the one-hot term is linear in them); Resad variants are not blended here. "
      "monotonicity = |s(1) - s(0)| / total variation (1 = monotone); max step = largest change between "
      "neighbouring weights as a fraction of s(1) - s(0) (0.1 = linear, 1 = a jump).\n")
    w("| variant | s(0) | s(1) | monotonicity | max step | RMS from linear |")
    w("|---|---:|---:|---:|---:|---:|")
    for v, r in results.items():
        i = r.get("interp")
        if i is None:
            continue
        if i.get("diverged"):
            w(f"| {v} | diverged | | | | | | | |")
            continue
        small = abs(i["change"]) < 0.2             # the score hardly moves: the ratio means little
        step = "n/a" if small else f"{i['max_step']:.2f}"
        w(f"| {v} | {i['score'][0]:.3f} | {i['score'][-1]:.3f} | {i['monotonicity']:.2f} | {step} | "
          f"{i['linear_rmse']:.3f} |")
    if "interp" in files:
        w(f"\n![interpolation]({files['interp']})\n")
    L.extend(compare_finetune.section(ctx, results, meta.get("finetuned") or ({"LPN FiLM": ft} if ft else {}),
                                      files.get("film")))
    w("\n## The paper's claims, here\n")
    for c in claims(ctx, results, ft):
        w(f"- {c}")
    L.append("")
    L.extend(claim_sections(ctx, results, ft, meta))
    bad = [v for v, r in results.items() if r["rollout"]["diverged"]]
    if bad:
        w(f"- Rollouts of {', '.join(bad)} diverged (a joint more than 10 m from the root, or non-finite): the "
          "autoregressive loop blew up, so no rollout metrics are given for them. Their one-step test errors "
          "above are unaffected.")
    path = out / f"compare_{name}.md"
    atomic_write_text(path, "\n".join(L) + "\n")
    return path


def draw_film_codes(axes, separation, labels, names, holdouts):
    """Figure 11 on two matplotlib axes: the 2-D PCA embedding of FiLM codes before and after
    fine-tuning Ψ, one colour per style, the held-out styles as stars (black for one).

    separation: {'before'|'after': {'embedding' (M, 2), 'silhouette', 'focus_silhouette'}};
    labels (M,) style index of each code into ``names``; holdouts: the held-out names."""
    holdouts = [holdouts] if isinstance(holdouts, str) else list(holdouts)
    held = ", ".join(holdouts) if len(holdouts) <= 2 else f"{len(holdouts)} held out"
    for ax, tag in zip(axes, ("before", "after")):
        sep = separation[tag]
        Y = sep["embedding"]
        for k, name in enumerate(names):
            pts = Y[labels == k]
            new = name in holdouts
            if new:           # stars on top; black for a single held-out style, else a colour each
                colour = "black" if len(holdouts) == 1 else f"C{holdouts.index(name) % 10}"
            ax.scatter(pts[:, 0], pts[:, 1], s=50 if new else 14, marker="*" if new else "o",
                       color=colour if new else f"C{k % 10}", label=name + (" (held out)" if new else ""),
                       edgecolors="black" if new else None, zorder=3 if new else 2)
        ax.set_title(f"{tag} fine-tuning Ψ: silhouette {sep['silhouette']:.2f}, "
                     f"{held} {sep['focus_silhouette']:.2f}", fontsize=9)
        ax.set_xlabel("PC 1")
        ax.set_ylabel("PC 2")
    if len(names) <= 20:
        axes[1].legend(fontsize=7)
    else:                        # a legend of 100 styles would not fit: name the held-out styles only
        stars = [(h, n) for h, n in zip(*axes[1].get_legend_handles_labels()) if n.endswith("(held out)")]
        axes[1].legend([h for h, _ in stars], [n for _, n in stars], fontsize=7)
