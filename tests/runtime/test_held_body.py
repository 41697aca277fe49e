"""The geometry of a held body (minifilm/runtime/held_body.py): legs found, feet kept, root kept."""
import numpy as np
import pytest

from minifilm.motion.skeletons import STYLE100
from minifilm.runtime.held_body import hold_root, leg_chains, plant_feet

# a body with a pelvis (0) and two legs: hip, knee, ankle, toe; [right, left]
NAMES = ("Hips", "RightHip", "RightKnee", "RightAnkle", "RightToe", "LeftHip", "LeftKnee", "LeftAnkle", "LeftToe")
PARENTS = (-1, 0, 1, 2, 3, 0, 5, 6, 7)
CHAINS = np.array([[1, 2, 3, 4], [5, 6, 7, 8]])


def standing_pose(hip_height=0.9):
    """(1, 9, 3): legs bent a little, feet flat on the floor, toes forward."""
    p = np.zeros((9, 3))
    p[0] = [0, hip_height, 0]
    for side, (hip, knee, ankle, toe) in zip((-0.1, 0.1), CHAINS):
        p[hip] = [side, hip_height, 0]
        p[knee] = [side, hip_height - 0.42, 0.03]
        p[ankle] = [side, 0.08, 0]
        p[toe] = [side, 0.02, 0.15]
    return p[None]


def bone_lengths(p):
    return np.array([[np.linalg.norm(p[0, c[i + 1]] - p[0, c[i]]) for i in range(3)] for c in CHAINS])


def test_the_legs_are_found_from_the_toes_and_their_parents():
    assert leg_chains(NAMES, PARENTS).tolist() == CHAINS.tolist()
    chains = leg_chains(STYLE100.joints, STYLE100.parents)
    names = [[STYLE100.joints[j] for j in c] for c in chains]
    assert names == [["RightHip", "RightKnee", "RightAnkle", "RightToe"], ["LeftHip", "LeftKnee", "LeftAnkle", "LeftToe"]]
    assert leg_chains(("Hips", "Spine"), (-1, 0)) is None                 # no toes: nothing to hold


def test_held_feet_stay_put_while_the_body_moves_and_the_legs_keep_their_lengths():
    p0 = standing_pose()
    _, held, _ = plant_feet(p0, None, np.ones(1), CHAINS)
    moved = p0.copy()
    moved[0, :, 0] += 0.05                                   # the network sways the whole body 5 cm
    moved[0, [3, 4, 7, 8], 2] += 0.2                         # and slides both feet forward
    out, held2, _ = plant_feet(moved, held, np.ones(1), CHAINS)
    np.testing.assert_allclose(held2, held)
    np.testing.assert_allclose(out[0, [3, 7]], p0[0, [3, 7]], atol=1e-9)       # ankles where they were
    np.testing.assert_allclose(out[0, [4, 8]], p0[0, [4, 8]], atol=1e-9)       # toes too
    np.testing.assert_allclose(bone_lengths(out)[:, :2], bone_lengths(moved)[:, :2], atol=1e-9)
    np.testing.assert_allclose(out[0, 0], moved[0, 0])                          # the upper body is the network's


def test_free_feet_follow_the_pose_and_a_partial_hold_lags_behind():
    p0 = standing_pose()
    _, held, _ = plant_feet(p0, None, np.ones(1), CHAINS)
    moved = p0.copy()
    moved[0, 1:, 2] += 0.1                                   # the legs step 10 cm forward
    free, held_free, _ = plant_feet(moved, held, np.zeros(1), CHAINS)
    np.testing.assert_allclose(free, moved, atol=1e-9)
    half, held_half, _ = plant_feet(moved, held, np.full(1, 0.5), CHAINS)
    np.testing.assert_allclose(held_half[0, :, :, 2] - held[0, :, :, 2], 0.05)


def test_hips_rising_out_of_reach_lower_the_body_instead_of_dragging_the_feet():
    p0 = standing_pose()
    _, held, _ = plant_feet(p0, None, np.ones(1), CHAINS)
    up = p0.copy()
    up[0, :, 1] += 0.2                                       # a hop: everything 20 cm higher
    out, _, _ = plant_feet(up, held, np.ones(1), CHAINS)
    np.testing.assert_allclose(out[0, [3, 4, 7, 8]], p0[0, [3, 4, 7, 8]], atol=1e-6)
    assert out[0, 0, 1] < up[0, 0, 1] - 0.1                  # the pelvis came down
    np.testing.assert_allclose(bone_lengths(out)[:, :2], bone_lengths(up)[:, :2], atol=1e-9)


def test_a_raised_foot_is_put_down_to_the_other_at_the_given_speed():
    p = standing_pose()
    p[0, [3, 4], 1] += 0.2                                   # right foot 20 cm up (toe at 0.22 m)
    _, held, _ = plant_feet(p, None, np.ones(1), CHAINS)
    lowering = None
    for _ in range(10):
        _, held, lowering = plant_feet(p, held, np.ones(1), CHAINS, np.full(1, 0.01), 0.08, lowering)
    assert held[0, 0, 1, 1] == pytest.approx(0.22 - 0.10)   # 10 frames of 1 cm
    assert lowering.tolist() == [[True, False]]
    for _ in range(30):
        _, held, lowering = plant_feet(p, held, np.ones(1), CHAINS, np.full(1, 0.01), 0.08, lowering)
    assert held[0, 0, 1, 1] == pytest.approx(0.02)           # down to the left toe, no further
    assert held[0, 1, 1, 1] == pytest.approx(0.02)           # the left foot was on the floor: untouched


def test_the_root_keeps_what_is_asked_and_the_body_goes_with_it():
    rng = np.random.default_rng(0)
    root, facing = np.array([[1.0, 2.0]]), np.array([[0.0, 1.0]])
    turn = np.radians(10)
    new_pos = root[:, None] + np.array([[[0.02, 0.03], [0.1, 0.3], [0.2, 0.6]]])
    new_dir = np.repeat(np.array([[[np.sin(turn), np.cos(turn)]]]), 3, axis=1)
    joints = np.concatenate([rng.normal(size=(1, 5, 3)) * 0.3, np.zeros((1, 1, 3))], axis=1)
    joints[0, :, 0] += new_pos[0, 0, 0]
    joints[0, :, 2] += new_pos[0, 0, 1]
    vel = rng.normal(size=(1, 6, 3))
    same = hold_root(root, facing, new_pos, new_dir, joints, [vel], np.ones(1), np.ones(1))
    assert same[0] is new_pos and same[1] is new_dir and same[2] is joints and same[3][0] is vel   # the paper's loop
    pos, direction, body, (v,) = hold_root(root, facing, new_pos, new_dir, joints, [vel], np.zeros(1), np.zeros(1))
    np.testing.assert_allclose(pos[0, 0], root[0])                     # no step
    np.testing.assert_allclose(direction[0, 0], facing[0], atol=1e-12)  # no turn
    # the body moved back with its root and turned back about it: the same pose relative to the root
    rel_before = joints[0] - np.r_[new_pos[0, 0, 0], 0, new_pos[0, 0, 1]]
    rel_after = body[0] - np.r_[pos[0, 0, 0], 0, pos[0, 0, 1]]
    c, s = np.cos(turn), np.sin(turn)
    unturn = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])                # heading -10 degrees
    np.testing.assert_allclose(rel_after, rel_before @ unturn.T, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(v, axis=-1), np.linalg.norm(vel, axis=-1))


def test_a_character_s_hold_does_not_depend_on_its_batch_mates():
    """A walks (not held, a foot up: it steps) while B already stands held, then A stops: A's held
    body is the one it gets alone, where nothing is planted until its own hold begins. (A's raised
    foot while it walked once marked that foot as 'on its way down' for its later hold.)"""
    walking, stopped = standing_pose(), standing_pose()
    walking[0, [3, 4], 1] += 0.05                             # mid-step: right toe at 0.07 m
    walking[0, [7, 8], 1] += 0.2                              # left toe 22 cm up
    stopped[0, [3, 4], 1] += 0.03                             # comes to rest with a toe just off the floor
    lower = 0.01
    # alone: no hold while it walks; then its hold starts fresh
    alone, held, lowering = [], None, None
    for _ in range(5):
        p, held, lowering = plant_feet(stopped, held, np.ones(1), CHAINS, np.full(1, lower), 0.08, lowering)
        alone.append(p[0])
    # beside B, held from the start: A's rows go through plant_feet with weight 0 while it walks
    B = standing_pose()
    held, lowering = None, None
    for _ in range(4):
        _, held, lowering = plant_feet(np.concatenate([walking, B]), held, np.array([0.0, 1.0]), CHAINS,
                                       np.array([0.0, lower]), 0.08, lowering)
    together, fresh = [], np.array([True, False])            # A's hold begins (as StandStill.plant says)
    for _ in range(5):
        p, held, lowering = plant_feet(np.concatenate([stopped, B]), held, np.array([1.0, 1.0]), CHAINS,
                                       np.full(2, lower), 0.08, lowering, fresh)
        together.append(p[0])
        fresh = np.array([False, False])
    np.testing.assert_allclose(np.array(together), np.array(alone), atol=1e-12)
