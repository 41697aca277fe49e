"""Data-parallel training (minifilm/train/parallel.py): the gradients, losses and updates of 1
process and of 2 worker processes are the same to float32 round-off, dropout masks and minibatch
order do not depend on the number of workers, and the workers and their shared memory are gone
afterwards, also when a worker dies mid-run."""
import os
import signal
import threading
from pathlib import Path

import numpy as np
import pytest

from minifilm.dataset.arrays import TrainData
from minifilm.dataset.stats import NormStats
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.train.parallel import DataParallel, WorkerDied
from minifilm.train.parallel_shares import shares
from minifilm.train.parallel_worker import wait_until
from minifilm.train.trainer import TrainConfig, Trainer, TrainingDiverged

CFG = ModelConfig.tiny(dropout=0.3)


def data(n=120, styles=3, seed=1):
    rng = np.random.default_rng(seed)
    clips = rng.standard_normal((4 * styles, CFG.clip_frames, CFG.clip_channels)).astype(np.float32)
    return TrainData(x=rng.standard_normal((n, CFG.x_dim)).astype(np.float32),
                     p=rng.standard_normal((n, CFG.phase_dim)).astype(np.float32),
                     z=rng.standard_normal((n, CFG.z_dim)).astype(np.float32),
                     style=np.arange(n) % styles, clips=clips, clip_style=np.arange(4 * styles) % styles)


def trainer(clips_per_batch=None, batch_size=16):
    stats = NormStats(x_mean=np.zeros(CFG.x_dim), x_std=np.ones(CFG.x_dim), z_mean=np.zeros(CFG.z_dim),
                      z_std=np.ones(CFG.z_dim), p_mean=np.zeros(CFG.phase_dim), p_std=np.ones(CFG.phase_dim))
    positions = np.arange(12).reshape(4, 3)                     # four joints in the first 12 columns of z
    return Trainer(StyleModel(CFG, np.random.default_rng(0)), stats,
                   TrainConfig(epochs=2, batch_size=batch_size, lr=1e-3, seed=3, clips_per_batch=clips_per_batch),
                   positions_idx=positions, parents=np.array([-1, 0, 1, 2]))


def grads(t):
    return np.concatenate([ps.grad for ps in t.model.parameter_sets()])


def weights(t):
    return np.concatenate([ps.data for ps in t.model.parameter_sets()])


def leftovers(pid):
    return [p.name for p in Path("/dev/shm").glob(f"minifilm_{pid}_*")] if Path("/dev/shm").is_dir() else []


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    status = Path(f"/proc/{pid}/status")
    return not (status.exists() and "zombie" in status.read_text())


@pytest.mark.parametrize("clips_per_batch", [None, 4, 1, 3])
def test_one_step_with_two_workers_has_the_gradients_of_one_process(clips_per_batch):
    one, two, d = trainer(clips_per_batch), trainer(clips_per_batch), data()
    b1 = next(one.minibatches(d))
    mse1, bll1 = one.gradients(b1)
    with DataParallel(two, 2) as pool:
        b2 = next(two.minibatches(d))
        mse2, bll2 = two.gradients(b2, pool)
    g1, g2 = grads(one), grads(two)
    assert np.abs(g1).max() > 0
    assert np.abs(g2 - g1).max() <= 1e-6 * np.abs(g1).max()
    assert mse2 == pytest.approx(mse1, rel=1e-6) and bll2 == pytest.approx(bll1, rel=1e-6)
    # the masks came from the same draws: the generators are in the same state afterwards
    assert one.rng.bit_generator.state == two.rng.bit_generator.state
    assert leftovers(os.getpid()) == []


def test_an_epoch_with_two_workers_equals_one_process():
    one, two, d = trainer(4), trainer(4), data()
    h1 = one.fit(d, d, epochs=2, workers=1)
    h2 = two.fit(d, d, epochs=2, workers=2)
    assert np.allclose(weights(two), weights(one), rtol=0, atol=1e-5 * np.abs(weights(one)).max())
    for r1, r2 in zip(h1, h2):
        assert r2["train"]["mse"] == pytest.approx(r1["train"]["mse"], rel=1e-5)
        assert r2["val"]["mse"] == pytest.approx(r1["val"]["mse"], rel=1e-5)
    assert isinstance(two.model.gating.params.data, np.ndarray) and two.model.gating.params.data.base is None
    assert leftovers(os.getpid()) == []


@pytest.mark.parametrize("clips_per_batch", [None, 4])
def test_three_workers_take_the_steps_of_one_process(clips_per_batch):
    one, three, d = trainer(clips_per_batch), trainer(clips_per_batch), data()
    with DataParallel(three, 3) as pool:
        assert len(pool.procs) == 2                        # two worker processes beside this one
        for b1, b3 in zip(one.minibatches(d), three.minibatches(d)):
            assert one.train_step(b1) == pytest.approx(three.train_step(b3, pool), rel=1e-5)
    assert one.step == three.step > 3 and one.optimizer.steps == three.optimizer.steps
    assert np.allclose(weights(three), weights(one), rtol=0, atol=1e-5 * np.abs(weights(one)).max())
    assert one.rng.bit_generator.state == three.rng.bit_generator.state
    assert leftovers(os.getpid()) == []


def test_a_nan_stops_the_parallel_step_before_any_weight_changes():
    t, d = trainer(), data()
    with DataParallel(t, 2) as pool:
        batches = t.minibatches(d)
        t.train_step(next(batches), pool)
        before, steps = weights(t).copy(), list(t.optimizer.steps)
        b = next(batches)
        b.x[-1, 0] = np.nan                                # in the last rows: worker 1's share
        with pytest.raises(TrainingDiverged, match="is not finite"):
            t.train_step(b, pool)
        assert np.array_equal(weights(t), before) and t.optimizer.steps == steps
    assert leftovers(os.getpid()) == []


def test_a_wait_ends_when_its_check_finds_the_other_side_gone():
    calls = []

    def check():
        calls.append(1)
        if len(calls) == 3:
            raise WorkerDied("gone")
    with pytest.raises(WorkerDied, match="gone"):
        wait_until(lambda: False, check, threading.Semaphore(0))    # never ready: only the check ends it
    assert len(calls) == 3


def test_unequal_shares_are_weighted_by_their_rows():
    # 3 clips over 2 workers: 1 and 2 clips, so shares of unequal size (with batch 16: 6 / 10 rows)
    idx = np.sort(np.arange(16) % 3)
    parts = shares(16, idx, 3, 2)
    assert parts == [(0, 6, 0, 1), (6, 16, 1, 3)]
    assert shares(5, None, 5, 2) == [(0, 2, 0, 2), (2, 5, 2, 5)]
    assert shares(16, np.zeros(16, int), 1, 2) == [(0, 8, 0, 1), (8, 16, 0, 1)]


def test_a_worker_killed_mid_run_stops_training_with_one_message_and_leaves_nothing():
    t, d = trainer(), data(n=600)
    with pytest.raises(WorkerDied, match=r"worker 1 \(process \d+\) was killed by SIGKILL"):
        with DataParallel(t, 2) as pool:
            assert pool.pids[0] == os.getpid() and len(pool.pids) == 2   # this process is worker 0
            pids = pool.pids[1:]
            before = weights(t).copy()
            batches = t.minibatches(d)
            t.gradients(next(batches), pool)
            os.kill(pids[0], signal.SIGKILL)
            t.gradients(next(batches), pool)
    assert np.array_equal(weights(t), before)          # no update from the broken step
    assert not any(alive(pid) for pid in pids)
    assert leftovers(os.getpid()) == []


def test_the_workers_adam_step_is_the_one_process_step_number_for_number():
    one, two = trainer(), trainer()
    two.model.gating.params.trainable = one.model.gating.params.trainable = False    # a frozen set stays
    rng = np.random.default_rng(5)
    g = [rng.standard_normal(ps.size).astype(ps.dtype) for ps in one.model.parameter_sets()]
    with DataParallel(two, 2) as pool:
        for _ in range(3):
            for t in (one, two):
                for ps, gi in zip(t.model.parameter_sets(), g):
                    ps.grad[...] = gi
            one.update()
            two.update(pool)
    assert np.array_equal(weights(two), weights(one))
    for a, b in zip(one.optimizer.state_dict().values(), two.optimizer.state_dict().values()):
        assert np.array_equal(a, b)
    assert two.optimizer.m[0].base is None                 # the moments are private arrays again
    assert leftovers(os.getpid()) == []


def test_all_finite_agrees_with_the_number_by_number_test():
    from minifilm.train.objective import all_finite
    big = np.full(10, 3e38, np.float32)                    # finite numbers whose sum overflows
    cases = [np.ones(5, np.float32), big, np.array([1.0, np.nan]), np.array([np.inf, 1.0]),
             np.array([np.inf, -np.inf], np.float32), np.zeros(0), 2.5, float("nan")]
    for value in cases:
        assert all_finite(value) == bool(np.all(np.isfinite(value))), value


def test_the_default_is_every_usable_core_but_no_more_workers_than_shared_clips(monkeypatch):
    import minifilm.train.parallel as parallel
    import minifilm.train.parallel_shares as split
    monkeypatch.setattr(split, "usable_cores", lambda: 16)
    assert split.default_workers(trainer(clips_per_batch=4)) == 4        # one clip each at most
    assert split.default_workers(trainer(clips_per_batch=None)) == 16    # a clip per sample: 16 rows
    monkeypatch.setattr(split, "usable_cores", lambda: 2)
    assert split.default_workers(trainer(clips_per_batch=4)) == 2
    monkeypatch.setattr(split, "usable_cores", lambda: 1)
    with parallel.data_parallel(trainer(clips_per_batch=4)) as pool:
        assert pool is None                                                 # one core: this process
