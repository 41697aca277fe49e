"""Tests for minifilm.motion.skeletons: built-ins against the real files, root transforms by closed form."""
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from minifilm.body.rig import detect_skeleton
from minifilm.motion import skeletons as S
from minifilm.motion.bvh import read_bvh
from minifilm.motion.kinematics import euler_to_matrix
from minifilm.motion.motion import Motion

# Which shared-data files belong to which built-in skeleton.
GROUPS = {
    "100style": ["100style/*.bvh"],
    "bandai": ["bandai2/*.bvh", "bvh/bandai1/*.bvh"],
    "cmu": ["bvh/xia/*.bvh"],
    "cmu-mb": ["bvh/cmu/*.bvh"],
}
BY_NAME = {s.name: s for s in S.BUILTIN_SKELETONS}


def files_of(root: Path, name: str):
    files = sorted(f for pattern in GROUPS[name] for f in root.glob(pattern))
    assert files, f"no files for {name} under {root}"
    return files


@lru_cache(maxsize=None)
def summary(path: str, scale: float):
    """Per-file numbers the tests need (read once): hips height, sensor heights, facing vs travel."""
    m = read_bvh(path, scale=scale)
    sk = detect_skeleton(m)
    P, _ = m.world()
    root_pos, root_rot = S.root_transforms(m, sk)
    travel = np.diff(root_pos, axis=0) * m.fps                     # (F-1, 3), y = 0
    speed = np.linalg.norm(travel, axis=-1)
    moving = speed > 0.2
    facing = root_rot[1:, :, 2]
    cos = np.sum(facing[moving] * travel[moving], axis=-1) / speed[moving]
    sensors = P[:, sk.contact_indices(m), 1]                       # (F, 2)
    return dict(skeleton=sk.name, hips_y=P[:, sk.hips_index(m), 1].mean(),
                lowest_sensor=np.percentile(sensors.min(axis=1), 5),
                mean_cos=cos.mean() if cos.size else np.nan, moving=int(moving.sum()))


# ------------------------------------------------------------------ descriptions

def test_style100_matches_the_original_export_table(shared_data):
    assert S.STYLE100.parents == (-1, 0, 1, 2, 3, 4, 5, 4, 7, 8, 9, 10, 4, 12, 13, 14, 15, 0, 17, 18, 19,
                                  0, 21, 22, 23)
    m = read_bvh(shared_data / "100style" / "Neutral_FR_first3frames.bvh")
    # docs/original-code.md §1.2: export_to_bvh
    expected = [0, 1, 2, 3, 4, 5, 6, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 23, 24, 25, 26]
    assert S.STYLE100.joint_indices(m).tolist() == expected
    assert S.STYLE100.contact_indices(m).tolist() == [22, 27]
    assert S.STYLE100.phase_indices(m).tolist() == [17, 12, 26, 21]


@pytest.mark.parametrize("name", list(GROUPS))
def test_builtin_parents_agree_with_the_file_hierarchy(shared_data, name):
    sk = BY_NAME[name]
    m = read_bvh(files_of(shared_data, name)[0], scale=sk.bvh_scale)
    assert S.parents_from_motion(m, sk.joints) == sk.parents
    assert detect_skeleton(m) is sk
    # phase bones and hips are exported joints, so features and phases see the same bones
    assert set(sk.phase_bones) <= set(sk.joints) and sk.hips == sk.joints[0]


def test_bandai_and_cmu_sizes():
    assert S.CMU.n_joints == 31 and S.STYLE100.n_joints == 25
    assert S.BANDAI.n_joints == 21  # the 22 channel joints minus the floor marker joint_Root


def test_skeleton_validation_errors():
    base = dict(name="t", joints=("A", "B"), parents=(-1, 0), hips="A",
                phase_bones=("B", "B", "B", "B"), contact_bones=("B", "B"))
    S.Skeleton(**base)
    for change, msg in [(dict(parents=(-1,)), "parents"), (dict(parents=(-1, 1)), "parent"),
                        (dict(parents=(0, -1)), "parent"), (dict(facing_axis=(0, 0, 2)), "unit"),
                        (dict(phase_bones=("B",) * 3), "phase_bones"), (dict(joints=("A", "A")), "duplicate"),
                        (dict(bvh_scale=0.0), "bvh_scale")]:
        with pytest.raises(ValueError, match=msg):
            S.Skeleton(**{**base, **change})


def _tiny_motion(names, hips_rot, hips_pos):
    J = len(names)
    rot = np.tile(np.eye(3), (len(hips_rot), J, 1, 1))
    rot[:, 0] = hips_rot
    trans = np.zeros((len(hips_rot), J, 3))
    trans[:, 0] = hips_pos
    trans[:, 1:, 1] = -0.1
    return Motion(list(names), [-1] + list(range(J - 1)), np.zeros((J, 3)), [()] * J, rot, trans, 1 / 60,
                  "tiny")


def test_detect_skeleton_error_lists_candidates():
    m = _tiny_motion(["Pelvis", "Foot"], np.eye(3)[None], [[0, 1, 0]])
    with pytest.raises(ValueError) as err:
        detect_skeleton(m)
    for sk in S.BUILTIN_SKELETONS:
        assert sk.name in str(err.value)
    with pytest.raises(KeyError, match="Hips"):
        S.STYLE100.joint_indices(m)


def test_root_transforms_closed_form():
    # Hips turned 30 deg about y and pitched 20 deg forward: the root faces (sin 30, 0, cos 30).
    a = np.radians([[30.0, 20.0, 0.0], [-120.0, -10.0, 5.0]])
    R = euler_to_matrix(a, "YXZ")
    m = _tiny_motion(["P", "Q"], R, [[1.0, 0.9, 2.0], [-3.0, 1.1, 0.5]])
    sk = S.Skeleton("tiny", ("P", "Q"), (-1, 0), "P", ("Q",) * 4, ("Q", "Q"))
    pos, rot = S.root_transforms(m, sk)
    np.testing.assert_allclose(pos, [[1, 0, 2], [-3, 0, 0.5]], atol=1e-12)
    for k, yaw in enumerate(np.radians([30.0, -120.0])):
        c, s = np.cos(yaw), np.sin(yaw)
        np.testing.assert_allclose(rot[k], [[c, 0, s], [0, 1, 0], [-s, 0, c]], atol=1e-12)
    np.testing.assert_allclose(S.facing_directions(m, sk), rot[:, :, 2])
    # another facing axis: hips-local +x
    side = S.Skeleton("side", ("P", "Q"), (-1, 0), "P", ("Q",) * 4, ("Q", "Q"), facing_axis=(1, 0, 0))
    m0 = _tiny_motion(["P", "Q"], np.eye(3)[None], [[0, 1, 0]])
    np.testing.assert_allclose(S.root_transforms(m0, side)[1][0, :, 2], [1, 0, 0], atol=1e-12)


# ------------------------------------------------------------------ real data

@pytest.mark.parametrize("name", list(GROUPS))
def test_units_hips_height_and_feet_on_floor(shared_data, name):
    sk = BY_NAME[name]
    for f in files_of(shared_data, name):
        info = summary(str(f), sk.bvh_scale)
        assert info["skeleton"] == name, f.name
        assert 0.75 < info["hips_y"] < 1.1, (f.name, info)
        assert -0.05 < info["lowest_sensor"] < 0.1, (f.name, info)


# The 100STYLE sample has only 3 frames at the very start of a take (the hips barely move), too
# little to tell a direction of travel; its +Z facing is the original's (docs/original-code.md §5).
@pytest.mark.parametrize("name", ["bandai", "cmu", "cmu-mb"])
def test_root_facing_agrees_with_direction_of_travel(shared_data, name):
    sk = BY_NAME[name]
    checked = 0
    for f in files_of(shared_data, name):
        info = summary(str(f), sk.bvh_scale)
        if info["moving"] < 2:
            continue
        checked += 1
        if "walk-back" in f.name:       # walking backwards: travel opposes the facing
            assert info["mean_cos"] < -0.8, (f.name, info)
        else:
            assert info["mean_cos"] > 0.8, (f.name, info)
    assert checked > 0


def test_builtin_skeleton_by_name():
    from minifilm.motion.skeletons import BUILTIN_SKELETONS, builtin_skeleton
    for s in BUILTIN_SKELETONS:
        assert builtin_skeleton(s.name) is s
    with pytest.raises(ValueError, match=r"unknown skeleton 'nope'.*'100style'"):
        builtin_skeleton("nope")
