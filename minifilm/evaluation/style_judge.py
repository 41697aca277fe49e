"""Is a taught style's motion recognised as that style among all the others? Two measures that
must agree (minifilm/evaluation/style_measures.py says why one is not enough):

* the **Fréchet rank**: the squared Fréchet distance from the generated motion's windows to every
  style's reference windows (:class:`~minifilm.evaluation.style_measures.StyleSpace`), and the
  target's place among them (1 = nearest);
* the **classifier's recognition**: the share of the motion's windows that a style classifier
  (:class:`~minifilm.evaluation.style_classifier.StyleClassifier`) trained on the same reference
  windows gives the target, for several classifier seeds; the minimum over seeds is what counts.

A reference is whatever stands for a style: for the released network's styles their own
generated motion, for a style taught from a clip the clip itself. Every motion is read the same
way (:func:`motion_block`): each frame's clip features (every joint's position, forward, up and
velocity relative to that frame's root, docs/features.md) on the 100STYLE skeleton, normalised
with the network's input statistics, cut into windows of 0.75 s every 0.25 s at 60 fps (as the
project's classifier is trained).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Dict, List, Mapping, Sequence

import numpy as np

from minifilm.evaluation.style_classifier import StyleClassifier, cut_windows, window_summary
from minifilm.evaluation.style_measures import StyleSpace, classifier_spread
from minifilm.features.compute import joint_features, motion_arrays
from minifilm.motion.skeletons import STYLE100

WINDOW = 45          # frames: 0.75 s at 60 fps
STRIDE = 15          # frames: 0.25 s


def motion_block(motion, stats, layout, skeleton=STYLE100) -> np.ndarray:
    """A Motion on ``skeleton`` -> its per-frame clip features (F, 12 J), normalised with the
    statistics of x's joint block (the same numbers as the joint block of its x rows)."""
    positions, rotations, vel, root_pos, root_rot = motion_arrays(motion, skeleton)
    raw = joint_features(positions, rotations, vel, root_pos, root_rot)
    return stats.normalize_clip(np.asarray(raw, np.float64), layout.x_joints)


def rows_block(x: np.ndarray, stats, layout) -> np.ndarray:
    """Raw x rows (N, x_dim) -> their normalised joint block (N, 12 J): for a clip whose rows were
    changed on the way in (a retargeted clip's joint axes turned to the network's convention)."""
    return stats.normalize_clip(np.asarray(x, np.float64)[:, layout.x_joints], layout.x_joints)


def windows(block: np.ndarray, window: int = WINDOW, stride: int = STRIDE) -> np.ndarray:
    """(F, C) consecutive frames -> (M, window, C)."""
    return cut_windows(np.asarray(block, np.float64), window, stride)


def summaries(block: np.ndarray, window: int = WINDOW, stride: int = STRIDE) -> np.ndarray:
    """(F, C) consecutive frames -> (M, 2C) window summaries (mean and spread over each window):
    what both measures read, far smaller than the windows themselves."""
    return window_summary(windows(block, window, stride))


@dataclass
class StyleJudge:
    """The Fréchet space and ``len(seeds)`` classifiers, all fitted on the same reference windows."""

    names: List[str]
    space: StyleSpace
    classifiers: List[StyleClassifier]

    @classmethod
    def fit(cls, references: Mapping[str, np.ndarray], seeds: Sequence[int] = (0, 1, 2), hidden: int = 64,
            epochs: int = 60, dims: int = 32) -> "StyleJudge":
        """references: style name -> (M, 2C) window summaries (:func:`summaries`, M >= 2). One
        classifier per seed."""
        names = list(references)
        if len(seeds) < 1:
            raise ValueError("StyleJudge.fit: at least one classifier seed")
        refs = {n: np.asarray(references[n], np.float64) for n in names}
        space = StyleSpace.fit(refs, dims=dims, summarised=True)
        X = np.concatenate([refs[n] for n in names])
        y = np.concatenate([np.full(len(refs[n]), i) for i, n in enumerate(names)])
        classifiers = []
        for seed in seeds:
            clf = StyleClassifier(X.shape[1], len(names), hidden, np.random.default_rng(seed))
            clf.fit(X, y, epochs=epochs, rng=np.random.default_rng(seed + 1000))
            classifiers.append(clf)
        return cls(names, space, classifiers)

    def judge(self, motion_summaries: np.ndarray, target: str, top: int = 3) -> dict:
        """Everything measured for one motion meant to be ``target``: (M >= 2, 2C) summaries ->
        {rank, distance, nearest [(name, distance)] the ``top`` nearest, recognition per seed,
        recognition_min / _mean, picked: the classes the classifiers give most often
        [(name, share of windows)] over all seeds}."""
        if target not in self.names:
            raise KeyError(f"StyleJudge.judge: no style {target!r}")
        s = np.asarray(motion_summaries, np.float64)
        d = self.space.distances(s, summarised=True)
        rank = 1 + sum(v <= d[target] for n, v in d.items() if n != target)
        order = sorted(d, key=d.get)[:top]
        i = self.names.index(target)
        preds = [clf.predict(s) for clf in self.classifiers]
        rec = [float(np.mean(p == i)) for p in preds]
        counts = Counter(int(c) for p in preds for c in p)
        total = sum(counts.values())
        picked = [(self.names[c], k / total) for c, k in counts.most_common(top)]
        spread = classifier_spread(rec)
        return dict(target=target, rank=int(rank), distance=float(d[target]),
                    nearest=[(n, float(d[n])) for n in order], recognition=rec,
                    recognition_min=spread["min"], recognition_mean=spread["mean"], picked=picked)


def judge_many(judge: StyleJudge, motions: Dict[str, np.ndarray]) -> Dict[str, dict]:
    """``judge.judge`` for every target name -> summaries of its motion."""
    return {name: judge.judge(w, name) for name, w in motions.items()}
