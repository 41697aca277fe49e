"""Foot contacts (Sec. 4.1.2, docs/original-code.md §2) on hand-built sensor tracks."""
import numpy as np
import pytest

from minifilm.phases.contacts import estimate_floor_height, foot_contacts, majority_filter


def test_majority_filter_by_hand():
    # half width 1: windows [k-1, k+1] clamped to the sequence.
    raw = np.array([1, 0, 1, 1, 0, 0, 1, 0])
    # k=0: window [1,0] -> tie -> raw 1; k=1: [1,0,1] -> 1; k=2: [0,1,1] -> 1; k=3: [1,1,0] -> 1;
    # k=4: [1,0,0] -> 0; k=5: [0,0,1] -> 0; k=6: [0,1,0] -> 0; k=7: [1,0] tie -> raw 0.
    expected = [1, 1, 1, 1, 0, 0, 0, 0]
    np.testing.assert_array_equal(majority_filter(raw, 1), expected)


def test_majority_filter_tie_keeps_raw_and_works_per_column():
    raw = np.array([[0, 1], [1, 0]])  # a 2-frame window at half width 1 is always a tie
    np.testing.assert_array_equal(majority_filter(raw, 1), raw)
    np.testing.assert_array_equal(majority_filter(raw, 0), raw)


def walk_sensors(fps, seconds=6.0, floor=0.0, period=1.0, stance=0.6, stride=1.4):
    """Two toe tips walking along +x: stance = still on the floor, swing = lifted and moving.

    Returns sensor positions (F, 2, 3) [right, left] and the true stance mask (F, 2). The left
    foot is half a period behind the right one.
    """
    t = np.arange(int(round(seconds * fps))) / fps
    pos = np.zeros((t.size, 2, 3))
    truth = np.zeros((t.size, 2), bool)
    for foot, shift in ((0, 0.0), (1, 0.5)):
        u = np.mod(t / period - shift, 1.0)
        cycle = np.floor(t / period - shift)
        swing = np.clip((u - stance) / (1 - stance), 0, 1)  # 0 during stance, 0..1 during swing
        # Smooth swing profile: the foot leaves and lands with zero speed.
        s = 0.5 - 0.5 * np.cos(np.pi * swing)
        pos[:, foot, 0] = stride * (cycle + s)
        pos[:, foot, 1] = floor + 0.12 * np.sin(np.pi * swing)
        pos[:, foot, 2] = 0.1 * (1 - 2 * foot)
        truth[:, foot] = u < stance
    return pos, truth


@pytest.mark.parametrize("fps", [30, 60, 120])
def test_walk_contacts_match_stance(fps):
    pos, truth = walk_sensors(fps)
    c = foot_contacts(pos, fps, floor_height=0.0)
    assert c.shape == truth.shape and set(np.unique(c)) <= {0.0, 1.0}
    # Around touch-down and lift-off the foot is slow and low for a few frames, so allow a
    # disagreement of at most 0.06 s per transition (2 transitions per 1 s cycle).
    disagree = np.mean(c != truth)
    assert disagree < 2 * 0.06
    # Mid-stance and mid-swing are unambiguous.
    t = np.arange(len(c)) / fps
    for foot, shift in ((0, 0.0), (1, 0.5)):
        u = np.mod(t - shift, 1.0)
        assert np.all(c[(np.abs(u - 0.3) < 0.1), foot] == 1)
        assert np.all(c[(np.abs(u - 0.8) < 0.1), foot] == 0)


def test_frame_rate_independent():
    a = foot_contacts(walk_sensors(120)[0], 120, floor_height=0.0)
    b = foot_contacts(walk_sensors(30)[0], 30, floor_height=0.0)
    # Compare at the 30 fps instants: same motion, same contacts up to a frame or two per transition.
    assert np.mean(a[::4] != b) < 0.05


def test_floor_height_is_estimated():
    pos, _ = walk_sensors(60, floor=0.0)
    lifted = pos.copy()
    lifted[..., 1] += 0.07  # this dataset's floor is 7 cm up
    base = foot_contacts(pos, 60, floor_height=0.0)
    np.testing.assert_array_equal(foot_contacts(lifted, 60), base)
    np.testing.assert_array_equal(foot_contacts(lifted, 60, floor_height=0.07), base)
    assert foot_contacts(lifted, 60, floor_height=0.0).sum() == 0  # 7 cm above y = 0: never in contact
    assert estimate_floor_height(lifted[..., 1]) == pytest.approx(0.07, abs=1e-9)


def test_speed_threshold_and_sinking_foot():
    fps = 60
    n = 120
    pos = np.zeros((n, 2, 3))
    pos[:, 0, 0] = 0.10 * np.arange(n) / fps   # right foot slides at 0.10 m/s: contact
    pos[:, 1, 0] = 0.20 * np.arange(n) / fps   # left foot slides at 0.20 m/s: no contact
    c = foot_contacts(pos, fps, floor_height=0.0)
    assert np.all(c[:, 0] == 1) and np.all(c[:, 1] == 0)
    sunk = np.zeros((n, 2, 3))
    sunk[:, 0, 1] = -0.02  # 2 cm below the floor: not in contact (sphere-against-plane test)
    c = foot_contacts(sunk, fps, floor_height=0.0)
    assert np.all(c[:, 0] == 0) and np.all(c[:, 1] == 1)


def test_bad_input_names_the_problem():
    with pytest.raises(ValueError, match=r"\(F, 2, 3\)"):
        foot_contacts(np.zeros((10, 3)), 60)
    with pytest.raises(ValueError, match="fps"):
        foot_contacts(np.zeros((10, 2, 3)), 0)


def test_floor_estimate_with_feet_resting_at_different_heights():
    # Retargeted data: the right toe rests 1 cm below the left one. The floor from the slow samples
    # lies between them, so both feet find it; the lowest percentile would miss the left foot.
    pos, truth = walk_sensors(60)
    pos[:, 0, 1] -= 0.006
    pos[:, 1, 1] += 0.004
    c = foot_contacts(pos, 60)
    assert np.mean(c != truth) < 2 * 0.06
    speed = np.zeros(pos.shape[:2])
    speed[1:] = np.linalg.norm(np.diff(pos, axis=0), axis=-1) * 60
    floor = estimate_floor_height(pos[..., 1], speed)
    assert -0.006 < floor < 0.004
    assert estimate_floor_height(pos[..., 1]) == pytest.approx(-0.006, abs=1e-6)
