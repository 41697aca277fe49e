"""Training (Sec. 4.3), checkpoints, resume, NaN stop and fine-tuning (Sec. 5.3.2) on a small
learnable problem built from random arrays."""
import json

import numpy as np
import pytest

from minifilm.train.checkpoint import CheckpointError, load_checkpoint
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.train.batches import draw_clips, draw_shared_clips, epoch_batches
from minifilm.train.finetune import finetune
from minifilm.train.trainer import TrainConfig, Trainer, TrainingDiverged, train
from minifilm.dataset.arrays import TrainData
from minifilm.dataset.stats import NormStats

PARENTS = np.array([-1, 0, 1, 0])
POS_IDX = 4 + np.arange(12).reshape(4, 3)      # z columns 4..15 hold 4 joint positions
CFG = ModelConfig.tiny(x_dim=10, z_dim=18, clip_channels=4, dropout=0.1)


def make_data(seed, styles=(0, 1, 2), frames=(64, 80, 72), n_clips=4):
    """z depends on x, on the phases and on the style; the style is visible only in the clips."""
    teacher = np.random.default_rng(123)                      # the same task for every split
    A = teacher.standard_normal((CFG.x_dim, CFG.z_dim)) / np.sqrt(CFG.x_dim)
    Pm = teacher.standard_normal((8, CFG.z_dim)) / np.sqrt(8)
    offsets = teacher.standard_normal((10, CFG.z_dim))
    patterns = teacher.standard_normal((10, CFG.clip_frames, CFG.clip_channels))
    rng = np.random.default_rng(seed)
    xs, ps, zs, ss, cs, css = [], [], [], [], [], []
    for s, n in zip(styles, frames):
        x = rng.standard_normal((n, CFG.x_dim))
        p = rng.standard_normal((n, 8))
        xs.append(x); ps.append(p)
        zs.append(np.tanh(x @ A) + 0.5 * np.sin(p @ Pm) + offsets[s])
        ss.append(np.full(n, s))
        cs.append(patterns[s] + 0.3 * rng.standard_normal((n_clips, CFG.clip_frames, CFG.clip_channels)))
        css.append(np.full(n_clips, s))
    f32 = lambda a: np.concatenate(a).astype(np.float32)
    return TrainData(f32(xs), f32(ps), f32(zs), np.concatenate(ss), f32(cs), np.concatenate(css),
                     style_names=[f"S{i}" for i in range(10)])


STATS = NormStats.identity(CFG.x_dim, CFG.z_dim)


def new_trainer(epochs=2, seed=0, **kw):
    model = StyleModel(CFG, np.random.default_rng(seed))
    cfg = TrainConfig(epochs=epochs, batch_size=16, lr=2e-3, seed=seed, **kw)
    return Trainer(model, STATS, cfg, POS_IDX, PARENTS, style_names=[f"S{i}" for i in range(10)])


def test_epoch_batches_are_style_balanced():
    style = np.array([0] * 40 + [1] * 70 + [2] * 35)
    batches = epoch_batches(style, 8, np.random.default_rng(0))
    assert [s for s, _ in batches] == [0, 1, 2] * (35 // 8)           # fixed cycle, shortest style
    for s, idx in batches:
        assert len(idx) == 8 and (style[idx] == s).all()
    all_idx = np.concatenate([idx for _, idx in batches])
    assert len(np.unique(all_idx)) == len(all_idx)                     # no frame twice in an epoch


def test_each_sample_gets_a_clip_of_its_own_style():
    data = make_data(0)
    idx = np.arange(len(data))
    clips = draw_clips(data, data.style[idx], np.random.default_rng(0))
    np.testing.assert_array_equal(data.clip_style[clips], data.style[idx])
    assert len(np.unique(clips)) > 3


def test_training_reduces_loss():
    train_data, val_data = make_data(0), make_data(1)
    trainer = new_trainer(epochs=10)
    before = trainer.evaluate(val_data)
    trainer.fit(train_data, val_data)
    after = trainer.history[-1]["val"]
    assert after["mse"] < 0.5 * before["mse"], (before["mse"], after["mse"])
    assert after["bll"] < before["bll"]
    assert set(after["per_style"]) == {"S0", "S1", "S2"}
    assert trainer.history[-1]["train"]["loss"] < trainer.history[0]["train"]["loss"]
    assert trainer.step == 10 * 3 * (64 // 16)


def test_checkpoint_round_trip_and_resume_equivalence(tmp_path):
    data, val = make_data(0), make_data(1)
    straight = new_trainer(epochs=2)
    straight.fit(data, val)

    path = tmp_path / "ck.npz"
    first = new_trainer(epochs=1, checkpoint_path=str(path))
    first.fit(data, val)
    meta, arrays = load_checkpoint(path)
    assert meta["epoch"] == 1 and meta["model_config"] == CFG.to_dict()
    resumed = Trainer.resume(path, TrainConfig.from_dict({**meta["train_config"], "epochs": 2}))
    for a, b in zip(first.model.parameter_sets(), resumed.model.parameter_sets()):
        np.testing.assert_array_equal(a.data, b.data)
    assert resumed.rng.bit_generator.state == first.rng.bit_generator.state
    np.testing.assert_array_equal(resumed.optimizer.m[1], first.optimizer.m[1])
    resumed.fit(data, val)
    for a, b in zip(straight.model.parameter_sets(), resumed.model.parameter_sets()):
        np.testing.assert_array_equal(a.data, b.data)
    assert json.dumps(resumed.history) == json.dumps(straight.history)


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")
def test_nan_stops_with_a_clear_error_and_keeps_the_checkpoint(tmp_path):
    path = tmp_path / "ck.npz"
    trainer = new_trainer(epochs=1, checkpoint_path=str(path))
    data = make_data(0)
    trainer.fit(data)
    good = path.read_bytes()
    before = [ps.data.copy() for ps in trainer.model.parameter_sets()]
    bad = make_data(0)
    bad.z[:] = np.nan
    with pytest.raises(TrainingDiverged, match=r"step 12 \(epoch 2, batch 1, style S0\): MSE loss is not finite"):
        trainer.fit(bad, epochs=2)
    assert path.read_bytes() == good
    for a, b in zip(before, trainer.model.parameter_sets()):
        np.testing.assert_array_equal(a, b.data)       # the bad step did not update anything
    # an infinite clip value reaches the loss through Ψ as well
    bad = make_data(0)
    bad.clips[:] = np.inf
    with pytest.raises(TrainingDiverged, match="not finite"):
        trainer.fit(bad, epochs=2)


def test_corrupt_checkpoints_give_clear_errors(tmp_path):
    path = tmp_path / "ck.npz"
    trainer = new_trainer(epochs=0)
    trainer.save(path)
    Trainer.resume(path)                                    # sane one loads
    raw = path.read_bytes()
    (tmp_path / "trunc.npz").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(CheckpointError, match="trunc.npz"):
        Trainer.resume(tmp_path / "trunc.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip file at all")
    with pytest.raises(CheckpointError, match="not a readable"):
        Trainer.resume(tmp_path / "junk.npz")
    np.savez(tmp_path / "nometa.npz", a=np.zeros(3))
    with pytest.raises(CheckpointError, match="meta.json"):
        Trainer.resume(tmp_path / "nometa.npz")
    # a parameter of the wrong shape
    meta, arrays = load_checkpoint(path)
    arrays["motion.W1"] = np.zeros((2, 2), np.float32)
    from minifilm.train.checkpoint import save_checkpoint
    meta.pop("format")
    save_checkpoint(tmp_path / "shape.npz", meta, arrays)
    with pytest.raises(CheckpointError, match="motion"):
        Trainer.resume(tmp_path / "shape.npz")
    with pytest.raises(CheckpointError, match="no such file"):
        Trainer.resume(tmp_path / "missing.npz")


def test_finetuning_moves_only_the_film_generator(tmp_path):
    path = tmp_path / "base.npz"
    base = new_trainer(epochs=3, checkpoint_path=str(path))
    base.fit(make_data(0))
    new_style, new_val = make_data(2, styles=(5,), frames=(64,)), make_data(3, styles=(5,), frames=(48,))
    tuned = finetune(path, new_style, new_val, TrainConfig(epochs=6, batch_size=16, lr=2e-3, seed=1))
    np.testing.assert_array_equal(tuned.model.gating.params.data, base.model.gating.params.data)
    np.testing.assert_array_equal(tuned.model.motion.params.data, base.model.motion.params.data)
    assert not np.array_equal(tuned.model.film.params.data, base.model.film.params.data)
    losses = [h["val"]["loss"] for h in tuned.history]
    assert losses[-1] < losses[0]
    assert tuned.config.freeze == ("gating", "motion")


def test_nan_gradient_is_named(monkeypatch):
    trainer = new_trainer(epochs=1)
    real_backward = trainer.model.backward

    def poisoned(dz, **options):
        out = real_backward(dz, **options)
        trainer.model.motion.params.grads["W1"][0, 0, 0] = np.inf
        return out

    monkeypatch.setattr(trainer.model, "backward", poisoned)
    before = trainer.model.motion.params.data.copy()
    with pytest.raises(TrainingDiverged, match=r"step 0 .*gradient of the motion network is not finite \(inf\)"):
        trainer.fit(make_data(0))
    np.testing.assert_array_equal(trainer.model.motion.params.data, before)


def test_trained_model_uses_the_style_clip():
    """After training, pairing frames with clips of the wrong style raises the error: the style
    information reaches Φ through Ψ's FiLM parameters only."""
    trainer = new_trainer(epochs=12)
    trainer.fit(make_data(0))
    val = make_data(1)
    right = trainer.evaluate(val)["mse"]
    wrong = make_data(1)
    wrong.clip_style = (wrong.clip_style + 1) % 3          # relabel: style s now gets clips of s-1
    assert trainer.evaluate(wrong)["mse"] > 1.5 * right


def test_progress_line_on_stderr(capsys):
    trainer = new_trainer(epochs=1, progress=True)
    trainer.fit(make_data(0))
    err = capsys.readouterr().err
    assert "\repoch 1/1  batch 12/12" in err and "loss" in err


def test_input_noise_perturbs_only_the_training_inputs(monkeypatch):
    """With input_noise the model sees x and p plus N(0, sigma^2) noise in training steps (the
    targets and the evaluation stay clean); without it, exactly the data rows."""
    data = make_data(0)
    for sigma in (0.0, 0.3):
        trainer = new_trainer(epochs=1, input_noise=sigma)
        seen = []
        real_forward = trainer.model.forward

        def spy(x, p, clip, train=False, **kw):
            if train:
                seen.append((x.copy(), p.copy()))
            return real_forward(x, p, clip, train=train, **kw)

        monkeypatch.setattr(trainer.model, "forward", spy)
        batches = epoch_batches(data.style, trainer.config.batch_size, np.random.default_rng(0))
        trainer.fit(data)
        dx = np.concatenate([x - data.x[idx] for (x, _), (_, idx) in zip(seen, batches)])
        dp = np.concatenate([p - data.p[idx] for (_, p), (_, idx) in zip(seen, batches)])
        assert len(seen) == len(batches)
        if sigma == 0:
            assert np.all(dx == 0) and np.all(dp == 0)
        else:
            assert abs(dx.std() - sigma) < 0.03 and abs(dp.std() - sigma) < 0.05
            assert abs(dx.mean()) < 0.02


def test_negative_input_noise_is_refused():
    with pytest.raises(ValueError, match="input_noise"):
        TrainConfig(input_noise=-0.1)


def test_shared_clips_are_of_the_batch_style_and_spread_evenly():
    data = make_data(2)
    rng = np.random.default_rng(0)
    clips, assign = draw_shared_clips(data, 1, 4, 16, rng)
    assert clips.shape == (4,) and (data.clip_style[clips] == 1).all()
    assert sorted(np.bincount(assign, minlength=4).tolist()) == [4, 4, 4, 4]    # 16 samples over 4 clips
    clips, assign = draw_shared_clips(data, 0, 32, 5, rng)                      # never more clips than samples
    assert clips.shape == (5,) and sorted(assign.tolist()) == [0, 1, 2, 3, 4]


def test_training_with_shared_clips_runs_psi_on_fewer_clips(monkeypatch):
    """clips_per_batch: Ψ sees that many clips per step, training still learns, and the trainer's
    evaluation (Ψ once per clip) gives the same numbers as per-sample clips would."""
    data, val = make_data(0), make_data(1)
    trainer = new_trainer(epochs=3, clips_per_batch=2)
    seen = []
    original = trainer.model.film.forward
    monkeypatch.setattr(trainer.model.film, "forward", lambda clip, **kw: seen.append(len(clip)) or original(clip, **kw))
    first = trainer.evaluate(val)["loss"]
    seen.clear()
    trainer.fit(data)
    assert set(seen) == {2}                            # every training step: two clips through Ψ
    assert trainer.history[-1]["train"]["loss"] < trainer.history[0]["train"]["loss"]
    assert trainer.evaluate(val)["loss"] < first
    # evaluation: Ψ once per clip equals Ψ per sample
    rng = np.random.default_rng([trainer.config.seed, 1])
    s0 = val.style == 0
    idx = np.flatnonzero(s0)
    clip_idx = draw_clips(val, val.style[idx], rng)
    per_sample = trainer.model.forward(val.x[idx], val.p[idx], val.clips[clip_idx])
    once = trainer.model.forward_with_film(val.x[idx], val.p[idx], trainer._clip_films(val)[clip_idx])
    np.testing.assert_allclose(once, per_sample, rtol=1e-5, atol=1e-6)


def test_clips_per_batch_below_one_is_refused():
    with pytest.raises(ValueError, match="clips_per_batch"):
        TrainConfig(clips_per_batch=0)


def test_cosine_learning_rate_schedule():
    trainer = new_trainer(epochs=4, lr_schedule="cosine", lr_floor=0.1)
    lr = trainer.config.lr
    assert trainer.learning_rate(0) == pytest.approx(lr)
    assert trainer.learning_rate(2) == pytest.approx(lr * 0.55)          # half-way: the mean of lr and the floor
    assert trainer.learning_rate(4) == pytest.approx(lr * 0.1)
    assert new_trainer(epochs=4).learning_rate(3) == lr                  # constant by default (the paper)
    data = make_data(0)
    trainer.fit(data, epochs=1)
    assert trainer.optimizer.lr < lr and trainer.optimizer.lr > trainer.learning_rate(1.0) - 1e-12
    with pytest.raises(ValueError, match="lr_schedule"):
        TrainConfig(lr_schedule="step")
