"""A skeleton's hierarchy with its pose, and reading arms and legs off its chains (for
minifilm.body.humanoid: the name and structure finders share these)."""
from __future__ import annotations

from typing import Dict, List, Optional

import numpy as np

from minifilm.body.parts import ARM_ROLES, LEG_ROLES, Humanoid, HumanoidError

__all__ = ["PosedTree", "leg_from_chain", "arm_from_chain", "farthest_leaf", "assemble"]


class PosedTree:
    """The hierarchy of a motion with its first frame's joint positions (file units, y up)."""

    def __init__(self, motion):
        self.names = tuple(motion.names)
        self.parents = np.asarray(motion.parents, dtype=np.int64)
        self.source = getattr(motion, "source", "<memory>")
        if motion.n_frames == 0:
            raise HumanoidError(f"{self.source}: the motion has no frames, so its pose cannot be read")
        P, _ = motion.world()
        self.P_all = np.asarray(P, dtype=np.float64)                        # (F, J, 3)
        self.P = self.P_all[0]                                              # (J, 3) first frame
        if not np.isfinite(self.P_all).all():
            raise HumanoidError(f"{self.source}: the joint positions are not finite")
        self.site = [len(c) == 0 for c in motion.channels]
        J = len(self.names)
        self.children: List[List[int]] = [[] for _ in range(J)]
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[int(p)].append(j)
        extent = np.ptp(self.P, axis=0)
        self.size = max(float(extent.max()), 1e-9)                          # for "same place" tests
        self.height = max(float(extent[1]), 1e-9)

    def is_ancestor(self, a: int, b: int) -> bool:
        """True when ``a`` is a strict ancestor of ``b``."""
        p = int(self.parents[b])
        while p >= 0:
            if p == a:
                return True
            p = int(self.parents[p])
        return False

    def common_ancestor(self, a: int, b: int) -> int:
        """The deepest joint that is ``a`` or an ancestor of it and ``b`` or an ancestor of it."""
        above_a = {a}
        while self.parents[a] >= 0:
            a = int(self.parents[a])
            above_a.add(a)
        while b not in above_a:
            b = int(self.parents[b])
        return b

    def path(self, top: int, bottom: int) -> List[int]:
        """Joints from ``top`` (exclusive) down to ``bottom`` (inclusive); ``top`` must be an ancestor."""
        out = [bottom]
        while int(self.parents[out[-1]]) != top:
            out.append(int(self.parents[out[-1]]))
            if out[-1] < 0:
                raise ValueError(f"{self.names[top]} is not an ancestor of {self.names[bottom]}")
        return out[::-1]

    def subtree(self, j: int) -> List[int]:
        out, stack = [], [j]
        while stack:
            k = stack.pop()
            out.append(k)
            stack.extend(self.children[k])
        return out

    def length(self, j: int) -> float:
        """Length of the bone from ``j``'s parent to ``j`` (0 for the root)."""
        p = int(self.parents[j])
        return 0.0 if p < 0 else float(np.linalg.norm(self.P[j] - self.P[p]))

    def real_children(self, j: int) -> List[int]:
        """Children of ``j``, looking through joints that sit on ``j`` (zero-length helpers) to theirs."""
        out = []
        for c in self.children[j]:
            if self.length(c) <= 1e-6 * self.size and self.children[c]:
                out.extend(self.real_children(c))
            else:
                out.append(c)
        return out


def leg_from_chain(tree: PosedTree, chain: List[int], what: str) -> Dict[str, int]:
    """Leg roles from the joints below the hips down to the foot's end (``chain``, top to bottom).

    The thigh and shin are the two consecutive bones of largest summed length; the foot is what
    lies below the ankle (no joint below it: a rig without feet)."""
    lengths = [tree.length(j) for j in chain]            # bone ending at chain[i]
    if len(chain) < 3:
        raise HumanoidError(f"{what} has {len(chain)} joints below the hips "
                            f"({[tree.names[j] for j in chain]}); a leg needs a hip, knee and ankle")
    best = max(range(1, len(chain) - 1), key=lambda i: lengths[i] + lengths[i + 1])
    hip, knee, ankle = chain[best - 1], chain[best], chain[best + 1]
    below = chain[best + 2:]
    if not below:
        raise HumanoidError(f"{what} ends at its ankle {tree.names[ankle]!r}: no foot (no joint "
                            "below the ankle), so foot contacts cannot be found")
    toe = next((j for j in below if tree.length(j) > 1e-6 * tree.size), below[0])
    return dict(hip=hip, knee=knee, ankle=ankle, toe=toe, toe_tip=chain[-1])


def arm_from_chain(tree: PosedTree, chain: List[int], what: str) -> Dict[str, Optional[int]]:
    """Arm roles from the joints below the spine out to the hand's end (``chain``, top to bottom).

    The wrist is the first joint that branches (into fingers) or whose only child is the chain's
    end; else the two longest consecutive bones are the upper arm and forearm."""
    wrist_at = None
    for i, j in enumerate(chain[:-1]):
        if i >= 2 and (len(tree.real_children(j)) >= 2 or chain[i + 1] == chain[-1]):
            wrist_at = i
            break
    if wrist_at is None:
        if len(chain) < 3:
            raise HumanoidError(f"{what} has {len(chain)} joints ({[tree.names[j] for j in chain]}); "
                                "an arm needs a shoulder, elbow and wrist")
        lengths = [tree.length(j) for j in chain]
        best = max(range(1, len(chain) - 1), key=lambda i: lengths[i] + lengths[i + 1])
        wrist_at = best + 1
    shoulder_at = wrist_at - 2
    # joints sitting on the upper arm's joint are not a collar; the collar is the joint above it
    collar = chain[shoulder_at - 1] if shoulder_at >= 1 else None
    return dict(collar=collar, shoulder=chain[shoulder_at], elbow=chain[wrist_at - 1], wrist=chain[wrist_at])


def farthest_leaf(tree: PosedTree, top: int, j: int) -> int:
    """The leaf of ``j``'s subtree farthest (along its bones) from ``top``: a hand's longest finger."""
    best, best_d = j, -1.0
    stack = [(j, tree.length(j))]
    while stack:
        k, d = stack.pop()
        if not tree.children[k] and d > best_d:
            best, best_d = k, d
        stack.extend((c, d + tree.length(c)) for c in tree.children[k])
    return best


def assemble(tree: PosedTree, method: str, hips: int, neck: Optional[int], head: int,
           limbs: Dict[str, Dict[str, Optional[int]]]) -> Humanoid:
    """Assemble the Humanoid and check it is plausible (raises HumanoidError otherwise).

    The torso is read off the hierarchy, whatever the names said: the chest is the joint where
    the two arms and the head's chain part (their nearest common ancestor), the spine runs from
    the hips to it, and the neck is the first joint above it towards the head. So a neck of any
    name (``NeckBase``, ``C7``), spine joints above the arms (collars off ``Chest2`` while
    ``Chest3``, ``Chest4`` lead to the head) and collars off the neck chain all come out right;
    ``neck`` (the names' or the structure's guess) only serves when it agrees."""
    if not tree.is_ancestor(hips, head):
        raise HumanoidError(f"by {method}: the head {tree.names[head]!r} is not below the hips {tree.names[hips]!r}")
    arm_tops = []
    for side in ("left", "right"):
        shoulder = limbs[side]["shoulder"]
        if not tree.is_ancestor(hips, shoulder):
            raise HumanoidError(f"by {method}: the {side} arm {tree.names[shoulder]!r} is not below the hips "
                                f"{tree.names[hips]!r}")
        arm_tops.append(shoulder)
    chest = tree.common_ancestor(tree.common_ancestor(arm_tops[0], arm_tops[1]), head)
    if chest != hips and not tree.is_ancestor(hips, chest):
        raise HumanoidError(f"by {method}: the arms and the head {tree.names[head]!r} meet at "
                            f"{tree.names[chest]!r}, which is not above the hips {tree.names[hips]!r}")
    if chest in arm_tops or chest == head:
        raise HumanoidError(f"by {method}: the arms {[tree.names[j] for j in arm_tops]} and the head "
                            f"{tree.names[head]!r} do not branch off a spine (one hangs below another)")
    chest_path = tree.path(hips, chest) if chest != hips else []
    neck_path = tree.path(chest, head)
    neck = neck_path[0] if len(neck_path) > 1 else None
    limbs = {side: dict(limbs[side], collar=_collar(tree, chest, limbs[side]["collar"], limbs[side]["shoulder"]))
             for side in ("left", "right")}
    root = hips
    while tree.parents[root] >= 0:
        root = int(tree.parents[root])
    kw = {}
    for side in ("left", "right"):
        for role in ARM_ROLES + LEG_ROLES:
            kw[f"{side}_{role}"] = limbs[side][role]
    sites = [c for c in tree.children[head] if tree.site[c] and not tree.children[c]]
    head_top = max(sites, key=tree.length) if sites else None
    h = Humanoid(names=tree.names, method=method, root=root, hips=hips, spine=tuple(chest_path),
                 neck=neck, head=head, head_top=head_top, **kw)
    _check_plausible(tree, h)
    return h


def _collar(tree: PosedTree, chest: int, collar: Optional[int], shoulder: int) -> Optional[int]:
    """The collar between the chest and the upper arm: ``collar`` when it lies there, else the
    joint right above the shoulder when that is below the chest, else None (the arm hangs off the
    chest directly)."""
    if collar is not None and tree.is_ancestor(chest, collar) and tree.is_ancestor(collar, shoulder):
        return collar
    above = int(tree.parents[shoulder])
    return above if above != chest and tree.is_ancestor(chest, above) else None


def _check_plausible(tree: PosedTree, h: Humanoid) -> None:
    """A human stands on two feet below the hips, with its head above them and hands off the floor."""
    P = tree.P
    leg = max(np.linalg.norm(P[h.left_knee] - P[h.left_hip]) + np.linalg.norm(P[h.left_ankle] - P[h.left_knee]),
              1e-9)
    Y = tree.P_all[..., 1]                                   # (F, J): heights, judged over the clip

    def above(a: int, b: int) -> float:                      # median height of a above b
        return float(np.median(Y[:, a] - Y[:, b]))

    floor = Y[:, [h.left_toe_tip, h.right_toe_tip, h.left_ankle, h.right_ankle]].min(axis=1)
    problems = []
    if above(h.head, h.hips) < 0.3 * leg:
        problems.append(f"the head {tree.names[h.head]!r} is not above the hips {tree.names[h.hips]!r}")
    for side in ("left", "right"):
        wrist = getattr(h, f"{side}_wrist")
        if np.median(Y[:, wrist] - floor) < 0.15 * leg:
            problems.append(f"the {side} hand {tree.names[wrist]!r} is on the floor like a foot "
                            "(four legs: not a humanoid?)")
        ankle = getattr(h, f"{side}_ankle")
        if above(h.hips, ankle) < 0.4 * leg:
            problems.append(f"the {side} ankle {tree.names[ankle]!r} is not below the hips")
    if problems:
        raise HumanoidError(f"by {h.method}: " + "; ".join(problems))
