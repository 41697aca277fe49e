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


# ---- settings and entry points: bll_weight, evaluate's weighting, train(), resume, checkpoints ----
@pytest.mark.parametrize("weight", [0.0, 0.5, 2.0])
def test_bll_weight_scales_the_bone_length_loss_and_its_gradient(weight):
    """L = L_mse + w L_bll (Eq. 5-7 with the weight of TrainConfig.bll_weight): the reported BLL is
    w times Eq. (7) and the gradient w times its gradient; w = 0 leaves the MSE alone."""
    from minifilm.model.losses import bone_length_loss, mse_loss
    trainer = new_trainer(bll_weight=weight)
    rng = np.random.default_rng(0)
    pred, target = rng.standard_normal((5, CFG.z_dim)), rng.standard_normal((5, CFG.z_dim))
    mse, bll, dpred = trainer.losses(pred, target)
    m, dm = mse_loss(pred, target)
    b, db = bone_length_loss(pred, target, POS_IDX, PARENTS, STATS.z_mean, STATS.z_std)
    assert b > 0.1 and mse == m
    assert bll == pytest.approx(weight * b, rel=1e-12, abs=0.0)
    np.testing.assert_allclose(dpred, dm + weight * db, rtol=1e-12, atol=1e-15)
    if weight == 0.0:
        assert bll == 0.0 and np.array_equal(dpred, dm)


def test_bll_weight_changes_training():
    """The weight reaches the optimiser: one epoch with w = 0 and w = 2 from the same start ends
    at different weights, and the recorded training BLL of w = 0 is 0."""
    data = make_data(0)
    runs = {w: new_trainer(epochs=1, bll_weight=w) for w in (0.0, 2.0)}
    for t in runs.values():
        t.fit(data)
    assert runs[0.0].history[0]["train"]["bll"] == 0.0 and runs[2.0].history[0]["train"]["bll"] > 0
    assert not np.array_equal(runs[0.0].model.motion.params.data, runs[2.0].model.motion.params.data)


def test_evaluate_weights_every_style_equally():
    """Eq. (5)/(7) average per style, then over styles: a style with 10 frames counts as much as
    one with 100 (evaluation batches of 7 frames, so the per-style means span uneven batches).
    One clip per style, so the expected numbers follow from plain forward passes."""
    data = make_data(3, styles=(0, 1), frames=(10, 100), n_clips=1)
    trainer = new_trainer(eval_batch=7)
    result = trainer.evaluate(data)
    per_style = {}
    for s in (0, 1):
        idx = np.flatnonzero(data.style == s)
        clip = data.clips[data.clip_style == s]
        pred = trainer.model.forward(data.x[idx], data.p[idx], np.repeat(clip, len(idx), axis=0))
        mse, bll, _ = trainer.losses(pred, data.z[idx])
        per_style[f"S{s}"] = (mse, bll)
        assert result["per_style"][f"S{s}"]["mse"] == pytest.approx(mse, rel=1e-4)
        assert result["per_style"][f"S{s}"]["bll"] == pytest.approx(bll, rel=1e-4)
    (m0, b0), (m1, b1) = per_style["S0"], per_style["S1"]
    assert result["mse"] == pytest.approx((m0 + m1) / 2, rel=1e-4)
    assert result["bll"] == pytest.approx((b0 + b1) / 2, rel=1e-4)
    assert result["loss"] == pytest.approx(result["mse"] + result["bll"], rel=1e-12)
    frame_weighted = (10 * m0 + 100 * m1) / 110
    assert abs(result["mse"] - frame_weighted) > 100 * abs(result["mse"] - (m0 + m1) / 2)


def test_train_is_a_fresh_trainer_fitted():
    """train(): a new Trainer with the given settings, fitted for config.epochs with validation
    after every epoch, exactly as building the Trainer and calling fit would."""
    data, val = make_data(0), make_data(1)
    cfg = TrainConfig(epochs=2, batch_size=16, lr=2e-3, seed=4)
    trainer = train(StyleModel(CFG, np.random.default_rng(4)), data, val, STATS, POS_IDX, PARENTS, cfg,
                    style_names=[f"S{i}" for i in range(10)])
    manual = Trainer(StyleModel(CFG, np.random.default_rng(4)), STATS, TrainConfig(**cfg.to_dict()), POS_IDX,
                     PARENTS, [f"S{i}" for i in range(10)])
    manual.fit(data, val)
    assert trainer.epoch == 2 and [h["epoch"] for h in trainer.history] == [1, 2]
    assert all("val" in h for h in trainer.history) and trainer.config is cfg
    assert json.dumps(trainer.history) == json.dumps(manual.history)
    for a, b in zip(trainer.model.parameter_sets(), manual.model.parameter_sets()):
        np.testing.assert_array_equal(a.data, b.data)


def test_resume_without_the_optimiser_is_a_new_run_from_the_weights(tmp_path):
    """restore_optimizer=False (what fine-tuning uses): the weights, statistics and loss settings
    come from the checkpoint, but the optimiser, the generator, the epoch count and the history
    start afresh, so the run equals a new Trainer built on those weights."""
    path = tmp_path / "ck.npz"
    first = new_trainer(epochs=1, checkpoint_path=str(path))
    first.fit(make_data(0))
    assert first.optimizer.steps[0] > 0
    cfg = TrainConfig(epochs=1, batch_size=16, lr=2e-3, seed=9)
    fresh = Trainer.resume(path, cfg, restore_optimizer=False)
    for a, b in zip(first.model.parameter_sets(), fresh.model.parameter_sets()):
        np.testing.assert_array_equal(a.data, b.data)
    assert fresh.epoch == 0 and fresh.step == 0 and fresh.history == []
    assert fresh.optimizer.steps == [0, 0, 0] and all(not m.any() for m in fresh.optimizer.m + fresh.optimizer.v)
    assert fresh.rng.bit_generator.state == np.random.default_rng(9).bit_generator.state
    np.testing.assert_array_equal(fresh.positions_idx, POS_IDX)
    # and it trains like a new Trainer on the same weights
    twin = Trainer(StyleModel(CFG, np.random.default_rng(0)), STATS, cfg, POS_IDX, PARENTS, fresh.style_names)
    for a, b in zip(twin.model.parameter_sets(), fresh.model.parameter_sets()):
        a.data[...] = b.data
    for t in (fresh, twin):
        t.fit(make_data(0))
    for a, b in zip(twin.model.parameter_sets(), fresh.model.parameter_sets()):
        np.testing.assert_array_equal(a.data, b.data)
    # restore_optimizer=True (the default) continues the old run instead
    cont = Trainer.resume(path, cfg)
    assert cont.epoch == 1 and cont.optimizer.steps == first.optimizer.steps


@pytest.mark.parametrize("every,epochs,saved", [(1, 3, [1, 2, 3]), (2, 3, [2]), (2, 4, [2, 4]), (5, 3, [])])
def test_checkpoint_every_n_epochs(tmp_path, monkeypatch, every, epochs, saved):
    path = tmp_path / "ck.npz"
    trainer = new_trainer(epochs=epochs, checkpoint_path=str(path), checkpoint_every=every)
    calls = []
    real_save = trainer.save
    monkeypatch.setattr(trainer, "save", lambda p: (calls.append((trainer.epoch, p)), real_save(p)))
    trainer.fit(make_data(0, frames=(32, 32, 32)))
    assert calls == [(e, str(path)) for e in saved]
    if saved:
        assert load_checkpoint(path)[0]["epoch"] == saved[-1]
    else:
        assert not path.exists()
