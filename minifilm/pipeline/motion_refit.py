"""Refining a taught FiLM vector by the motion it makes, not by the next frame it predicts.

Teacher-forced, a fitted vector predicts the clip's next frame as well as the true style does, yet
walked on its own, frame after frame, its motion drifts to a neighbouring style: most of the 2,048
numbers barely change one prediction and the rows cannot pin them down, but in a rollout they add
up (reports on teaching the released network). So here the vector is moved to where the *motion*
it generates looks like the clip:

    objective(film) = d²(walk, clip) / min over s in N of d²(walk, walk of known style s)

    walk: the windows of the network's own walk in ``film``; N: the ``contrast`` known styles whose
    walks lie nearest the clip (10 by default; with none, the objective is d²(walk, clip) alone)

d² is the Fréchet distance between two sets of window summaries (mean and spread of every
joint's features over 0.75 s, minifilm/evaluation/style_judge.py) in a StyleSpace fitted on the
clip and the known styles' own walks. Below 1, the walk lies nearer the clip than any of those
styles' walks: it is the clip's style, not a neighbour's, that it is taken for. Measured only
against the clip, a search can end on a walk that is nearer the clip than the start's and still
nearer a neighbouring style than the clip (reports/2026-12-05_teaching_by_motion.md).

A rollout has no gradient here, so the search is derivative-free: the cross-entropy method over
the k leading principal directions of the known styles' vectors (the directions along which
styles differ), around the teacher-forced fit:

    film(c) = start + (c * scales) @ directions        c in R^k, scales: the styles' spread
    each round: draw ``population`` c ~ N(m, σ² I), walk them all in one batch, keep the best
    ``elite``, m <- their mean, σ <- σ * ``shrink``; the best vector seen is returned

A walk may look like the clip by its windows and still be worse than the start's walk (the feet
leaving the floor, say): with ``problems`` (a rollout and a character -> what is wrong with that
walk, kind -> how bad, runtime/walk_checks.py), a vector whose walk has a kind of fault the
start's has not, or one of the start's worse by more than walk_checks.WORSE_BY, is never chosen.

Cost: the known styles' walks once, then one batch rollout of population + 2 characters (the
centre and the best so far beside the new ones) per round, about 3.5 s each on one core: about
a minute in all with the defaults, in shares walked by worker processes (walks.walk). The motion
is deterministic, so a vector's score does not change between rounds.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Callable, Mapping, Optional

import numpy as np

from minifilm.evaluation.style_measures import StyleSpace, frechet_distance, gaussian
from minifilm.pipeline.walks import walk_here
from minifilm.runtime.walk_checks import Faults, adds_faults


@dataclass
class RefitSettings:
    """The search: k directions, rounds, candidates per round, the best kept, start spread σ (in
    units of the styles' own spread along each direction) and how it shrinks per round; seconds of
    walking per candidate (after the first second), the space's dimensions; ``contrast``: how many
    of the known styles nearest the clip the walk is measured against (module docstring; 0: the
    distance to the clip alone).

    Without contrast, six rounds of 32 (elite 8, shrink 0.85²: the same 192 candidates and
    spread) cost less, a round of 34 walks about as much as one of 18, and found 9 of 10 known
    styles again against 8; but four real clips ranked worse (benchmarks/README.md), so twelve
    of 16 stay."""
    directions: int = 16
    rounds: int = 12
    population: int = 16
    elite: int = 4
    sigma: float = 0.4
    shrink: float = 0.85
    seconds: float = 8.0
    dims: int = 32
    seed: int = 0
    contrast: int = 10


@dataclass
class Refit:
    """The refined vector, its objective, the start's objective, one line per round, and the
    distances of the refined and the start's walks to the clip's windows (the objective itself
    without ``contrast``)."""
    film: np.ndarray
    score: float
    start_score: float
    history: list = field(default_factory=list)
    distance: float = float("nan")
    start_distance: float = float("nan")


def style_directions(known: np.ndarray, k: int):
    """(k, D) orthonormal principal directions of the known styles' vectors (S, D) and the styles'
    standard deviation along each (k,)."""
    V = np.asarray(known, np.float64)
    _, s, Wt = np.linalg.svd(V - V.mean(axis=0), full_matrices=False)
    k = max(1, min(k, len(s)))
    return Wt[:k], s[:k] / np.sqrt(max(len(V) - 1, 1))


def refine_by_motion(network, layout, stats, start: np.ndarray, known: Mapping[str, np.ndarray],
                     clip_summaries: np.ndarray, speed: float, settings: RefitSettings = RefitSettings(),
                     known_summaries: Optional[Mapping[str, np.ndarray]] = None,
                     problems: Optional[Callable[[object, int], Faults]] = None,
                     walks: Optional[Callable] = None, log: Callable[[str], None] = lambda m: None) -> Refit:
    """Move ``start`` (D,) so that the network's walk in it looks like the clip (module docstring).

    known: the styles whose vectors give the search directions (name -> (D,)), and whose walks,
    with the clip's windows ``clip_summaries`` (M, 2C), give the space the distance is measured in
    (``known_summaries``: those walks' summaries if already made). speed: m/s of the walks.
    problems: (rollout, character) -> the faults of that walk (kind -> severity, or a set of kinds);
    a vector whose walk is worse than the start's (walk_checks.adds_faults) scores infinity.
    walks: (films, speed, seconds, check) -> their walks and faults (walks.walk with a pool of
    workers, which need ``problems`` to be a FaultCheck); default: walks.walk_here, this process."""
    s = settings
    names = list(known)
    V = np.stack([np.asarray(known[n], np.float64) for n in names])
    directions, scales = style_directions(V, s.directions)
    if walks is None:
        walks = functools.partial(walk_here, network, layout, stats)
    if known_summaries is None:
        known_summaries = dict(zip(names, walks(V, speed, s.seconds)[0]))
    clip_key = "\0clip"                 # beside the styles: no style name holds a NUL character
    space = StyleSpace.fit({**known_summaries, clip_key: clip_summaries}, dims=s.dims, summarised=True)
    target = space.gaussians[clip_key]
    # contrast k: the distance to the clip over that to the nearest of the k known styles nearest
    # the clip (below 1: the walk is nearer the clip than any of them)
    near = sorted(names, key=lambda n: frechet_distance(*space.gaussians[n], *target))[:s.contrast]
    rivals = [space.gaussians[n] for n in near]

    def objective(w):
        """-> (the objective, the distance to the clip) of one walk's window summaries."""
        g = gaussian(space.project(w, summarised=True))
        d = frechet_distance(*g, *target)
        return (d / max(min(frechet_distance(*g, *r) for r in rivals), 1e-9) if rivals else d), d

    allowed = None                      # the start's faults, once its walk is seen

    def scores(films):
        nonlocal allowed
        walked, faults = walks(films, speed, s.seconds, problems)
        allowed = faults[0] if allowed is None else allowed         # films[0] is the start in round 1
        got = np.array([objective(w) if len(w) >= 2 and not adds_faults(f, allowed) else (np.inf, np.inf)
                        for w, f in zip(walked, faults)])
        return got[:, 0], got[:, 1]

    def film_of(c):
        return np.asarray(start, np.float64) + (c * scales) @ directions

    rng = np.random.default_rng(s.seed)
    mean, sigma = np.zeros(len(scales)), s.sigma
    best_c, best, history = mean.copy(), None, []
    for r in range(s.rounds):
        cs = np.concatenate([mean[None], best_c[None], mean + sigma * rng.standard_normal((s.population, len(mean)))])
        got, distance = scores(np.stack([film_of(c) for c in cs]))
        if best is None:
            start_score, best, start_distance = float(got[0]), float(got[0]), float(distance[0])
            best_distance = start_distance
        order = np.argsort(got)
        if got[order[0]] < best:
            best, best_c, best_distance = float(got[order[0]]), cs[order[0]].copy(), float(distance[order[0]])
        kept = [i for i in order[:s.elite] if np.isfinite(got[i])]      # a refused walk never sets the centre
        mean = cs[kept].mean(axis=0) if kept else mean
        sigma *= s.shrink
        history.append(f"round {r + 1}: best {best:.1f} (start {start_score:.1f}), this round's best "
                       f"{got[order[0]]:.1f}, σ {sigma:.3f}")
        log(history[-1])
    return Refit(film_of(best_c).astype(np.float32), best, start_score, history, best_distance, start_distance)
