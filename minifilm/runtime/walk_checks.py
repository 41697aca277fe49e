"""Does a rollout walk? Plain checks of generated locomotion, said in words.

A style taught from a clip far from the network's data can fit its loss and still not walk: the
character stands, slides, floats above the floor or sinks into it, or leaves the path. These
checks read a :class:`~minifilm.runtime.rollout.Rollout` (after its first second, which starts
from the data's mean pose) and compare, where given, with the clip the style was taught from:

    steps_per_s   foot strikes (a predicted contact starting) per second, both feet
    toe_on_floor  share of frames whose lower toe is within ±3 cm of the floor (height 0)
    hips          median hip height, m
    path_mean     mean distance of the root from the commanded path, m
"""
from __future__ import annotations

from dataclasses import dataclass, asdict
from typing import Collection, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np

from minifilm.runtime.control import distance_to_path

FLOOR_TOLERANCE = 0.03        # m, the lowest toe's band around the floor
MIN_STEPS_PER_S = 0.5         # fewer strikes than this while asked to move: not walking
STEP_RATIO = (0.75, 1.25)     # steps/s against the clip's: within 25 %
PATH_LIMIT = 1.0              # m, mean distance from the path
FLOOR_SHARE = 0.9             # share of frames with the lowest toe on the floor
HIPS_SHARE = 0.1              # hips within 10 % of the clip's
#: how much worse than a reference walk's (in the measure of severity_by_kind) a fault may get
#: before a walk counts as worse than it (adds_faults): a step rate 0.1 steps/s further out, 5 %
#: more of the frames with the feet off the floor, hips 2 cm further off, the path 25 cm further
WORSE_BY = {"steps": 0.1, "floor": 0.05, "hips": 0.02, "path": 0.25}


def count_strikes(contacts: np.ndarray) -> int:
    """Foot strikes (a contact starting) over both feet: contacts (F, 2) in [0, 1]."""
    c = np.asarray(contacts) > 0.5
    return int(np.sum(c[1:] & ~c[:-1]))


def lowest_toe(positions: np.ndarray, toes: Sequence[int]) -> np.ndarray:
    """(F, J, 3) positions -> (F,) height of the lower of the two toe joints."""
    return np.min(np.asarray(positions)[:, list(toes), 1], axis=1)


@dataclass
class WalkReport:
    steps_per_s: float
    toe_on_floor: float
    hips: float
    path_mean: float
    clip_steps_per_s: Optional[float] = None
    clip_hips: Optional[float] = None

    def problems_by_kind(self) -> Dict[str, str]:
        """What is wrong, in words, by kind ('steps', 'floor', 'hips', 'path'; {} when it walks): two
        walks compared by kind (does one add a problem the other has not?) whatever their numbers."""
        out = {}
        if self.steps_per_s < MIN_STEPS_PER_S:
            out["steps"] = f"it hardly steps ({self.steps_per_s:.2f} steps/s)"
        elif self.clip_steps_per_s and not (STEP_RATIO[0] <= self.steps_per_s / self.clip_steps_per_s <= STEP_RATIO[1]):
            out["steps"] = f"it steps {self.steps_per_s:.2f}/s, the clip {self.clip_steps_per_s:.2f}/s"
        if self.toe_on_floor < FLOOR_SHARE:
            out["floor"] = (f"the feet leave the floor (lowest toe within {FLOOR_TOLERANCE * 100:.0f} cm of it in only "
                            f"{self.toe_on_floor:.0%} of frames)")
        if self.clip_hips and abs(self.hips / self.clip_hips - 1) > HIPS_SHARE:
            out["hips"] = f"hips at {self.hips:.2f} m, the clip's at {self.clip_hips:.2f} m"
        if self.path_mean > PATH_LIMIT:
            out["path"] = f"it leaves the path ({self.path_mean:.2f} m from it on average)"
        return out

    def severity_by_kind(self) -> Dict[str, float]:
        """How far past its limit each fault of :meth:`problems_by_kind` is, in its own measure:
        steps per second outside the clip's band (or below MIN_STEPS_PER_S), the share of frames
        short of FLOOR_SHARE, metres of hips beyond HIPS_SHARE of the clip's, metres of path beyond
        PATH_LIMIT. Two walks with the same kind of fault can so be told apart by how bad it is."""
        out = {}
        for kind in self.problems_by_kind():
            if kind == "steps":
                c, s = self.clip_steps_per_s, self.steps_per_s
                out[kind] = max(MIN_STEPS_PER_S - s, (STEP_RATIO[0] * c - s) if c else 0.0,
                                (s - STEP_RATIO[1] * c) if c else 0.0)
            elif kind == "floor":
                out[kind] = FLOOR_SHARE - self.toe_on_floor
            elif kind == "hips":
                out[kind] = abs(self.hips - self.clip_hips) - HIPS_SHARE * self.clip_hips
            else:
                out[kind] = self.path_mean - PATH_LIMIT
        return {k: float(v) for k, v in out.items()}

    def problems(self) -> List[str]:
        """What is wrong, in words ([] when it walks)."""
        return list(self.problems_by_kind().values())

    def words(self) -> str:
        p = self.problems()
        return "it walks (steps, feet on the floor, path kept)" if not p else "WARNING: " + "; ".join(p)

    def to_dict(self) -> dict:
        return {k: (None if v is None else float(v)) for k, v in asdict(self).items()}


def walk_report(rollout, character: int, toes: Sequence[int], path: Optional[np.ndarray] = None,
                warmup_seconds: float = 1.0, clip_steps_per_s: Optional[float] = None,
                clip_hips: Optional[float] = None) -> WalkReport:
    """The checks of one character of ``rollout`` (toes: exported joint indices of the two toes)."""
    k0 = min(int(round(warmup_seconds * rollout.fps)), rollout.positions.shape[1] - 2)
    P = rollout.positions[character, k0:]
    seconds = len(P) / rollout.fps
    steps = count_strikes(rollout.contacts[character, k0:]) / seconds
    toe = lowest_toe(P, toes)
    on_floor = float(np.mean(np.abs(toe) <= FLOOR_TOLERANCE))
    d = float(distance_to_path(rollout.root_positions[character, k0:], path).mean()) if path is not None else 0.0
    return WalkReport(float(steps), on_floor, float(np.median(P[:, 0, 1])), d, clip_steps_per_s, clip_hips)


Faults = Union[Mapping[str, float], Collection[str]]


def adds_faults(faults: Faults, reference: Faults) -> bool:
    """Is a walk with ``faults`` worse than one with ``reference``: a kind of fault the reference
    has not, or one it has, worse by more than WORSE_BY? Each is a mapping kind -> severity
    (:meth:`WalkReport.severity_by_kind`) or a collection of kinds (each of severity 0)."""
    f = faults if isinstance(faults, Mapping) else dict.fromkeys(faults, 0.0)
    r = reference if isinstance(reference, Mapping) else dict.fromkeys(reference, 0.0)
    return any(k not in r or v > r[k] + WORSE_BY.get(k, 0.0) for k, v in f.items())
