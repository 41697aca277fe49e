"""The Controller, rewritten to read in the order of Sec. 4.4, makes the same motion as before, to the bit.

``controller_before.py`` (beside this file) is a frozen copy of the Controller from before its
step was split into one function per step of the paper and its optional behaviours were moved
out of the main path. Both run here in the same process, on the same network, with the same
commands, so every array must be equal exactly (the same operations in the same order on the same
machine; nothing here compares numbers made in different processes). Each case switches on
a different optional branch: standing (on, without the held body, off), heading follow, the
velocity blend and future smoothing off, skeleton fit with and without feedback, foot locking
with and without the fit, the run feed, a start from a data frame, per-frame FiLM, and options
switched mid-run as the demo does. The generated BVH text is compared too.

The network is a small random one on the 100STYLE layout whose normalisation statistics come from
a synthetic clip (its outputs stay in the data's range, so the motion is bounded); the released
network, when the shared data is there, runs the main cases again on real motion.
"""
import dataclasses

import numpy as np
import pytest

import controller_before
from minifilm.dataset.stats import NormStats
from minifilm.features.compute import frame_features_from_arrays, motion_arrays
from minifilm.features.layout import FeatureLayout
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.motion.bvh_write import format_bvh
from minifilm.runtime.held_body import foot_locker
from minifilm.motion.skeletons import STYLE100
from minifilm.runtime import controller as after
from minifilm.runtime.control import CommandScript, make_script
from minifilm.runtime.heading import HeadingFollow
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.standing import StandStill
from minifilm.synthetic import generator as synthetic
from repo_paths import SHARED_DATA, need_data

FPS = 60


def scripts():
    """Three characters: walk, stop long enough for the feet to be held, walk on, stop; a figure
    eight (turning, for the heading follow); walk, stop, and the target turned on the spot."""
    stop_go = CommandScript([(0, 1.5, 0, 0), (0.8, 1.5, 0, 0), (0.82, 0, 0, 0), (2.2, 0, 0, 0),
                             (2.22, 1.2, 30, 30), (2.9, 1.2, 30, 30), (2.92, 0, 30, 30), (5, 0, 30, 30)])
    turn = CommandScript([(0, 1.0, 0, 0), (0.6, 1.0, 0, 0), (0.62, 0, 0, 0), (1.2, 0, 0, 0), (2.4, 0, 150, 0),
                          (5, 0, 150, 0)], start_position=(1.0, -2.0))
    return [stop_go, make_script("figure8", 4.0, speed=1.2), turn]


@pytest.fixture(scope="module")
def tiny():
    """(network, layout, skeleton Motion, films (3, 4H), start frames x (3, x_dim), phases (3, 8))."""
    rng = np.random.default_rng(7)
    clip = synthetic.generate_style("Drunk", "TR", 3.0, rng, fps=FPS)
    arrays = motion_arrays(clip.motion, STYLE100, FPS)
    ang = 2 * np.pi * clip.true_phase
    phases = np.stack([np.sin(ang), np.cos(ang)], axis=-1).reshape(-1, 8)
    layout = FeatureLayout.for_skeleton(STYLE100)
    feats = frame_features_from_arrays(*arrays, phases, clip.true_contacts, FPS, dtype=np.float64, layout=layout)
    stats = NormStats.fit(feats.x, feats.p, feats.z)
    cfg = ModelConfig.tiny(x_dim=layout.x_dim, z_dim=layout.z_dim)
    model = StyleModel(cfg, rng, dtype=np.float64, with_film_generator=False)
    net = RuntimeNetwork.from_model(model, stats, dtype=np.float64)
    H = cfg.hidden
    films = np.concatenate([1 + 0.3 * rng.normal(size=(3, H)), 0.3 * rng.normal(size=(3, H)),
                            1 + 0.3 * rng.normal(size=(3, H)), 0.3 * rng.normal(size=(3, H))], axis=1)
    rows = [10, len(feats.x) // 2, len(feats.x) - 20]
    return net, layout, clip.motion, films, feats.x[rows], feats.p[rows]


@pytest.fixture(scope="module")
def released():
    from minifilm.demo.source import DemoSource
    src = DemoSource.released(need_data(SHARED_DATA / "released-lpn", "the released network"), calibrate=False)
    films = np.stack([src.library[s] for s in ("Neutral", "Drunk", "Zombie")])
    return src.network, src.layout, src.skeleton, films, None, None


def options(layout, skeleton, name):
    """Fresh constructor arguments for case ``name`` (a new FootLocker each time: it keeps state)."""
    fit = after.Controller.skeleton_for(layout, skeleton)
    lock = foot_locker(layout)
    return {
        "default": {},
        "no_stand": dict(stand=None),
        "stand_without_hold": dict(stand=StandStill(hold=False)),
        "heading": dict(heading_follow=HeadingFollow()),
        "no_blend_no_smoothing": dict(velocity_blend=1.0, future_smoothing=0.0),
        "fit": dict(skeleton=fit),
        "fit_fed_back": dict(skeleton=fit, feed_back_fit=True),
        "lock": dict(foot_locker=lock),
        "fit_lock_fed_back": dict(skeleton=fit, feed_back_fit=True, foot_locker=lock, heading_follow=HeadingFollow()),
        "fit_lock": dict(skeleton=fit, foot_locker=lock, stand=None),
        "run_feed": dict(heading_follow=HeadingFollow()),
        "start_x": dict(skeleton=fit, feed_back_fit=True),
        "film_per_frame": {},
    }[name]


def assert_same_state(old, new):
    for field in dataclasses.fields(old.state):
        a, b = getattr(old.state, field.name), getattr(new.state, field.name)
        if a is None or b is None:
            assert a is None and b is None, field.name
        else:
            np.testing.assert_array_equal(b, a, err_msg=f"state.{field.name}")


def assert_same_rollout(r_old, r_new):
    for field in dataclasses.fields(r_old):
        np.testing.assert_array_equal(getattr(r_new, field.name), getattr(r_old, field.name), err_msg=field.name)


def rollout_both(setup, case, n_frames):
    net, layout, skeleton, films, start_x, start_p = setup
    ctrls = []
    for module in (controller_before, after):
        ctrls.append(module.Controller(net, layout, fps=FPS, **options(layout, skeleton, case)))
    runs = []
    for ctrl in ctrls:
        kwargs, film = {}, films
        if case == "run_feed":
            ctrl.run_feed, ctrl.run_feed_speed = np.array([1.0, 0.4, 0.0]), 6.0
        if case == "start_x" and start_x is not None:
            kwargs = dict(start_x=start_x, phases=start_p)
        if case == "film_per_frame":         # a style transition: (n_frames, B, 4H)
            w = np.linspace(0, 1, n_frames)[:, None, None]
            film = (1 - w) * films[None] + w * films[::-1][None]
        runs.append(ctrl.run(scripts(), n_frames, film, **kwargs))
    assert_same_rollout(*runs)
    assert_same_state(*ctrls)
    return ctrls, runs


CASES = ["default", "no_stand", "stand_without_hold", "heading", "no_blend_no_smoothing", "fit", "fit_fed_back",
         "lock", "fit_lock_fed_back", "fit_lock", "run_feed", "start_x", "film_per_frame"]


@pytest.mark.parametrize("case", CASES)
def test_the_rewritten_controller_makes_the_same_rollout_as_before(tiny, case):
    ctrls, runs = rollout_both(tiny, case, 200)
    if case == "fit_fed_back":                 # and so the same BVH text
        net, layout, skeleton = tiny[:3]
        fit = ctrls[1].skeleton
        texts = [format_bvh(r.to_motion(skeleton, fit.joint_indices, character=0)) for r in runs]
        assert texts[0] == texts[1]


def test_the_cases_reach_the_branches_they_are_meant_to(tiny):
    """The comparison is only worth something if the branches ran: the first character's feet
    were held (standing), and the run feed changed the input."""
    ctrls, runs = rollout_both(tiny, "default", 200)
    speed = np.linalg.norm(np.diff(runs[1].root_positions[0, 100:125], axis=0), axis=-1) * FPS
    assert speed.max() < 1e-9                                   # stood, its root held
    assert ctrls[1].state.feet is not None and ctrls[1].state.feet_weight[[0, 2]].min() > 0.5   # feet held
    fed = rollout_both(tiny, "run_feed", 40)[1][1]
    plain = rollout_both(tiny, "heading", 40)[1][1]
    assert not np.array_equal(fed.positions[0], plain.positions[0])


def test_options_switched_mid_run_as_the_demo_does(tiny):
    """The demo turns the fit, its feedback, foot locking and the run feed on and off between
    frames (minifilm/demo/character.py): step by step, both controllers give the same inputs and
    frames."""
    net, layout, skeleton, films, start_x, start_p = tiny
    fit = after.Controller.skeleton_for(layout, skeleton)
    ctrls = [m.Controller(net, layout, fps=FPS, heading_follow=HeadingFollow()) for m in (controller_before, after)]
    for ctrl in ctrls:
        ctrl.reset(np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([[0.0, 1.0], [1.0, 0.0]]),
                   phases=start_p[:2], start_x=start_x[0])
    for k in range(150):
        t = k / FPS
        speed = 0.0 if 0.8 < t < 1.7 else 1.4
        facing = np.array([[np.sin(t), np.cos(t)], [1.0, 0.0]])
        velocity = speed * np.array([[np.sin(t), np.cos(t)], [0.6, 0.8]])
        frames = []
        for ctrl in ctrls:
            if k == 20:
                ctrl.skeleton, ctrl.feed_back_fit = fit, True
            if k == 50:
                ctrl.foot_locker = foot_locker(layout)
            if k == 70:
                ctrl.feed_back_fit = False
                ctrl.run_feed = np.array([0.5, 0.0])
            if k == 110:
                ctrl.skeleton, ctrl.foot_locker, ctrl.run_feed = None, None, None
            frames.append(ctrl.step(facing, velocity, films[:2]))
        for key in frames[0]:
            np.testing.assert_array_equal(frames[1][key], frames[0][key], err_msg=f"frame {k} {key}")
        np.testing.assert_array_equal(ctrls[1].build_input(), ctrls[0].build_input(), err_msg=f"frame {k} input")
    assert_same_state(*ctrls)


class _Diverging:
    """A network that predicts the stats' mean, until frame ``bad`` where character 1 gets NaN."""

    def __init__(self, net, bad):
        self.x_dim, self.z_dim, self.stats, self.film_dim = net.x_dim, net.z_dim, net.stats, net.film_dim
        self.bad, self.calls = bad, 0

    def predict(self, x, p, film):
        z = np.repeat(self.stats.z_mean[None], len(x), axis=0)
        self.calls += 1
        if self.calls > self.bad:
            z[1, 3] = np.nan
        return z


def test_a_non_finite_output_stops_both_at_the_same_frame_with_the_same_error(tiny):
    net, layout, skeleton, films = tiny[:4]
    messages = []
    for module in (controller_before, after):
        ctrl = module.Controller(_Diverging(net, 5), layout, fps=FPS)
        with pytest.raises(module.NonFiniteOutputError) as err:
            ctrl.run(scripts()[:2], 20, films[:2])
        messages.append((str(err.value), ctrl.state.root.copy()))
    assert messages[0][0] == messages[1][0]
    np.testing.assert_array_equal(messages[1][1], messages[0][1])


@pytest.mark.parametrize("case", ["default", "fit_lock_fed_back", "run_feed", "fit"])
def test_the_released_network_makes_the_same_rollout_as_before(released, case):
    rollout_both(released, case, 200)
