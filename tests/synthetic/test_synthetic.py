"""Tests of the synthetic locomotion generator (minifilm/synthetic/generator.py).

Each style claims a property (a hopping foot that never lands, hands above the head, arms cycling
at another frequency than the legs, ...). These tests measure the claims on the generated motion
with the same contact and phase code users run (``contacts.foot_contacts``,
``phases.extract_local_phases``) or with independent few-line computations written here (forward
kinematics, PCA, FFT), never by comparing the generator with itself.
"""
import numpy as np
import pytest

from minifilm.phases.contacts import foot_contacts
from minifilm.synthetic.generator import (DEFAULT_GAITS, GAITS, STYLES, default_dataset, generate_style,
                                       skeleton_100style, write_dataset)

FPS = 60


def _fk(motion):
    """Independent forward kinematics: world positions (F, J, 3) and rotations (F, J, 3, 3)."""
    F, J = motion.n_frames, motion.n_joints
    pos, rot = np.zeros((F, J, 3)), np.zeros((F, J, 3, 3))
    for j, p in enumerate(motion.parents):
        if p < 0:
            pos[:, j], rot[:, j] = motion.translations[:, j], motion.rotations[:, j]
        else:
            rot[:, j] = rot[:, p] @ motion.rotations[:, j]
            pos[:, j] = pos[:, p] + np.einsum("fij,fj->fi", rot[:, p], motion.translations[:, j])
    return pos, rot


def _tips(motion):
    pos, _ = _fk(motion)
    return pos[:, [motion.index("RightToeSite"), motion.index("LeftToeSite")]]


def _contacts(motion):
    return foot_contacts(_tips(motion), motion.fps)


def _hips_local(motion, name):
    """(F, 3) position of joint ``name`` in the hips' frame, R_hips^T (p - p_hips)."""
    pos, rot = _fk(motion)
    rel = pos[:, motion.index(name)] - pos[:, 0]
    return np.einsum("fji,fj->fi", rot[:, 0], rel)


def _circ(a, b):
    """Circular distance in cycles, in [0, 0.5]."""
    return np.abs((np.asarray(a) - np.asarray(b) + 0.5) % 1.0 - 0.5)


@pytest.fixture(scope="module")
def clips():
    """Every style × gait, 4 s each (the generator is fast: well under a second for all)."""
    return {(c.style, c.gait): c for c in default_dataset(seed=7, seconds=4.0)}


# ---------------------------------------------------------------------------------------------
# The skeleton and the Motion container
# ---------------------------------------------------------------------------------------------

def test_skeleton_is_the_real_100style_one(shared_data):
    from minifilm.motion.bvh import read_bvh

    real = read_bvh(shared_data / "100style" / "Neutral_FR_first3frames.bvh")
    names, parents, offsets, channels = skeleton_100style()
    assert names == real.names
    np.testing.assert_array_equal(parents, real.parents)
    np.testing.assert_allclose(offsets, real.offsets, atol=1e-9)
    assert [tuple(c) for c in channels] == [tuple(c) for c in real.channels]


def test_right_side_is_negative_x_and_toes_point_forward():
    names, _, offsets, _ = skeleton_100style()
    for side, sign in (("Right", -1), ("Left", 1)):
        for joint in ("Hip", "Collar"):
            assert np.sign(offsets[names.index(side + joint)][0]) == sign
        assert offsets[names.index(side + "Toe")][2] > 0.1  # foot points along +z = forward


@pytest.mark.parametrize("gait", GAITS)
def test_motion_is_valid(clips, gait):
    for style in STYLES:
        m = clips[(style, gait)].motion
        F = int(round(4.0 * FPS))
        assert m.n_frames == F and m.n_joints == 28
        assert m.rotations.shape == (F, 28, 3, 3) and m.translations.shape == (F, 28, 3)
        assert m.frame_time == pytest.approx(1 / 60)
        assert np.isfinite(m.rotations).all() and np.isfinite(m.translations).all()
        R = m.rotations
        np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
        np.testing.assert_allclose(m.translations[:, 1:], np.broadcast_to(m.offsets[1:], (F, 27, 3)))
        for j, name in enumerate(m.names):
            if name.endswith("Site"):
                np.testing.assert_array_equal(R[:, j], np.broadcast_to(np.eye(3), (F, 3, 3)))
        c = clips[(style, gait)]
        assert c.true_phase.shape == (F, 4) and c.true_contacts.shape == (F, 2)
        assert ((c.true_phase >= 0) & (c.true_phase < 1)).all()
        assert set(np.unique(c.true_contacts)) <= {0.0, 1.0}


def test_bone_lengths_are_constant(clips):
    for key in [("Neutral", "FR"), ("Drunk", "TR"), ("LeftHop", "FW"), ("Crouched", "SW")]:
        m = clips[key].motion
        pos, _ = _fk(m)
        for j, p in enumerate(m.parents):
            if p >= 0:
                length = np.linalg.norm(pos[:, j] - pos[:, p], axis=1)
                np.testing.assert_allclose(length, np.linalg.norm(m.offsets[j]), atol=1e-9)


def test_world_matches_independent_fk(clips):
    m = clips[("Swimming", "TR")].motion
    pos, rot = m.world()
    mine_pos, mine_rot = _fk(m)
    np.testing.assert_allclose(pos, mine_pos, atol=1e-9)
    np.testing.assert_allclose(rot, mine_rot, atol=1e-9)


def test_deterministic_given_a_seed():
    a = generate_style("Drunk", "TR", 3.0, np.random.default_rng(5))
    b = generate_style("Drunk", "TR", 3.0, np.random.default_rng(5))
    c = generate_style("Drunk", "TR", 3.0, np.random.default_rng(6))
    np.testing.assert_array_equal(a.motion.rotations, b.motion.rotations)
    np.testing.assert_array_equal(a.motion.translations, b.motion.translations)
    np.testing.assert_array_equal(a.true_phase, b.true_phase)
    assert not np.allclose(a.motion.translations[:, 0], c.motion.translations[:, 0])
    # The data set seeds each clip from (seed, style, gait): a subset gives the same clips.
    full = {(x.style, x.gait): x for x in default_dataset(seed=3, seconds=2.0)}
    sub = default_dataset(seed=3, seconds=2.0, styles=["Limp"], gaits=["SW"])[0]
    np.testing.assert_array_equal(sub.motion.rotations, full[("Limp", "SW")].motion.rotations)


def test_errors_name_the_problem():
    with pytest.raises(ValueError, match="Moonwalk"):
        generate_style("Moonwalk", "FW", 1.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="XX"):
        generate_style("Neutral", "XX", 1.0, np.random.default_rng(0))


def test_other_frame_rates_give_the_same_motion_in_seconds():
    # Parameters are in seconds, so 30 fps gives the same speeds and step rates as 60 fps (the
    # random speed changes differ, as the noise is drawn per frame).
    for fps in (30, 120):
        c = generate_style("Neutral", "FW", 6.0, np.random.default_rng(2), fps=fps)
        assert c.motion.n_frames == 6 * fps and c.motion.frame_time == pytest.approx(1 / fps)
        hips = c.motion.translations[:, 0, [0, 2]]
        speed = np.linalg.norm(np.diff(hips, axis=0), axis=1).mean() * fps
        assert 0.8 < speed < 1.6, (fps, speed)
        contacts = foot_contacts(_tips(c.motion), fps)
        assert (contacts == c.true_contacts).mean() > 0.9
        stride_seconds = np.diff(np.flatnonzero(np.diff(contacts[:, 0]) > 0)).mean() / fps
        assert 0.8 < 1 / stride_seconds < 1.25, (fps, 1 / stride_seconds)


# ---------------------------------------------------------------------------------------------
# Contacts: the stance feet really touch the floor
# ---------------------------------------------------------------------------------------------

def test_stance_toe_tips_are_planted_on_the_floor(clips):
    for c in clips.values():
        tips = _tips(c.motion)
        stance = c.true_contacts > 0.5
        assert np.abs(tips[..., 1][stance]).max() < 0.002, (c.style, c.gait)
        speed = np.linalg.norm(np.diff(tips, axis=0), axis=-1) * FPS     # (F-1, 2)
        both = stance[1:] & stance[:-1]
        # Planted: still, except tiny shuffles (< 5 mm) when standing, under the contact speed.
        assert speed[both].max(initial=0) <= 0.15, (c.style, c.gait)
        assert np.percentile(speed[both], 95) < 1e-6, (c.style, c.gait)
        assert tips[..., 1].min() > -0.002, (c.style, c.gait)           # never through the floor


def test_contact_detector_recovers_the_true_contacts(clips):
    worst = 1.0
    for c in clips.values():
        agreement = (_contacts(c.motion) == c.true_contacts).mean()
        worst = min(worst, agreement)
        assert agreement > 0.9, (c.style, c.gait, agreement)
    assert worst > 0.9


def test_walking_feet_alternate_and_running_has_flight(clips):
    walk = clips[("Neutral", "FW")].true_contacts
    run = clips[("Neutral", "FR")].true_contacts
    assert (walk.sum(1) >= 1).mean() > 0.95            # walking: a foot is (almost) always down
    assert (run.sum(1) == 0).mean() > 0.15             # running: flight phases
    assert (run.sum(1) == 2).mean() < 0.05             # ... and hardly any double support


# ---------------------------------------------------------------------------------------------
# Style claims
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("gait", DEFAULT_GAITS)
def test_left_hop_right_foot_never_touches_the_floor(clips, gait):
    c = clips[("LeftHop", gait)]
    contacts = _contacts(c.motion)
    assert contacts[:, 0].max() == 0.0                 # right never
    assert contacts[:, 1].mean() > 0.3                 # the left foot does the hopping
    assert _tips(c.motion)[:, 0, 1].min() > 0.1        # right toe tip at least 10 cm up
    assert c.true_contacts[:, 0].max() == 0.0


@pytest.mark.parametrize("gait", DEFAULT_GAITS)
def test_hands_above_keeps_the_wrists_above_the_head(clips, gait):
    m = clips[("HandsAbove", gait)].motion
    pos, _ = _fk(m)
    top_of_head = pos[:, m.index("HeadSite"), 1]
    for name in ("LeftWrist", "RightWrist"):
        assert (pos[:, m.index(name), 1] > top_of_head + 0.05).all(), (gait, name)
    # ... and the other styles do not.
    n = clips[("Neutral", gait)].motion
    npos, _ = _fk(n)
    assert (npos[:, n.index("LeftWrist"), 1] < npos[:, n.index("Head"), 1]).all()


def _dominant_frequency(signal, fps):
    x = np.asarray(signal, dtype=np.float64) - np.mean(signal)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    freqs = np.fft.rfftfreq(x.size, 1 / fps)
    return freqs[np.argmax(spectrum[1:]) + 1]


def test_swimming_arm_frequency_differs_from_step_frequency():
    ratios = {}
    for style in ("Swimming", "Neutral"):
        c = generate_style(style, "FW", 12.0, np.random.default_rng(11))
        hand = _hips_local(c.motion, "LeftWristSite")[:, 2]     # forward-back in the hips frame
        f_hand = _dominant_frequency(hand, FPS)
        f_foot = _dominant_frequency(_contacts(c.motion)[:, 1], FPS)
        ratios[style] = f_hand / f_foot
    assert ratios["Neutral"] == pytest.approx(1.0, abs=0.1)
    assert abs(ratios["Swimming"] - 1.0) > 0.3


def test_swimming_frequencies_through_the_phase_pipeline():
    from minifilm.phases.local_phases import extract_local_phases
    from minifilm.motion.skeletons import STYLE100

    c = generate_style("Swimming", "FW", 8.0, np.random.default_rng(12))
    lp = extract_local_phases(c.motion, STYLE100, _contacts(c.motion))
    mid = slice(60, -60)
    hands = np.median(lp.frequency[mid, :2])
    feet = np.median(lp.frequency[mid, 2:])
    assert hands / feet > 1.3


def test_pendulum_hands_swing_together_neutral_in_opposition(clips):
    corr = {}
    for style in ("PendulumHands", "Neutral"):
        m = clips[(style, "FW")].motion
        left = _hips_local(m, "LeftWristSite")[:, 2]
        right = _hips_local(m, "RightWristSite")[:, 2]
        corr[style] = np.corrcoef(left, right)[0, 1]
    assert corr["PendulumHands"] > 0.9
    assert corr["Neutral"] < -0.9


def test_limp_is_asymmetric(clips):
    contacts = _contacts(clips[("Limp", "FW")].motion)
    right, left = contacts.mean(0)
    assert left - right > 0.12                           # the sound (left) leg bears longer
    nr, nl = _contacts(clips[("Neutral", "FW")].motion).mean(0)
    assert abs(nl - nr) < 0.05


def test_crouched_is_low(clips):
    low = clips[("Crouched", "FW")].motion.translations[:, 0, 1].mean()
    normal = clips[("Neutral", "FW")].motion.translations[:, 0, 1].mean()
    assert normal - low > 0.15


def _step_intervals(contacts):
    onsets = np.flatnonzero(np.diff(contacts) > 0)
    return np.diff(onsets)


def test_drunk_steps_are_irregular():
    cv = {}
    for style in ("Drunk", "Neutral"):
        c = generate_style(style, "FW", 12.0, np.random.default_rng(4))
        con = _contacts(c.motion)
        d = np.concatenate([_step_intervals(con[:, 0]), _step_intervals(con[:, 1])])
        cv[style] = d.std() / d.mean()
    assert cv["Drunk"] > 2 * cv["Neutral"]


# ---------------------------------------------------------------------------------------------
# Gaits and trajectories
# ---------------------------------------------------------------------------------------------

def _local_velocity(motion):
    """(F-1, 2) hips velocity in the facing frame: (sideways towards +x = left, forwards)."""
    pos, rot = _fk(motion)
    v = np.diff(pos[:, 0], axis=0) * motion.fps
    fwd = rot[:-1, 0][:, :, 2] * np.array([1, 0, 1])
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    left = np.stack([fwd[:, 2], np.zeros(len(fwd)), -fwd[:, 0]], axis=1)
    return np.stack([np.sum(v * left, 1), np.sum(v * fwd, 1)], axis=1)


def test_gaits_move_as_named(clips):
    for style in ("Neutral", "Crouched"):
        v = {g: _local_velocity(clips[(style, g)].motion) for g in ("FW", "BW", "SW", "FR", "ID")}
        assert v["FW"][:, 1].mean() > 0.6
        assert v["BW"][:, 1].mean() < -0.4
        assert np.abs(v["SW"][:, 0]).mean() > 0.3 and np.abs(v["SW"][:, 1]).mean() < 0.15
        assert v["FR"][:, 1].mean() > 1.6 * v["FW"][:, 1].mean()
        assert np.linalg.norm(v["ID"], axis=1).max() < 0.15
    # Trajectories turn: the facing changes by tens of degrees over a walk.
    m = generate_style("Neutral", "FW", 12.0, np.random.default_rng(8)).motion
    fwd = m.rotations[:, 0, :, 2]
    yaw = np.unwrap(np.arctan2(fwd[:, 0], fwd[:, 2]))
    assert np.ptp(yaw) > np.radians(20)


def test_transitions_switch_gaits_smoothly():
    c = generate_style("Neutral", "TR", 12.0, np.random.default_rng(9))
    assert len(set(c.frame_gaits)) >= 3
    speed = np.linalg.norm(np.diff(c.motion.translations[:, 0, [0, 2]], axis=0), axis=1) * FPS
    assert speed.max() > 1.5 and speed.min() < 0.3          # walks/runs and stops
    accel = np.abs(np.diff(speed)) * FPS
    assert np.percentile(accel, 99) < 15.0                   # no jumps of the whole body


def test_knees_never_bend_backwards(clips):
    for c in clips.values():
        m = c.motion
        pos, rot = _fk(m)
        for side in ("Right", "Left"):
            hip, knee, ankle = (pos[:, m.index(side + j)] for j in ("Hip", "Knee", "Ankle"))
            foot_fwd = rot[:, m.index(side + "Ankle")][:, :, 2]      # the foot's +z
            u = (ankle - hip) / np.linalg.norm(ankle - hip, axis=1, keepdims=True)
            bulge = (knee - hip) - np.sum((knee - hip) * u, 1, keepdims=True) * u
            assert (np.sum(bulge * foot_fwd, 1) > -1e-6).all(), (c.style, c.gait, side)


# ---------------------------------------------------------------------------------------------
# Ground-truth phases
# ---------------------------------------------------------------------------------------------

def test_foot_truth_is_quarter_cycle_at_mid_stance(clips):
    for key in [("Neutral", "FW"), ("Limp", "FW"), ("Neutral", "FR"), ("LeftHop", "FW")]:
        c = clips[key]
        contacts = _contacts(c.motion)
        for foot, slot in ((0, 3), (1, 2)):
            x = np.concatenate([[0], contacts[:, foot], [0]])
            starts, stops = np.flatnonzero(np.diff(x) > 0), np.flatnonzero(np.diff(x) < 0)
            whole = (starts > 0) & (stops < len(contacts))       # stances inside the clip
            mids = ((starts + stops - 1) // 2)[whole]
            if key[0] == "LeftHop" and foot == 0:
                assert mids.size == 0
                continue
            assert mids.size >= 2, key
            assert _circ(c.true_phase[mids, slot], 0.25).max() < 0.04, (key, foot)


def _pca_projection(local):
    """Signed projection on the largest principal axis, turned to point forwards (+z)."""
    centred = local - local.mean(0)
    _, vecs = np.linalg.eigh(centred.T @ centred)
    axis = vecs[:, -1] * (1 if vecs[2, -1] >= 0 else -1)
    return centred @ axis


@pytest.mark.parametrize("style", ["Neutral", "PendulumHands", "HandsAbove", "Swimming", "Drunk"])
def test_hand_truth_peaks_at_the_forward_extreme(clips, style):
    c = clips[(style, "FW")]
    for slot, name in ((0, "LeftWristSite"), (1, "RightWristSite")):
        proj = _pca_projection(_hips_local(c.motion, name))
        expected = np.sin(2 * np.pi * c.true_phase[:, slot])   # peaks at φ = 0.25
        assert np.corrcoef(proj, expected)[0, 1] > 0.9, (style, name)


def test_lifted_foot_truth_peaks_at_the_forward_extreme(clips):
    c = clips[("LeftHop", "FW")]
    proj = _pca_projection(_hips_local(c.motion, "RightToe"))
    assert np.corrcoef(proj, np.sin(2 * np.pi * c.true_phase[:, 3]))[0, 1] > 0.9


@pytest.mark.parametrize("style", ["Neutral", "LeftHop"])
def test_phase_pipeline_recovers_the_true_phases(style):
    from minifilm.phases.local_phases import default_sources, extract_local_phases
    from minifilm.motion.skeletons import STYLE100

    c = generate_style(style, "FW", 6.0, np.random.default_rng(21))
    lp = extract_local_phases(c.motion, STYLE100, _contacts(c.motion), default_sources(style))
    err = _circ(lp.phase, c.true_phase)[30:-30]
    active = c.phase_active[30:-30]
    for slot in range(4):
        assert active[:, slot].mean() > 0.8
        assert np.median(err[active[:, slot], slot]) < 0.05, (style, slot)


def test_idle_feet_have_no_active_phase(clips):
    c = clips[("Neutral", "ID")]
    assert not c.phase_active[:, 2:].any()
    assert (c.true_contacts == 1).all()


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------

def test_write_dataset_round_trips_through_bvh(tmp_path):
    from minifilm.motion.bvh import read_bvh

    clips = default_dataset(seed=1, seconds=1.0, styles=["Swimming", "LeftHop"], gaits=["FR", "TR"])
    paths = write_dataset(tmp_path, clips)
    assert sorted(p.name for p in paths) == ["LeftHop_FR.bvh", "LeftHop_TR.bvh", "Swimming_FR.bvh",
                                             "Swimming_TR.bvh"]
    for clip, path in zip(clips, paths):
        back = read_bvh(path)
        assert back.names == clip.motion.names
        assert back.frame_time == pytest.approx(clip.motion.frame_time, rel=1e-5)
        np.testing.assert_allclose(_fk(back)[0], _fk(clip.motion)[0], atol=1e-4)
        truth = np.load(path.with_suffix(".truth.npz"), allow_pickle=False)
        np.testing.assert_array_equal(truth["true_phase"], clip.true_phase)


def test_unknown_style_or_gait_is_named():
    with pytest.raises(ValueError, match=r"unknown styles or gaits \['Moonwalk'\]"):
        default_dataset(styles=["Neutral", "Moonwalk"], gaits=["FW"], seconds=1.0)
    with pytest.raises(ValueError, match=r"\['XX'\]"):
        default_dataset(styles=["Neutral"], gaits=["XX"], seconds=1.0)
