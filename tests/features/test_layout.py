"""FeatureLayout (minifilm/features/layout.py): sizes and column indices of x, z, p and the clip.

Expected numbers come from the paper (x 348, z 342, clip 240 x 300 for 100STYLE) and from
docs/original-code.md §6-§7 (joint j at 48 + 12 j in x, positions at 24 + 12 j in z, phases at
324..331, updates 332..339, contacts 340..341).
"""
import json

import numpy as np
import pytest

from minifilm.features.compute import FeatureLayout as ReExported
from minifilm.features.layout import TRAJECTORY_SECONDS, FeatureLayout

PARENTS_100STYLE = (-1, 0, 1, 2, 3, 4, 5, 4, 7, 8, 9, 10, 4, 12, 13, 14, 15, 0, 17, 18, 19, 0, 21, 22, 23)
NAMES = tuple(f"joint{j}" for j in range(25))


@pytest.fixture
def style100():
    return FeatureLayout(25, PARENTS_100STYLE, NAMES)


def test_sizes_for_100style(style100):
    L = style100
    assert (L.x_dim, L.z_dim, L.clip_dim, L.phase_dim) == (348, 342, 300, 8)
    assert ReExported is FeatureLayout


def test_slices_match_the_original_layout(style100):
    L = style100
    assert (L.x_trajectory, L.x_joints) == (slice(0, 48), slice(48, 348))
    assert (L.z_trajectory, L.z_root_delta, L.z_joints) == (slice(0, 24), slice(0, 4), slice(24, 324))
    assert (L.z_phases, L.z_phase_updates, L.z_contacts) == (slice(324, 332), slice(332, 340), slice(340, 342))


def test_joint_columns(style100):
    L = style100
    j = np.arange(25)[:, None]
    np.testing.assert_array_equal(L.joint_columns("x", "position"), 48 + 12 * j + [0, 1, 2])
    np.testing.assert_array_equal(L.joint_columns("x", "forward"), 48 + 12 * j + [3, 4, 5])
    np.testing.assert_array_equal(L.joint_columns("x", "up"), 48 + 12 * j + [6, 7, 8])
    np.testing.assert_array_equal(L.joint_columns("x", "velocity"), 48 + 12 * j + [9, 10, 11])
    np.testing.assert_array_equal(L.joint_columns("z", "position"), 24 + 12 * j + [0, 1, 2])  # Bll.py
    np.testing.assert_array_equal(L.joint_columns("clip", "velocity"), 12 * j + [9, 10, 11])
    # every x column belongs to exactly one (trajectory sample or joint field)
    used = np.concatenate([L.joint_columns("x", f).ravel() for f in ("position", "forward", "up", "velocity")]
                          + [L.trajectory_columns("x", s) for s in range(12)])
    assert sorted(used.tolist()) == list(range(348))
    assert L.trajectory_columns("x", 6).tolist() == [24, 25, 26, 27]
    assert L.trajectory_columns("z", 6).tolist() == [0, 1, 2, 3]
    with pytest.raises(ValueError, match="z has samples 6..11"):
        L.trajectory_columns("z", 5)
    with pytest.raises(ValueError, match="field must be one of"):
        L.joint_columns("x", "rotation")
    with pytest.raises(ValueError, match="which must be"):
        L.joint_columns("y", "position")


def test_other_skeleton_sizes():
    L = FeatureLayout(21, (-1,) + tuple(range(20)), tuple(f"j{i}" for i in range(21)))   # Bandai
    assert (L.x_dim, L.z_dim, L.clip_dim) == (48 + 252, 24 + 252 + 18, 252)
    assert L.z_contacts == slice(L.z_dim - 2, L.z_dim)


@pytest.mark.parametrize("which, size", [("x", 348), ("z", 342), ("p", 8), ("clip", 300)])
def test_describe_covers_every_column(style100, which, size):
    cols = style100.describe(which)
    assert [c.index for c in cols] == list(range(size))
    assert all(len(c) == 5 and all(isinstance(v, str) for v in c[1:]) for c in cols)


def test_describe_content(style100):
    L = style100
    x = L.describe("x")
    assert x[0].joint == "root" and "-1.000 s" in x[0].quantity and x[0].units == "m"
    assert "direction z" in x[27].quantity and x[27].units == "unit vector"
    for f, unit in (("position", "m"), ("forward", "unit vector"), ("velocity", "m/s")):
        for j, cols in enumerate(L.joint_columns("x", f)):
            for axis, c in zip("xyz", cols):
                assert x[c].joint == NAMES[j] and x[c].units == unit
                assert f in x[c].quantity and f" {axis}," in x[c].quantity
                assert "current" in x[c].frame
    z = L.describe("z")
    assert "next frame" in z[0].quantity and "current frame" in z[0].frame
    assert z[340].quantity.startswith("right foot contact") and z[341].quantity.startswith("left foot")
    assert z[324].joint == "left hand" and "sin" in z[324].quantity and "cos" in z[325].quantity
    assert z[330].joint == "right foot" and "update" in z[332].quantity
    clip = L.describe("clip")
    assert "own" in clip[0].frame
    with pytest.raises(ValueError, match="which must be"):
        L.describe("q")


def test_round_trip_through_json(style100):
    d = json.loads(json.dumps(style100.to_dict()))
    assert FeatureLayout.from_dict(d) == style100
    assert tuple(d["trajectory_seconds"]) == TRAJECTORY_SECONDS


def test_for_skeleton():
    from minifilm.motion.skeletons import STYLE100

    L = FeatureLayout.for_skeleton(STYLE100)
    assert L.parents == PARENTS_100STYLE and L.joint_names[11] == "RightWristSite" and L.x_dim == 348


def test_bad_layouts_are_named():
    with pytest.raises(ValueError, match="3 joints but 2 parents"):
        FeatureLayout(3, (-1, 0), ("a", "b", "c"))
    with pytest.raises(ValueError, match=r"joint 1 \(b\) has parent 1"):
        FeatureLayout(2, (-1, 1), ("a", "b"))
    with pytest.raises(ValueError, match="12 increasing times"):
        FeatureLayout(1, (-1,), ("a",), trajectory_seconds=(0.0,) * 12)


def test_generic_layout_and_mismatch():
    from minifilm.features.compute import frame_features_from_arrays

    g = FeatureLayout.generic(25)
    assert (g.x_dim, g.z_dim) == (348, 342) and g.parents[:3] == (-1, 0, 1)
    F = 5
    eye = np.broadcast_to(np.eye(3), (F, 3, 3, 3))
    with pytest.raises(ValueError, match="the layout has 25 joints, the arrays 3"):
        frame_features_from_arrays(np.zeros((F, 3, 3)), eye, np.zeros((F, 3, 3)), np.zeros((F, 3)),
                                   eye[:, 0], np.zeros((F, 8)), np.zeros((F, 2)), 30, layout=g)
