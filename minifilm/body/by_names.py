"""Humanoid parts from joint names (the conventions are listed in minifilm/body/humanoid.py)."""
from __future__ import annotations

import re
from typing import Dict, List, Optional, Sequence, Tuple

from minifilm.body.parts import Humanoid, HumanoidError
from minifilm.body.tree import PosedTree, assemble

__all__ = ["split_name", "humanoid_by_names"]

_SIDE_WORDS = {"left": "left", "right": "right", "l": "left", "r": "right"}
_SEP = r"[_\-\s\.]"


def split_name(name: str) -> Tuple[Optional[str], str, bool]:
    """(side, part, is_end_site) of a joint name: ``"mixamorig:LeftUpLeg"`` -> ("left", "upleg", False).

    ``side`` is "left", "right" or None; ``part`` is lower case without separators or trailing
    digits (``Spine1`` -> "spine", ``Neck1`` -> "neck"); End Sites (named ``<parent>Site``) are
    flagged and their part is the parent's."""
    n = name.split(":")[-1].split("|")[-1].strip()          # namespaces: mixamorig:, a|b
    site = False
    m = re.fullmatch(r"(.+?)Site\d*", n)
    if m:
        n, site = m.group(1), True
    n = re.sub(r"^(joint|jnt|bip\d*|bone|def|mixamorig\d*)" + _SEP + "*", "", n, flags=re.I)
    side = None
    patterns = (
        (r"(left|right)" + _SEP + r"*(.+)", re.I),          # LeftUpLeg, left_knee, Left Arm
        (r"(.+?)" + _SEP + r"*(left|right)", re.I),         # UpLegLeft, knee_left
        (r"([lr])" + _SEP + r"+(.+)", re.I),                # l_knee, L Thigh, R.Foot
        (r"(.+?)" + _SEP + r"+([lr])", re.I),               # Shoulder_L, thigh.l, Foot R
        (r"([LRlr])([A-Z].*)", 0),                          # LHipJoint, lCollar, rShldr
        (r"(.*[a-z])([LR])", 0),                            # ThighL, UpperArmR
    )
    for k, (pattern, flags) in enumerate(patterns):
        m = re.fullmatch(pattern, n, flags)
        if m:
            a, b = m.groups()
            word, rest = (a, b) if k in (0, 2, 4) else (b, a)
            side, n = _SIDE_WORDS[word.lower()], rest
            break
    part = re.sub(r"\d+$", "", re.sub(r"[^a-z0-9]", "", n.lower()))
    return side, part, site


#: part names -> role, for sided joints (first match in a chain wins; see _name_chain)
_LEG_NAMES = {
    "hip": ("upleg", "upperleg", "thigh", "hip", "femur", "legupper", "uleg", "hipjoint"),
    "knee": ("knee", "leg", "lowerleg", "shin", "calf", "loleg", "lowleg", "leglower", "lleg", "tibia"),
    "ankle": ("ankle", "foot"),
    "toe": ("toe", "toes", "toebase", "ball", "toebone", "footend"),
}
_ARM_NAMES = {
    "collar": ("collar", "clavicle", "shoulder", "scapula", "clav"),
    "shoulder": ("arm", "upperarm", "shoulder", "shldr", "humerus", "armupper", "uparm", "uarm"),
    "elbow": ("forearm", "elbow", "lowerarm", "armlower", "loarm", "lowarm", "farm", "radius"),
    "wrist": ("wrist", "hand"),
}
_HIPS_NAMES = ("hips", "pelvis", "hip", "root", "waist")
_NECK_NAMES = ("neck",)
_HEAD_NAMES = ("head",)


def humanoid_by_names(motion) -> Humanoid:
    """The humanoid parts from the joint names (conventions in the module docstring).

    HumanoidError naming the parts whose names were not found or are out of order."""
    tree = PosedTree(motion)
    parsed = [split_name(n) for n in tree.names]

    def find(alias: Sequence[str], side: Optional[str], under: Optional[int] = None) -> List[int]:
        out = [j for j, (s, part, site) in enumerate(parsed)
               if not site and s == side and part in alias and (under is None or tree.is_ancestor(under, j))]
        return out

    hips_c = [j for a in _HIPS_NAMES for j in find((a,), None)]
    missing: List[str] = []
    hips = None
    for j in hips_c:   # the first name in _HIPS_NAMES order that has sided legs below it
        if any(tree.is_ancestor(j, k) for k in find(_LEG_NAMES["knee"] + _LEG_NAMES["ankle"], "left")):
            hips = j
            break
    if hips is None:
        raise HumanoidError("by names: no hips/pelvis joint with legs below it")

    limbs: Dict[str, Dict[str, Optional[int]]] = {}
    for side in ("left", "right"):
        limbs[side] = {}
        leg = limbs[side]
        leg_joints = [j for j in range(len(tree.names))
                      if parsed[j][0] == side and not parsed[j][2] and tree.is_ancestor(hips, j)]
        ankle = _first(tree, leg_joints, parsed, _LEG_NAMES["ankle"])
        toe = _first(tree, leg_joints, parsed, _LEG_NAMES["toe"], below=ankle)
        knee = _first(tree, leg_joints, parsed, _LEG_NAMES["knee"], above=ankle)
        hip = _first(tree, leg_joints, parsed, _LEG_NAMES["hip"], above=knee, last=True)
        for role, j in (("hip", hip), ("knee", knee), ("ankle", ankle)):
            if j is None:
                missing.append(f"{side} {role}")
        if ankle is not None and toe is None:
            below = tree.children[ankle]
            if below:
                toe = below[0]
            else:
                missing.append(f"{side} toe (nothing below the ankle {tree.names[ankle]!r})")
        if toe is not None:
            leg.update(hip=hip, knee=knee, ankle=ankle, toe=toe, toe_tip=_lowest_end(tree, toe))
        wrist = _first(tree, leg_joints, parsed, _ARM_NAMES["wrist"])
        elbow = _first(tree, leg_joints, parsed, _ARM_NAMES["elbow"], above=wrist)
        shoulder = _first(tree, leg_joints, parsed, _ARM_NAMES["shoulder"], above=elbow, last=True)
        collar = _first(tree, leg_joints, parsed, _ARM_NAMES["collar"], above=shoulder, last=True)
        for role, j in (("shoulder", shoulder), ("elbow", elbow), ("wrist", wrist)):
            if j is None:
                missing.append(f"{side} {role}")
        leg.update(collar=collar, shoulder=shoulder, elbow=elbow, wrist=wrist)
    head = next(iter(find(_HEAD_NAMES, None, under=hips)), None)
    neck = next(iter(find(_NECK_NAMES, None, under=hips)), None)
    if head is None:
        missing.append("head")
    if neck is not None and head is not None and not tree.is_ancestor(neck, head):
        neck = None
    if missing:
        raise HumanoidError(f"by names: {', '.join(missing)} not found")
    for side in ("left", "right"):   # the arms hang off the spine, not the neck's top or the head
        if not tree.is_ancestor(hips, limbs[side]["wrist"]) or tree.is_ancestor(head, limbs[side]["wrist"]):
            raise HumanoidError(f"by names: the {side} hand {tree.names[limbs[side]['wrist']]!r} is not on the spine")
    return assemble(tree, "names", hips, neck, head, limbs)


_ANY = -2   # "no constraint" for _first (None means: the anchor itself was not found)


def _first(tree: PosedTree, candidates: List[int], parsed, alias: Sequence[str], above: Optional[int] = _ANY,
           below: Optional[int] = _ANY, last: bool = False) -> Optional[int]:
    """The joint among ``candidates`` whose part is in ``alias`` (earlier alias first) that is a
    strict ancestor of ``above`` and a descendant of ``below`` (each unless left out). ``last``: of
    several with the best alias, the deepest (the one nearest ``above``). None when not found, or
    when ``above`` / ``below`` is None (the joint it hangs on was not found either)."""
    if above is None or below is None:
        return None
    above, below = (None if above == _ANY else above), (None if below == _ANY else below)
    for a in alias:
        js = [j for j in candidates if parsed[j][1] == a
              and (above is None or tree.is_ancestor(j, above))
              and (below is None or tree.is_ancestor(below, j))]
        if js:
            return js[-1] if last else js[0]
    return None


def _lowest_end(tree: PosedTree, j: int) -> int:
    """The end of the chain below ``j`` (through its first child each time): a toe's tip."""
    while tree.children[j]:
        j = tree.children[j][0]
    return j
