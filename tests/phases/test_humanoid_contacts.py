"""Foot contacts on every humanoid file, with the feet found by name or by structure alone."""
import numpy as np
import pytest

from humanoid_rigs import CMU_CONVERSION_FROM_MB, renamed_bvh, scrambled
from minifilm.body.read import read_in_metres
from minifilm.body.humanoid import HumanoidError, find_humanoid
from minifilm.phases.contacts import humanoid_contacts

LAYOUTS = ["bandai2/dataset-2_walk_normal_001.bvh", "bandai2/dataset-2_run_normal_001.bvh",
           "bvh/bandai1/dataset-1_walk_normal_001.bvh", "bvh/xia/neutral_01_000.bvh", "bvh/xia/angry_13_000.bvh",
           "bvh/cmu/08_01_trimmed.bvh"]


def _changes(c):
    return int(np.abs(np.diff(c, axis=0)).sum())


@pytest.mark.parametrize("rel", LAYOUTS)
def test_both_feet_touch_down_and_lift_off(shared_data, rel):
    m, h, _ = read_in_metres(shared_data / rel)
    contacts, sensors = humanoid_contacts(m, h)
    assert contacts.shape == (m.n_frames, 2)
    assert [m.names[j] for j in sensors] == [m.names[h.right_toe_tip], m.names[h.left_toe_tip]]
    share = contacts.mean(axis=0)
    assert np.all(share >= 0.1) and np.all(share <= 0.8), share        # a walk or run, not frozen or flying
    assert all(_changes(contacts[:, k]) >= 2 for k in range(2))        # at least one step per foot
    # the same from the structure alone
    s = scrambled(m)
    same, _ = humanoid_contacts(s, find_humanoid(s))
    np.testing.assert_array_equal(same, contacts)


def test_the_cmu_conversion_layout_gets_contacts(shared_data, tmp_path):
    path = renamed_bvh(shared_data / "bvh/cmu/08_01_trimmed.bvh", tmp_path / "c.bvh", CMU_CONVERSION_FROM_MB)
    m, h, _ = read_in_metres(path)
    original, _ = humanoid_contacts(*read_in_metres(shared_data / "bvh/cmu/08_01_trimmed.bvh")[:2])
    contacts, sensors = humanoid_contacts(m, h)
    assert [m.names[j] for j in sensors] == ["RightAnkleSite", "LeftAnkleSite"]
    np.testing.assert_array_equal(contacts, original)
    assert contacts.mean() > 0.1


def test_the_papers_thresholds_when_asked(shared_data):
    # 08_01's toe tips slide at about 0.2 m/s through a stance: the paper's 0.15 m/s finds nothing
    m, h, _ = read_in_metres(shared_data / "bvh/cmu/08_01_trimmed.bvh")
    paper, _ = humanoid_contacts(m, h, speed_threshold=0.15, height_threshold=0.01)
    assert paper.sum() == 0
    assert humanoid_contacts(m, h)[0].sum() > 0


def test_a_motion_without_a_humanoid_is_one_error():
    from humanoid_rigs import quadruped
    dog = quadruped()
    with pytest.raises(HumanoidError, match="on the floor like a foot"):
        humanoid_contacts(dog, find_humanoid(dog))
