"""Rollout-aware training of a whole run (pipeline/self_fed_training.py) on a tiny synthetic data set:
the runs of consecutive rows it rolls out along, the rows it gathers per style, and the rounds."""
import numpy as np
import pytest

from minifilm.dataset.build import build_dataset
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.pipeline.self_fed import SelfFed
from minifilm.pipeline.self_fed_training import file_runs, gather_rows, self_fed_training
from minifilm.synthetic import generator as synthetic
from minifilm.train.trainer import TrainConfig, Trainer


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    folder = tmp_path_factory.mktemp("self_fed_training")
    clips = synthetic.default_dataset(seed=0, seconds=6.0, styles=["Neutral", "Limp"], gaits=["FW", "TR"])
    synthetic.write_dataset(folder / "data", clips)
    return build_dataset(folder / "data", progress=False, clip_seconds=1.0, clip_stride_seconds=0.5, seed=0,
                         split_unit="segments")


def new_trainer(ds, epochs=2):
    L, train = ds.layout, ds.train_data("train")
    config = ModelConfig(x_dim=L.x_dim, z_dim=L.z_dim, phase_dim=L.phase_dim, clip_frames=train.clips.shape[1],
                         clip_channels=L.clip_dim, n_experts=2, hidden=32, gating_hidden=8, conv_filters=4,
                         conv_kernel=5, film_dense=8, dropout=0.1)
    trainer = Trainer(StyleModel(config, np.random.default_rng(0)), ds.stats,
                      TrainConfig(epochs=epochs, batch_size=32, lr=1e-3, seed=0, progress=False),
                      positions_idx=L.joint_columns("z", "position"), parents=np.asarray(L.parents),
                      style_names=ds.styles)
    trainer.fit(train, ds.train_data("val"))
    return trainer


def test_file_runs_are_the_consecutive_rows_of_one_file(ds):
    split = ds.split("train")
    runs, styles = file_runs(split)
    assert sum(len(r[0]) for r in runs) == len(split)
    assert len(runs) == len(styles) and set(styles) == {0, 1}
    start = 0
    for (x, p, z), s in zip(runs, styles):
        rows = slice(start, start + len(x))
        assert len(np.unique(split.file[rows])) == 1 and np.all(np.diff(split.frame[rows]) == 1)
        assert np.all(split.style[rows] == s)
        np.testing.assert_array_equal(x, split.x[rows])
        np.testing.assert_array_equal(z, split.z[rows])
        start += len(x)
    assert file_runs(split.__class__(**{k: v[:0] for k, v in vars(split).items()}))[0] == []


def test_each_style_is_rolled_out_along_its_own_files(ds):
    trainer = new_trainer(ds)
    settings = SelfFed(rounds=1, horizon=20, every=20)
    runs, run_style = file_runs(ds.split("train"))
    x, p, z, s, error = gather_rows(trainer.model, ds, ds.train_data("train"), runs, run_style, settings)
    for k in (0, 1):
        starts = sum(len(range(0, len(r[0]) - 20, 20)) for r, st in zip(runs, run_style) if st == k)
        assert np.sum(s == k) == 20 * starts > 0
    assert x.dtype == np.float32 and len(x) == len(p) == len(z) == len(s)
    assert 0.0 < error < 1.0          # metres: an untrained-ish model drifts, but stays on the body's scale
    # the targets are the files' own next frames: every gathered target is a training target
    train_z = ds.train_data("train").z
    keys = {row.tobytes() for row in train_z}
    assert all(row.tobytes() in keys for row in z[:50])


def test_rounds_train_every_network_on_the_gathered_rows(ds):
    ends = {}
    for aggregate in (True, False):
        trainer = new_trainer(ds)
        weights = [ps.data.copy() for ps in trainer.model.parameter_sets()]
        logged = []
        errors = self_fed_training(trainer, ds, SelfFed(rounds=2, horizon=20, every=20), log=logged.append,
                                   aggregate=aggregate)
        assert len(errors) == 3 and all(np.isfinite(errors))
        assert trainer.epoch == 2 + 2
        changed = [not np.array_equal(w, ps.data) for w, ps in zip(weights, trainer.model.parameter_sets())]
        assert changed == [True, True, True]          # Ω, Φ and Ψ all train
        assert any("round 2" in line for line in logged)
        ends[aggregate] = np.concatenate([ps.data.ravel() for ps in trainer.model.parameter_sets()])
    # the same seeds and steps: only the gathered rows make the two differ
    assert not np.array_equal(ends[True], ends[False])
