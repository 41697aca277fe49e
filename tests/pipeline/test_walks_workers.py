"""Walks and fits of teaching in worker processes (walks.walk and a map of fit_film over a pool,
minifilm/parallel.py): the window summaries, faults and fits of one process, to a tolerance; the
controller's position bias reaches the workers; the refinement by motion finds the vector of one
process."""
import functools

import numpy as np
import pytest

from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.parallel import executor, map_in_order
from minifilm.pipeline.walks import FaultCheck, straight_path, walk, walk_here

LAYOUT = FeatureLayout.for_skeleton(STYLE100)
SPEED, SECONDS = 1.3, 2.0


@pytest.fixture(scope="module")
def rel(shared_data):
    from minifilm.runtime.released import load_released
    return load_released(shared_data / "released-lpn")


@pytest.fixture(scope="module")
def pool():
    """Two worker processes, shared by the tests of this file (each worker starts once)."""
    with executor(2, 2) as workers:
        yield workers


def films_of(rel, n):
    return np.stack(list(rel.styles.values())[:n]).astype(np.float32)


def check_for(speed, seconds):
    toes = [LAYOUT.joint_names.index("RightToe"), LAYOUT.joint_names.index("LeftToe")]
    return FaultCheck(toes, straight_path(speed, seconds + 1), clip_steps_per_s=1.8, clip_hips=0.93)


def assert_same_walks(got, expected):
    """The same faults, and window summaries to 1e-4: a share of 2-4 walks takes the network's
    vector-product path and a larger batch its matrix products, which sum in another order (float32,
    6e-8 relative per operation), and a rollout feeds its output back frame after frame: seven walks
    in two shares differed from one batch by 2e-6 at most (summaries up to 9); another style's walk
    differs by more than 1."""
    (walks, faults), (walks0, faults0) = got, expected
    assert len(walks) == len(walks0) and [set(f) for f in faults] == [set(f) for f in faults0]
    for f, f0 in zip(faults, faults0):                      # kind -> how bad, to the same tolerance
        assert f == pytest.approx(f0, rel=1e-4, abs=1e-4)
    for w, w0 in zip(walks, walks0):
        np.testing.assert_allclose(w, w0, rtol=1e-4, atol=1e-4)


def test_walks_in_shares_on_workers_are_those_of_one_process(rel, pool):
    films, check = films_of(rel, 7), check_for(SPEED, SECONDS)
    alone = walk_here(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS, check)
    assert any(alone[1]) and not all(alone[1]), "the check finds faults in some walks, not all"
    assert_same_walks(walk(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS, check, pool=pool, shares=2), alone)
    assert_same_walks(walk(rel.network, LAYOUT, rel.stats, films[:5], SPEED, SECONDS, pool=pool, shares=3),
                      (alone[0][:5], [{}] * 5))
    assert walk(rel.network, LAYOUT, rel.stats, films[:0], SPEED, SECONDS, pool=pool, shares=2) == ([], [])


def test_the_controllers_position_bias_reaches_the_workers(rel, pool):
    """A trained run walks with its own position bias: the workers' walks are this process's with
    that bias, and the bias changes the walk (else the test could not fail)."""
    films = films_of(rel, 3)
    plain = walk_here(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS)
    biased = walk_here(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS, position_bias=2.0)
    assert max(np.abs(a - b).max() for a, b in zip(plain[0], biased[0])) > 1e-2
    assert_same_walks(walk(rel.network, LAYOUT, rel.stats, films, SPEED, SECONDS, position_bias=2.0, pool=pool,
                           shares=2), biased)


def test_fits_in_workers_are_the_fits_of_this_process(rel, pool):
    from minifilm.train.film_fit import FitSettings, FrozenRows, StylePrior, fit_film
    rng = np.random.default_rng(0)
    x, p = rng.normal(size=(64, LAYOUT.x_dim)), rng.normal(size=(64, 8))
    z = rng.normal(scale=0.5, size=(64, LAYOUT.z_dim))
    V = np.stack(list(rel.styles.values())[:20]).astype(np.float64)
    rows, prior, start = FrozenRows(rel.model, x, p, z), StylePrior.from_vectors(V), V[3]
    settings = [FitSettings(steps=12, batch=16, every=4, prior_weight=w) for w in (0.3, 3.0)]
    fit = functools.partial(fit_film, rows, prior, start)
    here = [fit(s) for s in settings]
    there = map_in_order(fit, settings, pool)
    for a, b in zip(there, here):
        assert (a.steps, a.best_step) == (b.steps, b.best_step)
        # the rows are float32: a worker may sum in another order (6e-8 relative per operation);
        # twelve Adam steps of lr 0.05 on whitened coordinates pass a gradient's relative error into
        # the vector about as is, so 1e-5 relative holds it with room; the two prior weights' fits
        # differ by far more (checked below)
        np.testing.assert_allclose(a.film, b.film, rtol=1e-5, atol=1e-6)
        assert a.loss == pytest.approx(b.loss, rel=1e-5) and a.holdout_loss == pytest.approx(b.holdout_loss, rel=1e-5)
    assert np.abs(here[0].film - here[1].film).max() > 1e-3 and not np.allclose(here[0].film, start)


def test_refining_by_motion_on_workers_finds_the_vector_of_one_process(rel, pool):
    from minifilm.evaluation.style_judge import motion_block, summaries
    from minifilm.pipeline.motion_refit import RefitSettings, refine_by_motion
    from minifilm.pipeline.refit_released import generated_motions
    motion, = generated_motions(rel, ["Zombie"], 5.0, script="straight")
    clip = summaries(motion_block(motion, rel.stats, LAYOUT))
    known = {n: rel.styles[n] for n in list(rel.styles)[:10] if n != "Zombie"}
    settings = RefitSettings(directions=4, rounds=2, population=6, elite=2, seconds=2.0, dims=8)
    start = next(iter(known.values()))
    alone = refine_by_motion(rel.network, LAYOUT, rel.stats, start, known, clip, SPEED, settings)
    walks = functools.partial(walk, rel.network, LAYOUT, rel.stats, pool=pool, shares=2)
    shared = refine_by_motion(rel.network, LAYOUT, rel.stats, start, known, clip, SPEED, settings, walks=walks)
    # the walks agree to about 1e-5 (assert_same_walks); the search keeps the same candidates, so
    # its vector is a mean of the same draws, and its score a distance of nearly the same walks
    np.testing.assert_allclose(shared.film, alone.film, rtol=1e-5, atol=1e-6)
    assert shared.score == pytest.approx(alone.score, rel=1e-4)
