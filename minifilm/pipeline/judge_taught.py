"""A style taught to the released network, judged among all the network's styles by its motion.

    the taught vectors (every candidate of the fit) and the 100 released vectors walk the same
    straight line at the clip's speed, one batch -> each motion's window summaries
    (minifilm/evaluation/style_judge.py) -> references: the released styles' own motion, and the
    clip itself for the new style -> Fréchet rank and classifier recognition among the 101

The released styles' references are the first half of their rollout (after the first second);
every vector is judged on the second half, so nothing is judged on the windows that stand for it.
The candidate to keep can be chosen on the first half (its Fréchet distance to the clip) and is
still judged on the second.
"""
from __future__ import annotations

import re
from typing import Dict, List, Sequence

import numpy as np

from minifilm.evaluation.style_judge import StyleJudge, summaries
from minifilm.pipeline.walks import clip_summaries, walk_blocks


def halves(blocks) -> tuple:
    """Window summaries of the first and of the second half of every block."""
    first = [summaries(b[:len(b) // 2]) for b in blocks]
    second = [summaries(b[len(b) // 2:]) for b in blocks]
    return first, second


def judge_refits(rel, layout, fitted: Dict[str, np.ndarray], speed: float = 1.3, seconds: float = 20.0,
                 seeds: Sequence[int] = (0, 1, 2)) -> dict:
    """The known-answer case by motion: ``fitted`` maps a released style's name to the vector re-fitted
    from its motion with its own vector hidden. Every fitted vector and the 100 released walk one
    straight line at ``speed``; each fitted motion (second half) is judged among the released
    styles' motion (first halves) with its hidden style as the target. -> {'fitted': {name: judge},
    'released_self': released styles ranking themselves first on their second half,
    'released_recognition_min': the median over released styles of their minimum recognition}."""
    names, targets = list(rel.styles), list(fitted)
    films = np.concatenate([np.stack([fitted[t] for t in targets]), np.stack([rel.styles[n] for n in names])])
    blocks, _ = walk_blocks(rel.network, layout, rel.stats, films, speed, seconds)
    first, second = halves(blocks)
    k = len(targets)
    judge = StyleJudge.fit({n: first[k + i] for i, n in enumerate(names)}, seeds=seeds)
    own = [judge.judge(second[k + i], n) for i, n in enumerate(names)]
    return dict(fitted={t: judge.judge(second[i], t) for i, t in enumerate(targets)},
                released_self=int(sum(j["rank"] == 1 for j in own)),
                released_recognition_min=float(np.median([j["recognition_min"] for j in own])))


def judge_taught(rel, layout, taught, seconds: float = 20.0, seeds: Sequence[int] = (0, 1, 2),
                 released: Sequence[str] = None, unseen=None) -> dict:
    """Judge every candidate vector of ``taught``
    (a :class:`~minifilm.pipeline.teach_released.TaughtStyle`) among the released styles
    and the clip. -> {'chosen': judge of the vector teach kept, 'candidates': [judge per candidate,
    with 'clip_distance_first_half'], 'by_frechet': index of the candidate nearest the clip on the
    first half, 'clip_nearest': [(released style, distance)] nearest the clip itself, 'released_self':
    how many released styles rank themselves first on their second half, 'released_spread': the
    median distance of a released style's second half to its own first half and to the nearest
    other style, 'unseen': the judge of ``unseen`` (window summaries of real motion of the clip's
    style that it was not taught from: what a perfect generator would score), or None}."""
    names = list(released or rel.styles)
    films = np.concatenate([taught.candidate_films, np.stack([rel.styles[n] for n in names])])
    blocks, _ = walk_blocks(rel.network, layout, rel.stats, films, taught.clip.speed, seconds)
    first, second = halves(blocks)
    k = len(taught.candidate_films)
    refs: Dict[str, np.ndarray] = {n: first[k + i] for i, n in enumerate(names)}
    refs[taught.name] = clip_summaries(taught.clip, rel.stats, layout)
    judge = StyleJudge.fit(refs, seeds=seeds)
    cands: List[dict] = []
    for c in range(k):
        j = judge.judge(second[c], taught.name)
        j["clip_distance_first_half"] = judge.space.distances(first[c], summarised=True)[taught.name]
        cands.append(j)
    chosen = next(i for i, c in enumerate(taught.candidates) if c.get("chosen"))
    clip_d = {n: v for n, v in judge.space.distances(refs[taught.name], summarised=True).items() if n != taught.name}
    gap = feature_gap(judge, refs[taught.name], second[chosen], layout)
    own = [judge.judge(second[k + i], n) for i, n in enumerate(names)]
    self_first = sum(j["rank"] == 1 for j in own)
    spread = dict(own=float(np.median([j["distance"] for j in own])),
                  nearest_other=float(np.median([next(d for m, d in j["nearest"] if m != j["target"]) for j in own])))
    ceiling = None if unseen is None else judge.judge(unseen, taught.name)
    return dict(released_spread=spread, unseen=ceiling,chosen=cands[chosen], chosen_index=chosen, candidates=cands,
                by_frechet=int(np.argmin([c["clip_distance_first_half"] for c in cands])),
                clip_nearest=sorted(clip_d.items(), key=lambda kv: kv[1])[:3], released_self=int(self_first),
                n_styles=len(refs), gap=gap)


def feature_gap(judge, clip: np.ndarray, motion: np.ndarray, layout, top: int = 6) -> List[tuple]:
    """Where the generated motion differs most from the clip: the features whose window mean or
    window spread differ most between the two, in units of their spread over all references.
    -> [(feature name, 'mean' or 'spread', clip value minus motion value in those units)]."""
    names = [c.joint + " " + re.sub(r" \(.*\)|, clip frame t", "", c.quantity) for c in layout.describe("clip")]
    diff = (clip.mean(axis=0) - motion.mean(axis=0)) / judge.space.std
    order = np.argsort(-np.abs(diff))[:top]
    C = len(names)
    return [(names[i % C], "mean" if i < C else "spread", float(diff[i])) for i in order]
