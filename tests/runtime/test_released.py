"""Loading / writing the released network (docs/original-code.md §10.1) and one forward pass from
the released input mean checked against NumPy written here straight from the .bin files
(§10.2) and the sanity facts of §13.3."""
import filecmp

import numpy as np
import pytest

from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.runtime.released import ReleasedFormatError, load_released, write_released
from minifilm.dataset.stats import NormStats


def f32(d, name):
    return np.fromfile(d / f"{name}.bin", dtype="<f4").astype(np.float64)


def reference_predict(d, X, L, style="000"):
    """§10.2 steps 1-6 from the raw files, float64, biased layer norm, FiLM from unit 0."""
    elu = lambda v: np.where(v > 0, v, np.exp(np.minimum(v, 0)) - 1)
    x = (X - f32(d, "Xmean")) / f32(d, "Xstd")
    g = (L - f32(d, "GT_Xmean")) / f32(d, "GT_Xstd")
    h = g
    for l in range(3):
        b = f32(d, f"wc{l}_b")
        h = f32(d, f"wc{l}_w").reshape(b.size, h.size) @ h + b
        h = elu(h) if l < 2 else np.exp(h) / np.exp(h).sum()
    omega = h
    film = [f32(d, f"Style_{style}_{k}") for k in ("scale1", "shift1", "scale2", "shift2")]
    h = x
    for l in range(3):
        bs = [f32(d, f"cp{l}_b{e}") for e in range(8)]
        W = sum(omega[e] * f32(d, f"cp{l}_a{e}").reshape(bs[e].size, h.size) for e in range(8))
        h = W @ h + sum(omega[e] * bs[e] for e in range(8))
        if l < 2:
            h = (h - h.mean()) / h.std()
            h = elu(film[2 * l] * h + film[2 * l + 1])
    return h * f32(d, "Ystd") + f32(d, "Ymean"), omega


@pytest.fixture(scope="module")
def released_dir(shared_data):
    return shared_data / "released-lpn"


@pytest.fixture(scope="module")
def released(released_dir):
    return load_released(released_dir, dtype=np.float64)


def test_sizes_and_styles(released):
    cfg = released.model.config
    assert (cfg.x_dim, cfg.z_dim, cfg.phase_dim, cfg.n_experts, cfg.hidden, cfg.gating_hidden) == (348, 342, 8, 8, 512, 32)
    assert len(released.styles) == 100
    names = list(released.styles)
    assert names[:3] == ["Aeroplane", "Akimbo", "Angry"]
    assert names[95:] == ["095", "096", "097", "098", "099"]    # fine-tuned, unnamed
    assert all(v.shape == (2048,) for v in released.styles.values())
    assert released.model.film is None


def test_forward_from_input_mean_matches_numpy_from_files(released, released_dir):
    d = released_dir
    X, L = f32(d, "Xmean"), f32(d, "GT_Xmean")
    Y_ref, omega = reference_predict(d, X, L)
    Y = released.predict(X, L, released.styles["Aeroplane"])
    np.testing.assert_allclose(Y, Y_ref, rtol=1e-9, atol=1e-10)
    # §13.3 sanity facts
    assert 0.07 < omega.min() and omega.max() < 0.25
    np.testing.assert_allclose(Y[0:4], [0, 0.003, 0.001, 1.003], atol=1.5e-3)
    np.testing.assert_allclose(Y[24:30], [0, 0.991, 0.003, 0.001, 0.027, 1.004], atol=1.5e-3)
    np.testing.assert_allclose(Y[340:342], [0.5, 0.5], atol=0.02)
    # the float32 model agrees to float32 precision
    r32 = load_released(d)
    np.testing.assert_allclose(r32.predict(X, L, r32.styles["Aeroplane"]), Y_ref, rtol=1e-4, atol=1e-4)


def test_phase_and_contact_response(released, released_dir):
    """§13.3: with L = [0,2,0,-2, 2,0,-2,0] the feet update and contacts point the right way."""
    L = np.array([0, 2, 0, -2, 2, 0, -2, 0], float)
    X = f32(released_dir, "Xmean")
    Y = released.predict(X, L, released.styles["Aeroplane"])
    np.testing.assert_allclose(Y, reference_predict(released_dir, X, L)[0], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(Y[336:340], [-0.006, -0.201, 0.021, 0.200], atol=2e-3)
    np.testing.assert_allclose(Y[340:342], [0.086, 0.877], atol=2e-3)


def test_write_released_reproduces_the_files_byte_for_byte(released_dir, tmp_path):
    r = load_released(released_dir)
    write_released(r.model, r.stats, r.styles, tmp_path)
    originals = sorted(p.name for p in released_dir.glob("*.bin"))
    assert sorted(p.name for p in tmp_path.glob("*.bin")) == originals
    match, mismatch, errors = filecmp.cmpfiles(released_dir, tmp_path, originals + ["styles.txt"], shallow=False)
    assert not mismatch and not errors, (mismatch, errors)


def small_folder(tmp_path):
    cfg = ModelConfig.tiny()
    rng = np.random.default_rng(1)
    model = StyleModel(cfg, rng, with_film_generator=False)
    stats = NormStats(rng.standard_normal(cfg.x_dim), 1 + rng.random(cfg.x_dim), rng.standard_normal(cfg.z_dim),
                      1 + rng.random(cfg.z_dim), rng.standard_normal(8), 1 + rng.random(8))
    styles = {"Happy": rng.standard_normal(cfg.film_dim), "001": rng.standard_normal(cfg.film_dim)}
    write_released(model, stats, styles, tmp_path)
    return model, stats, styles


def test_round_trip_small_model(tmp_path):
    model, stats, styles = small_folder(tmp_path)
    r = load_released(tmp_path)
    assert r.model.config.hidden == model.config.hidden and r.model.config.n_experts == model.config.n_experts
    for a, b in zip(model.parameter_sets(), r.model.parameter_sets()):
        np.testing.assert_array_equal(a.data, b.data)
    assert list(r.styles) == ["Happy", "001"]
    np.testing.assert_allclose(r.styles["Happy"], styles["Happy"].astype(np.float32))
    np.testing.assert_allclose(r.stats.z_std, stats.z_std.astype(np.float32))


def test_clear_errors(tmp_path):
    small_folder(tmp_path)
    (tmp_path / "cp1_a2.bin").unlink()
    with pytest.raises(ReleasedFormatError, match="missing file .*cp1_a2.bin"):
        load_released(tmp_path)
    small_folder(tmp_path)
    np.zeros(7, "<f4").tofile(tmp_path / "wc1_w.bin")
    with pytest.raises(ReleasedFormatError, match="wc1_w.bin holds 7 float32"):
        load_released(tmp_path)
    small_folder(tmp_path)
    (tmp_path / "styles.txt").write_text("000 Happy\nbad line\n")
    with pytest.raises(ReleasedFormatError, match="line 2"):
        load_released(tmp_path)
    with pytest.raises(ReleasedFormatError, match="not a directory"):
        load_released(tmp_path / "nope")
