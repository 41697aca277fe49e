"""Local phases on real motion capture: Bandai-Namco dataset 2 walks (30 fps) and a Xia clip (120 fps).

The expectations come from the motion itself, measured independently of the phase pipeline: the
step frequency from the touch-down times of the contacts, the hand swing from the hips-local
forward coordinate of the hand.
"""
import numpy as np
import pytest

from minifilm.motion.bvh import read_bvh
from minifilm.phases.contacts import foot_contacts
from minifilm.motion.editing import resample
from minifilm.phases.local_phases import extract_local_phases, hips_local_positions
from minifilm.motion.skeletons import BANDAI, CMU

WALKS = ("normal_001", "elderly_001", "exhausted_001", "feminine_001")


def circular_mean(cycles):
    return np.mod(np.angle(np.mean(np.exp(2j * np.pi * np.asarray(cycles)))) / (2 * np.pi), 1.0)


def cycle_error(a, b):
    return np.abs(np.mod(np.asarray(a) - np.asarray(b) + 0.5, 1.0) - 0.5)


def phase_rate(phase, fps):
    """Least-squares slope (cycles/s) of the unwrapped phase."""
    unwrapped = np.unwrap(2 * np.pi * phase) / (2 * np.pi)
    return np.polyfit(np.arange(phase.size) / fps, unwrapped, 1)[0]


_cache = {}


def load(shared_data, name, skeleton, folder):
    key = (name, skeleton.name)
    if key not in _cache:
        motion = read_bvh(shared_data / folder / name, scale=skeleton.bvh_scale)
        positions, _ = motion.world()
        contacts = foot_contacts(positions[:, skeleton.contact_indices(motion)], motion.fps)
        _cache[key] = motion, contacts, extract_local_phases(motion, skeleton, contacts)
    return _cache[key]


def bandai(shared_data, style):
    return load(shared_data, f"dataset-2_walk_{style}.bvh", BANDAI, "bandai2")


@pytest.mark.parametrize("style", WALKS)
def test_bandai_foot_phases_follow_the_steps(shared_data, style):
    motion, contacts, lp = bandai(shared_data, style)
    fps = motion.fps
    assert fps == pytest.approx(30, abs=0.01)
    core = slice(int(fps), motion.n_frames - int(fps))   # away from the start/stop of the walk
    for slot, column in ((2, 1), (3, 0)):                # left foot <- contacts[:, 1], right <- [:, 0]
        c = contacts[:, column]
        touch_down = np.nonzero((c[1:] > 0.5) & (c[:-1] < 0.5))[0] + 1
        assert touch_down.size >= 4, f"{style}: too few steps detected"
        step_frequency = fps / np.median(np.diff(touch_down))   # one cycle per foot per stride
        rate = phase_rate(lp.phase[core, slot], fps)
        assert rate == pytest.approx(step_frequency, rel=0.05)
        # Steady advance: the phase moves forwards on (almost) every frame.
        step = np.mod(np.diff(lp.phase[core, slot]) + 0.5, 1.0) - 0.5
        assert np.mean(step > 0) > 0.97
        # §4.7 convention on real data: mid-stance sits at φ ≈ 0.25.
        lift_off = np.nonzero((c[1:] < 0.5) & (c[:-1] > 0.5))[0] + 1
        mids = [(a + b) // 2 for a in touch_down for b in lift_off[lift_off > a][:1]]
        mids = [m for m in mids if core.start <= m < core.stop]
        assert len(mids) >= 2
        assert cycle_error(circular_mean(lp.phase[mids, slot]), 0.25) < 0.08
    # The feet alternate: about half a cycle apart.
    assert cycle_error(circular_mean(lp.phase[core, 2] - lp.phase[core, 3]), 0.5) < 0.06


def hand_swing(motion, skeleton):
    """(F, 2) hips-local forward coordinate of the left and right hand, mean removed (metres)."""
    local = hips_local_positions(motion, skeleton)[:, :2]
    forward = local @ np.asarray(skeleton.facing_axis)
    return forward - forward.mean(axis=0)


def test_bandai_hands_small_amplitude_when_arms_barely_swing(shared_data):
    normal_motion, _, normal = bandai(shared_data, "normal_001")
    elderly_motion, _, elderly = bandai(shared_data, "elderly_001")
    swing_normal = hand_swing(normal_motion, BANDAI).std(axis=0)
    swing_elderly = hand_swing(elderly_motion, BANDAI).std(axis=0)
    # The independent measurement: the elderly walker's hands swing far less.
    assert np.all(swing_elderly < 0.5 * swing_normal)
    amp_normal = np.median(normal.amplitude[:, :2], axis=0)
    amp_elderly = np.median(elderly.amplitude[:, :2], axis=0)
    assert np.all(amp_elderly < 0.5 * amp_normal)
    # ... while the feet, which step just as regularly, keep a comparable amplitude.
    assert np.median(elderly.amplitude[:, 2:]) > 0.5 * np.median(normal.amplitude[:, 2:])
    assert np.median(elderly.amplitude[:, :2]) < 0.35 * np.median(elderly.amplitude[:, 2:])


def test_bandai_hands_swing_in_antiphase_at_the_step_frequency(shared_data):
    motion, contacts, lp = bandai(shared_data, "normal_001")
    fps = motion.fps
    core = slice(int(fps), motion.n_frames - int(fps))
    swing = hand_swing(motion, BANDAI)
    for slot in (0, 1):
        # Hand forward-most (swing maximum) <-> source maximum <-> φ = 0.25.
        s = swing[core, slot]
        peaks = np.nonzero((s[1:-1] > s[:-2]) & (s[1:-1] >= s[2:]) & (s[1:-1] > 0.5 * s.max()))[0] + 1 + core.start
        assert peaks.size >= 3
        assert cycle_error(circular_mean(lp.phase[peaks, slot]), 0.25) < 0.06
        assert phase_rate(lp.phase[core, slot], fps) == pytest.approx(fps / np.median(np.diff(peaks)), rel=0.05)
    assert cycle_error(circular_mean(lp.phase[core, 0] - lp.phase[core, 1]), 0.5) < 0.06


def test_xia_hands_at_120_fps(shared_data):
    motion, contacts, lp = load(shared_data, "neutral_01_000.bvh", CMU, "bvh/xia")
    fps = motion.fps
    assert fps == pytest.approx(120, abs=0.01)
    core = slice(int(0.25 * fps), motion.n_frames - int(0.25 * fps))
    swing = hand_swing(motion, CMU)
    for slot in (0, 1):
        s = swing[:, slot]
        # Independent frequency: the hand's forward coordinate crosses its mean twice per cycle.
        crossings = np.nonzero(np.diff(np.sign(s)) != 0)[0]
        swing_frequency = fps / (2 * np.mean(np.diff(crossings)))
        step = np.mod(np.diff(lp.phase[core, slot]) + 0.5, 1.0) - 0.5
        assert np.mean(step > 0) > 0.97
        assert phase_rate(lp.phase[core, slot], fps) == pytest.approx(swing_frequency, rel=0.15)
    assert cycle_error(circular_mean(lp.phase[core, 0] - lp.phase[core, 1]), 0.5) < 0.08
    assert contacts.sum(axis=0).min() > 0.2 * fps   # both feet find the floor


def test_bandai_frame_rate_independent(shared_data):
    motion, _, lp30 = bandai(shared_data, "normal_001")
    motion60 = resample(motion, 60.0)
    positions, _ = motion60.world()
    contacts60 = foot_contacts(positions[:, BANDAI.contact_indices(motion60)], motion60.fps)
    lp60 = extract_local_phases(motion60, BANDAI, contacts60)
    n = min(motion.n_frames, (motion60.n_frames + 1) // 2)
    core = slice(30, n - 30)
    err = cycle_error(lp60.phase[::2][:n][core], lp30.phase[:n][core])
    assert np.median(err) < 0.02
    ratio = np.median(lp60.amplitude[::2][:n][core], axis=0) / np.median(lp30.amplitude[:n][core], axis=0)
    np.testing.assert_allclose(ratio, 1.0, atol=0.1)
