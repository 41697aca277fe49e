"""The released network walking: straight-ahead rollouts of many FiLM vectors in one batch, and
the window summaries by which motion is compared (minifilm/evaluation/style_judge.py) -- of those
walks and of a clip. Shared by teaching (teach_released.py, motion_refit.py) and judging
(judge_taught.py).

:func:`walk` splits many vectors into shares walked by worker processes (minifilm/parallel.py).
The answer is that of one process to float32 round-off: a character of a batch rollout depends
only on its own vector (the batch is the rows of the same matrix products), so a vector walks the
same in any share but for the order of float sums (a share of 2-4 vectors takes the network's
vector-product path, runtime/network.py).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable, Dict, List, Mapping, Optional, Tuple

import numpy as np

from minifilm.evaluation.style_judge import WINDOW, motion_block, rows_block, summaries
from minifilm.features.layout import FeatureLayout
from minifilm.parallel import map_in_order
from minifilm.runtime.control import CommandScript
from minifilm.runtime.controller import Controller
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.walk_checks import walk_report
from minifilm.synthetic.generator import rest_motion

FPS = 60.0
CHECK_SECONDS = 6.0               # rollout of each candidate vector
POSITION_BIAS = 0.75              # the controller's blend of the user's path (the original demo's)
#: worker processes at most for a refinement's walks (and a taught style's fits): a round's 18
#: walks in shares of 4-5; smaller shares save little (a step costs about as much for 1 walk as for 9)
WALK_WORKERS = 4


def candidate_rollouts(network, layout: FeatureLayout, films: np.ndarray, speed: float, seconds: float = CHECK_SECONDS,
                       position_bias: float = POSITION_BIAS):
    """All candidate vectors walked straight ahead at the clip's speed, one batch; -> (rollout, path).
    position_bias: the controller's (a trained run's own; the released network's is the default)."""
    skeleton = rest_motion()
    ctrl = Controller(network, layout, fps=FPS, skeleton=Controller.skeleton_for(layout, skeleton), feed_back_fit=True,
                      position_bias=position_bias)
    v = float(np.clip(speed, 0.3, 4.0))
    script = CommandScript([(0.0, v, 0.0, 0.0), (seconds, v, 0.0, 0.0)])
    r = ctrl.run([script] * len(films), int(round(seconds * FPS)), films)
    return r, straight_path(speed, seconds)


def straight_path(speed: float, seconds: float) -> np.ndarray:
    """The path (2, 2) a walk of :func:`candidate_rollouts` is commanded along: straight ahead from
    the origin, twice as long as it walks (so its end is never reached)."""
    v = float(np.clip(speed, 0.3, 4.0))
    return np.array([[0.0, 0.0], [0.0, v * seconds * 2]])


def walk_blocks(network, layout, stats, films: np.ndarray, speed: float, seconds: float,
                position_bias: float = POSITION_BIAS):
    """Every vector walked straight ahead at ``speed`` for ``seconds`` after a first second cut
    (the start from the mean pose): -> (list of (F, 12 J) normalised clip-feature blocks, rollout)."""
    r, _ = candidate_rollouts(network, layout, np.asarray(films, np.float32), speed, seconds + 1, position_bias)
    skeleton = rest_motion()
    joints = root_joint_indices(layout, skeleton)
    n = r.positions.shape[1]
    blocks = [motion_block(r.to_motion(skeleton, joints, character=b).slice(int(FPS), n), stats, layout)
              for b in range(len(films))]
    return blocks, r


def clip_summaries(clip, stats, layout) -> np.ndarray:
    """The clip's own windows (the rows the fit saw, joint axes as taught), file by file so no
    window spans two files."""
    files, a = [], 0
    for src in clip.sources:
        b = a + max(0, int(src["frames"]) - 2)              # frame_features: frames 1 .. F-2
        files.append(clip.x[a:b])
        a = b
    return rows_summaries(files, stats, layout)


def rows_summaries(files, stats, layout) -> np.ndarray:
    """Window summaries (M, 2C) of raw input rows, one (F_i, x_dim) array per file, each cut into
    windows of its own (a file too short for one window gives none)."""
    parts = [summaries(block) for block in (rows_block(x, stats, layout) for x in files) if len(block) >= WINDOW]
    return np.concatenate(parts) if parts else np.zeros((0, 0))


@dataclass
class FaultCheck:
    """What ``finetune`` would warn about in one character's walk, by kind ('steps', 'floor', 'hips',
    'path': runtime/walk_checks.py), judged against the clip: plain numbers, so a worker process can
    be sent it (the check of :func:`walk` in shares).

    toes: exported joint indices of the two toes; path: (2, 2) the straight path walked
    (:func:`straight_path`); the clip's steps per second and hip height."""
    toes: List[int]
    path: List[List[float]]
    clip_steps_per_s: float
    clip_hips: float

    def __post_init__(self):        # plain Python numbers, whatever they were given as
        self.toes = [int(t) for t in self.toes]
        self.path = np.asarray(self.path, float).reshape(2, 2).tolist()
        self.clip_steps_per_s, self.clip_hips = float(self.clip_steps_per_s), float(self.clip_hips)

    def __call__(self, rollout, character: int) -> Dict[str, float]:
        """The walk's faults: kind -> how far past its limit (WalkReport.severity_by_kind)."""
        return walk_report(rollout, character, self.toes, np.asarray(self.path, float),
                           clip_steps_per_s=self.clip_steps_per_s, clip_hips=self.clip_hips).severity_by_kind()


#: each vector's window summaries (M, 2C), and what is wrong with each walk (kind -> how bad)
Walks = Tuple[List[np.ndarray], List[dict]]


def walk_here(network, layout, stats, films: np.ndarray, speed: float, seconds: float,
              check: Optional[Callable] = None, position_bias: float = POSITION_BIAS) -> Walks:
    """In this process: every vector's walk summaries, and the faults ``check`` finds (a mapping
    kind -> severity as FaultCheck gives, or a set of kinds from another check)."""
    films = np.asarray(films, np.float32)
    if not len(films):
        return [], []
    blocks, r = walk_blocks(network, layout, stats, films, speed, seconds, position_bias)
    return [summaries(b) for b in blocks], [_faults(check(r, b)) if check else {} for b in range(len(films))]


def _faults(found):
    return dict(found) if isinstance(found, Mapping) else set(found)


def walk(network, layout, stats, films: np.ndarray, speed: float, seconds: float, check: Optional[Callable] = None,
         position_bias: float = POSITION_BIAS, pool=None, shares: int = 1) -> Walks:
    """:func:`walk_here` of ``films`` in ``shares`` contiguous shares, mapped over ``pool`` (an
    executor of minifilm/parallel.py; None: all here, in one batch); the walks in the films' order.
    With a pool the check is sent to the workers: a :class:`FaultCheck`, not a lambda."""
    if pool is None:
        return walk_here(network, layout, stats, films, speed, seconds, check, position_bias)
    films = np.asarray(films, np.float32)
    bounds = np.linspace(0, len(films), max(1, shares) + 1).round().astype(int)
    parts = [films[a:b] for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    one = functools.partial(walk_here, network, layout, stats, speed=speed, seconds=seconds, check=check,
                            position_bias=position_bias)
    done = map_in_order(one, parts, pool, doing="walking", name=lambda f: f"{len(f)} vectors")
    return [w for walks, _ in done for w in walks], [f for _, faults in done for f in faults]
