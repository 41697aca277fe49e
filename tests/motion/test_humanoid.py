"""minifilm.body.humanoid: the parts of every real layout, by names and by structure alone, and
one clear error for what is not a humanoid."""
from functools import lru_cache

import numpy as np
import pytest

from humanoid_rigs import (CMU_CONVERSION_FROM_MB, CMU_CONVERSION_FROM_XIA, posed, quadruped, renamed,
                           renamed_bvh, scrambled, single_chain, without)
from minifilm.errors import InputError
from minifilm.motion.bvh import read_bvh
from minifilm.body.humanoid import (HumanoidError, find_humanoid, humanoid_by_names, humanoid_by_structure,
                                      split_name)

# What a person reading each file's header calls each part (written by hand, not by the code).
EXPECTED = {
    "100style/Neutral_FR_first3frames.bvh": dict(
        hips="Hips", spine0="Chest", spine3="Chest4", neck="Neck", head="Head",
        left_collar="LeftCollar", left_shoulder="LeftShoulder", left_elbow="LeftElbow", left_wrist="LeftWrist",
        left_hip="LeftHip", left_knee="LeftKnee", left_ankle="LeftAnkle", left_toe="LeftToe",
        left_toe_tip="LeftToeSite", right_wrist="RightWrist", right_ankle="RightAnkle", right_toe_tip="RightToeSite"),
    "bandai2/dataset-2_walk_normal_001.bvh": dict(
        root="joint_Root", hips="Hips", spine0="Spine", spine1="Chest", neck="Neck", head="Head",
        left_collar="Shoulder_L", left_shoulder="UpperArm_L", left_elbow="LowerArm_L", left_wrist="Hand_L",
        left_hip="UpperLeg_L", left_knee="LowerLeg_L", left_ankle="Foot_L", left_toe="Toes_L",
        right_collar="Shoulder_R", right_hip="UpperLeg_R", right_toe_tip="Toes_RSite"),
    "bvh/bandai1/dataset-1_run_normal_001.bvh": dict(
        root="joint_Root", hips="Hips", left_wrist="Hand_L", right_wrist="Hand_R", left_ankle="Foot_L",
        right_ankle="Foot_R", right_knee="LowerLeg_R"),
    "bvh/xia/neutral_01_000.bvh": dict(
        hips="Hips", spine0="LowerBack", spine1="Spine", spine2="Spine1", neck="Neck", head="Head",
        left_collar="LeftShoulder", left_shoulder="LeftArm", left_elbow="LeftForeArm", left_wrist="LeftHand",
        left_hip="LeftUpLeg", left_knee="LeftLeg", left_ankle="LeftFoot", left_toe="LeftToeBase",
        right_hip="RightUpLeg", right_wrist="RightHand"),
    "bvh/cmu/08_01_trimmed.bvh": dict(
        hips="hip", spine0="abdomen", spine1="chest", neck="neck", head="head",
        left_collar="lCollar", left_shoulder="lShldr", left_elbow="lForeArm", left_wrist="lHand",
        left_hip="lThigh", left_knee="lShin", left_ankle="lFoot", left_toe="lFootSite",
        right_collar="rCollar", right_hip="rThigh", right_ankle="rFoot", right_toe_tip="rFootSite"),
}


@lru_cache(maxsize=None)
def _read(path):
    return read_bvh(path, scale=1.0)


def _check(found, expected):
    described = found.describe()
    wrong = {r: (described.get(r), n) for r, n in expected.items() if described.get(r) != n}
    assert not wrong, f"(found, expected) per role: {wrong}"


@pytest.mark.parametrize("rel", sorted(EXPECTED))
def test_every_real_layout_by_names_and_by_structure_alone(shared_data, rel):
    m = _read(str(shared_data / rel))
    by_names = humanoid_by_names(m)
    assert by_names.method == "names"
    _check(by_names, EXPECTED[rel])
    by_structure = humanoid_by_structure(scrambled(m))       # no name tells anything here
    assert by_structure.method == "structure"
    assert by_structure.roles() == by_names.roles()
    assert find_humanoid(m).method == "names"
    assert find_humanoid(scrambled(m, seed=1)).roles() == by_names.roles()


def test_structure_agrees_with_names_on_every_shared_file(shared_data):
    # every shared file (running Bandai files kick a foot backwards: left/right must still hold)
    files = sorted(shared_data.glob("**/*.bvh"))
    assert len(files) > 100
    for path in files[::7]:
        m = _read(str(path))
        assert humanoid_by_structure(m).roles() == humanoid_by_names(m).roles(), path.name


@pytest.mark.parametrize("source, mapping", [("bvh/xia/neutral_01_000.bvh", CMU_CONVERSION_FROM_XIA),
                                             ("bvh/cmu/08_01_trimmed.bvh", CMU_CONVERSION_FROM_MB)])
def test_the_widely_shared_cmu_conversion_layout(shared_data, tmp_path, source, mapping):
    path = renamed_bvh(shared_data / source, tmp_path / "cmu_renamed.bvh", mapping)
    m = read_bvh(path, scale=1.0)
    assert "LHipJoint" in m.names and "LeftKnee" in m.names
    h = find_humanoid(m)
    assert h.method == "names"
    _check(h, dict(hips="Hips", left_hip="LeftHip", left_knee="LeftKnee", left_ankle="LeftAnkle",
                   right_hip="RightHip", right_knee="RightKnee", right_ankle="RightAnkle", head="Head",
                   left_collar="LeftCollar", left_shoulder="LeftShoulder", left_elbow="LeftElbow",
                   left_wrist="LeftWrist", right_wrist="RightWrist"))
    if "xia" in source:
        _check(h, dict(left_toe="LeftToe", right_toe="RightToe"))


def test_a_mixamo_rig_is_read_by_names(shared_data):
    m = _read(str(shared_data / "100style/Neutral_FR_first3frames.bvh"))
    mixamo = {"Hips": "Hips", "Chest": "Spine", "Chest2": "Spine1", "Chest3": "Spine2", "Chest4": "Spine3",
              "Neck": "Neck", "Head": "Head"}
    for side in ("Left", "Right"):
        mixamo.update({f"{side}Collar": f"{side}Shoulder", f"{side}Shoulder": f"{side}Arm",
                       f"{side}Elbow": f"{side}ForeArm", f"{side}Wrist": f"{side}Hand",
                       f"{side}Hip": f"{side}UpLeg", f"{side}Knee": f"{side}Leg", f"{side}Ankle": f"{side}Foot",
                       f"{side}Toe": f"{side}ToeBase"})
    names = [("mixamorig:" + mixamo[n]) if n in mixamo else n for n in m.names]
    h = humanoid_by_names(renamed(m, names))
    _check(h, {"left_collar": "mixamorig:LeftShoulder", "left_shoulder": "mixamorig:LeftArm",
               "left_elbow": "mixamorig:LeftForeArm", "left_wrist": "mixamorig:LeftHand",
               "left_hip": "mixamorig:LeftUpLeg", "left_knee": "mixamorig:LeftLeg",
               "left_ankle": "mixamorig:LeftFoot", "left_toe": "mixamorig:LeftToeBase",
               "spine0": "mixamorig:Spine", "neck": "mixamorig:Neck"})
    assert h.roles() == humanoid_by_names(m).roles()


@pytest.mark.parametrize("name, side, part", [
    ("LeftUpLeg", "left", "upleg"), ("mixamorig:RightForeArm", "right", "forearm"),
    ("LHipJoint", "left", "hipjoint"), ("lShldr", "left", "shldr"), ("rButtock", "right", "buttock"),
    ("Shoulder_L", "left", "shoulder"), ("thigh.R", "right", "thigh"), ("Bip01 L Thigh", "left", "thigh"),
    ("joint_Foot_R", "right", "foot"), ("l_knee", "left", "knee"), ("UpperArmR", "right", "upperarm"),
    ("knee_left", "left", "knee"), ("LowerBack", None, "lowerback"), ("Spine1", None, "spine"),
    ("Root", None, "root"), ("joint_Root", None, "root"), ("RightHandIndex1", "right", "handindex"),
])
def test_split_name_reads_the_common_conventions(name, side, part):
    assert split_name(name)[:2] == (side, part)


def test_end_sites_are_flagged():
    assert split_name("LeftToeSite") == ("left", "toe", True)


# ------------------------------------------------------------------ not a humanoid: one clear error

@pytest.mark.parametrize("human_names", [False, True])
def test_a_quadruped_is_refused(human_names):
    with pytest.raises(HumanoidError) as e:
        find_humanoid(quadruped(human_names))
    assert "on the floor like a foot" in str(e.value) and "<quadruped>" in str(e.value)
    assert isinstance(e.value, InputError)


def test_a_single_chain_is_refused():
    with pytest.raises(HumanoidError, match="no joint has two chains going down"):
        find_humanoid(single_chain())


def test_a_rig_without_feet_is_refused(shared_data):
    m = _read(str(shared_data / "100style/Neutral_FR_first3frames.bvh"))
    footless = without(m, {"LeftToe", "RightToe"})
    with pytest.raises(HumanoidError) as e:
        find_humanoid(footless)
    assert "nothing below the ankle 'LeftAnkle'" in str(e.value)            # by names
    with pytest.raises(HumanoidError, match="ends at its ankle .* no foot"):
        humanoid_by_structure(scrambled(footless))                          # by structure


def test_a_one_armed_rig_is_refused(shared_data):
    m = _read(str(shared_data / "bvh/xia/neutral_01_000.bvh"))
    with pytest.raises(HumanoidError) as e:
        find_humanoid(scrambled(without(m, {"RightShoulder"})))
    assert "found 1 arm" in str(e.value)


def test_nan_positions_are_refused():
    m = posed(["a", "b"], [-1, 0], [(0, 1, 0), (0, 1, 0)])
    m.translations[1, 1, 0] = np.nan
    with pytest.raises(HumanoidError, match="not finite"):
        find_humanoid(m)


@pytest.mark.parametrize("pelvis_apart", [False, True])
@pytest.mark.parametrize("arms", ["T", "down"])
def test_a_hand_built_human_by_structure(pelvis_apart, arms):
    from humanoid_rigs import stick_human
    m = stick_human(pelvis_apart=pelvis_apart, arms=arms)
    h = find_humanoid(m)
    assert h.method == "structure"                      # names that say nothing: arm_l0, leg_r2, ...
    _check(h, dict(hips="root", neck="neck", head="head", head_top="headtop",
                   left_collar="arm_l0", left_shoulder="arm_l1", left_elbow="arm_l2", left_wrist="arm_l3",
                   right_collar="arm_r0", right_wrist="arm_r3",
                   left_hip="leg_l0", left_knee="leg_l1", left_ankle="leg_l2", left_toe="leg_l3",
                   left_toe_tip="leg_l4", right_hip="leg_r0", right_ankle="leg_r2", right_toe_tip="leg_r4"))
    assert [m.names[j] for j in h.spine] == ["spine", "chest"]


_STICK_PARTS = {"root": "hips", "spine": "spine", "chest": "chest", "neck": "neck", "head": "head",
                "arm_{s}0": "collar", "arm_{s}1": "upper arm", "arm_{s}2": "forearm", "arm_{s}3": "hand",
                "leg_{s}0": "thigh", "leg_{s}1": "shin", "leg_{s}2": "foot", "leg_{s}3": "toe"}
CONVENTIONS = {   # part -> name, with {S} the side as the convention writes it
    "3ds Max biped": dict(sides=("L", "R"), hips="Bip01 Pelvis", spine="Bip01 Spine", chest="Bip01 Spine1",
                          neck="Bip01 Neck", head="Bip01 Head", collar="Bip01 {S} Clavicle",
                          **{"upper arm": "Bip01 {S} UpperArm", "forearm": "Bip01 {S} Forearm", "hand": "Bip01 {S} Hand",
                             "thigh": "Bip01 {S} Thigh", "shin": "Bip01 {S} Calf", "foot": "Bip01 {S} Foot",
                             "toe": "Bip01 {S} Toe0"}),
    "Blender": dict(sides=("L", "R"), hips="pelvis", spine="spine", chest="spine.001", neck="neck", head="head",
                    collar="shoulder.{S}", **{"upper arm": "upper_arm.{S}", "forearm": "forearm.{S}", "hand": "hand.{S}",
                                              "thigh": "thigh.{S}", "shin": "shin.{S}", "foot": "foot.{S}",
                                              "toe": "toe.{S}"}),
    "Mixamo": dict(sides=("Left", "Right"), hips="mixamorig:Hips", spine="mixamorig:Spine", chest="mixamorig:Spine1",
                   neck="mixamorig:Neck", head="mixamorig:Head", collar="mixamorig:{S}Shoulder",
                   **{"upper arm": "mixamorig:{S}Arm", "forearm": "mixamorig:{S}ForeArm", "hand": "mixamorig:{S}Hand",
                      "thigh": "mixamorig:{S}UpLeg", "shin": "mixamorig:{S}Leg", "foot": "mixamorig:{S}Foot",
                      "toe": "mixamorig:{S}ToeBase"}),
    "snake_case": dict(sides=("l", "r"), hips="joint_pelvis", spine="joint_spine_01", chest="joint_spine_02",
                       neck="joint_neck", head="joint_head", collar="joint_{S}_clavicle",
                       **{"upper arm": "joint_{S}_upperarm", "forearm": "joint_{S}_lowerarm", "hand": "joint_{S}_hand",
                          "thigh": "joint_{S}_thigh", "shin": "joint_{S}_calf", "foot": "joint_{S}_foot",
                          "toe": "joint_{S}_ball"}),
}


@pytest.mark.parametrize("convention", sorted(CONVENTIONS))
def test_naming_conventions_on_a_hand_built_human(convention):
    from humanoid_rigs import stick_human
    m = stick_human(arms="down")
    c = CONVENTIONS[convention]
    mapping = {}
    for generic, part in _STICK_PARTS.items():
        for s, S in zip(("l", "r"), c["sides"]):
            mapping[generic.format(s=s)] = c[part].format(S=S)
    h = humanoid_by_names(renamed(m, mapping))
    assert h.method == "names"
    assert h.roles() == humanoid_by_structure(m).roles()          # the same joints as its shape says
