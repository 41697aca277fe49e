"""Toes kept out of the floor in swing (minifilm/body/clearance.py): the 100STYLE foot, twice as long as
Bandai's, sank its toe tip 5-7 cm below the floor just after toe-off."""
import numpy as np

from minifilm.evaluation.retargeting import contact_agreement
from minifilm.body import load_rig, read_source, retarget_motion
from minifilm.body.clearance import away_from, needed_lift, turn_up, upper_envelope


def test_upper_envelope_is_never_below_the_series_and_has_no_jumps():
    rng = np.random.default_rng(0)
    x = np.maximum(rng.normal(size=200), 0.0) * (rng.random(200) < 0.2)
    e = upper_envelope(x, 3)
    assert np.all(e >= x - 1e-12)
    # a spike of height 1 is spread: no frame-to-frame step more than half of it
    spike = np.zeros(30)
    spike[15] = 1.0
    assert np.max(np.abs(np.diff(upper_envelope(spike, 3)))) < 0.5


def test_away_from_is_zero_on_contacts_and_rises_to_one():
    c = np.zeros(20)
    c[5:8] = 1
    w = away_from(c, 2)
    assert np.all(w[5:8] == 0.0)
    assert w[8] < w[9] < w[10] <= 1.0 and w[11] == 1.0 and w[0] == 1.0
    assert np.all(away_from(np.zeros(5), 2) == 1.0)


def test_turning_a_foot_up_by_the_needed_lift_puts_its_tip_on_the_floor():
    # an ankle 10 cm up, the tip 24 cm away pointing 45 degrees down: 7 cm under the floor
    F = 3
    P = np.zeros((F, 2, 3))
    P[:, 0, 1] = 0.10
    P[:, 1] = P[:, 0] + 0.24 * np.array([0.0, -np.sqrt(0.5), np.sqrt(0.5)])
    R = np.broadcast_to(np.eye(3), (F, 2, 3, 3)).copy()
    floor = np.array([0.0, -0.01, -0.2])
    lift = needed_lift(P[:, 0], P[:, 1], floor)
    assert lift[2] == 0.0 and np.all(lift[:2] > 0)
    turn_up(P, R, 0, 1, [1], lift)
    np.testing.assert_allclose(P[:2, 1, 1], floor[:2], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(P[:, 1] - P[:, 0], axis=-1), 0.24)      # rigid
    np.testing.assert_allclose(P[:, 1, 0], 0.0, atol=1e-12)                           # same heading


def test_bandai_walk_on_100style_keeps_its_toes_out_of_the_floor(shared_data):
    """Before: the lowest tip 6.7 cm under the floor, a tip more than 1 cm under it on 42 % of
    frames; the source's own tips never went more than 0.6 cm under their floor."""
    style = load_rig("100style")
    m, roles = read_source(shared_data / "bvh" / "bandai1" / "dataset-1_walk_proud_001.bvh")
    out = retarget_motion(m, style, roles)
    P, _ = out.world()
    tips = P[:, [out.names.index(style.roles.limb(s).sensor) for s in ("left", "right")], 1].min(axis=1)
    assert tips.min() > -0.02, tips.min()
    assert np.mean(tips < -0.01) < 0.05, np.mean(tips < -0.01)
    assert contact_agreement(m, roles, out, style.roles) >= 0.95


def test_a_shorter_target_foot_is_not_turned(shared_data):
    """Only a target foot reaching further (in leg lengths) than the source's is turned: the
    100STYLE -> Bandai pass of a round trip is left as the planting put it."""
    import minifilm.body.retarget_clip as clip
    bandai, style = load_rig("bandai"), load_rig("100style")
    m, roles = read_source(shared_data / "bvh" / "bandai1" / "dataset-1_walk_proud_001.bvh")
    there = retarget_motion(m, style, roles)
    calls = []
    real = clip.clear_floor_keeping_contacts
    clip.clear_floor_keeping_contacts = lambda P, R, *a, **k: calls.append(a) or (P, R)
    try:
        retarget_motion(there, bandai, style.roles)
        assert not calls
        retarget_motion(m, style, roles)
        assert calls
    finally:
        clip.clear_floor_keeping_contacts = real
