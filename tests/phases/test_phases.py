"""Local phases (Sec. 4.1, Eq. 1): sinusoid fit, source functions, phase/amplitude, on synthetic data
whose true phase is known in closed form."""
import numpy as np
import pytest

from minifilm.motion.motion import Motion
from minifilm.phases.sinusoid_fit import fit_sinusoids, overflow_window, window_half_width
from minifilm.phases.sources import (butterworth, pca_source, preprocess_source,
                                           window_normalise)
from minifilm.phases.local_phases import (LocalPhases, default_sources, extract_local_phases,
                                    phase_and_amplitude, phase_updates)
from minifilm.motion.skeletons import Skeleton


def cycle_error(a, b):
    """Distance between phases in cycles, in [0, 0.5]."""
    return np.abs(np.mod(np.asarray(a) - np.asarray(b) + 0.5, 1.0) - 0.5)


# ---------------------------------------------------------------- the fit on known sinusoids

@pytest.mark.parametrize("f", [0.5, 0.7, 1.0, 1.5, 2.0, 3.0])
def test_fit_recovers_noisy_sinusoid(f):
    fps, a, s, b = 60, 1.3, 0.37, 0.2
    rng = np.random.default_rng(int(f * 10))
    t = np.arange(20 * fps) / fps
    v = a * np.sin(2 * np.pi * (f * t - s)) + b + 0.05 * a * rng.standard_normal(t.size)
    fit = fit_sinusoids(v, fps)
    assert np.median(cycle_error(fit.phase, f * t - s)) < 0.01
    # Below 1 Hz one 0.5 s window alone could not reach this (its Cramér-Rao bound is a relative
    # std of 48 % at 0.5 Hz); the reported frequency is the slope of the phase track over 1 s.
    assert np.median(np.abs(fit.frequency / f - 1)) < 0.02
    # Amplitude and frequency trade off against each other in a fraction of a cycle.
    assert np.median(np.abs(fit.amplitude / a - 1)) < (0.03 if f >= 1.0 else 0.06)
    assert np.median(np.abs(fit.offset - b)) < (0.03 if f >= 1.0 else 0.06) * a


@pytest.mark.parametrize("f", [0.5, 1.0, 2.5])
def test_fit_is_nearly_exact_without_noise(f):
    fps = 60
    t = np.arange(10 * fps) / fps
    fit = fit_sinusoids(0.8 * np.sin(2 * np.pi * (f * t - 0.1)) - 0.3, fps)
    # In the last and first 0.25 s the window is one-sided (shifted), so a small frequency error
    # turns into a phase error growing towards the ends: check the interior tightly, the ends loosely.
    inner = (t > 0.25) & (t < t[-1] - 0.25)
    assert np.max(cycle_error(fit.phase, f * t - 0.1)[inner]) < 0.005
    assert np.max(cycle_error(fit.phase, f * t - 0.1)) < 0.02
    away = (t > 0.5) & (t < t[-1] - 0.5)   # beyond the reach of the connect terms
    # (at 0.5 Hz the 1 s bound range just holds half a cycle; at the extremes B touches its bound)
    assert np.max(np.abs(fit.frequency / f - 1)[away]) < 0.02
    assert np.median(np.abs(fit.frequency / f - 1)) < 0.005
    assert np.max(np.abs(fit.frequency / f - 1)) < 0.1   # the ends see less than 0.4 cycle at 0.5 Hz
    np.testing.assert_allclose(fit.fit, 0.8 * np.sin(2 * np.pi * (f * t - 0.1)) - 0.3, atol=0.01)


def test_fit_tracks_a_chirp():
    fps = 60
    t = np.arange(30 * fps) / fps
    f0, f1, T = 0.5, 3.0, t[-1]
    inst_f = f0 + (f1 - f0) * t / T
    phase = f0 * t + 0.5 * (f1 - f0) * t * t / T   # ∫ inst_f dt
    fit = fit_sinusoids(np.sin(2 * np.pi * phase), fps)
    inner = (t > 1.0) & (t < T - 1.0)
    assert np.median(cycle_error(fit.phase, phase)[inner]) < 0.01
    assert np.median(np.abs(fit.frequency / inst_f - 1)[inner]) < 0.03


@pytest.mark.parametrize("fps", [30, 60, 120])
def test_fit_frame_rate_independent(fps):
    t = np.arange(8 * fps) / fps
    fit = fit_sinusoids(np.sin(2 * np.pi * (1.2 * t - 0.3)), fps)
    assert np.median(cycle_error(fit.phase, 1.2 * t - 0.3)) < 0.005
    assert np.median(np.abs(fit.frequency - 1.2)) < 0.02


def test_fit_respects_bounds_and_skips_zero_windows():
    fps = 60
    t = np.arange(6 * fps) / fps
    v = np.where(t < 3, np.sin(2 * np.pi * 1.5 * t), 0.0)
    fit = fit_sinusoids(v, fps, max_frequency=4.0, min_frequency=0.25)
    assert np.all(fit.amplitude >= 0)
    live = ~fit.skipped
    assert np.all((fit.frequency[live] >= 0.25 - 1e-12) & (fit.frequency[live] <= 4.0 + 1e-12))
    assert np.all(fit.amplitude <= 2.0 + 1e-9)          # <= vmax - vmin of any window
    # From 0.25 s after the signal stops, every 31-frame window is all zeros: skipped, all 0.
    quiet = t > 3.0 + 0.26
    assert np.all(fit.skipped[quiet]) and not np.any(fit.skipped[t < 2.5])
    assert np.all(fit.amplitude[quiet] == 0) and np.all(fit.frequency[quiet] == 0)


def test_fit_is_deterministic():
    rng = np.random.default_rng(3)
    v = np.sin(np.linspace(0, 40, 900)) + 0.1 * rng.standard_normal(900)
    a, b = fit_sinusoids(v, 60), fit_sinusoids(v.copy(), 60)
    for name in ("amplitude", "frequency", "phase", "offset", "fit"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_fit_short_and_bad_signals():
    fit = fit_sinusoids(np.sin(np.arange(7) / 3.0), 60)  # shorter than one window
    assert fit.phase.shape == (7,) and np.all(np.isfinite(fit.phase))
    with pytest.raises(ValueError, match="1-D"):
        fit_sinusoids(np.zeros((4, 2)), 60)
    with pytest.raises(ValueError, match="NaN"):
        fit_sinusoids(np.array([0.0, np.nan, 1.0]), 60)


def test_overflow_window_shifts_at_the_ends():
    lo, hi = overflow_window(np.array([0, 3, 10, 19]), np.array([2, 2, 2, 2]), 20)
    np.testing.assert_array_equal(lo, [0, 1, 8, 15])
    np.testing.assert_array_equal(hi, [4, 5, 12, 19])
    assert window_half_width(0.5, 60) == 15 and window_half_width(0.5, 120) == 30


# ---------------------------------------------------------------- preprocessing

def test_window_normalise_matches_direct_computation():
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.standard_normal(200))
    fps, half = 20, 10                                   # 1 s at 20 fps: 21 samples
    got = window_normalise(x, fps)
    padded = np.concatenate([np.full(half, x[0]), x, np.full(half, x[-1])])
    for k in (0, 5, 100, 199):
        w = padded[k:k + 2 * half + 1]
        assert got[k] == pytest.approx((x[k] - w.mean()) / w.std(), rel=1e-9, abs=1e-9)
    np.testing.assert_array_equal(window_normalise(np.full(50, 0.3), fps), 0.0)  # std 0 -> 1, mean removed


def test_butterworth_gain():
    fps = 60
    t = np.arange(20 * fps) / fps
    mid = slice(3 * fps, -3 * fps)
    for f in (1.0, 10.0):
        y = butterworth(np.sin(2 * np.pi * f * t), fps, cutoff=4.0)
        gain = np.abs(y[mid]).max()
        # Forward-backward squares the 2nd-order Butterworth magnitude: 1 / (1 + (f/fc)^4)
        # (up to the bilinear transform's frequency warping).
        assert gain == pytest.approx(1 / (1 + (f / 4.0) ** 4), abs=0.02)
    with pytest.raises(ValueError, match="cutoff"):
        butterworth(t, 6, cutoff=4.0)


def original_butterworth(x, a=0.0335718, b=0.0671436, c=0.0335718, d=1.4189827, e=-0.5532699):
    """The original's filter at 60 fps / 4 Hz, written from docs/original-code.md §3.6 (its own edges)."""
    N = len(x)
    P = np.concatenate([[x[0], x[0]], x[:N - 1], [x[N - 1], x[N - 1]]])
    Y = np.zeros(N + 3)
    Y[0] = Y[1] = x[0]
    for s in range(2, N + 1):
        Y[s] = a * P[s] + b * P[s - 1] + c * P[s - 2] + d * Y[s - 1] + e * Y[s - 2]
    Y[N + 1] = Y[N + 2] = Y[N]
    Z = np.zeros(N + 1)
    Z[N - 1], Z[N] = Y[N + 1], Y[N + 2]
    for k in range(N - 2, -1, -1):
        Z[k] = a * Y[k + 2] + b * Y[k + 3] + c * Y[k + 4] + d * Z[k + 1] + e * Z[k + 2]
    out = Z[:N].copy()
    out[N - 1] = x[N - 1]
    return out


def test_butterworth_matches_the_original_away_from_the_edges():
    fps = 60
    t = np.arange(10 * fps) / fps
    contact = (np.mod(0.9 * t, 1.0) < 0.45).astype(float)
    x = window_normalise(contact, fps)
    ours, theirs = butterworth(x, fps), original_butterworth(x)
    # The original feeds the forward pass a one-sample-delayed copy of x (P[s] = x[s-2] against
    # Y[s]) and the backward pass undoes it, so away from the end both agree up to the rounding of
    # the published coefficients. The end differs by design (phase_sources module docstring).
    head = slice(0, -fps)
    assert np.max(np.abs(ours[head] - theirs[head])) < 1e-5
    assert np.max(np.abs(ours - theirs)) < 0.1


def test_pca_source_is_directed_forward():
    t = np.linspace(0, 4, 240)
    swing = np.sin(2 * np.pi * t)
    q = np.stack([0.01 * np.cos(2 * np.pi * t), 0.2 * swing - 0.05 * swing, 0.3 * swing], axis=1) + [0.3, 1.0, 0.1]
    src = pca_source(q, forward_axis=(0, 0, 1))
    # The source grows as the bone moves forward (+z), whatever sign eigh returns.
    assert np.corrcoef(src, swing)[0, 1] > 0.99
    assert np.corrcoef(pca_source(q, forward_axis=(0, 0, -1)), swing)[0, 1] < -0.99
    assert abs(src.mean()) < 1e-12


# ---------------------------------------------------------------- phase, amplitude, Eq. (1)

def test_contact_step_gives_quarter_phase_at_mid_stance():
    """§4.7: a z-scored contact signal peaks mid-stance, and A sin peaks at φ = 0.25."""
    fps, f = 60, 0.9
    t = np.arange(15 * fps) / fps
    for duty in (0.4, 0.6):
        contact = (np.mod(f * t, 1.0) < duty).astype(float)
        fit = fit_sinusoids(preprocess_source(contact, fps), fps)
        phase, amp = phase_and_amplitude(fit, np.ones_like(t), fps)
        mid_stance = cycle_error(f * t, duty / 2) < 0.5 * f / fps
        inner = mid_stance & (t > 1.5) & (t < t[-1] - 1.5)
        assert inner.sum() >= 10
        assert np.max(cycle_error(phase[inner], 0.25)) < 0.03
        assert np.all(amp[inner] > 0.5)


def test_vectors_and_updates_follow_eq1():
    phase = np.array([[0.0, 0.25, 0.5, 0.75], [0.125, 0.0, 0.0, 0.0]])
    amp = np.array([[1.0, 2.0, 3.0, 4.0], [2.0, 0.0, 1.0, 1.0]])
    p = LocalPhases(phase, amp).vectors()
    np.testing.assert_allclose(p[0], [0, 1, 2, 0, 0, -3, -4, 0], atol=1e-12)
    np.testing.assert_allclose(p[1, :2], [2 * np.sqrt(0.5), 2 * np.sqrt(0.5)])
    np.testing.assert_allclose(phase_updates(p), p[1:] - p[:1])
    assert phase_updates(p).shape == (1, 8)


def test_mirrored_swaps_left_and_right():
    phase = np.array([[0.1, 0.2, 0.3, 0.4]])
    m = LocalPhases(phase, 2 * phase).mirrored()
    np.testing.assert_array_equal(m.phase, [[0.2, 0.1, 0.4, 0.3]])
    np.testing.assert_array_equal(m.amplitude, [[0.4, 0.2, 0.8, 0.6]])
    assert m.source is None


def test_default_sources_for_hopping():
    assert default_sources() == ("pca", "pca", "contact", "contact")
    assert default_sources("LeftHop") == ("pca", "pca", "contact", "pca")
    assert default_sources("RightHop") == ("pca", "pca", "pca", "contact")


# ---------------------------------------------------------------- extract_local_phases on a stand-in motion

TOY = Skeleton("toy", joints=("Hips", "LHand", "RHand", "LToe", "RToe"), parents=(-1, 0, 0, 0, 0),
               hips="Hips", phase_bones=("LHand", "RHand", "LToe", "RToe"),
               contact_bones=("RToeSite", "LToeSite"), facing_axis=(0.0, 0.0, 1.0))


def toy_walk(fps=60, seconds=10.0, f=1.1, hand_amp=(0.15, 0.15), yaw_rate=0.3):
    """A stand-in Motion: hips walking along a curve and turning; hands swinging forward/back in
    the hips frame as 0.2 sin(2π(f t − s)) with s = 0 (left) and 0.5 (right); toes on the floor.

    Hand positions are set in the hips frame, so the true hand phase is known: the source is +z.
    """
    n = int(round(seconds * fps))
    t = np.arange(n) / fps
    names = ["Hips", "LHand", "RHand", "LToe", "RToe", "RToeSite", "LToeSite"]
    parents = [-1, 0, 0, 0, 0, 4, 3]
    J = len(names)
    rot = np.tile(np.eye(3), (n, J, 1, 1))
    yaw = yaw_rate * t
    c, s = np.cos(yaw), np.sin(yaw)
    rot[:, 0] = np.stack([np.stack([c, 0 * c, s], -1), np.stack([0 * c, 1 + 0 * c, 0 * c], -1),
                          np.stack([-s, 0 * c, c], -1)], -2)
    tr = np.zeros((n, J, 3))
    tr[:, 0] = np.stack([np.sin(yaw), np.full(n, 0.9), 1.2 * t], -1)
    for j, (amp, shift, x) in enumerate(zip(hand_amp, (0.0, 0.5), (0.2, -0.2)), start=1):
        tr[:, j] = np.stack([np.full(n, x), np.full(n, -0.1), amp * np.sin(2 * np.pi * (f * t - shift))], -1)
    tr[:, 3] = [0.1, -0.9, 0.1]
    tr[:, 4] = [-0.1, -0.9, 0.1]
    motion = Motion(names, parents, tr[0], [()] * J, rot, tr, 1.0 / fps, "toy_walk")
    return motion, t


def test_hand_phases_follow_the_swing_and_feet_follow_contacts():
    fps, f = 60, 1.1
    motion, t = toy_walk(fps, f=f)
    # Feet: contacts with 60 % stance, the left foot half a cycle after the right.
    right = (np.mod(f * t, 1.0) < 0.6).astype(float)
    left = (np.mod(f * t - 0.5, 1.0) < 0.6).astype(float)
    lp = extract_local_phases(motion, TOY, np.stack([right, left], 1))
    inner = (t > 1.0) & (t < t[-1] - 1.0)
    # Hands: the left hand is furthest forward (source max, φ = 0.25) when f t = 0.25.
    assert np.median(cycle_error(lp.phase[inner, 0], f * t[inner])) < 0.01
    assert np.median(cycle_error(lp.phase[inner, 1], f * t[inner] - 0.5)) < 0.01
    # Feet: φ = 0.25 at mid-stance, i.e. f t − 0.3 + 0.25 for the right foot (stance centre at 0.3).
    # A step is not a sinusoid, so the local phase wobbles a little around the linear one, but
    # without a systematic lag (the original's one-frame contact lag, §12.3, is not replicated).
    for slot, centre in ((3, 0.3), (2, 0.8)):
        expected = f * t[inner] - centre + 0.25
        assert np.max(cycle_error(lp.phase[inner, slot], expected)) < 0.05
        signed = np.mod(lp.phase[inner, slot] - expected + 0.5, 1.0) - 0.5
        assert abs(np.mean(signed)) < 0.005
    # Hand amplitude: A ≈ 1.4 (a z-scored sinusoid) times the peak hips-relative speed 2π f 0.15.
    peak_speed = 2 * np.pi * f * 0.15
    amp = np.median(lp.amplitude[inner, 0])
    assert 1.0 * peak_speed < amp < 1.6 * peak_speed
    # Feet do not move relative to the hips here, so their amplitude is 0 whatever the contacts.
    assert np.max(lp.amplitude[:, 2:]) < 1e-9
    assert lp.vectors().shape == (t.size, 8)


def test_still_hand_has_no_amplitude_and_runs_are_identical():
    motion, t = toy_walk(hand_amp=(0.0, 0.15))
    contacts = np.zeros((t.size, 2))
    a = extract_local_phases(motion, TOY, contacts)
    assert np.max(a.amplitude[:, 0]) < 1e-6
    assert np.median(a.amplitude[:, 1]) > 0.5
    b = extract_local_phases(motion, TOY, contacts)
    np.testing.assert_array_equal(a.vectors(), b.vectors())


def test_extract_checks_its_inputs():
    motion, t = toy_walk(seconds=2.0)
    with pytest.raises(ValueError, match="contacts must have shape"):
        extract_local_phases(motion, TOY, np.zeros((t.size, 3)))
    with pytest.raises(ValueError, match="sources"):
        extract_local_phases(motion, TOY, np.zeros((t.size, 2)), sources=("pca", "pca", "contact"))
    with pytest.raises(ValueError, match="1 frame.*needs at least 2"):
        extract_local_phases(motion.slice(0, 1), TOY, np.zeros((1, 2)))
    with pytest.raises(ValueError, match="no foot contact"):
        extract_local_phases(motion, TOY, np.zeros((t.size, 2)), sources=("contact", "pca", "pca", "pca"))


def test_sinusoid_fit_memory_stays_bounded_at_high_frame_rates(monkeypatch):
    # at 1000 fps a window holds ~1000 samples: the blocks shrink so that no design matrix holds
    # more than BLOCK_NUMBERS numbers (it once took 3 GB for 6 s), and the fit is the same
    from minifilm.phases import sinusoid_fit as sf
    fps = 1000.0
    t = np.arange(int(3 * fps)) / fps
    v = np.sin(2 * np.pi * 1.5 * t)
    sizes = []
    design = sf._design

    def spy(offsets, weights, freqs, fps_):
        per_window = freqs.size if freqs.ndim == 1 else 1          # a grid, or one frequency per window
        sizes.append(np.broadcast_shapes(offsets.shape, weights.shape)[0] * offsets.shape[-1] * per_window)
        return design(offsets, weights, freqs, fps_)
    monkeypatch.setattr(sf, "_design", spy)
    fit = sf.fit_sinusoids(v, fps)
    assert max(sizes) <= sf.BLOCK_NUMBERS
    mid = slice(500, -500)
    np.testing.assert_allclose(fit.frequency[mid], 1.5, rtol=0.02)


def test_low_frame_rates_lower_the_cutoff_instead_of_failing():
    # below 10 fps the paper's 4 Hz lies at or above the Nyquist rate: the filter keeps what it can
    from minifilm.phases.sources import usable_cutoff
    assert usable_cutoff(4.0, 60.0) == 4.0 and usable_cutoff(4.0, 5.0) == pytest.approx(2.0)
    for fps in (2.0, 5.0, 8.0):
        t = np.arange(int(20 * fps)) / fps
        v = preprocess_source(np.sin(2 * np.pi * 0.5 * t), fps)
        assert np.all(np.isfinite(v)) and np.abs(v).max() > 0.1
