"""The plain, per-frame sinusoid fit (minifilm/phases/sinusoid_fit_plain.py, Sec. 4.1.4) against
known sinusoids and by hand, and the vectorised fit that labelling runs
(minifilm/phases/sinusoid_fit.py::fit_sinusoids) against it: on synthetic signals and on the
preprocessed sources of real BVH files from ../shared/data, every frame's phase, amplitude,
frequency, offset and fitted value agree to 1e-9 (measured: phases within 3e-13 cycles, the
offset within 1.1e-11 of the largest value, the rest closer), and the same frames
are skipped."""
import numpy as np
import pytest

from minifilm.motion.bvh import read_bvh
from minifilm.body.rig import detect_skeleton
from minifilm.phases.label import label
from minifilm.phases.sinusoid_fit import fit_sinusoids
from minifilm.phases.sinusoid_fit_plain import (Window, apply_bounds, fit_sinusoids_plain, frame_window,
                                                normal_equations)
from repo_paths import SHARED_DATA, need_data

TOL = 1e-9


def assert_fits_agree(plain, fast):
    d = np.abs(plain.phase - fast.phase) % 1.0
    assert np.max(np.minimum(d, 1.0 - d)) < TOL, "phase (cycles)"
    for name in ("amplitude", "frequency", "offset", "fit"):
        a, b = getattr(plain, name), getattr(fast, name)
        assert np.max(np.abs(a - b)) < TOL * max(1.0, float(np.max(np.abs(b)))), name
    assert np.array_equal(plain.skipped, fast.skipped)


# ------------------------------------------------------------------------------ the plain fit itself
def test_the_3x3_system_recovers_a_sinusoid_at_its_frequency():
    """y = 0.3 sin 2πFτ + 0.4 cos 2πFτ + 0.1 exactly: solving G c = r at F gives (0.3, 0.4, 0.1)."""
    fps, F = 60.0, 1.7
    tau = np.arange(-15, 16, dtype=float)
    angle = 2 * np.pi * F * tau / fps
    y = 0.3 * np.sin(angle) + 0.4 * np.cos(angle) + 0.1
    G, r, yy = normal_equations(np.array([F, 2 * F]), tau, np.ones_like(tau), y, fps)
    assert G.shape == (2, 3, 3) and r.shape == (2, 3)
    c = np.linalg.solve(G[0], r[0])
    np.testing.assert_allclose(c, [0.3, 0.4, 0.1], atol=1e-9)
    assert abs(yy - c @ r[0]) < 1e-8                      # no error left (but the ridge) at the right F
    c2 = np.linalg.solve(G[1], r[1])
    assert yy - c2 @ r[1] > 0.1                           # and plenty at the wrong one


def test_bounds_clip_the_offset_and_scale_the_amplitude():
    G, r, yy = np.eye(3), np.array([3.0, 4.0, 2.0]), 30.0  # unbounded optimum c = r: A = 5, B = 2
    c, sse = apply_bounds(G, r, yy, r.copy(), vmin=-1.0, vmax=1.0)
    assert c[2] == 1.0                                    # B clipped to vmax
    np.testing.assert_allclose(np.hypot(c[0], c[1]), 2.0)   # A scaled to vmax - vmin
    np.testing.assert_allclose(c[:2] / np.hypot(c[0], c[1]), [0.6, 0.8])  # direction (the phase) kept
    np.testing.assert_allclose(sse, yy - 2 * c @ r + c @ c)


def test_windows_shift_inwards_and_weight_the_connect_frames():
    v = np.arange(1.0, 21.0)                              # 20 frames, P = 3 -> 7 data frames
    w = frame_window(v, 0, 3, 1e-3)
    assert isinstance(w, Window)
    assert list(w.offset[w.data > 0]) == [0, 1, 2, 3, 4, 5, 6]          # shifted, not cut
    assert np.all(w.connect[:3] == 0)                     # the left connect frames lie before frame 0
    np.testing.assert_allclose(w.connect[-3:], [(1 - 1 / 3) ** 2, (1 - 2 / 3) ** 2, 0.0])
    assert (w.vmin, w.vmax) == (1.0, 10.0) and not w.skipped           # frames 0..9 seen
    assert frame_window(np.zeros(20), 10, 3, 1e-3).skipped


def test_plain_fit_finds_phase_and_frequency_of_a_clean_sinusoid():
    fps, F, n = 60.0, 1.25, 240
    t = np.arange(n) / fps
    fit = fit_sinusoids_plain(np.sin(2 * np.pi * (F * t + 0.1)), fps)
    mid = slice(40, -40)
    d = np.abs(fit.phase[mid] - np.mod(F * t[mid] + 0.1, 1.0)) % 1.0
    assert np.max(np.minimum(d, 1 - d)) < 1e-3
    np.testing.assert_allclose(fit.frequency[mid], F, rtol=1e-3)
    np.testing.assert_allclose(fit.amplitude[mid], 1.0, rtol=5e-3)    # the connect terms pull a little


def test_plain_fit_refuses_bad_input():
    with pytest.raises(ValueError, match="non-empty 1-D"):
        fit_sinusoids_plain(np.zeros((3, 2)), 30.0)
    with pytest.raises(ValueError, match="NaN"):
        fit_sinusoids_plain(np.array([0.0, np.nan]), 30.0)
    with pytest.raises(ValueError, match="fps > 0"):
        fit_sinusoids_plain(np.zeros(5), 0.0)


# ------------------------------------------------------------------------------ vectorised == plain
@pytest.mark.parametrize("fps, n", [(30, 200), (60, 300), (120, 400), (30, 9), (60, 1)])
def test_the_vectorised_fit_equals_the_plain_one_on_synthetic_signals(fps, n):
    """Two frequencies plus noise with a still stretch (skipped windows); shorter than a window;
    one frame. Several blocks (block=64) so edge and interior blocks both run."""
    rng = np.random.default_rng(fps * 1000 + n)
    t = np.arange(n) / fps
    v = np.sin(2 * np.pi * 1.3 * t) + 0.5 * np.sin(2 * np.pi * 0.4 * t + 1) + 0.1 * rng.standard_normal(n)
    v[n // 4: n // 2] = 0.0
    plain = fit_sinusoids_plain(v, fps)
    assert_fits_agree(plain, fit_sinusoids(v, fps, block=64))
    assert np.any(plain.skipped) == (n >= 200)


REAL_FILES = [("bandai2", "dataset-2_walk_active_001.bvh", None),          # 30 fps
              ("bvh/xia", "angry_13_000.bvh", None),                         # CMU skeleton, 120 fps
              ("bvh/bandai1", "dataset-1_walk-left_normal_001.bvh", ("pca", "pca", "contact", "pca"))]


@pytest.mark.parametrize("folder, name, sources", REAL_FILES, ids=[f[1] for f in REAL_FILES])
def test_the_vectorised_fit_equals_the_plain_one_on_real_files(folder, name, sources):
    """The four preprocessed sources (hands by PCA, feet by contacts, a turn's right foot by PCA)
    of real files, fitted both ways."""
    path = need_data(SHARED_DATA / folder / name, f"the shared BVH file {folder}/{name}")
    skeleton = detect_skeleton(read_bvh(path, scale=1.0))
    motion = read_bvh(path, scale=skeleton.bvh_scale)
    labels = label(motion, skeleton, sources=sources)
    for slot in range(4):
        v = labels.phases.source[:, slot]
        plain = fit_sinusoids_plain(v, motion.fps)
        assert_fits_agree(plain, fit_sinusoids(v, motion.fps))
        assert np.any(plain.amplitude > 0.1)              # a real source, with something to fit
