"""Sec. 5.3.2 / Figure 11 in the comparison (minifilm/evaluation/compare.py): new styles taught to
every FiLM variant by fine-tuning Ψ alone on the held-out styles' training frames, the backbone (Ω or
the PFNN's phase function, and Φ) frozen.

Measured per variant, before and after: the held-out styles' test MSE and BLL (together and per
style), the silhouette of their FiLM codes among all styles' codes (together and per style), and
the seen styles' test MSE afterwards (how much Ψ forgot). The one-hot and residual-adapter variants
cannot be taught this way: a new style there is a full retraining or a new adapter set.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

from minifilm.baselines.variant_data import variant_data
from minifilm.baselines.variants import model_from_checkpoint
from minifilm.evaluation.compare_report_tools import fmt
from minifilm.evaluation.compare_tools import film_codes, film_separation, motion_errors, steps_per_epoch, style_subset
from minifilm.train.finetune import finetune
from minifilm.train.trainer import TrainConfig

#: the variants a new style is taught to by Ψ alone, in the order the report lists them
FILM_VARIANTS = ("LPN FiLM", "MANN FiLM", "PFNN FiLM")


def checkpoint_name(variant: str) -> str:
    """'LPN FiLM' -> 'lpn_film_base.npz': the trained model the fine-tuning starts from."""
    return variant.lower().replace(" ", "_").replace("-", "") + "_base.npz"


def finetune_separation(result, ctx, variant: str = "LPN FiLM") -> dict:
    """Fine-tune Ψ alone of ``variant`` (trained: ``result`` from compare.train_variant) on the
    held-out styles; their errors and FiLM-code silhouettes before and after.

    Returns {'variant', 'steps', 'seconds', 'before_new' / 'after_new' (motion_errors of the held-out
    test frames, 'per_style' by name), 'seen_after', 'separation': {'before' / 'after':
    film_separation with the held-out styles as focus}, 'labels' (clip style ids: seen styles first,
    then the held-out ones in ctx.holdouts' order)}."""
    a, L, norm = ctx.args, ctx.layout, ctx.norm
    trainer, info = result["trainer"], result["info"]
    path = Path(a.work) / checkpoint_name(variant)
    trainer.save(path)

    def shaped(data):          # the LPN's rows as this variant reads them (the MANN's gate, the PFNN's phase)
        return variant_data(variant, data, L, norm, ctx.end_effectors, reference=info)[0]

    new_train = shaped(ctx.new_train)
    new_test = shaped(style_subset(ctx.ds, "test", ctx.holdouts, norm))
    n_motion = L.z_phases.start
    before_new = motion_errors(trainer.model, new_test, L, norm, n_motion, seed=a.seed)
    epochs = max(1, math.ceil(a.finetune_steps / steps_per_epoch(new_train.style, a.batch_size)))
    t0 = time.perf_counter()
    ft = finetune(path, new_train, config=TrainConfig(epochs=epochs, batch_size=a.batch_size, lr=a.lr,
                                                      seed=a.seed + 1, progress=False),
                  style_names=list(ctx.holdouts), build_model=model_from_checkpoint)
    seconds = time.perf_counter() - t0
    after_new = motion_errors(ft.model, new_test, L, norm, n_motion, seed=a.seed)
    labels = ctx.all_train.clip_style
    focus = list(range(len(ctx.seen), len(ctx.seen) + len(ctx.holdouts)))
    sep = {"before": film_separation(film_codes(trainer.model, ctx.all_train.clips), labels, focus),
           "after": film_separation(film_codes(ft.model, ctx.all_train.clips), labels, focus)}
    seen_after = motion_errors(ft.model, shaped(ctx.data["test"]), L, norm, n_motion, seed=a.seed)
    return {"variant": variant, "separation": sep, "labels": labels, "seconds": seconds, "steps": ft.step,
            "before_new": before_new, "after_new": after_new, "seen_after": seen_after}


def finetune_all(results, ctx, log=print) -> dict:
    """{variant: finetune_separation(...)} for every FiLM variant of ``results``; {} without held-out styles."""
    if ctx.new_train is None:
        return {}
    out = {}
    for v in (v for v in FILM_VARIANTS if v in results):
        ft = out[v] = finetune_separation(results[v], ctx, v)
        sb, sa = ft["separation"]["before"], ft["separation"]["after"]
        log(f"[finetune] {v}: Ψ only on {', '.join(ctx.holdouts)}: {ft['steps']} steps in {ft['seconds']:.0f} s; "
            f"held-out test MSE {ft['before_new']['mse']:.4f} -> {ft['after_new']['mse']:.4f}; silhouette of the "
            f"held-out codes {sb['focus_silhouette']:.3f} -> {sa['focus_silhouette']:.3f} (all styles "
            f"{sb['silhouette']:.3f} -> {sa['silhouette']:.3f})")
    return out


def section(ctx, results, finetuned: dict, figure=None) -> list:
    """The report's Figure 11 section (markdown lines): per FiLM variant, the held-out styles'
    errors and silhouettes before and after, then per held-out style; ``figure``: the PNG of the
    LPN FiLM's codes, if drawn."""
    held = ", ".join(ctx.holdouts)
    L = [f"\n## Figure 11: a new style, Ψ alone fine-tuned on the held-out styles ({held})\n"]
    if not finetuned:
        return L + ["Not run (needs a FiLM variant and a held-out style).\n"]
    a = ctx.args
    L.append(f"Every FiLM variant's Ψ fine-tuned on the training frames of {held} together "
             f"({a.finetune_steps} steps asked, lr {a.lr:g}; Ω or the phase function and Φ frozen). FiLM codes "
             "Ψ(clip) of every training clip of all styles; silhouette (Euclidean, full 4H-dimensional codes and in "
             "the 2-D PCA plane); 'held-out' = the held-out styles' codes only. Held-out errors are in the seen "
             "styles' normalised units (the statistics never saw the held-out styles), so a style outside their "
             "range gives large numbers: compare before with after, not with the seen styles.\n")
    L += ["| variant | | silhouette (all styles) | silhouette 2-D | silhouette, held-out | held-out test MSE | "
          "held-out test BLL | seen styles' test MSE | steps, time |",
          "|---|---|---:|---:|---:|---:|---:|---:|---|"]
    for v, ft in finetuned.items():
        sb, sa = ft["separation"]["before"], ft["separation"]["after"]
        for tag, sep, err in (("before", sb, ft["before_new"]), ("after", sa, ft["after_new"])):
            seen = results[v]["errors"]["mse"] if tag == "before" else ft["seen_after"]["mse"]
            cost = f"{ft['steps']}, {ft['seconds']:.0f} s" if tag == "after" else ""
            L.append(f"| {v} | {tag} | {sep['silhouette']:.3f} | {sep['silhouette_2d']:.3f} | "
                     f"{sep['focus_silhouette']:.3f} | {err['mse']:.4f} | {err['bll']:.4f} | {seen:.4f} | {cost} |")
    L.append("\nPer held-out style: test MSE and the silhouette of its FiLM codes, before -> after.\n")
    L += ["| style | " + " | ".join(finetuned) + " |", "|---|" + "---|" * len(finetuned)]
    first = len(ctx.seen)
    for k, name in enumerate(ctx.holdouts):
        cells = []
        for ft in finetuned.values():
            b, f = ft["before_new"]["per_style"].get(name), ft["after_new"]["per_style"].get(name)
            sb = ft["separation"]["before"]["focus_each"].get(first + k)
            sa = ft["separation"]["after"]["focus_each"].get(first + k)
            cells.append(f"MSE {fmt(b and b['mse'], 4)} -> {fmt(f and f['mse'], 4)}; "
                         f"silhouette {fmt(sb, 3)} -> {fmt(sa, 3)}")
        L.append(f"| {name} | " + " | ".join(cells) + " |")
    L.append("\nSeen styles' test MSE after: Ψ was trained on the new styles only, so this shows how much it forgot.")
    if figure:
        L.append(f"\n![FiLM codes of LPN FiLM before and after]({figure})\n")
    return L
