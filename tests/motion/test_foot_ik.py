"""Two-bone leg IK and foot locking (minifilm.motion.foot_ik)."""
import numpy as np

from minifilm.motion.foot_ik import FootLocker, contact_weight, two_bone_ik
from minifilm.motion.measures import foot_sliding


def leg(n=50, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, 3))
    b = a + np.array([0.0, -0.42, 0.15]) + rng.normal(scale=0.02, size=(n, 3))   # a bent knee
    c = b + np.array([0.0, -0.42, -0.15]) + rng.normal(scale=0.02, size=(n, 3))
    return a, b, c, rng


def test_two_bone_ik_reaches_reachable_targets_and_keeps_lengths():
    a, b, c, rng = leg()
    target = a + 0.92 * (c - a) + rng.normal(scale=0.03, size=c.shape)
    reach = np.linalg.norm(b - a, axis=1) + np.linalg.norm(c - b, axis=1)
    assert np.all(np.linalg.norm(target - a, axis=1) < reach - 1e-3)  # all reachable
    b2, c2 = two_bone_ik(a, b, c, target)
    np.testing.assert_allclose(c2, target, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(b2 - a, axis=1), np.linalg.norm(b - a, axis=1), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(c2 - b2, axis=1), np.linalg.norm(c - b, axis=1), atol=1e-9)
    # the knee stays on the side it was bent to
    axis = target - a
    side_before = np.cross(axis, b - a)
    side_after = np.cross(axis, b2 - a)
    assert np.all(np.sum(side_before * side_after, axis=1) > 0)
    # no change when the target is where the end already is
    b3, c3 = two_bone_ik(a, b, c, c)
    np.testing.assert_allclose(b3, b, atol=1e-9)
    np.testing.assert_allclose(c3, c, atol=1e-9)


def test_two_bone_ik_unreachable_target_straightens_towards_it():
    a = np.zeros((1, 3)); b = np.array([[0, -0.5, 0.1]]); c = np.array([[0, -1.0, 0.0]])
    l = np.linalg.norm(b - a) + np.linalg.norm(c - b)
    b2, c2 = two_bone_ik(a, b, c, np.array([[0, -5.0, 0]]))
    np.testing.assert_allclose(c2, [[0, -(l - 1e-4), 0]], atol=1e-9)


def test_contact_weight_ends():
    np.testing.assert_allclose(contact_weight([0.0, 1.0, -1.0, 2.0]), [0, 1, 0, 1])
    w = contact_weight(np.linspace(0, 1, 11))
    assert np.all(np.diff(w) >= 0)


def test_foot_locker_pins_toes_in_contact_and_frees_them_otherwise():
    # 1 character, joints: 0 hips, then (hip, knee, ankle, toe) per leg [right, left]
    base = np.array([[0, 1.0, 0], [-0.1, 0.95, 0], [-0.1, 0.52, 0.12], [-0.1, 0.08, 0], [-0.1, 0.02, 0.15],
                     [0.1, 0.95, 0], [0.1, 0.52, 0.12], [0.1, 0.08, 0], [0.1, 0.02, 0.15]])
    locker = FootLocker([[1, 2, 3, 4], [5, 6, 7, 8]])
    frames = []
    for k in range(30):   # the whole body glides forward 3 mm per frame (sliding feet)
        P = (base + [0, 0, 0.003 * k])[None]
        frames.append(locker.apply(P, np.array([[1.0, 0.0]]))[0])
    frames = np.array(frames)
    right_toe, left_toe = frames[:, 4], frames[:, 8]
    np.testing.assert_allclose(right_toe, np.broadcast_to(base[4], right_toe.shape), atol=1e-6)  # pinned
    np.testing.assert_allclose(left_toe, base[8] + np.outer(0.003 * np.arange(30), [0, 0, 1]), atol=1e-12)  # free
    thigh = np.linalg.norm(frames[:, 2] - frames[:, 1], axis=1)
    np.testing.assert_allclose(thigh, np.linalg.norm(base[2] - base[1]), atol=1e-9)
    contacts = np.tile([1.0, 0.0], (30, 1))
    assert foot_sliding(frames, contacts, [4, 8], fps=60) < 1e-4
    free = base[None] + np.outer(0.003 * np.arange(30), [0, 0, 1])[:, None]
    np.testing.assert_allclose(foot_sliding(free, contacts, [4, 8], fps=60), 0.18, atol=1e-9)  # 3 mm/frame
