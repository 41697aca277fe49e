"""Teaching the released network (minifilm/pipeline/teach_released.py): the joint-axis alignment
undoes a known per-joint rotation, the printed report warns in words on a short clip, a clip far
from the data and a style that does not walk, and a small known-answer re-fit on the real network."""
from types import SimpleNamespace

import numpy as np
import pytest

from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.joint_axes import align_axes
from minifilm.pipeline.teach_released import (ClipRows, Distance, TaughtStyle, input_distance,
                                              report_lines)
from minifilm.runtime.walk_checks import WalkReport

LAYOUT = FeatureLayout.for_skeleton(STYLE100)


def rotation(axis, degrees):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.radians(degrees)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K


def test_align_axes_undoes_a_constant_rotation_per_joint():
    rng = np.random.default_rng(0)
    J = LAYOUT.n_joints
    fx, ux = LAYOUT.joint_columns("x", "forward"), LAYOUT.joint_columns("x", "up")
    fz, uz = LAYOUT.joint_columns("z", "forward"), LAYOUT.joint_columns("z", "up")
    x_mean = np.zeros(LAYOUT.x_dim)
    truth = [rotation(rng.normal(size=3), rng.uniform(0, 40)) for _ in range(J)]
    for j in range(J):
        x_mean[ux[j]], x_mean[fx[j]] = truth[j][:, 1], truth[j][:, 2]
    N = 50
    x, z = rng.normal(size=(N, LAYOUT.x_dim)), rng.normal(size=(N, LAYOUT.z_dim))
    offsets = [rotation(rng.normal(size=3), 150) for _ in range(J)]      # the retargeted rig's convention
    for j in range(J):
        wobble = [rotation(rng.normal(size=3), 3) for _ in range(N)]
        for rows, f, u in ((x, fx[j], ux[j]), (z, fz[j], uz[j])):
            frames = np.stack([truth[j] @ w @ offsets[j].T for w in wobble])   # network frame · offset⁻¹
            rows[:, u], rows[:, f] = frames[:, :, 1], frames[:, :, 2]
    before_pos = x[:, LAYOUT.joint_columns("x", "position")].copy()
    x2, z2, angles = align_axes(x, z, LAYOUT, SimpleNamespace(x_mean=x_mean))
    for j in range(J):
        assert np.allclose(x2[:, fx[j]].mean(0), x_mean[fx[j]], atol=0.02)
        assert np.allclose(z2[:, uz[j]].mean(0), x_mean[ux[j]], atol=0.02)
    assert np.all(np.abs(angles - 150) < 3)
    np.testing.assert_array_equal(x2[:, LAYOUT.joint_columns("x", "position")], before_pos)


def test_input_distance_names_the_joint_and_feature():
    x = np.zeros((10, LAYOUT.x_dim))
    col = LAYOUT.joint_columns("x", "forward")[3, 0]
    x[:, col] = 9.0
    share, worst = input_distance(x, LAYOUT)
    assert share == pytest.approx(1 / LAYOUT.x_dim)
    assert worst[0][0].startswith(LAYOUT.joint_names[3]) and "forward axis" in worst[0][0] and worst[0][1] == 1.0


def taught(seconds, share, start_loss, own, check):
    clip = ClipRows(np.zeros((int(seconds * 60), 3)), None, None, seconds, 1.7, 0.92, 1.2, [])
    return TaughtStyle("Mine", np.zeros(4), 3.0, clip, Distance(share, [("Hips up axis x", 0.4)], start_loss, [own]),
                       0.05, "Old", "Old", check, [])


def test_the_report_warns_in_words():
    walks = WalkReport(1.6, 0.97, 0.92, 0.2, 1.7, 0.92)
    fine = "\n".join(report_lines(taught(30.0, 0.0, 0.05, 0.04, walks)))
    assert "WARNING" not in fine and "it walks" in fine
    short = "\n".join(report_lines(taught(2.5, 0.0, 0.05, 0.04, walks)))
    assert "WARNING: the clip lasts 2.5 s" in short
    far = "\n".join(report_lines(taught(30.0, 0.05, 2.0, 0.04, walks)))
    assert "far outside" in far and "5.0% of the clip's normalised input numbers" in far
    stands = WalkReport(0.1, 0.5, 0.92, 3.0, 1.7, 0.92)
    bad = "\n".join(report_lines(taught(30.0, 0.0, 0.05, 0.04, stands)))
    assert "hardly steps" in bad and "leave the floor" in bad and "leaves the path" in bad
    assert "refined by the motion" not in fine
    refined = taught(30.0, 0.0, 0.05, 0.04, walks)
    refined.candidates = [{"prior_weight": 1.0}, {"label": "refined by motion", "rounds": 12,
                                                  "motion_distance_start": 496.4, "motion_distance": 85.2}]
    assert "refined by the motion it makes (12 rounds): distance of its walk's windows to the clip's 496 -> 85" \
        in "\n".join(report_lines(refined))
    refined.candidates[-1].update(motion_ratio_start=1.62, motion_ratio=0.81)
    assert "496 -> 85, 1.62 -> 0.81 times that to the nearest known style's (below 1: nearer the clip than any)" \
        in "\n".join(report_lines(refined))


def test_a_released_style_is_found_again_from_its_own_motion(shared_data):
    """The small version of benchmarks/teach_released.py: one style, 10 s, one prior weight; the
    hidden vector's predictions must be the closest to the fitted one's among the 100."""
    from minifilm.pipeline.refit_released import generated_motions, refit
    from minifilm.runtime.released import load_released
    from minifilm.train.film_fit import FitSettings
    rel = load_released(shared_data / "released-lpn")
    motion, = generated_motions(rel, ["Zombie"], 10.0)
    r = refit(rel, "Zombie", motion, FitSettings(steps=80), prior_weights=(1.0,), by_motion=None)
    assert r["loss_rank"] == 1
    assert r["output_rank"] == 1, r


def small_refit_case(shared_data):
    """The released network, Zombie's own 6 s straight walk as the clip (window summaries), 11
    other styles as the known ones, small search settings, and Rushed's vector as the start."""
    from minifilm.evaluation.style_judge import motion_block, summaries
    from minifilm.pipeline.motion_refit import RefitSettings
    from minifilm.pipeline.refit_released import generated_motions
    from minifilm.runtime.released import load_released
    rel = load_released(shared_data / "released-lpn")
    layout = FeatureLayout.for_skeleton(STYLE100)
    motion, = generated_motions(rel, ["Zombie"], 6.0, script="straight")
    clip = summaries(motion_block(motion, rel.stats, layout))
    known = {n: rel.styles[n] for n in list(rel.styles)[:12] if n != "Zombie"}
    settings = RefitSettings(directions=4, rounds=2, population=4, elite=2, seconds=3.0, dims=8)
    start = known["Rushed"] if "Rushed" in known else next(iter(known.values()))
    return rel, layout, clip, known, settings, start


def test_refining_by_motion_brings_the_walk_nearer_the_clip(shared_data):
    """motion_refit on a small scale: Zombie's own motion as the clip, the vector of the style the
    network finds nearest by loss as the start. The distance to the clip's windows never grows
    (the start is a candidate of every round), falls here, and a rerun gives the same vector."""
    from minifilm.pipeline.motion_refit import refine_by_motion
    rel, layout, clip, known, settings, start = small_refit_case(shared_data)
    r = refine_by_motion(rel.network, layout, rel.stats, start, known, clip, 1.3, settings)
    assert r.film.shape == start.shape and np.all(np.isfinite(r.film))
    assert r.score < r.start_score and len(r.history) == 2
    again = refine_by_motion(rel.network, layout, rel.stats, start, known, clip, 1.3, settings)
    np.testing.assert_array_equal(again.film, r.film)
    # a walk with a fault the start's walk has not is never chosen: here every walk but the first of
    # each round (the start in round 1, the centre after it) is said to leave the floor
    kept = refine_by_motion(rel.network, layout, rel.stats, start, known, clip, 1.3, settings,
                            problems=lambda rollout, b: {"floor"} if b > 0 else set())
    np.testing.assert_array_equal(kept.film, np.asarray(start, np.float32))
    assert kept.score == kept.start_score


def test_teaching_with_workers_gives_the_vector_of_one_process(shared_data):
    """With two workers, the candidates' fits run there and every round's walks are split between
    them: the candidates, the refined vector and its distance are those of one process, to the
    round-off of float32 sums in another order (tests/pipeline/test_walks_workers.py says how much)."""
    from minifilm.pipeline.motion_refit import RefitSettings
    from minifilm.pipeline.refit_released import generated_motions
    from minifilm.pipeline.teach_adapter import AdapterPlan
    from minifilm.pipeline.teach_released import teach
    from minifilm.runtime.released import load_released
    from minifilm.train.film_fit import FitSettings
    rel = load_released(shared_data / "released-lpn")
    motion, = generated_motions(rel, ["Zombie"], 8.0, script="straight")
    known = {n: rel.styles[n] for n in list(rel.styles)[:12] if n != "Zombie"}
    kw = dict(known=known, settings=FitSettings(steps=20, every=5), prior_weights=(0.3, 3.0),
              motion=RefitSettings(directions=4, rounds=2, population=4, elite=2, seconds=2.0, dims=8),
              adapter=AdapterPlan("off"), log=lambda line: None)      # the vector alone (no adapter)
    alone = teach(rel, LAYOUT, "Taught", [motion], ["zombie.bvh"], workers=1, **kw)
    shared = teach(rel, LAYOUT, "Taught", [motion], ["zombie.bvh"], workers=2, **kw)
    assert [c.get("steps") for c in shared.candidates] == [c.get("steps") for c in alone.candidates]
    np.testing.assert_allclose(shared.candidate_films[:2], alone.candidate_films[:2], rtol=1e-5, atol=1e-6)  # the fits
    np.testing.assert_allclose(shared.film, alone.film, rtol=1e-5, atol=1e-6)
    assert shared.candidates[-1]["motion_distance"] == pytest.approx(alone.candidates[-1]["motion_distance"], rel=1e-4)
    assert shared.candidates[-1]["label"] == "refined by motion"


def test_the_contrast_is_the_distance_to_the_clip_over_that_to_the_nearest_rival(shared_data):
    """With contrast k, a walk scores d(walk, clip) / min d(walk, s) over the k known styles whose
    walks lie nearest the clip (computed here from the walks themselves); without, d(walk, clip)."""
    from minifilm.evaluation.style_judge import motion_block, summaries
    from minifilm.evaluation.style_measures import StyleSpace, frechet_distance, gaussian
    from minifilm.pipeline.motion_refit import RefitSettings, refine_by_motion
    from minifilm.pipeline.refit_released import generated_motions
    from minifilm.pipeline.walks import walk_here
    from minifilm.runtime.released import load_released
    rel = load_released(shared_data / "released-lpn")
    motion, = generated_motions(rel, ["Zombie"], 6.0, script="straight")
    clip = summaries(motion_block(motion, rel.stats, LAYOUT))
    known = {n: rel.styles[n] for n in list(rel.styles)[:8] if n != "Zombie"}
    first, second = list(known.values())[:2]
    start = 0.5 * (first + second)                         # not a known style: no rival walks as it does
    walks = dict(zip(known, walk_here(rel.network, LAYOUT, rel.stats, np.stack(list(known.values())), 1.3, 2.0)[0]))
    space = StyleSpace.fit({**walks, "\0clip": clip}, dims=8, summarised=True)
    start_walk = walk_here(rel.network, LAYOUT, rel.stats, start[None], 1.3, 2.0)[0][0]
    own = gaussian(space.project(start_walk, summarised=True))
    to_clip = frechet_distance(*own, *space.gaussians["\0clip"])
    by_nearness = sorted(known, key=lambda n: frechet_distance(*space.gaussians[n], *space.gaussians["\0clip"]))
    for k in (0, 1, 3):
        settings = RefitSettings(directions=2, rounds=1, population=1, elite=1, seconds=2.0, dims=8, contrast=k)
        r = refine_by_motion(rel.network, LAYOUT, rel.stats, start, known, clip, 1.3, settings, known_summaries=walks)
        rival = min(frechet_distance(*own, *space.gaussians[n]) for n in by_nearness[:k]) if k else 1.0
        assert r.start_score == pytest.approx(to_clip / rival, rel=1e-6)
        assert r.start_distance == pytest.approx(to_clip, rel=1e-6)
        assert r.score <= r.start_score


def test_the_refinement_refuses_a_walk_that_makes_the_starts_fault_worse(shared_data):
    """The start's walk leaves the floor a little (severity 0.1); every other walk leaves it far more
    (0.3: worse by more than WORSE_BY): the start is kept. Worse by less than the margin: it moves."""
    from minifilm.pipeline.motion_refit import refine_by_motion
    from minifilm.runtime.walk_checks import WORSE_BY
    rel, layout, clip, known, settings, start = small_refit_case(shared_data)

    def floor(worse_by):
        return lambda rollout, b: {"floor": 0.1 + (worse_by if b > 0 else 0.0)}
    kept = refine_by_motion(rel.network, layout, rel.stats, start, known, clip, 1.3, settings,
                            problems=floor(3 * WORSE_BY["floor"]))
    np.testing.assert_array_equal(kept.film, np.asarray(start, np.float32))
    moved = refine_by_motion(rel.network, layout, rel.stats, start, known, clip, 1.3, settings,
                             problems=floor(0.5 * WORSE_BY["floor"]))
    assert moved.score < moved.start_score and not np.array_equal(moved.film, np.asarray(start, np.float32))
