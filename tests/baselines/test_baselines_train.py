"""The variants' data path (minifilm.baselines.variant_data) and training every variant with train.Trainer."""
import numpy as np
import pytest

from minifilm.model.config import ModelConfig
from minifilm.baselines.variants import VARIANTS, build_variant, model_from_checkpoint
from minifilm.features.layout import FeatureLayout
from minifilm.train.trainer import TrainConfig, Trainer
from minifilm.dataset.arrays import TrainData
from minifilm.dataset.stats import NormStats
from minifilm.baselines.variant_data import variant_data

J = 3
LAYOUT = FeatureLayout.generic(J)               # x 84, z 78 (motion 60, phases 8, updates 8, contacts 2)
CFG = ModelConfig.tiny(x_dim=LAYOUT.x_dim, z_dim=LAYOUT.z_dim, clip_channels=LAYOUT.clip_dim, dropout=0.1)


def make_data(seed, n_per_style=48, styles=(0, 1, 2)):
    """Random frames whose phase columns hold known local phases, normalised with random stats."""
    rng = np.random.default_rng(seed)
    teacher = np.random.default_rng(99)
    A = teacher.standard_normal((LAYOUT.x_dim, LAYOUT.z_dim)) / np.sqrt(LAYOUT.x_dim)
    style_offset = teacher.standard_normal((3, LAYOUT.z_dim))
    N = n_per_style * len(styles)
    style = np.repeat(styles, n_per_style)
    phase = rng.random((N, 4))
    step = 0.02 + 0.01 * rng.random((N, 4))
    amp = 0.5 + rng.random((N, 4))
    vec = lambda ph: np.stack([amp * np.sin(2 * np.pi * ph), amp * np.cos(2 * np.pi * ph)], axis=2).reshape(N, 8)  # noqa: E731
    x = rng.standard_normal((N, LAYOUT.x_dim))
    z = np.tanh(x @ A) + style_offset[style]
    z[:, LAYOUT.z_phases] = vec(phase + step)
    z[:, LAYOUT.z_phase_updates] = vec(phase + step) - vec(phase)
    z[:, LAYOUT.z_contacts] = rng.random((N, 2)) > 0.5
    stats = NormStats(np.zeros(LAYOUT.x_dim), np.ones(LAYOUT.x_dim), 0.1 * rng.standard_normal(LAYOUT.z_dim),
                      0.5 + rng.random(LAYOUT.z_dim), 0.1 * rng.standard_normal(8), 0.5 + rng.random(8))
    clips = rng.standard_normal((3 * len(styles), CFG.clip_frames, CFG.clip_channels)) + np.repeat(styles, 3)[:, None, None]
    f32 = lambda a: np.asarray(a, dtype=np.float32)   # noqa: E731
    data = TrainData(f32(x), f32(stats.normalize_p(vec(phase))), f32(stats.normalize_z(z)), style, f32(clips),
                     np.repeat(styles, 3), style_names=["A", "B", "C"])
    return data, stats, phase, step


def test_pfnn_gets_the_right_foot_phase_and_its_update():
    data, stats, phase, step = make_data(0)
    out, info = variant_data("PFNN FiLM", data, LAYOUT, stats)
    np.testing.assert_allclose(out.p[:, 0], phase[:, 3], atol=1e-5)        # slot 3 = right foot
    assert out.z.shape == (len(data), 60 + 1 + 2)
    dphi = out.z[:, 60] * info["phase_update_std"] + info["phase_update_mean"]
    np.testing.assert_allclose(dphi, step[:, 3], atol=1e-5)
    np.testing.assert_array_equal(out.z[:, :60], data.z[:, :60])
    np.testing.assert_array_equal(out.z[:, 61:], data.z[:, LAYOUT.z_contacts])
    # val / test reuse the training split's Δφ statistics
    val, _ = make_data(1)[:2]
    out_val, info_val = variant_data("PFNN one-hot", val, LAYOUT, stats, reference=info)
    assert info_val["phase_update_std"] == info["phase_update_std"]


def test_mann_gets_end_effector_velocities_from_x():
    data, stats, _, _ = make_data(0)
    out, _ = variant_data("MANN FiLM", data, LAYOUT, stats, end_effectors=[2, 0, 1, 2])
    # x: 48 trajectory numbers, then per joint [position, forward, up, velocity] x 3
    cols = [48 + 12 * j + 9 + c for j in (2, 0, 1, 2) for c in range(3)]
    np.testing.assert_array_equal(out.p, data.x[:, cols])
    assert out.z.shape == (len(data), 60 + 2)
    with pytest.raises(ValueError, match="end-effector"):
        variant_data("MANN FiLM", data, LAYOUT, stats)


@pytest.mark.parametrize("name", VARIANTS)
def test_every_variant_trains_with_the_trainer(name):
    data, stats, _, _ = make_data(0)
    vdata, _ = variant_data(name, data, LAYOUT, stats, end_effectors=[0, 1, 2, 2])
    model = build_variant(name, CFG, np.random.default_rng(0), n_styles=3)
    trainer = Trainer(model, stats, TrainConfig(epochs=4, batch_size=16, lr=3e-3, seed=0),
                      positions_idx=LAYOUT.joint_columns("z", "position"), parents=np.array(LAYOUT.parents))
    before = trainer.evaluate(vdata)
    trainer.fit(vdata)
    after = trainer.evaluate(vdata)
    assert after["loss"] < 0.8 * before["loss"], (before["loss"], after["loss"])


def test_variant_checkpoint_resumes_as_the_same_variant(tmp_path):
    data, stats, _, _ = make_data(0)
    vdata, _ = variant_data("PFNN Resad", data, LAYOUT, stats)
    model = build_variant("PFNN Resad", CFG, np.random.default_rng(0), n_styles=3)
    path = tmp_path / "pfnn_resad.npz"
    trainer = Trainer(model, stats, TrainConfig(epochs=1, batch_size=16, checkpoint_path=str(path)))
    trainer.fit(vdata)
    resumed = Trainer.resume(path, build_model=model_from_checkpoint)
    assert resumed.model.name == "PFNN Resad" and resumed.model.n_styles == 3
    for a, b in zip(model.parameter_sets(), resumed.model.parameter_sets()):
        np.testing.assert_array_equal(a.data, b.data)
    idx = np.arange(5)
    np.testing.assert_array_equal(model.forward(vdata.x[idx], vdata.p[idx], None, style=vdata.style[idx]),
                                  resumed.model.forward(vdata.x[idx], vdata.p[idx], None, style=vdata.style[idx]))
