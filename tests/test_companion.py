"""The one-file companion (examples/minifilm_in_one_file.py) computes what the package computes.

The companion imports nothing from minifilm, so these tests are the bridge: the same weights go
into both, and the forward outputs, the losses and every gradient must agree (float64, relative
error <= 1e-6; measured at most 4e-11); Adam's steps agree; its gradient check passes on a draw
away from every kink; its runtime (Sec. 4.4) walks 60 frames as the package's Controller does;
and on real BVH files from ../shared/data the companion's reader, foot contacts and per-frame
local phases agree with the package's reader and its vectorised labelling
(minifilm/phases/label.py::label). One test shows the comparison catches a one-detail difference
(the layer norm's epsilon).
"""
from __future__ import annotations

import ast
import importlib.util

import numpy as np
import pytest

from gradcheck_report import other
from minifilm.dataset.stats import NormStats
from minifilm.features.layout import FeatureLayout
from minifilm.model.config import ModelConfig
from minifilm.model.losses import bone_length_loss, mse_loss
from minifilm.model.style_model import StyleModel
from minifilm.motion.bvh import read_bvh
from minifilm.body.rig import detect_skeleton
from minifilm.nn.optim import Adam
from minifilm.nn.params import Parameters
from minifilm.phases.contacts import foot_contacts
from minifilm.phases.label import Labels, label
from minifilm.phases.local_phases import DEFAULT_SOURCES, extract_local_phases, fit_sinusoids
from minifilm.runtime.controller import Controller
from minifilm.runtime.network import RuntimeNetwork
from repo_paths import REPO_ROOT, SHARED_DATA, need_data

COMPANION = REPO_ROOT / "examples" / "minifilm_in_one_file.py"
LIMIT = 1e-6
#: package parameter set -> the companion's name prefix
PREFIX = {"gating": "omega", "motion": "phi", "film": "psi"}


def load_companion(name="minifilm_in_one_file"):
    spec = importlib.util.spec_from_file_location(name, COMPANION)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


one = load_companion()


def rel_error(a, b):
    """Largest elementwise |a - b| / max(1e-8, |a| + |b|) (the package's gradient-check measure)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape, (a.shape, b.shape)
    return float(np.max(np.abs(a - b) / np.maximum(1e-8, np.abs(a) + np.abs(b)))) if a.size else 0.0


def test_the_companion_imports_only_numpy_scipy_and_the_standard_library():
    tree = ast.parse(COMPANION.read_text(encoding="utf-8"))
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add((node.module or "").split(".")[0])
    assert "minifilm" not in imported
    allowed = {"numpy", "scipy", "argparse", "os", "subprocess", "sys", "tempfile", "time", "pathlib"}
    assert imported <= allowed, imported - allowed


# ------------------------------------------------------------------------------ the network
def random_model(rng, config):
    """The package's model in float64 with every weight and bias random (no path left at zero)."""
    model = StyleModel(config, rng, dtype=np.float64)
    for ps in model.parameter_sets():
        ps.data[...] += 0.1 * rng.standard_normal(ps.size)
    return model


def companion_params(model):
    """The package's weights under the companion's names (copies: nothing is shared)."""
    sets = {"gating": model.gating.params, "motion": model.motion.params, "film": model.film.params}
    return {f"{PREFIX[s]}.{name}": ps.params[name].copy() for s, ps in sets.items() for name in ps.names()}


def loss_inputs(rng, config, n_joints=5):
    positions = rng.permutation(config.z_dim)[:3 * n_joints].reshape(n_joints, 3)
    parents = np.array([-1, 0, 1, 1, 3])[:n_joints]
    return positions, parents, rng.standard_normal(config.z_dim), 0.5 + rng.random(config.z_dim)


@pytest.mark.parametrize("shared_clip", [False, True], ids=["clip per sample", "one clip per batch"])
@pytest.mark.parametrize("train", [True, False], ids=["training (dropout)", "evaluation"])
def test_forward_losses_and_every_gradient_agree_with_the_package(shared_clip, train):
    rng = np.random.default_rng(3)
    config = ModelConfig.tiny(x_dim=24, z_dim=20, clip_channels=12, dropout=0.3)
    model = random_model(rng, config)
    P = companion_params(model)
    B = 6
    x, p = rng.standard_normal((B, config.x_dim)), rng.standard_normal((B, config.phase_dim))
    clip = rng.standard_normal((1 if shared_clip else B, config.clip_frames, config.clip_channels))
    target = rng.standard_normal((B, config.z_dim))
    positions, parents, z_mean, z_std = loss_inputs(rng, config)

    z_pkg = model.forward(x, p, clip, train=train, rng=rng, clip_index=np.zeros(B, int) if shared_clip else None)
    # the package drew its dropout masks; the companion replays them, site by site
    drop = {"rate": config.dropout, "masks": dict(model.used_masks), "rng": None} if train else None
    z_one, cache = one.model_forward(P, x, p, clip, drop)
    if train:
        assert set(drop["masks"]) == set(model.used_masks) == {"gating0", "gating1", "gating2", "motion0",
                                                               "motion1", "motion2", "film_dense"}
    assert rel_error(z_one, z_pkg) < LIMIT

    bones = (positions, parents, z_mean, z_std)
    (mse_p, dmse_p), (bll_p, dbll_p) = mse_loss(z_pkg, target), bone_length_loss(z_pkg, target, *bones)
    (mse_o, dmse_o), (bll_o, dbll_o) = one.mse_loss(z_one, target), one.bone_length_loss(z_one, target, *bones)
    assert rel_error(mse_o, mse_p) < LIMIT and rel_error(bll_o, bll_p) < LIMIT
    assert rel_error(dmse_o, dmse_p) < LIMIT and rel_error(dbll_o, dbll_p) < LIMIT

    dz = dmse_p + dbll_p
    model.zero_grad()
    inputs_pkg = model.backward(dz)
    grads, dx, dp, dclip = one.model_backward(dz, cache)
    errors = {"x": rel_error(dx, inputs_pkg["x"]), "p": rel_error(dp, inputs_pkg["p"]),
              "clip": rel_error(dclip, inputs_pkg["clip"])}
    sets = {"gating": model.gating.params, "motion": model.motion.params, "film": model.film.params}
    for s, ps in sets.items():
        for name in ps.names():
            errors[f"{s}.{name}"] = rel_error(grads[f"{PREFIX[s]}.{name}"], ps.grads[name])
    assert set(grads) == set(P)
    assert max(errors.values()) < LIMIT, {k: v for k, v in errors.items() if v >= LIMIT}


@pytest.mark.gradcheck
def test_the_companion_s_own_gradient_check_passes(capsys):
    """The companion's gradient check (its section 6: two-point differences, the worst entry
    against the largest gradient), which its main runs before training: one printed row per
    layer and per array of the whole model, every one below 1e-7."""
    assert one.gradient_check(0)
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[1:]]
    assert len(rows) > 30 and all(row[-1] == "ok" for row in rows)
    other("the companion's own gradient check", {" ".join(row[:-2]): float(row[-2]) for row in rows}, 1e-7)


def test_the_layer_norm_epsilon_matters_so_the_comparison_can_fail(monkeypatch):
    """One detail changed (the layer norm's ε, 1e-3 instead of 1e-6) and the outputs no longer agree."""
    rng = np.random.default_rng(4)
    config = ModelConfig.tiny(x_dim=24, z_dim=20, clip_channels=12)
    model = random_model(rng, config)
    x, p = rng.standard_normal((4, 24)), rng.standard_normal((4, 8))
    clip = rng.standard_normal((4, config.clip_frames, 12))
    z_pkg = model.forward(x, p, clip)
    assert rel_error(one.model_forward(companion_params(model), x, p, clip)[0], z_pkg) < LIMIT
    monkeypatch.setattr(one, "LN_EPS", 1e-3)
    assert rel_error(one.model_forward(companion_params(model), x, p, clip)[0], z_pkg) > LIMIT


def test_adam_steps_agree_with_the_package():
    rng = np.random.default_rng(5)
    ps = Parameters({"W": (3, 4), "b": (4,)}, dtype=np.float64)
    ps.data[...] = rng.standard_normal(ps.size)
    P = {name: a.copy() for name, a in ps.params.items()}
    adam, state = Adam([ps], lr=1e-2), {"t": 0, "m": {}, "v": {}}
    for _ in range(5):
        ps.grad[...] = rng.standard_normal(ps.size)
        one.adam_step(P, {name: g.copy() for name, g in ps.grads.items()}, state, lr=1e-2)
        adam.step()
    assert max(rel_error(P[name], ps.params[name]) for name in P) < 1e-10


@pytest.mark.gradcheck
def test_the_gradient_check_passes_on_a_draw_away_from_every_kink(monkeypatch, capsys):
    """Every row under 1e-7 (per entry), and the model's draw as check_model says: its ELU and ReLU
    inputs, max-pool pairs of live units and bone errors >= 5e-3 from their kinks, 8x the reach
    2h = 6e-4 of the four-point stencil (within it, a difference measures the kink)."""
    assert one.gradient_check()
    assert capsys.readouterr().out.count(" ok\n") == 34
    near = {"ELU": [], "ReLU": [], "max-pool": [], "bone": []}
    elu, relu, pool, bll = one.elu_forward, one.relu_forward, one.max_pool_forward, one.bone_length_loss

    def pairs(h):
        even, odd = h[:, 0:h.shape[1] // 2 * 2:2], h[:, 1:h.shape[1] // 2 * 2:2]
        return np.abs(even - odd)[np.maximum(even, odd) > 0]

    def bones(pred, target, cols, parents, mean, std):
        child = np.flatnonzero(parents >= 0)
        lengths = [np.linalg.norm(p[:, parents[child]] - p[:, child], axis=-1)
                   for p in (z[:, cols] * std[cols] + mean[cols] for z in (pred, target))]
        return lengths[0] - lengths[1]
    watch = [("elu_forward", "ELU", elu, np.abs), ("relu_forward", "ReLU", relu, np.abs),
             ("max_pool_forward", "max-pool", pool, pairs), ("bone_length_loss", "bone", bll, bones)]
    for name, kink, f, distance in watch:
        monkeypatch.setattr(one, name, lambda *a, f=f, kink=kink, d=distance: (near[kink].append(
            np.min(np.abs(d(*a)))), f(*a))[1])
    monkeypatch.setattr(one, "numerical_gradient", lambda f, x: (f(), np.zeros_like(x))[1])
    one.check_model()
    assert all(near.values()) and min(min(v) for v in near.values()) >= 5e-3, near


def test_the_runtime_walks_as_the_package_s_controller_for_60_frames():
    """Sec. 4.4, frame after frame: the companion's runtime_start / runtime_step against the
    package's Controller without its standing logic (stand=None, the paper's loop), with the same
    random network, statistics, FiLM vector, start frame and a turning command, at 30 fps."""
    rng = np.random.default_rng(7)
    layout = FeatureLayout.generic(5)
    config = ModelConfig.tiny(x_dim=layout.x_dim, z_dim=layout.z_dim, clip_channels=layout.joint_dim)
    model = random_model(rng, config)
    stats = [(rng.standard_normal(n) * scale, (0.5 + rng.random(n)) * scale)
             for n, scale in [(layout.x_dim, 0.3), (8, 1.0), (layout.z_dim, 0.1)]]   # x, p, z
    (x_mean, x_std), (p_mean, p_std), (z_mean, z_std) = stats
    network = RuntimeNetwork.from_model(model, NormStats(x_mean, x_std, z_mean, z_std, p_mean, p_std),
                                        dtype=np.float64)
    film = model.film_parameters(rng.standard_normal((1, config.clip_frames, config.clip_channels)))[0]
    x0, p0 = x_mean + x_std * rng.standard_normal(layout.x_dim), p_mean + p_std * rng.standard_normal(8)
    controller = Controller(network, layout, fps=30.0, stand=None)
    controller.reset(np.zeros((1, 2)), np.array([[0.0, 1.0]]), phases=p0[None], start_x=x0[None])
    state, P = one.runtime_start(x0, p0, 30.0), companion_params(model)
    for k in range(60):
        facing, velocity = np.array([np.sin(0.05 * k), np.cos(0.05 * k)]), np.array([0.5, 1.2])
        frame = controller.step(facing[None], velocity[None], film)
        z = one.runtime_step(P, stats, state, facing, velocity, film[None], 30.0)
        ours = [state["pos"], state["root"], state["facing"], state["p"], z[-2:]]
        theirs = [frame[key][0] for key in ("positions", "root", "facing", "phases", "contacts")]
        # float64 round-off of differently ordered sums, fed back for 60 frames: measured at
        # most 3e-14 (five seeds); one of the loop's blend weights changed by 0.05 differed by
        # 3e-4 to 4e-3 within two frames
        assert max(np.max(np.abs(a - b)) for a, b in zip(ours, theirs)) < 1e-10, k
    assert np.linalg.norm(state["root"]) > 0.3 and np.max(np.abs(state["p"] - p0)) > 0.1   # it moved


# ------------------------------------------------------------------------------ the phases
@pytest.mark.parametrize("fps, n", [(30, 200), (60, 300), (120, 500), (30, 9)])
def test_the_per_frame_sinusoid_fit_equals_the_package_s_vectorised_fit(fps, n):
    """Noisy two-frequency sources with a still stretch (skipped windows), at three frame rates and
    shorter than one window; through the companion's preprocessing first (a real source's values)."""
    rng = np.random.default_rng(fps + n)
    t = np.arange(n) / fps
    g = np.sin(2 * np.pi * 1.3 * t) + 0.5 * np.sin(2 * np.pi * 0.4 * t + 1) + 0.1 * rng.standard_normal(n)
    g[n // 4: 3 * n // 4] = 0.0                                   # 2 s or more: skipped windows
    v = one.preprocess_source(g, fps)
    amplitude, frequency, phase = one.fit_sinusoids(v, fps)
    fit = fit_sinusoids(v, fps)
    d = np.abs(phase - fit.phase) % 1.0
    assert np.max(np.minimum(d, 1 - d)) < LIMIT
    assert rel_error(amplitude, fit.amplitude) < LIMIT and rel_error(frequency, fit.frequency) < LIMIT
    assert np.any(fit.skipped) == (n > 9) and np.any(fit.amplitude > 0.1)


REAL_FILES = [("bandai2", "dataset-2_walk_active_001.bvh", None),
              ("bvh/bandai1", "dataset-1_run_normal_001.bvh", None),     # 24 frames: under a second
              ("bvh/xia", "angry_13_000.bvh", None),                     # CMU skeleton, 120 fps
              ("bvh/bandai1", "dataset-1_walk-left_normal_001.bvh", ("pca", "pca", "contact", "pca"))]   # a turn


@pytest.mark.parametrize("folder, name, sources", REAL_FILES, ids=[f[1] for f in REAL_FILES])
def test_reader_contacts_and_phases_agree_with_the_package_on_real_files(folder, name, sources):
    path = need_data(SHARED_DATA / folder / name, f"the shared BVH file {folder}/{name}")
    skeleton = detect_skeleton(read_bvh(path, scale=1.0))
    motion = read_bvh(path, scale=skeleton.bvh_scale)
    # the paper's recipe as the package runs it: its contacts (the labeller's rule on these files
    # but the short run, where it takes the gait rule instead: phases/label.py), then the phases
    paper_contacts = foot_contacts(motion.world()[0][:, skeleton.contact_indices(motion)], motion.fps)
    labels = label(motion, skeleton, sources=sources)
    assert labels.contact_rule == ("gait" if name == "dataset-1_run_normal_001.bvh" else "paper")
    labels = Labels(paper_contacts, extract_local_phases(motion, skeleton, paper_contacts, sources or DEFAULT_SOURCES))
    names, parents, pos, rot, fps = one.read_bvh(path, scale=skeleton.bvh_scale)
    pos_pkg, rot_pkg = motion.world()
    assert names == list(motion.names) and list(parents) == list(motion.parents)
    assert np.max(np.abs(pos - pos_pkg)) < 1e-9 and np.max(np.abs(rot - rot_pkg)) < 1e-12
    assert fps == pytest.approx(motion.fps, rel=1e-12)

    contacts = one.foot_contacts(pos_pkg[:, skeleton.contact_indices(motion)], motion.fps)
    assert np.array_equal(contacts, labels.contacts)
    phase, amplitude = one.local_phases(pos_pkg, rot_pkg, motion.fps, skeleton.hips_index(motion),
                                        skeleton.phase_indices(motion), contacts,
                                        sources or ("pca", "pca", "contact", "contact"), skeleton.facing_axis)
    d = np.abs(phase - labels.phases.phase) % 1.0
    assert np.max(np.minimum(d, 1 - d)) < LIMIT
    assert np.max(np.abs(amplitude - labels.phases.amplitude)) < LIMIT * max(1.0, np.max(labels.phases.amplitude))
    vectors = one.phase_vectors(phase, amplitude)
    assert np.max(np.abs(vectors - labels.vectors)) < LIMIT * max(1.0, np.max(np.abs(labels.vectors)))
    assert np.any(amplitude > 0.05)                                # a real walk has phases to compare
