"""Humanoid parts from the hierarchy and the pose alone, names unused (the rules are in
minifilm/motion/humanoid.py's docstring)."""
from __future__ import annotations

from typing import List, Tuple

import numpy as np

from minifilm.motion.humanoid_parts import Humanoid, HumanoidError
from minifilm.motion.humanoid_tree import (PosedTree, arm_from_chain, assemble, farthest_leaf, leg_from_chain,
                                           lowest_leaf)

__all__ = ["humanoid_by_structure"]


def humanoid_by_structure(motion) -> Humanoid:
    """The humanoid parts from the hierarchy and the first frame's pose alone (names unused).

    HumanoidError naming the first part that could not be found."""
    tree = PosedTree(motion)
    H = tree.height
    # hips: walking down from the root, the first joint with two branches reaching down and one up
    j, hips = int(np.nonzero(tree.parents < 0)[0][0]), None
    seen = 0
    while hips is None and seen < len(tree.names):
        seen += 1
        kids = tree.real_children(j)
        if not kids:
            break
        lows = [min(tree.P[k, 1] for k in tree.subtree(c)) for c in kids]
        highs = [max(tree.P[k, 1] for k in tree.subtree(c)) for c in kids]
        down = [c for c, lo in zip(kids, lows) if lo < tree.P[j, 1] - 0.25 * H]
        up = [c for c, hi in zip(kids, highs) if hi > tree.P[j, 1] + 0.2 * H]
        if len(down) >= 2 and up:
            hips = j
            break
        j = max(kids, key=lambda c: len(tree.subtree(c)))
    if hips is None:
        raise HumanoidError("by structure: no joint has two chains going down (legs) and one going up "
                            "(the spine), so no hips were found")
    kids = tree.real_children(hips)
    leg_tops = sorted(kids, key=lambda c: min(tree.P[k, 1] for k in tree.subtree(c)))[:2]
    torso = max((c for c in kids if c not in leg_tops), key=lambda c: max(tree.P[k, 1] for k in tree.subtree(c)))

    # the spine: up from the hips while the chain does not branch into long side chains
    leg_len = np.mean([tree.P[hips, 1] - min(tree.P[k, 1] for k in tree.subtree(c)) for c in leg_tops])
    path = [torso]
    side_chains: List[Tuple[int, int]] = []          # (branch joint, first joint of the side chain)
    while True:
        j = path[-1]
        kids = tree.children[j]
        if not kids:
            break
        reach = {c: _reach(tree, j, c) for c in kids}
        nxt = max(kids, key=lambda c: (tree.P[_highest(tree, c), 1], reach[c]))
        for c in kids:
            if c != nxt and reach[c] > 0.35 * leg_len:
                side_chains.append((j, c))
        if len(side_chains) >= 2:
            break
        path.append(nxt)
    if len(side_chains) < 2:
        raise HumanoidError(f"by structure: found {len(side_chains)} arm(s) branching off the spine above the "
                            f"hips {tree.names[hips]!r}; a humanoid has two")
    side_chains = sorted(side_chains, key=lambda bc: -_reach(tree, bc[0], bc[1]))[:2]
    chest = path[-1]
    # neck and head: up from the chest until the chain ends or branches (eyes, jaw)
    up_kids = [c for c in tree.children[chest] if c not in [c2 for _, c2 in side_chains]]
    if not up_kids:
        raise HumanoidError(f"by structure: nothing continues up from the chest {tree.names[chest]!r}: no head")
    head_path = [max(up_kids, key=lambda c: tree.P[_highest(tree, c), 1])]
    while len(tree.children[head_path[-1]]) == 1:
        head_path.append(tree.children[head_path[-1]][0])
    if not tree.children[head_path[-1]] and tree.site[head_path[-1]] and len(head_path) > 1:
        head_path.pop()                              # the head's End Site is its top, not the head
    head = head_path[-1]
    neck = head_path[0] if len(head_path) > 1 else None

    # arms and legs, then left and right from the facing
    arms = [arm_from_chain(tree, tree.path(b, farthest_leaf(tree, b, c)), "an") for b, c in side_chains]
    legs = [leg_from_chain(tree, tree.path(hips, lowest_leaf(tree, c)), "a") for c in leg_tops]
    if _first_leg_is_left(tree, legs) is False:
        legs = legs[::-1]
    # the arm on the left leg's side is the left arm (side = direction from the right hip to the left)
    side = tree.P_all[:, legs[0]["hip"]] - tree.P_all[:, legs[1]["hip"]]            # (F, 3)
    arm_side = tree.P_all[:, arms[0]["shoulder"]] - tree.P_all[:, arms[1]["shoulder"]]
    if np.sum(np.einsum("fi,fi->f", side, arm_side) > 0) < side.shape[0] / 2:
        arms = arms[::-1]
    limbs = {"left": {**arms[0], **legs[0]}, "right": {**arms[1], **legs[1]}}
    return assemble(tree, "structure", hips, neck, head, limbs)


def _first_leg_is_left(tree: PosedTree, legs) -> bool:
    """Whether ``legs[0]`` is the left leg. Forward is where the toes point and where bent knees
    bulge (knees bend forward; a running foot kicked back points backwards for a while, its knee
    still forward); left is ``up x forward``. Summed over the clip, so the clear frames outweigh
    the ambiguous ones. HumanoidError when neither toes nor knees point anywhere."""
    P = tree.P_all * np.array([1.0, 0.0, 1.0])                                        # on the floor
    forward = sum(P[:, lg["toe_tip"]] - P[:, lg["ankle"]]
                  + 2.0 * (P[:, lg["knee"]] - 0.5 * (P[:, lg["hip"]] + P[:, lg["ankle"]])) for lg in legs)
    side = P[:, legs[0]["hip"]] - P[:, legs[1]["hip"]]                                # (F, 3)
    vote = float(np.einsum("fi,fi->", np.cross([0.0, 1.0, 0.0], forward), side))
    if abs(vote) <= 1e-9 * tree.size ** 2 * len(P):
        raise HumanoidError("by structure: the feet do not point anywhere (no toe in front of the ankles, "
                            "no bent knee), so left and right are unknown")
    return vote > 0


def _reach(tree: PosedTree, top: int, c: int) -> float:
    """Length along the bones from ``top`` to the farthest leaf below ``c``."""
    leaf = farthest_leaf(tree, top, c)
    return sum(tree.length(k) for k in tree.path(top, leaf))


def _highest(tree: PosedTree, c: int) -> int:
    return max(tree.subtree(c), key=lambda k: tree.P[k, 1])
