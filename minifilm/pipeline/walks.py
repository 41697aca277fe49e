"""The released network walking: straight-ahead rollouts of many FiLM vectors in one batch, and
the window summaries by which motion is compared (minifilm/evaluation/style_judge.py) -- of those
walks and of a clip. Shared by teaching (teach_released.py, motion_refit.py) and judging
(judge_taught.py)."""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Dict, List

import numpy as np

from minifilm.evaluation.style_judge import WINDOW, motion_block, rows_block, summaries
from minifilm.features.layout import FeatureLayout
from minifilm.runtime.control import CommandScript
from minifilm.runtime.controller import Controller
from minifilm.runtime.start_state import root_joint_indices
from minifilm.runtime.walk_checks import walk_report
from minifilm.synthetic.generator import rest_motion

FPS = 60.0
CHECK_SECONDS = 6.0               # rollout of each candidate vector
POSITION_BIAS = 0.75              # the controller's blend of the user's path (the original demo's)


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
    'path': runtime/walk_checks.py), judged against the clip. Plain numbers only, so a worker process
    can be told it as JSON (:meth:`to_dict`, ``FaultCheck(**d)``).

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

    def to_dict(self) -> dict:
        return asdict(self)
