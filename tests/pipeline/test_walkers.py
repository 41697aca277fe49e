"""Walks shared with worker processes (minifilm/pipeline/walkers.py): the same window summaries
and faults as one process walking them all, by ``walk`` (split) and ``submit`` (all in the
workers); a teacher-forced fit in a worker is this process's fit; replies are read while this
process is busy; a worker that dies is named; no shared memory is left; the refinement by motion
finds the same vector with workers as without."""
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.walkers import WalkPool, walk_here
from minifilm.pipeline.walks import FaultCheck, straight_path
from minifilm.processes import WorkerDied

LAYOUT = FeatureLayout.for_skeleton(STYLE100)
SPEED, SECONDS = 1.3, 2.0


@pytest.fixture(scope="module")
def rel(shared_data):
    from minifilm.runtime.released import load_released
    return load_released(shared_data / "released-lpn")


def segments_left():
    """This process's walk segments in /dev/shm (none where there is no /dev/shm)."""
    shm = Path("/dev/shm")
    return sorted(p.name for p in shm.glob(f"minifilm_{os.getpid()}_walks_*")) if shm.is_dir() else []


def rows_and_prior(rel, n=64, seed=0):
    from minifilm.train.film_fit import FrozenRows, StylePrior
    rng = np.random.default_rng(seed)
    x, p = rng.normal(size=(n, LAYOUT.x_dim)), rng.normal(size=(n, 8))
    z = rng.normal(scale=0.5, size=(n, LAYOUT.z_dim))
    V = np.stack(list(rel.styles.values())[:20]).astype(np.float64)
    return FrozenRows(rel.model, x, p, z), StylePrior.from_vectors(V), V[3]


def films_of(rel, n):
    return np.stack(list(rel.styles.values())[:n]).astype(np.float32)


def check_for(speed, seconds):
    toes = [LAYOUT.joint_names.index("RightToe"), LAYOUT.joint_names.index("LeftToe")]
    return FaultCheck(toes, straight_path(speed, seconds + 1), clip_steps_per_s=1.8, clip_hips=0.93)


def assert_same_walks(got, expected):
    (walks, faults), (walks0, faults0) = got, expected
    assert len(walks) == len(walks0) and faults == faults0
    for w, w0 in zip(walks, walks0):
        np.testing.assert_allclose(w, w0, rtol=1e-4, atol=1e-4)


def test_walks_shared_with_workers_are_those_of_one_process(rel):
    films, check = films_of(rel, 7), check_for(SPEED, SECONDS)
    alone = walk_here(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS, check)
    assert any(alone[1]) and not all(alone[1]), "the check finds faults in some walks, not all"
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=2) as pool:
        pending = pool.submit(films[:5], SPEED, SECONDS)
        assert_same_walks(pending.result(), (alone[0][:5], [{}] * 5))
        assert_same_walks(pool.walk(films, SPEED, SECONDS, check), alone)
        pending = pool.submit(films[2:], SPEED, SECONDS, check)
        # a walk asked before the submitted ones were collected waits for them first
        assert_same_walks(pool.walk(films[:3], SPEED, SECONDS, check), (alone[0][:3], alone[1][:3]))
        assert_same_walks(pending.result(), (alone[0][2:], alone[1][2:]))
        procs = list(pool.procs)
        assert len(procs) == 2 and all(p.is_alive() for p in procs)
        assert len(segments_left()) == 1                    # the one copy of the weights every process reads
    assert not any(p.is_alive() for p in procs)
    assert segments_left() == []


def test_a_pool_without_workers_walks_here_and_takes_any_check(rel):
    films = films_of(rel, 2)
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=0) as pool:
        walks, faults = pool.walk(films, SPEED, SECONDS, lambda r, b: {"odd"} if b % 2 else set())
        assert pool.procs == [] and faults == [set(), {"odd"}] and len(walks) == 2
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=1) as pool:
        with pytest.raises(TypeError, match="FaultCheck"):
            pool.walk(films, SPEED, SECONDS, lambda r, b: set())


def test_a_killed_walk_worker_is_named_and_nothing_is_left(rel):
    films = films_of(rel, 4)
    said = r"walks: worker 0 \(process \d+\) was killed by SIGKILL while walking 2 vectors"
    with pytest.raises(WorkerDied, match=said):
        with WalkPool(rel.network, LAYOUT, rel.stats, workers=1) as pool:
            procs = list(pool.procs)
            pool.walk(films, SPEED, SECONDS)            # started and working
            os.kill(procs[0].pid, signal.SIGKILL)
            pool.walk(films, SPEED, SECONDS)
    assert not any(p.is_alive() for p in procs)
    assert segments_left() == []


def test_refining_by_motion_with_workers_finds_the_vector_of_one_process(rel):
    from minifilm.evaluation.style_judge import motion_block, summaries
    from minifilm.pipeline.motion_refit import RefitSettings, refine_by_motion
    from minifilm.pipeline.refit_released import generated_motions
    motion, = generated_motions(rel, ["Zombie"], 5.0, script="straight")
    clip = summaries(motion_block(motion, rel.stats, LAYOUT))
    known = {n: rel.styles[n] for n in list(rel.styles)[:10] if n != "Zombie"}
    settings = RefitSettings(directions=4, rounds=2, population=6, elite=2, seconds=2.0, dims=8)
    start = next(iter(known.values()))
    alone = refine_by_motion(rel.network, LAYOUT, rel.stats, start, known, clip, SPEED, settings)
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=1) as pool:
        shared = refine_by_motion(rel.network, LAYOUT, rel.stats, start, known, clip, SPEED, settings, pool=pool)
    np.testing.assert_allclose(shared.film, alone.film, rtol=1e-5, atol=1e-6)
    assert shared.score == pytest.approx(alone.score, rel=1e-4)


def test_a_walk_that_fails_here_leaves_the_pool_in_step(rel, monkeypatch):
    """An error in this process's share is raised once the workers' shares are read, so the
    next walk gets its own answers (the workers are separate processes: the patch is not theirs)."""
    import minifilm.pipeline.walkers as walkers
    films, here = films_of(rel, 4), walkers.walk_here
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=1) as pool:
        monkeypatch.setattr(walkers, "walk_here", lambda *a, **k: (_ for _ in ()).throw(ValueError("here")))
        with pytest.raises(ValueError, match="here"):
            pool.walk(films, SPEED, SECONDS)
        monkeypatch.setattr(walkers, "walk_here", here)
        got = pool.walk(films[2:], SPEED, SECONDS)
    assert_same_walks(got, walk_here(rel.network, LAYOUT, rel.stats, films[2:], SPEED, SECONDS))


def test_a_fit_in_a_worker_is_the_fit_of_this_process(rel):
    from minifilm.train.film_fit import FitSettings, fit_film
    rows, prior, start = rows_and_prior(rel)
    settings = FitSettings(steps=12, batch=16, every=4, prior_weight=0.3)
    here = fit_film(rows, prior, start, settings)
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=1) as pool:
        walks = pool.submit(films_of(rel, 3), SPEED, SECONDS)
        there = pool.submit_fit(rows, prior, start, settings).result()     # read after the walks' replies
        assert len(walks.result()[0]) == 3
    assert (there.steps, there.best_step, there.loss, there.holdout_loss) == \
        (here.steps, here.best_step, here.loss, here.holdout_loss)
    np.testing.assert_array_equal(there.film, here.film)
    np.testing.assert_array_equal(np.array(there.history), np.array(here.history))     # (NaN at step 0 in both)
    np.testing.assert_array_equal(np.stack(there.snapshots), np.stack(here.snapshots))
    assert not np.array_equal(here.film, start)


def test_a_workers_replies_are_read_while_this_process_is_busy(rel):
    """The worker goes on to its next job with its walks' reply unread by this process (a reply
    larger than the pipe holds would otherwise stop it until this process asked for it)."""
    from minifilm.train.film_fit import FitSettings
    rows, prior, start = rows_and_prior(rel)
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=1) as pool:
        walks = pool.submit(films_of(rel, 40), SPEED, SECONDS)
        fit = pool.submit_fit(rows, prior, start, FitSettings(steps=4, batch=8, every=2))
        deadline = time.monotonic() + 600                   # (not a timing: only how long to wait at most)
        while pool.inboxes[0].qsize() < 3 and time.monotonic() < deadline:
            time.sleep(0.05)                                # this process asks for nothing meanwhile
        assert pool.inboxes[0].qsize() == 3                 # ready, the walks, the fit: all answered
        assert len(walks.result()[0]) == 40 and fit.result().steps == 4


def test_a_fit_that_fails_in_a_worker_is_one_error_and_the_pool_stays_in_step(rel):
    from minifilm.train.film_fit import FitSettings
    rows, prior, start = rows_and_prior(rel)
    films = films_of(rel, 2)
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=1) as pool:
        bad = pool.submit_fit(rows, prior, start[:10], FitSettings(steps=4, batch=8, every=2))
        walks = pool.submit(films, SPEED, SECONDS)
        with pytest.raises(ValueError):
            bad.result()
        assert_same_walks(walks.result(), walk_here(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS))


def test_the_controllers_position_bias_reaches_the_workers(rel):
    """A trained run walks with its own position bias: the workers' walks are this process's with
    that bias, and the bias changes the walk (else the test could not fail)."""
    films = films_of(rel, 3)
    plain = walk_here(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS)
    biased = walk_here(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS, position_bias=2.0)
    assert max(np.abs(a - b).max() for a, b in zip(plain[0], biased[0])) > 1e-2
    with WalkPool(rel.network, LAYOUT, rel.stats, workers=1, position_bias=2.0) as pool:
        assert_same_walks(pool.walk(films, SPEED, SECONDS), biased)
        assert_same_walks(pool.submit(films, SPEED, SECONDS).result(), biased)
