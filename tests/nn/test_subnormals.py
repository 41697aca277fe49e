"""No subnormal float32 numbers in training (reports/2026-12-02_subnormal_floats.md): Adam's moments are flushed to 0 where they
would fall below the smallest normal number, and nothing else is changed.

Many CPUs take a slow path for every operation on a subnormal number; in train_small's own
checkpoint 67 % of Ψ's first moments were subnormal (a dead unit's m shrinks by beta1 a step).
benchmarks/kernels.py --only subnormal shows what they cost on the machine at hand."""
import numpy as np
import pytest

from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.dataset.arrays import TrainData
from minifilm.dataset.stats import NormStats
from minifilm.nn import fast_optim
from minifilm.nn.fast_optim import ChunkedAdam
from minifilm.nn.optim import Adam, flush_subnormals
from minifilm.nn.params import Parameters
from minifilm.train.trainer import TrainConfig, Trainer


def subnormals(a) -> int:
    a = np.asarray(a)
    return int(np.count_nonzero((a != 0) & (np.abs(a) < np.finfo(a.dtype).tiny)))


def unflushed_chunk(w, g, m, v, buf, beta1, beta2, step_size, eps_hat, tiny):
    """The chunk update as it was before the flush was added: the reference for 'unchanged'."""
    np.subtract(g, m, out=buf)
    buf *= 1 - beta1
    m += buf
    np.multiply(g, g, out=buf)
    buf -= v
    buf *= 1 - beta2
    v += buf
    np.sqrt(v, out=buf)
    buf += eps_hat
    np.divide(m, buf, out=buf)
    buf *= step_size
    w -= buf


def gradient_stream(rng, size, step):
    """Gradients of (size,) where units 0-99 go silent after step 10 (a dead ReLU: m and v decay)
    and units 100-199 get gradients of ~1e-21 (their squares are subnormal); the rest are N(0, 1e-2)."""
    g = (1e-2 * rng.standard_normal(size)).astype(np.float32)
    if step > 10:
        g[:100] = 0
    g[100:200] = np.float32(1e-21) * np.sign(g[100:200])
    return g


@pytest.mark.parametrize("optimiser", [Adam, ChunkedAdam])
def test_adam_on_a_gradient_stream_going_to_zero_keeps_nothing_subnormal(optimiser, monkeypatch):
    monkeypatch.setattr(fast_optim, "CHUNK", 512)
    p = Parameters({"w": (1300,)})                                 # three chunks, a partial last one
    rng = np.random.default_rng(0)
    p.data[...] = rng.standard_normal(p.size)
    opt = optimiser([p], lr=1e-3)
    for step in range(1, 1201):                                  # m of a silent unit: 0.9^t
        p.grad[...] = gradient_stream(rng, p.size, step)
        opt.step()
        assert subnormals(opt.m[0]) == subnormals(opt.v[0]) == subnormals(p.data) == 0, step
    assert np.all(opt.m[0][:100] == 0) and np.all(opt.v[0][100:200] == 0)   # flushed: what they decay to
    assert np.all(opt.m[0][100:] != 0) and np.all(opt.v[0][:100] > 0) and np.all(opt.v[0][200:] > 0)


def test_without_the_flush_the_same_stream_makes_subnormals(monkeypatch):
    """The test above can fail: the update without the flush leaves subnormal moments."""
    monkeypatch.setattr(fast_optim, "_adam_chunk", unflushed_chunk)
    p = Parameters({"w": (1000,)})
    rng = np.random.default_rng(0)
    opt = ChunkedAdam([p], lr=1e-3)
    counts = []
    for step in range(1, 901):
        p.grad[...] = gradient_stream(rng, p.size, step)
        opt.step()
        counts.append(subnormals(opt.m[0]) + subnormals(opt.v[0]))
    assert max(counts) >= 100 and subnormals(opt.v[0]) >= 100


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_flushing_update_is_bit_identical_for_normal_numbers(dtype):
    """Where no moment falls below the normal range, the chunked update with the flush gives
    exactly the numbers of the update without it (weights, both moments, every step)."""
    rng = np.random.default_rng(1)
    sets = [Parameters({"w": (n,)}, dtype=dtype) for n in (fast_optim.CHUNK + 77, 300)]
    twins = [Parameters({"w": (p.size,)}, dtype=dtype) for p in sets]
    for p, q in zip(sets, twins):
        p.data[...] = q.data[...] = rng.standard_normal(p.size)
    flushing, plain = ChunkedAdam(sets, lr=1e-3), ChunkedAdam(twins, lr=1e-3)
    for _ in range(20):
        for p, q in zip(sets, twins):
            p.grad[...] = q.grad[...] = rng.standard_normal(p.size) * 10.0 ** rng.integers(-6, 1)
        flushing.step()
        fast_optim._adam_chunk, real = unflushed_chunk, fast_optim._adam_chunk
        try:
            plain.step()
        finally:
            fast_optim._adam_chunk = real
        for i in range(2):
            np.testing.assert_array_equal(sets[i].data, twins[i].data)
            np.testing.assert_array_equal(flushing.m[i], plain.m[i])
            np.testing.assert_array_equal(flushing.v[i], plain.v[i])


def test_flush_subnormals_touches_only_subnormals():
    tiny = np.finfo(np.float32).tiny
    a = np.array([0.0, tiny, -tiny, tiny / 2, -tiny / 1e6, 1.0, -3e-30, np.inf], np.float32)
    flushed = flush_subnormals(a.copy())
    np.testing.assert_array_equal(flushed, np.array([0.0, tiny, -tiny, 0.0, 0.0, 1.0, -3e-30, np.inf], np.float32))
    assert subnormals(a) == 2 and subnormals(flushed) == 0


def test_loading_subnormal_moments_flushes_them():
    """A checkpoint written before the flush (67 % of Ψ's m subnormal) loads without them."""
    p = Parameters({"w": (4,)})
    opt = ChunkedAdam([p])
    tiny = np.finfo(np.float32).tiny
    opt.load_state_dict({"steps": np.array([5]), "m.0": np.array([tiny / 3, 1e-3, -tiny / 7, 0], np.float32),
                         "v.0": np.array([tiny / 2, 1e-6, 0, 1.0], np.float32)})
    np.testing.assert_array_equal(opt.m[0], [0, np.float32(1e-3), 0, 0])
    np.testing.assert_array_equal(opt.v[0], [0, np.float32(1e-6), 0, 1.0])


# ---- a few hundred steps of a small style model -------------------------------------------------
CFG = ModelConfig.tiny(x_dim=10, z_dim=18, clip_channels=4, dropout=0.1)


def toy_data(rng):
    n = 240
    style = np.repeat(np.arange(3), n // 3)
    x, p = rng.standard_normal((n, CFG.x_dim)), rng.standard_normal((n, 8))
    z = np.tanh(x @ rng.standard_normal((CFG.x_dim, CFG.z_dim))) + style[:, None]
    clips = rng.standard_normal((12, CFG.clip_frames, CFG.clip_channels)) + np.repeat(np.arange(3), 4)[:, None, None]
    f32 = lambda a: a.astype(np.float32)   # noqa: E731
    return TrainData(f32(x), f32(p), f32(z), style, f32(clips), np.repeat(np.arange(3), 4),
                     style_names=["A", "B", "C"])


def test_training_a_small_model_keeps_every_number_normal():
    """~1000 Adam steps at a learning rate high enough to kill some of Ψ's ReLUs part-way (without
    the flush this run ends with ~1000 subnormal first moments in Ψ): no parameter, gradient or
    moment of Ω, Φ or Ψ is subnormal after any epoch, and the dead units' moments are exactly 0."""
    rng = np.random.default_rng(0)
    data = toy_data(rng)
    model = StyleModel(CFG, np.random.default_rng(0))
    trainer = Trainer(model, NormStats.identity(CFG.x_dim, CFG.z_dim),
                      TrainConfig(epochs=100, batch_size=16, lr=1e-2, seed=0), style_names=["A", "B", "C"])
    while trainer.step < 1000:
        trainer.fit(data, None, epochs=trainer.epoch + 5)
        for i, ps in enumerate(model.parameter_sets()):
            found = {"parameters": subnormals(ps.data), "gradients": subnormals(ps.grad),
                     "m": subnormals(trainer.optimizer.m[i]), "v": subnormals(trainer.optimizer.v[i])}
            assert not any(found.values()), f"step {trainer.step}, set {i}: subnormal {found}"
    silent = np.count_nonzero((trainer.optimizer.m[2] == 0) & (trainer.optimizer.v[2] > 0))
    assert silent > 0                                    # units that had gradients, then none
