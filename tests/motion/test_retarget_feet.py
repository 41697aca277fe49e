"""Planted feet of a retargeted clip (minifilm/body/feet.py, tips.py): contacts as the source's, planted
tips that stay put, and round trips that come back with the feet planted on both passes."""
import glob

import numpy as np
import pytest

from minifilm.evaluation.retargeting import bone_direction_errors, contact_agreement, round_trip_errors
from minifilm.phases.contacts import foot_contacts
from minifilm.body import load_rig, read_source, retarget_motion
from minifilm.body.tips import HEIGHT_BAND, band_heights, pin_targets, slide_correction
from minifilm.synthetic.generator import generate_style


# ----------------------------------------------------------------------------------------------
# the helpers
# ----------------------------------------------------------------------------------------------

def test_band_heights_change_a_tip_only_where_the_contact_test_would_disagree():
    own = np.array([0.030, 0.005, 0.004, 0.050, 0.020])
    own_speed = np.array([0.05, 0.05, 0.05, 0.05, 0.05])
    guide = np.array([0.002, 0.030, 0.004, 0.060, 0.001])
    guide_speed = np.array([0.05, 0.05, 0.50, 0.05, 0.05])
    h = band_heights(own, own_speed, guide, guide_speed)
    assert h[0] == guide[0]                         # the source's tip passes: the target takes its height
    assert h[1] == guide[1]                         # the source's tip is high, the target's would pass: up
    assert abs(h[2]) > HEIGHT_BAND                  # the source's tip is fast, in the band: lifted out of it
    assert h[3] == own[3]                           # neither passes: its own height
    assert h[4] == guide[4]
    # then the contact test says the same of both on every frame
    same = (own_speed <= 0.15) & (np.abs(h) <= HEIGHT_BAND) == (guide_speed <= 0.15) & (np.abs(guide) <= HEIGHT_BAND)
    assert np.all(same)


def test_slide_correction_keeps_a_sliding_planted_tip_put():
    fps, F = 60.0, 120
    tips = np.zeros((F, 1, 3))
    tips[:, 0, 0] = np.arange(F) * 0.03 / fps        # slides 3 cm/s along x the whole time
    contacts = np.zeros((F, 1))
    contacts[20:100] = 1
    moved = tips[:, 0] + slide_correction(tips, contacts, fps)
    inner = slice(30, 90)                            # the shift is smoothed over 0.1 s at the run's edges
    assert np.ptp(moved[inner, 0]) < 0.05 * np.ptp(tips[inner, 0, 0])
    assert np.allclose(moved[:, 1:], tips[:, 0, 1:])  # horizontal only, and never along z here


def test_pin_targets_hold_the_pin_and_step_no_faster_than_allowed():
    fps, F = 60.0, 60
    tip = np.zeros((F, 3))
    tip[:, 2] = np.linspace(0.0, 0.6, F)             # 0.6 m/s forwards
    contacts = np.zeros(F)
    contacts[20:30] = 1
    limit = np.full(F, np.nan)
    limit[30:33] = 0.001                             # the source's tip creeps at 6 cm/s for 3 frames after
    targets, w = pin_targets(tip, contacts, fps, 0.1, limit)
    assert np.allclose(targets[20:30, 2], tip[20:30, 2].mean()) and np.all(w[20:30] == 1)
    steps = np.abs(np.diff(targets[29:40, 2]))
    assert np.all(steps[:3] <= 0.001 + 1e-12) and np.allclose(steps[3:], tip[1, 2] - tip[0, 2])
    assert w[0] == 0 and w[-1] == 0


# ----------------------------------------------------------------------------------------------
# round trips with the feet planted on both passes, and the bone directions on Xia's files
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("rel", ["bvh/bandai1/dataset-1_walk_normal_001.bvh",        # knees 8.3 cm p95 before
                                 "bandai2/dataset-2_walk-turn-right_exhausted_009.bvh"])   # a turn on the spot
def test_bandai_round_trip_with_planted_feet_within_3cm(shared_data, rel):
    bandai, style = load_rig("bandai"), load_rig("100style")
    m, roles = read_source(shared_data / rel)
    there = retarget_motion(m, style, roles)
    back = retarget_motion(there, bandai, style.roles)
    for joint, d in round_trip_errors(m, roles, back, bandai.roles).items():
        assert np.percentile(d, 95) < 0.03, (joint, np.percentile(d, 95))
    assert contact_agreement(m, roles, there, style.roles) >= 0.95


def test_100style_round_trip_with_planted_feet_within_3cm():
    clip = generate_style("Neutral", "FW", 3.0, np.random.default_rng(1)).motion
    style, bandai = load_rig("100style"), load_rig("bandai")
    back = retarget_motion(retarget_motion(clip, bandai, style.roles), style, bandai.roles)
    for joint, d in round_trip_errors(clip, style.roles, back, style.roles).items():
        assert np.percentile(d, 95) < 0.03, (joint, np.percentile(d, 95))
    P, _ = back.world()
    assert np.all(foot_contacts(P[:, [back.names.index("RightToeSite"), back.names.index("LeftToeSite")]],
                                back.fps).sum(axis=0) > 0)   # the feet are still planted somewhere


def test_xia_thighs_and_shins_keep_the_source_directions(shared_data):
    """The worst Xia file's shin was 5.9 degrees off (median over frames) when the leg IK bent
    the knee to make the target's toe tip follow the source tip's height."""
    style = load_rig("100style")
    files = sorted(glob.glob(str(shared_data / "bvh" / "xia" / "*.bvh")))
    assert files
    for path in files:
        m, roles = read_source(path)
        errors = bone_direction_errors(m, roles, retarget_motion(m, style, roles), style.roles)
        for bone, e in errors.items():
            if "upleg-knee" in bone or "knee-ankle" in bone:
                assert np.median(e) < 1.0, (path, bone, np.median(e))


def test_a_clip_without_contacts_is_left_as_the_pose_transfer_put_it(shared_data):
    """CMU 08_01's toe sites slide through every stance, so it has no contacts; a single frame
    passing the contact test (voted away by its majority filter) once pulled a tip down 12 cm."""
    style = load_rig("100style")
    m, roles = read_source(shared_data / "bvh" / "cmu" / "08_01_trimmed.bvh")
    planted, _ = retarget_motion(m, style, roles).world()
    free, _ = retarget_motion(m, style, roles, plant=False).world()
    np.testing.assert_allclose(planted, free, atol=1e-9)
