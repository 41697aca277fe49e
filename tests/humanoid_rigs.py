"""Rigs for the humanoid, body-size and viewer tests: real files renamed to other conventions, and
motions built by hand (a scrambled rig, a quadruped, a single chain, a rig without feet).

Shared by tests/motion and tests/viewer (the tests folder is on the path through its conftest).
"""
import re
from pathlib import Path

import numpy as np

from minifilm.motion.motion import Motion

#: The widely shared CMU conversion's names, for the 31-joint CMU skeleton of the Xia files.
CMU_CONVERSION_FROM_XIA = {
    "LeftUpLeg": "LeftHip", "LeftLeg": "LeftKnee", "LeftFoot": "LeftAnkle", "LeftToeBase": "LeftToe",
    "RightUpLeg": "RightHip", "RightLeg": "RightKnee", "RightFoot": "RightAnkle", "RightToeBase": "RightToe",
    "LeftShoulder": "LeftCollar", "LeftArm": "LeftShoulder", "LeftForeArm": "LeftElbow", "LeftHand": "LeftWrist",
    "RightShoulder": "RightCollar", "RightArm": "RightShoulder", "RightForeArm": "RightElbow",
    "RightHand": "RightWrist",
}
#: The same names for the MotionBuilder-friendly CMU file (08_01: hip, abdomen, rThigh, ...).
CMU_CONVERSION_FROM_MB = {
    "hip": "Hips", "abdomen": "Spine", "chest": "Spine1", "neck": "Neck", "head": "Head",
    "lButtock": "LHipJoint", "lThigh": "LeftHip", "lShin": "LeftKnee", "lFoot": "LeftAnkle",
    "rButtock": "RHipJoint", "rThigh": "RightHip", "rShin": "RightKnee", "rFoot": "RightAnkle",
    "lCollar": "LeftCollar", "lShldr": "LeftShoulder", "lForeArm": "LeftElbow", "lHand": "LeftWrist",
    "rCollar": "RightCollar", "rShldr": "RightShoulder", "rForeArm": "RightElbow", "rHand": "RightWrist",
}


def renamed_bvh(src: Path, dst: Path, mapping: dict) -> Path:
    """A copy of the BVH file ``src`` at ``dst`` with its ROOT/JOINT names replaced by ``mapping``."""
    text = Path(src).read_text(encoding="utf-8")

    def swap(m):
        return m.group(1) + mapping.get(m.group(2), m.group(2))
    Path(dst).write_text(re.sub(r"^(\s*(?:ROOT|JOINT)\s+)(\S+)", swap, text, flags=re.M), encoding="utf-8")
    return Path(dst)


def renamed(motion: Motion, names) -> Motion:
    """``motion`` with other joint names (a list, or a {old: new} dict)."""
    if isinstance(names, dict):
        names = [names.get(n, n) for n in motion.names]
    return Motion(list(names), motion.parents.copy(), motion.offsets.copy(), list(motion.channels),
                  motion.rotations.copy(), motion.translations.copy(), motion.frame_time, motion.source)


def scrambled(motion: Motion, seed: int = 0) -> Motion:
    """``motion`` with every joint called ``bone_<random number>``: only its structure tells."""
    rng = np.random.default_rng(seed)
    ids = rng.permutation(10 * motion.n_joints)[:motion.n_joints]
    return renamed(motion, [f"bone_{i:03d}" for i in ids])


def without(motion: Motion, drop) -> Motion:
    """``motion`` without the joints named in ``drop`` and their descendants."""
    gone = set()
    for j, n in enumerate(motion.names):
        if n in drop or (motion.parents[j] >= 0 and int(motion.parents[j]) in gone):
            gone.add(j)
    keep = [j for j in range(motion.n_joints) if j not in gone]
    new_index = {j: i for i, j in enumerate(keep)}
    parents = np.array([new_index[int(motion.parents[j])] if motion.parents[j] >= 0 else -1 for j in keep])
    return Motion([motion.names[j] for j in keep], parents, motion.offsets[keep], [motion.channels[j] for j in keep],
                  motion.rotations[:, keep].copy(), motion.translations[:, keep].copy(), motion.frame_time,
                  motion.source)


def posed(names, parents, offsets, frames: int = 4, fps: float = 30.0, source: str = "<built>") -> Motion:
    """A motion holding the rest pose given by ``offsets`` (metres, y up) for ``frames`` frames,
    the root walking slowly along +z; joints without children are End Sites (no channels)."""
    J = len(names)
    offsets = np.asarray(offsets, dtype=np.float64)
    R = np.broadcast_to(np.eye(3), (frames, J, 3, 3)).copy()
    T = np.broadcast_to(offsets, (frames, J, 3)).copy()
    T[:, 0, 2] += np.arange(frames) * 0.02
    has_child = set(int(p) for p in parents if p >= 0)
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] + \
        [("Zrotation", "Xrotation", "Yrotation") if j in has_child else () for j in range(1, J)]  # leaves: End Sites
    return Motion(list(names), np.asarray(parents), offsets, channels, R, T, 1.0 / fps, source)


def quadruped(human_names: bool = False) -> Motion:
    """A dog standing on four legs (spine along +z, head up front, a tail). With ``human_names`` its
    front legs are called arms and its hind legs legs, so only its shape gives it away."""
    if human_names:
        n = dict(hips="Hips", spine="Spine", chest="Chest", neck="Neck", head="Head",
                 fl=("LeftShoulder", "LeftElbow", "LeftWrist"), fr=("RightShoulder", "RightElbow", "RightWrist"),
                 hl=("LeftHip", "LeftKnee", "LeftAnkle", "LeftToe"), hr=("RightHip", "RightKnee", "RightAnkle", "RightToe"))
    else:
        n = dict(hips="pelvis", spine="back", chest="withers", neck="neck", head="skull",
                 fl=("front_l_1", "front_l_2", "front_l_3"), fr=("front_r_1", "front_r_2", "front_r_3"),
                 hl=("hind_l_1", "hind_l_2", "hind_l_3", "hind_l_4"), hr=("hind_r_1", "hind_r_2", "hind_r_3", "hind_r_4"))
    rows = [(n["hips"], -1, (0, 0.5, 0)), (n["spine"], 0, (0, 0.02, 0.3)), (n["chest"], 1, (0, 0.0, 0.3)),
            (n["neck"], 2, (0, 0.15, 0.1)), (n["head"], 3, (0, 0.15, 0.1)), ("tail", 0, (0, 0.0, -0.3))]
    for side, x in (("fl", 0.1), ("fr", -0.1)):
        top = len(rows)
        rows += [(n[side][0], 2, (x, -0.05, 0)), (n[side][1], top, (0, -0.22, 0)),
                 (n[side][2], top + 1, (0, -0.2, 0)), (n[side][2] + "Site", top + 2, (0, -0.03, 0.05))]
    for side, x in (("hl", 0.1), ("hr", -0.1)):
        top = len(rows)
        rows += [(n[side][0], 0, (x, -0.05, 0)), (n[side][1], top, (0, -0.2, 0.05)),
                 (n[side][2], top + 1, (0, -0.2, -0.05)), (n[side][3], top + 2, (0, -0.04, 0.05)),
                 (n[side][3] + "Site", top + 3, (0, -0.01, 0.03))]
    names, parents, offsets = zip(*rows)
    return posed(names, parents, offsets, source="<quadruped>")


def single_chain(n: int = 8) -> Motion:
    """A snake: ``n`` joints in one line going up."""
    return posed([f"seg{i}" for i in range(n)], list(range(-1, n - 1)), [(0, 0.2 if i else 1.0, 0) for i in range(n)],
                 source="<chain>")


def stick_human(pelvis_apart: bool = False, arms: str = "T") -> Motion:
    """A 1.75 m person built by hand (metres, facing +z, left = +x), names neutral (``j0``, ...).

    pelvis_apart: the legs hang off a ``pelvis`` joint beside the spine (both children of the
    root) instead of off the root itself. arms: "T" (straight out) or "down" (hanging)."""
    rows = [("root", -1, (0, 0.95, 0))]
    leg_top = 0
    if pelvis_apart:
        rows.append(("pelvis", 0, (0, -0.02, 0)))
        leg_top = 1
    spine = len(rows)
    rows += [("spine", 0, (0, 0.12, 0)), ("chest", spine, (0, 0.25, 0)), ("neck", spine + 1, (0, 0.15, 0)),
             ("head", spine + 2, (0, 0.1, 0.02)), ("headtop", spine + 3, (0, 0.18, 0))]
    names = {"arm_l": None, "arm_r": None}
    for side, x in (("l", 1.0), ("r", -1.0)):
        top = len(rows)
        if arms == "T":
            segs = [(0.03 * x, 0.12, 0), (0.15 * x, 0, 0), (0.28 * x, 0, 0), (0.25 * x, 0, 0), (0.08 * x, 0, 0)]
        else:
            segs = [(0.03 * x, 0.12, 0), (0.15 * x, 0, 0), (0.02 * x, -0.28, 0), (0, -0.25, 0.03), (0, -0.08, 0)]
        parent = spine + 1
        for k, off in enumerate(segs):
            rows.append((f"arm_{side}{k}", parent if k == 0 else top + k - 1, off))
        names[f"arm_{side}"] = top
    for side, x in (("l", 1.0), ("r", -1.0)):
        top = len(rows)
        segs = [(0.09 * x, -0.03, 0), (0, -0.43, 0.02), (0, -0.42, -0.02), (0, -0.06, 0.14), (0, -0.01, 0.05)]
        for k, off in enumerate(segs):
            rows.append((f"leg_{side}{k}", leg_top if k == 0 else top + k - 1, off))
    names_, parents, offsets = zip(*rows)
    return posed(names_, parents, offsets, frames=6, source="<stick human>")


#: Names a spine joint goes by, and a neck joint (the unfamiliar ones too: only the hierarchy tells).
SPINE_NAMES = ("Spine", "Spine1", "Spine2", "Chest", "Chest2", "Chest3", "abdomen", "LowerBack", "UpperBack",
               "torso", "thorax", "back_01")
NECK_NAMES = ("Neck", "NeckBase", "C7", "cervical", "Throat", "lowerneck", "upperneck", "Neck1", "neck_01",
              "nape")
#: (collar, upper arm, forearm, hand) names, {S} the side as the convention writes it
ARM_CONVENTIONS = (("{S}Collar", "{S}Shoulder", "{S}Elbow", "{S}Wrist"),        # 100STYLE, the CMU conversion
                   ("{S}Shoulder", "{S}Arm", "{S}ForeArm", "{S}Hand"),          # Mixamo, Xia
                   ("Clavicle_{s}", "UpperArm_{s}", "LowerArm_{s}", "Hand_{s}"),
                   ("{s}Collar", "{s}Shldr", "{s}ForeArm", "{s}Hand"))          # the MotionBuilder CMU file


def branching_human(n_spine: int, arms_at: int, n_neck: int, collars: bool, spine_names, neck_names,
                    arm_convention=ARM_CONVENTIONS[0], arms: str = "down", frames: int = 4):
    """A 1.75 m person (metres, facing +z, left = +x) whose arms branch off spine joint ``arms_at``
    (0-based, of ``n_spine`` joints above the hips): the spine joints above it and then ``n_neck``
    neck joints lead to ``Head`` (and its End Site). So the names may say "spine" for what the
    hierarchy makes the neck, and a neck may go by any name.

    Returns (motion, expected): expected is {role: joint name} as a person reading the hierarchy
    names the parts: the chest is where the arms branch, the neck is the first joint above it
    towards the head (None when the head sits on the chest)."""
    assert 0 <= arms_at < n_spine and len(spine_names) >= n_spine and len(neck_names) >= n_neck
    rows = [("Hips", -1, (0.0, 0.95, 0.0))]
    torso = 0.45 / (arms_at + 1)
    above = n_spine - 1 - arms_at + n_neck                 # joints between the chest and the head
    neck_step = 0.12 / max(above, 1)
    for k in range(n_spine):
        rows.append((spine_names[k], k, (0.0, torso if k <= arms_at else neck_step, 0.0)))
    chest = 1 + arms_at
    for k in range(n_neck):
        rows.append((neck_names[k], len(rows) - 1, (0.0, neck_step, 0.01)))
    head = len(rows)
    rows.append(("Head", head - 1, (0.0, 0.1 if above else 0.2, 0.02)))
    rows.append(("HeadSite", head, (0.0, 0.18, 0.0)))
    expected = dict(hips="Hips", head="Head", head_top="HeadSite",
                    neck=rows[chest + 1][0] if chest + 1 < head + 1 and above else None,
                    **{f"spine{k}": spine_names[k] for k in range(arms_at + 1)})
    for side, S, s, x in (("left", "Left", "l", 1.0), ("right", "Right", "r", -1.0)):
        names = [c.format(S=S, s=s) for c in arm_convention]
        if arms == "T":
            segs = [(0.03 * x, 0.02, 0), (0.15 * x, 0, 0), (0.28 * x, 0, 0), (0.25 * x, 0, 0), (0.08 * x, 0, 0)]
        else:
            segs = [(0.03 * x, 0.02, 0), (0.15 * x, 0, 0), (0.02 * x, -0.28, 0), (0, -0.25, 0.03), (0, -0.08, 0)]
        if not collars:
            segs = [(0.18 * x, 0.02, 0)] + segs[2:]
            names = names[1:]
        parent = chest
        for k, (name, off) in enumerate(zip(names + [names[-1] + "Site"], segs)):
            rows.append((name, parent, off))
            parent = len(rows) - 1
        roles = ("collar", "shoulder", "elbow", "wrist") if collars else ("shoulder", "elbow", "wrist")
        expected.update({f"{side}_{r}": n for r, n in zip(roles, names)})
        if not collars:
            expected[f"{side}_collar"] = None
        leg = [f"{S}Hip", f"{S}Knee", f"{S}Ankle", f"{S}Toe", f"{S}ToeSite"]
        segs = [(0.09 * x, -0.03, 0), (0, -0.43, 0.02), (0, -0.42, -0.02), (0, -0.06, 0.14), (0, -0.01, 0.05)]
        parent = 0
        for name, off in zip(leg, segs):
            rows.append((name, parent, off))
            parent = len(rows) - 1
        expected.update({f"{side}_{r}": n for r, n in zip(("hip", "knee", "ankle", "toe", "toe_tip"), leg)})
    names_, parents, offsets = zip(*rows)
    return posed(names_, parents, offsets, frames=frames, source="<branching human>"), expected


def branching_humans(n: int, seed: int = 0):
    """``n`` varied :func:`branching_human` rigs drawn at random (spine 1-5 joints, arms off any
    of them, 0-3 neck joints, with and without collars, names from the pools above): a list of
    (label, motion, expected)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        n_spine = int(rng.integers(1, 6))
        arms_at = int(rng.integers(0, n_spine))
        n_neck = int(rng.integers(0, 4))
        if arms_at == n_spine - 1 and n_neck == 0 and rng.random() < 0.5:
            n_neck = 1
        spine = [str(n) for n in rng.permutation(SPINE_NAMES)[:n_spine]]
        neck = [str(n) for n in rng.permutation(NECK_NAMES)[:n_neck]]
        collars = bool(rng.random() < 0.7)
        convention = ARM_CONVENTIONS[int(rng.integers(len(ARM_CONVENTIONS)))]
        arms = "down" if rng.random() < 0.7 else "T"
        m, expected = branching_human(n_spine, arms_at, n_neck, collars, spine, neck, convention, arms)
        label = (f"#{i} spine={spine} arms_at={spine[arms_at]} neck={neck} collars={collars} "
                 f"arms={convention[1]} {arms}")
        out.append((label, m, expected))
    return out


def reparented(motion: Motion, moves: dict, names: dict = None) -> Motion:
    """``motion`` with each joint of ``moves`` ({joint: new parent}, the new parent an ancestor of
    the old one) hung off its new parent where it stood at rest (its offset lengthened by the
    bones it now skips), then renamed by ``names``: e.g. the collars moved from ``Chest4`` to
    ``Chest2``, as the CMU layout hangs them."""
    parents, offsets = motion.parents.copy(), motion.offsets.copy()
    T = motion.translations.copy()
    index = {n: i for i, n in enumerate(motion.names)}
    for joint, new_parent in moves.items():
        j, target = index[joint], index[new_parent]
        p = int(parents[j])
        while p != target:
            offsets[j] += offsets[p]
            T[:, j] += offsets[p]
            p = int(parents[p])
            assert p >= 0, f"{new_parent} is not above {joint}"
        parents[j] = target
    out = Motion(list(motion.names), parents, offsets, list(motion.channels), motion.rotations.copy(), T,
                 motion.frame_time, motion.source)
    return renamed(out, names or {})


#: The CMU layout seen in released conversions: the collars off ``Chest2``; ``Chest3``, ``Chest4``
#: then lead up the neck (here renamed ``lowerneck``, ``upperneck``) to the head.
CMU_LAYOUT_FROM_100STYLE = (dict(LeftCollar="Chest2", RightCollar="Chest2"),
                            dict(Chest3="lowerneck", Chest4="upperneck"))
