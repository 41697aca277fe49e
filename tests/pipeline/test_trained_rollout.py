"""A minute-long rollout (3,600 frames) of a model trained by minifilm itself: the run-time checks.

The model is tiny and trained here for a few seconds on ten seconds of one synthetic style
walking forwards, so the thresholds are the released network's for stability (benchmarks/released_styles.py) (bone lengths, hips
height) and loose ones for control: the character must keep walking for the whole minute, in the
commanded direction, near the commanded path. A rollout that freezes into a pose and slides, drifts
into the floor, stretches its bones or wanders off fails. The minute-long rollouts of the
``examples/train_small.py`` model (all styles, figure-eight) are in ``benchmarks/trained_rollout.py``.
"""
import numpy as np
import pytest

from minifilm.runtime.control import figure_eight, straight_walk
from minifilm.dataset.build import build_dataset
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.synthetic import generator as synthetic
from minifilm.motion.bvh import read_bvh
from minifilm.motion.skeletons import builtin_skeleton
from minifilm.runtime.controller import Controller
from minifilm.runtime.start_state import start_from_dataset
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import StyleLibrary
from minifilm.train.trainer import TrainConfig, Trainer

SPEED = 1.3          # m/s commanded; the synthetic forward walk moves at about 1.1 m/s


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    folder = tmp_path_factory.mktemp("trained_rollout")
    clips = synthetic.default_dataset(seed=0, seconds=10.0, styles=["Neutral"], gaits=["FW"])
    synthetic.write_dataset(folder / "data", clips)
    ds = build_dataset(folder / "data", progress=False, clip_seconds=1.0, clip_stride_seconds=0.5, seed=0)
    L = ds.layout
    train, val = ds.train_data("train"), ds.train_data("val")
    config = ModelConfig(x_dim=L.x_dim, z_dim=L.z_dim, phase_dim=L.phase_dim, clip_frames=train.clips.shape[1],
                         clip_channels=L.clip_dim, n_experts=4, hidden=64, gating_hidden=16, conv_filters=8,
                         conv_kernel=5, film_dense=16, dropout=0.1)
    model = StyleModel(config, np.random.default_rng(0))
    trainer = Trainer(model, ds.stats, TrainConfig(epochs=20, batch_size=32, lr=1e-3, seed=0, progress=False),
                      positions_idx=L.joint_columns("z", "position"), parents=np.asarray(L.parents),
                      style_names=ds.styles)
    trainer.fit(train, val)
    library = StyleLibrary()
    library.add_from_clips("Neutral", model, train.clips)
    return ds, RuntimeNetwork.from_model(model, trainer.stats), library["Neutral"]


@pytest.mark.parametrize("script", ["straight", "figure8"])
def test_minute_long_rollout_of_a_trained_model(trained, script):
    ds, net, film = trained
    L = ds.layout
    seconds, n = 60.0, 3600
    path_script = straight_walk(seconds, SPEED) if script == "straight" else figure_eight(seconds, SPEED)
    x0, p0 = start_from_dataset(ds, "Neutral")
    r = Controller(net, L, fps=ds.fps).run(path_script, n, film, phases=p0, start_x=x0)
    m = r.metrics(L.parents, path_script.path)[0]
    assert np.all(np.isfinite(r.positions))
    assert m["bone_cv_max"] < 0.05, f"{script}: bone lengths vary by {m['bone_cv_max']:.1%} (CV)"
    assert 0.6 < m["hips_min"] and m["hips_max"] < 1.2, f"{script}: hips {m['hips_min']:.2f}-{m['hips_max']:.2f} m"
    # keeps walking all minute (a frozen pose gliding along would have no gait: phases stand still)
    step = np.linalg.norm(np.diff(r.root_positions[0], axis=0), axis=1) * ds.fps
    for a in range(60, n - 600, 600):
        assert step[a:a + 600].mean() > 0.5 * SPEED, f"{script}: speed {step[a:a + 600].mean():.2f} m/s in s {a // 60}-{a // 60 + 10}"
    foot_phase = r.phases[0, 60:, 4:8]
    assert foot_phase.std(axis=0).min() > 0.1, f"{script}: foot phases stand still ({foot_phase.std(axis=0)})"
    # near the path (the model follows the command only partly: §10.4 blends it in far samples)
    limit = 1.0 if script == "straight" else 2.0
    assert m["path_mean"] < limit, f"{script}: mean distance to the path {m['path_mean']:.2f} m"
    if script == "straight":    # and along it: the path runs along +z from the origin
        assert r.root_positions[0, -1, 1] > 0.5 * SPEED * seconds


def test_skeleton_fit_of_the_output_leaves_the_rollout_unchanged(trained):
    """Fitting only the output (what train_small does) gives rigid bones and the very same network
    trajectory as no fit: the fit is a pure post-process unless it is fed back."""
    ds, net, film = trained
    L, n = ds.layout, 600
    x0, p0 = start_from_dataset(ds, "Neutral")
    body = Controller.skeleton_for(L, read_bvh(ds.files[0]["path"], scale=builtin_skeleton(ds.skeleton).bvh_scale))
    plain = Controller(net, L, fps=ds.fps).run(figure_eight(10.0, SPEED), n, film, phases=p0, start_x=x0)
    fitted = Controller(net, L, fps=ds.fps, skeleton=body, feed_back_fit=False).run(
        figure_eight(10.0, SPEED), n, film, phases=p0, start_x=x0)
    np.testing.assert_array_equal(fitted.network_positions, plain.network_positions)
    np.testing.assert_array_equal(fitted.root_positions, plain.root_positions)
    m = fitted.metrics(L.parents)[0]
    assert m["bone_cv_max"] < 1e-6
    # each joint stays near the network's pose: the fit only corrects bone lengths and directions
    assert np.abs(fitted.positions - plain.positions).max() < 0.05
