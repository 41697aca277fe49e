"""Humanoid parts from the hierarchy and the pose alone, names unused (the rules are in
minifilm/body/humanoid.py's docstring)."""
from __future__ import annotations

from typing import List, Tuple

import numpy as np

from minifilm.body.parts import Humanoid, HumanoidError
from minifilm.body.tree import PosedTree, arm_from_chain, assemble, farthest_leaf, leg_from_chain

__all__ = ["humanoid_by_structure"]


def humanoid_by_structure(motion) -> Humanoid:
    """The humanoid parts from the hierarchy and the first frame's pose alone (names unused).

    HumanoidError naming the first part that could not be found."""
    tree = PosedTree(motion)
    # the feet: the two lowest ends of the hierarchy that are far apart along the bones; the hips:
    # where their chains meet, or the first joint above that with a chain going up (the spine)
    foot_a, foot_b = _two_feet(tree)
    hips = _meeting_point(tree, foot_a, foot_b)
    while not _up_branches(tree, hips, (foot_a, foot_b)):
        if tree.parents[hips] < 0:
            raise HumanoidError(f"by structure: nothing goes up from where the legs ending at "
                                f"{tree.names[foot_a]!r} and {tree.names[foot_b]!r} meet: no spine, so no hips")
        hips = int(tree.parents[hips])
    torso = max(_up_branches(tree, hips, (foot_a, foot_b)), key=lambda c: tree.P[_highest(tree, c), 1])
    leg_chains = [tree.path(hips, foot_a), tree.path(hips, foot_b)]

    # the spine: up from the hips while the chain does not branch into long side chains
    leg_len = np.mean([tree.P[hips, 1] - tree.P[f, 1] for f in (foot_a, foot_b)])
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
    try:
        arms = [arm_from_chain(tree, tree.path(b, farthest_leaf(tree, b, c)), f"the arm from {tree.names[c]!r}")
                for b, c in side_chains]
        legs = [leg_from_chain(tree, chain, f"the leg to {tree.names[chain[-1]]!r}") for chain in leg_chains]
    except HumanoidError as e:
        raise HumanoidError(f"by structure: {e}") from None
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


def _two_feet(tree: PosedTree) -> Tuple[int, int]:
    """The lowest end of the hierarchy (median height over the clip) and the lowest end at least
    half the body's height away from it along the bones (so not a heel of the same foot)."""
    leaves = [j for j in range(len(tree.names)) if not tree.children[j]]
    height = np.median(tree.P_all[:, leaves, 1], axis=0)
    order = [leaves[i] for i in np.argsort(height, kind="stable")]
    if order:
        a = order[0]
        for b in order[1:]:
            if _bone_distance(tree, a, b) >= 0.5 * tree.height:
                return a, b
    raise HumanoidError("by structure: no joint has two chains going down (legs) far apart: "
                        "no two feet were found")


def _meeting_point(tree: PosedTree, a: int, b: int) -> int:
    """The nearest joint that is an ancestor of both ``a`` and ``b``."""
    above_a = {a}
    while tree.parents[a] >= 0:
        a = int(tree.parents[a])
        above_a.add(a)
    while b not in above_a:
        b = int(tree.parents[b])
    return b


def _bone_distance(tree: PosedTree, a: int, b: int) -> float:
    """Length along the bones from leaf ``a`` to leaf ``b`` (through where their chains meet)."""
    m = _meeting_point(tree, a, b)
    return sum(sum(tree.length(k) for k in tree.path(m, x)) for x in (a, b) if x != m)


def _up_branches(tree: PosedTree, j: int, feet) -> List[int]:
    """Children of ``j`` (through zero-length helpers) that hold neither foot and reach well above it."""
    out = []
    for c in tree.real_children(j):
        below = tree.subtree(c)
        if any(f in below for f in feet):
            continue
        if max(tree.P[k, 1] for k in below) > tree.P[j, 1] + 0.2 * tree.height:
            out.append(c)
    return out


def _reach(tree: PosedTree, top: int, c: int) -> float:
    """Length along the bones from ``top`` to the farthest leaf below ``c``."""
    leaf = farthest_leaf(tree, top, c)
    return sum(tree.length(k) for k in tree.path(top, leaf))


def _highest(tree: PosedTree, c: int) -> int:
    return max(tree.subtree(c), key=lambda k: tree.P[k, 1])
