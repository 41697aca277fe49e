"""Runtime: the inference network, the autoregressive loop's geometry and phase rule, calibration.

These tests need no data: the loop is driven by a stand-in network whose outputs are closed-form
(a character gliding forward at constant speed), so every expected number is computed by hand.
"""
import numpy as np
import pytest

from minifilm.runtime.control import CommandScript
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.features.layout import FeatureLayout
from minifilm.dataset.stats import NormStats
from minifilm.runtime.calibration import SpeedCalibration
from minifilm.runtime.controller import Controller
from minifilm.runtime.network import RuntimeNetwork

PARENTS = (-1, 0, 1, 0, 3)
LAYOUT = FeatureLayout(5, PARENTS, ("Hips", "Spine", "Head", "Leg", "Foot"))


def random_stats(layout, rng):
    return NormStats(x_mean=rng.normal(size=layout.x_dim), x_std=rng.uniform(0.5, 2, layout.x_dim),
                     p_mean=rng.normal(size=8), p_std=rng.uniform(0.5, 2, 8),
                     z_mean=rng.normal(size=layout.z_dim), z_std=rng.uniform(0.5, 2, layout.z_dim))


def test_runtime_network_matches_style_model():
    rng = np.random.default_rng(0)
    cfg = ModelConfig.tiny(x_dim=LAYOUT.x_dim, z_dim=LAYOUT.z_dim)
    model = StyleModel(cfg, rng, dtype=np.float64)
    for ps in model.parameter_sets():  # non-zero biases so they are tested too
        ps.data[...] = rng.normal(scale=0.3, size=ps.data.shape)
    stats = random_stats(LAYOUT, rng)
    net = RuntimeNetwork.from_model(model, stats, dtype=np.float64)
    X, P = rng.normal(size=(3, LAYOUT.x_dim)), rng.normal(size=(3, 8))
    film = rng.normal(size=(3, cfg.film_dim))
    z_hat = model.forward_with_film((X - stats.x_mean) / stats.x_std, (P - stats.p_mean) / stats.p_std, film)
    expected = z_hat * stats.z_std + stats.z_mean
    np.testing.assert_allclose(net.predict(X, P, film), expected, rtol=1e-10, atol=1e-10)
    # one shared FiLM vector == the same vector repeated per row
    np.testing.assert_allclose(net.predict(X, P, film[0]), net.predict(X, P, np.repeat(film[:1], 3, 0)), atol=1e-12)
    # runtime layer-norm convention (biased sigma, no eps) is available too
    net_rt = RuntimeNetwork.from_model(model, stats, runtime_layer_norm=True, dtype=np.float64)
    z_rt = model.forward_with_film((X - stats.x_mean) / stats.x_std, (P - stats.p_mean) / stats.p_std, film,
                                   ln_unbiased=False, ln_eps=0.0)
    np.testing.assert_allclose(net_rt.predict(X, P, film), z_rt * stats.z_std + stats.z_mean, atol=1e-10)


class GlideNet:
    """Stand-in network: the character glides forward at `speed` m/s in its own frame, keeping the
    pose of x's joints; the phase output is a constant vector `a` with update `u`."""

    def __init__(self, layout, speed, a, u, stats):
        self.layout, self.speed, self.a, self.u, self.stats = layout, speed, a, u, stats
        self.x_dim, self.z_dim = layout.x_dim, layout.z_dim
        self.inputs = []

    def predict(self, x, p, film):
        L, d = self.layout, self.speed / 60.0
        self.inputs.append(x.copy())
        B = len(x)
        z = np.zeros((B, L.z_dim))
        for i, s in enumerate(range(6, 12)):
            dt = L.trajectory_seconds[s]
            z[:, L.trajectory_columns("z", s)] = [0.0, d + self.speed * dt, 0.0, 1.0]
        for f in ("position", "forward", "up", "velocity"):
            z[:, L.joint_columns("z", f)] = x[:, L.joint_columns("x", f)]
        z[:, L.joint_columns("z", "position")[:, 2]] += d     # the body moves with the root
        z[:, L.z_phases], z[:, L.z_phase_updates], z[:, L.z_contacts] = self.a, self.u, [1.0, 0.0]
        return z


def glide_setup(speed=1.5, heading_deg=30.0):
    rng = np.random.default_rng(1)
    stats = random_stats(LAYOUT, rng)
    # a plausible mean pose: unit axes, zero velocity (forward moves exactly with the body)
    fw, up, vel = (LAYOUT.joint_columns("x", f) for f in ("forward", "up", "velocity"))
    stats.x_mean[fw], stats.x_mean[up], stats.x_mean[vel] = [0, 0, 1.0], [0, 1.0, 0], [0, 0, speed]
    a, u = rng.normal(size=8), rng.normal(size=8) * 0.1
    net = GlideNet(LAYOUT, speed, a, u, stats)
    script = CommandScript([(0, speed, heading_deg, 0), (100, speed, heading_deg, 0)], start_position=(2.0, -1.0))
    return net, script, stats, a, u


def test_glide_moves_root_and_joints_along_the_heading():
    speed, heading = 1.5, 30.0
    net, script, stats, a, u = glide_setup(speed, heading)
    ctrl = Controller(net, LAYOUT, velocity_blend=0.5, future_smoothing=0.0)  # 0.15 would lag it by 0.15 frames
    N = 90
    r = ctrl.run(script, N, np.zeros(4))
    f = np.array([np.sin(np.radians(heading)), np.cos(np.radians(heading))])
    k = np.arange(1, N + 1)
    np.testing.assert_allclose(r.root_positions[0], np.array([2.0, -1.0]) + (speed / 60) * k[:, None] * f, atol=1e-9)
    np.testing.assert_allclose(r.root_facing[0], np.broadcast_to(f, (N, 2)), atol=1e-12)
    # joints: the mean pose (local to the root), carried along with the root
    local = stats.x_mean[LAYOUT.joint_columns("x", "position")]            # (J, 3)
    R = np.array([[f[1], 0, f[0]], [0, 1, 0], [-f[0], 0, f[1]]])          # LookRotation(f)
    world0 = local @ R.T + np.array([2.0, 0, -1.0])
    disp = np.array([f[0], 0, f[1]]) * (speed / 60)
    np.testing.assert_allclose(r.positions[0, -1], world0 + N * disp, atol=1e-9)
    np.testing.assert_allclose(r.rotations[0, -1, :, :, 2], np.broadcast_to([f[0], 0, f[1]], (5, 3)), atol=1e-9)
    # the input of the last frame: past samples at -1 s .. -1/6 s lie behind at speed * |t|
    x = net.inputs[-1][0]
    for s in range(6):
        t = LAYOUT.trajectory_seconds[s]
        np.testing.assert_allclose(x[LAYOUT.trajectory_columns("x", s)], [0, speed * t, 0, 1], atol=1e-9)
    for s in range(6, 12):  # the future is exactly what the user asks for, at the training spacing
        t = LAYOUT.trajectory_seconds[s]
        np.testing.assert_allclose(x[LAYOUT.trajectory_columns("x", s)], [0, speed * t, 0, 1], atol=1e-9)


def test_phase_rule_half_predicted_half_integrated():
    net, script, stats, a, u = glide_setup()
    ctrl = Controller(net, LAYOUT)
    L0 = np.linspace(-1, 1, 8)
    r = ctrl.run(script, 60, np.zeros(4), phases=L0[None])
    np.testing.assert_allclose(r.phases[0, 0], 0.5 * a + 0.5 * (L0 + u), atol=1e-12)
    # L <- 0.5 a + 0.5 (L + u) has the fixed point a + u, reached geometrically (error halves)
    np.testing.assert_allclose(r.phases[0, -1], a + u, atol=1e-12)
    np.testing.assert_allclose(r.contacts[0, -1], [1, 0])


def test_batch_equals_single_characters():
    rng = np.random.default_rng(4)
    cfg = ModelConfig.tiny(x_dim=LAYOUT.x_dim, z_dim=LAYOUT.z_dim)
    model = StyleModel(cfg, rng, dtype=np.float64)
    stats = random_stats(LAYOUT, rng)
    stats.x_std[:], stats.z_std[:] = 1.0, 0.01        # small outputs: a tame random network
    net = RuntimeNetwork.from_model(model, stats, dtype=np.float64)
    films = rng.normal(size=(2, cfg.film_dim))
    scripts = [CommandScript([(0, 1.0, 0, 0), (10, 1.0, 90, 0)]),
               CommandScript([(0, 0.5, 45, 90), (10, 0.5, 45, 90)], start_position=(3, 3))]
    ctrl = Controller(net, LAYOUT)
    both = ctrl.run(scripts, 40, films)
    for b in range(2):
        one = ctrl.run(scripts[b], 40, films[b])
        np.testing.assert_allclose(both.positions[b], one.positions[0], atol=1e-9)
        np.testing.assert_allclose(both.root_positions[b], one.root_positions[0], atol=1e-9)


def test_controller_rejects_mismatched_layout():
    net, *_ = glide_setup()
    other = FeatureLayout(4, (-1, 0, 1, 2), ("a", "b", "c", "d"))
    with pytest.raises(ValueError, match="do not match the layout"):
        Controller(net, other)


def test_speed_calibration_inverts_the_measured_map():
    cal = SpeedCalibration(commanded=[1.0, 2.0, 4.0], achieved=[0.5, 0.8, 1.6])
    np.testing.assert_allclose(cal.command_for([0.5, 0.8, 1.2]), [1.0, 2.0, 3.0], atol=1e-6)
    np.testing.assert_allclose(cal.command_for(0.25), 0.5, atol=1e-6)   # through the origin
    v = cal.apply(np.array([[0.0, 1.2], [0.0, 0.0]]))
    np.testing.assert_allclose(v, [[0.0, 3.0], [0.0, 0.0]], atol=1e-5)
    # per direction: forwards as above, sideways everything is twice as slow
    cal2 = SpeedCalibration([4.0, 1.0, 2.0], [[1.6, 0.5, 0.8], [0.8, 0.25, 0.4]], directions=(0.0, 90.0))
    np.testing.assert_allclose(cal2.command_for(0.8, 0.0), 2.0, atol=1e-6)
    np.testing.assert_allclose(cal2.command_for(0.8, 90.0), 4.0, atol=1e-6)
    np.testing.assert_allclose(cal2.command_for(0.8, -45.0), 3.0, atol=1e-6)   # halfway, symmetric
    side = cal2.apply(np.array([[0.8, 0.0]]), facing=np.array([[0.0, 1.0]]))    # moving +x, facing +z
    np.testing.assert_allclose(side, [[4.0, 0.0]], atol=1e-5)


def test_calibrate_speed_measures_each_command_and_direction_after_settling():
    """calibrate_speed: one character per (direction, command), all in one batch, each commanded
    at a constant speed and direction for `seconds`; the achieved speed is the path length
    after `settle` seconds over that time. A fake controller moves character b at a known speed
    (a function of its command and direction) after the settle time, and 10x faster before it."""
    from types import SimpleNamespace
    from minifilm.runtime.calibration import calibrate_speed

    def achieved(speed, direction):
        return speed * (0.6 - 0.2 * direction / 180.0)

    class FakeController:
        fps = 30.0

        def run(self, scripts, n, film, phases=None, start_x=None):
            self.args = (scripts, n, film, phases, start_x)
            k0 = int(round(2.0 * self.fps))
            t = np.arange(n) / self.fps
            pos = []
            for s in scripts:
                v, d = float(s.speeds[0]), float(np.degrees(s.moves[0]))
                assert np.allclose(s.speeds, v) and np.allclose(np.degrees(s.moves), d) and s.duration == 5.0
                w = achieved(v, d)
                dist = np.where(t < t[k0], 10 * w * t, 10 * w * t[k0] + w * (t - t[k0]))
                pos.append(dist[:, None] * np.array([np.cos(np.radians(d)), np.sin(np.radians(d))]))
            return SimpleNamespace(root_positions=np.stack(pos))

    ctl = FakeController()
    commands, directions = (0.5, 1.0, 3.0), (0.0, 90.0, 180.0)
    film, phases = np.arange(4.0), np.ones(8)
    cal = calibrate_speed(ctl, film, commands=commands, directions=directions, seconds=5.0, settle=2.0,
                          phases=phases)
    scripts, n, film_seen, phases_seen, start_x = ctl.args
    assert n == 150 and film_seen is film and phases_seen is phases and start_x is None
    assert [(float(s.speeds[0]), round(float(np.degrees(s.moves[0])))) for s in scripts] == \
        [(v, d) for d in directions for v in commands]                 # direction-major, one batch
    expect = np.array([[achieved(v, d) for v in commands] for d in directions])
    np.testing.assert_allclose(cal.achieved[:, 1:], expect, rtol=1e-9)          # after the origin
    np.testing.assert_allclose(cal.commanded, [0.0, *commands])
    np.testing.assert_allclose(cal.directions, directions)
    for d in directions:                                              # and the map inverts
        np.testing.assert_allclose(cal.command_for(achieved(1.0, d), d), 1.0, atol=1e-6)
    with pytest.raises(ValueError, match="settle"):
        calibrate_speed(ctl, film, seconds=2.0, settle=2.0)


def test_calibration_step_by_step_is_the_calibration_at_once():
    """calibrate_speed_stepwise (a generator: one network step per next(), for the demo's frame
    loop) measures exactly what calibrate_speed measures, on a random network that moves."""
    from minifilm.runtime.calibration import calibrate_speed, calibrate_speed_stepwise
    rng = np.random.default_rng(3)
    cfg = ModelConfig.tiny(x_dim=LAYOUT.x_dim, z_dim=LAYOUT.z_dim)
    model = StyleModel(cfg, rng, dtype=np.float64)
    net = RuntimeNetwork.from_model(model, random_stats(LAYOUT, rng), dtype=np.float64)
    film, kw = rng.normal(size=cfg.film_dim), dict(commands=(0.5, 2.0), directions=(0.0, 90.0), seconds=1.0, settle=0.5)
    at_once = calibrate_speed(Controller(net, LAYOUT), film, **kw)
    steps = calibrate_speed_stepwise(Controller(net, LAYOUT), film, **kw)
    yields = 0
    try:
        while True:
            next(steps)
            yields += 1
    except StopIteration as done:
        stepwise = done.value
    assert yields == 1 + 60                                       # the reset, then each of the 60 frames
    np.testing.assert_array_equal(stepwise.achieved, at_once.achieved)
    np.testing.assert_array_equal(stepwise.commanded, at_once.commanded)
    assert at_once.achieved.max() > 0


def test_per_frame_films_reach_the_network_in_order():
    net, script, stats, a, u = glide_setup()
    seen = []
    predict = net.predict
    net.predict = lambda x, p, film: (seen.append(np.array(film, copy=True)), predict(x, p, film))[1]
    ctrl = Controller(net, LAYOUT)
    F = 12
    films = np.arange(F * 4, dtype=float).reshape(F, 4)           # (n_frames, 4H): a style schedule
    ctrl.run(script, F, films)
    np.testing.assert_array_equal(np.array(seen), films)
    seen.clear()
    ctrl.run(script, F, lambda k: np.full(4, float(k)))             # or a callable frame -> film
    np.testing.assert_array_equal(np.array(seen)[:, 0], np.arange(F))


def test_rollout_metrics_closed_form():
    net, script, stats, a, u = glide_setup(speed=1.5, heading_deg=0.0)
    r = Controller(net, LAYOUT).run(script, 120, np.zeros(4))
    m = r.metrics(PARENTS, path=np.array([[2.0, -10.0], [2.0, 10.0]]), toes=[4, 2])[0]
    assert m["bone_cv_max"] < 1e-9                       # a rigid pose carried along
    hips = stats.x_mean[LAYOUT.joint_columns("x", "position")][0, 1]
    np.testing.assert_allclose([m["hips_min"], m["hips_max"]], [hips, hips], atol=1e-9)
    np.testing.assert_allclose(m["speed"], 1.5, atol=1e-9)
    assert m["path_mean"] < 1e-9
    np.testing.assert_allclose(m["foot_sliding"], 1.5, atol=1e-9)  # contact [1, 0]: joint 4 glides at 1.5 m/s


def glide_skeleton(stats, stretch=1.3):
    """A Motion for LAYOUT's joints whose bones are ``stretch`` times the mean pose's: the fit must
    change every bone's length."""
    from minifilm.motion.motion import Motion

    local = stats.x_mean[LAYOUT.joint_columns("x", "position")]
    offsets = np.zeros((5, 3))
    for j, p in enumerate(PARENTS):
        if p >= 0:
            offsets[j] = stretch * (local[j] - local[p])   # rest pose: the mean pose's directions, identity rotations
    ch = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] + \
         [("Zrotation", "Xrotation", "Yrotation")] * 4
    return Motion(list(LAYOUT.joint_names), np.array(PARENTS), offsets, ch, np.broadcast_to(np.eye(3), (1, 5, 3, 3)).copy(),
                  np.broadcast_to(offsets, (1, 5, 3)).copy(), 1 / 60, "glide")


@pytest.mark.parametrize("feed_back", [True, False])
def test_skeleton_fit_in_the_loop(feed_back):
    net, script, stats, a, u = glide_setup(speed=1.5, heading_deg=30.0)
    skel = glide_skeleton(stats)
    body = Controller.skeleton_for(LAYOUT, skel)
    r = Controller(net, LAYOUT, skeleton=body, feed_back_fit=feed_back).run(script, 30, np.zeros(4))
    rest = np.linalg.norm(skel.offsets[1:], axis=-1)
    out = np.linalg.norm(r.positions[0][:, 1:] - r.positions[0][:, np.array(PARENTS[1:])], axis=-1)
    np.testing.assert_allclose(out, np.broadcast_to(rest, out.shape), rtol=1e-9)    # the output is rigid, at rest length
    # the network's own prediction is kept beside it: it carries the previous input's pose
    x_pos = net.inputs[-1][0][LAYOUT.joint_columns("x", "position")]
    net_bones = np.linalg.norm(x_pos[1:] - x_pos[np.array(PARENTS[1:])], axis=-1)
    if feed_back:   # the fitted pose is what the network sees next
        np.testing.assert_allclose(net_bones, rest, rtol=1e-6)
    else:           # its own (mean-pose) bones, 1/1.3 of the skeleton's
        np.testing.assert_allclose(net_bones, rest / 1.3, rtol=1e-6)
    own = np.linalg.norm(r.network_positions[0, -1, 1:] - r.network_positions[0, -1, np.array(PARENTS[1:])], axis=-1)
    np.testing.assert_allclose(own, net_bones, rtol=1e-5)               # float32 storage


def test_per_character_calibration():
    from minifilm.runtime.calibration import PerCharacterCalibration

    slow = SpeedCalibration(commanded=[1.0, 2.0], achieved=[0.5, 1.0])
    fast = SpeedCalibration(commanded=[1.0, 2.0], achieved=[1.0, 2.0])
    both = PerCharacterCalibration([slow, fast])
    v = both.apply(np.array([[0.0, 1.0], [0.0, 1.0]]), np.array([[0.0, 1.0], [0.0, 1.0]]))
    np.testing.assert_allclose(v, [[0.0, 2.0], [0.0, 1.0]], atol=1e-6)
    with pytest.raises(ValueError, match=r"must be \(2, 2\)"):
        both.apply(np.zeros((3, 2)))


def test_a_skeleton_without_the_layouts_joints_is_named():
    from minifilm.runtime.start_state import root_joint_indices

    net, script, stats, a, u = glide_setup()
    skel = glide_skeleton(stats)
    skel.names[2] = "Skull"                          # the layout wants "Head"
    with pytest.raises(ValueError, match=r"lacks 1 of the network's 5 joints \('Head'\).*`minifilm retarget`"):
        root_joint_indices(LAYOUT, skel)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_runtime_network_written_as_arrays_is_the_same_network(dtype):
    """to_arrays / from_arrays keep every weight, the statistics, the layer-norm convention and the
    dtype: the same outputs, bit for bit (in this process)."""
    rng = np.random.default_rng(1)
    cfg = ModelConfig.tiny(x_dim=LAYOUT.x_dim, z_dim=LAYOUT.z_dim)
    model = StyleModel(cfg, rng, dtype=dtype)
    for ps in model.parameter_sets():
        ps.data[...] = rng.normal(scale=0.3, size=ps.data.shape)
    net = RuntimeNetwork.from_model(model, random_stats(LAYOUT, rng), runtime_layer_norm=True, dtype=dtype)
    again = RuntimeNetwork.from_arrays(net.to_arrays())
    assert again.dtype == np.dtype(dtype)
    assert (again.hidden.hidden, again.hidden.ln_unbiased, again.hidden.ln_eps) == (cfg.hidden, False, 0.0)
    X, P = rng.normal(size=(7, LAYOUT.x_dim)), rng.normal(size=(7, 8))
    film = rng.normal(size=(7, cfg.film_dim))
    np.testing.assert_array_equal(again.predict(X, P, film), net.predict(X, P, film))
    other = RuntimeNetwork.from_model(model, random_stats(LAYOUT, rng), dtype=dtype)      # training's layer norm
    assert RuntimeNetwork.from_arrays(other.to_arrays()).hidden.ln_unbiased == cfg.ln_unbiased


def test_only_a_film_network_is_written_as_arrays():
    net = RuntimeNetwork.__new__(RuntimeNetwork)
    net.gate, net.hidden = (lambda x, p: x), (lambda *a: a[1])
    with pytest.raises(TypeError, match="only a FiLM network"):
        net.to_arrays()
