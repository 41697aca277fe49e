"""Which bone of a drawn skeleton is torso, neck, head, arm or leg: the mannequin's body plan.

The shaded body of the player and the demo (``assets/mannequin.js``) gives each bone a thickness by
its part. The parts are the ones :func:`minifilm.body.humanoid.find_humanoid` finds (by names,
checked against the hierarchy, else by structure), taken as its reader found them
(minifilm/body/read.py), so the page never guesses them itself and every command that knows a rig
agrees with what is drawn. :func:`body_plan` returns, for the page:

    {"parts": [part of the bone ending at joint j, for each drawn joint j],
     "head": the head joint, "neck": the joint below it (the head sits along neck -> head),
     "toes": the toe tips (the feet point the way the face looks)}

with parts ``"hips"`` (the pelvis ball), ``"torso"`` (hips up to the chest), ``"neck"`` (chest up
to the head), ``"inhead"`` (eyes, the head's End Site: inside the head sphere, not drawn),
``"collar"`` (the first bone of an arm), ``"arm"``, ``"pelvis"`` (the first bone of a leg, from the
hips to the hip joint), ``"leg"``, or None (not part of the body: a floor marker, a tail). A
skeleton that is not a humanoid gets ``{"parts": None}``: it is drawn as sticks only.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence

import numpy as np

from minifilm.body.humanoid import find_humanoid
from minifilm.body.parts import Humanoid, HumanoidError
from minifilm.motion.motion import Motion

__all__ = ["body_plan", "body_plan_of_positions", "joint_parts"]


def joint_parts(motion: Motion, h) -> List[Optional[str]]:
    """(J,) the body part of the bone ending at each joint of ``motion``, from its humanoid ``h``."""
    parents = [int(p) for p in motion.parents]
    J = len(parents)
    children: List[List[int]] = [[] for _ in range(J)]
    for j, p in enumerate(parents):
        if p >= 0:
            children[p].append(j)
    parts: List[Optional[str]] = [None] * J

    def below(top: int, part_of_top: str, part: str) -> None:
        parts[top] = part_of_top
        stack = list(children[top])
        while stack:
            k = stack.pop()
            parts[k] = part
            stack.extend(children[k])

    def path(top: int, bottom: int) -> List[int]:            # below ``top`` down to ``bottom``
        out = [bottom]
        while parents[out[-1]] != top:
            out.append(parents[out[-1]])
        return out[::-1]

    below(h.head, "neck", "inhead")
    for j in path(h.hips, h.chest) if h.chest != h.hips else []:
        parts[j] = "torso"
    for j in path(h.chest, h.head)[:-1]:
        parts[j] = "neck"
    for side in ("left", "right"):
        arm = getattr(h, f"{side}_collar")
        arm = arm if arm is not None else getattr(h, f"{side}_shoulder")
        top = path(h.chest, arm)[0]                           # the arm's first joint off the chest
        below(top, "collar", "arm")
        leg = path(h.hips, getattr(h, f"{side}_hip"))[0]      # the leg's first joint off the hips
        below(leg, "pelvis", "leg")
    parts[h.hips] = "hips"
    return parts


def body_plan(motion: Motion, keep: Optional[Sequence[int]] = None, humanoid: Optional[Humanoid] = None) -> Dict:
    """The page's body plan (module docstring) for ``motion``, indexed by the drawn joints ``keep``
    (ascending joint indices of ``motion``; default: all). A dropped joint (one that sits on its
    parent) hands its role to the nearest drawn joint above it (the head, the toes) and its part to
    the drawn bone that spans it. ``humanoid``: its parts as its reader found them; None for a
    motion no reader looked at (a network's output): they are found here."""
    try:
        h = humanoid if humanoid is not None else find_humanoid(motion)
    except HumanoidError:
        return {"parts": None}
    keep = list(range(motion.n_joints)) if keep is None else [int(j) for j in keep]
    drawn = {j: i for i, j in enumerate(keep)}

    def shown(j: int) -> Optional[int]:
        while j >= 0 and j not in drawn:
            j = int(motion.parents[j])
        return drawn.get(j)

    parts = joint_parts(motion, h)
    head = shown(h.head)
    neck = shown(int(motion.parents[h.head]))
    toes = [shown(t) for t in (h.left_toe_tip, h.right_toe_tip)]
    if head is None or neck is None or None in toes:
        return {"parts": None}
    drawn_parts = [parts[_first_below_drawn(motion, j, drawn)] for j in keep]
    if h.hips in drawn:                 # the hips' bone from a floor marker is not drawn: still the hips
        drawn_parts[drawn[h.hips]] = "hips"
    return {"parts": drawn_parts, "head": head, "neck": neck, "toes": toes}


def _first_below_drawn(motion: Motion, j: int, drawn) -> int:
    """The joint right below ``j``'s nearest drawn ancestor on the way to ``j``: the drawn bone to
    ``j`` spans the dropped joints in between and is the part the first of them begins (Xia's
    zero-length ``LHipJoint`` begins the leg's pelvis bone)."""
    while int(motion.parents[j]) >= 0 and int(motion.parents[j]) not in drawn:
        j = int(motion.parents[j])
    return j


def body_plan_of_positions(positions: np.ndarray, parents: Sequence[int],
                           names: Optional[Sequence[str]] = None) -> Dict:
    """The body plan of a skeleton known only by its joint positions: (F, J, 3) metres, y up, with
    its drawing ``parents`` (J,) (a network's output, the demo's character). It is read as a motion
    whose bones are the links between the positions (identity rotations), so the humanoid finder
    sees the same hierarchy and pose as the page draws."""
    P = np.asarray(positions, dtype=np.float64)
    if P.ndim == 2:
        P = P[None]
    parents = np.asarray(parents, dtype=np.int64)
    F, J, _ = P.shape
    names = [str(n) for n in names] if names is not None else [f"joint {j}" for j in range(J)]
    T = P.copy()
    has_parent = parents >= 0
    T[:, has_parent] = P[:, has_parent] - P[:, parents[has_parent]]
    has_child = set(int(p) for p in parents if p >= 0)
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation") if p < 0 else
                (("Zrotation", "Xrotation", "Yrotation") if j in has_child else ()) for j, p in enumerate(parents)]
    R = np.broadcast_to(np.eye(3), (F, J, 3, 3)).copy()
    motion = Motion(names, parents, T[0].copy(), channels, R, T, 1.0 / 60.0, "<drawn skeleton>")
    return body_plan(motion)
