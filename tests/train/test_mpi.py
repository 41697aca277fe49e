"""Data-parallel training under MPI (minifilm/train/mpi.py), run for real: ``mpiexec -n 2`` trains a
tiny model for 20 steps and ends with the parameters of one process, to float32 round-off, with
every way of splitting a minibatch (a clip per sample, more clips than ranks, fewer)."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from minifilm.dataset.arrays import TrainData
from minifilm.dataset.stats import NormStats
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.nn.fast_optim import ChunkedAdam
from minifilm.train.trainer import TrainConfig, Trainer

pytest.importorskip("mpi4py", reason="the mpi extra (mpi4py, mpich) is not installed")
MPIEXEC = shutil.which("mpiexec")
pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="no mpiexec on the PATH (pip install -e '.[mpi]')")

CFG = ModelConfig.tiny(dropout=0.3)
STEPS = 20
#: clips per minibatch: None (a clip per sample), 4 and 3 (at least as many clips as ranks: whole
#: clips to each rank), 1 (fewer: both ranks run Ψ on the one clip)
SPLITS = (None, 4, 3, 1)


def data(n=120, styles=3, seed=1):
    rng = np.random.default_rng(seed)
    clips = rng.standard_normal((4 * styles, CFG.clip_frames, CFG.clip_channels)).astype(np.float32)
    return TrainData(x=rng.standard_normal((n, CFG.x_dim)).astype(np.float32),
                     p=rng.standard_normal((n, CFG.phase_dim)).astype(np.float32),
                     z=rng.standard_normal((n, CFG.z_dim)).astype(np.float32),
                     style=np.arange(n) % styles, clips=clips, clip_style=np.arange(4 * styles) % styles)


def trained(clips_per_batch, ranks=None):
    """A tiny trainer after STEPS steps of style-balanced minibatches (dropout on); its weights."""
    stats = NormStats(x_mean=np.zeros(CFG.x_dim), x_std=np.ones(CFG.x_dim), z_mean=np.zeros(CFG.z_dim),
                      z_std=np.ones(CFG.z_dim), p_mean=np.zeros(CFG.phase_dim), p_std=np.ones(CFG.phase_dim))
    t = Trainer(StyleModel(CFG, np.random.default_rng(0)), stats,
                TrainConfig(epochs=100, batch_size=16, lr=1e-3, seed=3, clips_per_batch=clips_per_batch,
                            progress=False),
                positions_idx=np.arange(12).reshape(4, 3), parents=np.array([-1, 0, 1, 2]), ranks=ranks)
    d, losses = data(), []
    while t.step < STEPS:
        for b in t.minibatches(d):
            if t.step < STEPS:
                losses.append(t.train_step(b))
    t.end_epoch({})                                    # under mpiexec: every rank's part of Adam's moments
    moments = np.concatenate([a.ravel() for a in (*t.optimizer.m, *t.optimizer.v)])
    return np.concatenate([ps.data for ps in t.model.parameter_sets()]), np.array(losses), moments


def mpiexec(n, code, tmp_path, timeout=300):
    """``mpiexec -n n python -c code`` with this test's module importable; its completed process."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).parent), *sys.path]),
               OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", TMPDIR=str(tmp_path))   # temporary files: here
    return subprocess.run([MPIEXEC, "-n", str(n), sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)


RANKS_TRAIN = """
import numpy as np
from minifilm.train import mpi
from test_mpi import SPLITS, trained
ranks = mpi.world()
assert ranks is not None and ranks.size == {n}
out = {{}}
for k, split in enumerate(SPLITS):
    out[f"w{{k}}"], out[f"l{{k}}"], out[f"m{{k}}"] = trained(split, ranks)
np.savez(f"rank{{ranks.rank}}.npz", **out)
"""


@pytest.fixture(scope="module")
def two_ranks(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mpi")
    proc = mpiexec(2, RANKS_TRAIN.format(n=2), folder)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return [dict(np.load(folder / f"rank{r}.npz")) for r in (0, 1)]


def relative(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.parametrize("k", range(len(SPLITS)), ids=[f"clips per batch {s}" for s in SPLITS])
def test_two_ranks_train_the_parameters_of_one_process(two_ranks, k):
    """1e-5 relative (the norm of the difference over the norm of the weights): two ranks add the
    same float32 numbers in another order, a few ulps per step; 20 Adam steps on a tiny model grow
    that to about 1e-6 here. The losses too (each rank's a mean over its rows, weighted by n_r / B)."""
    weights, losses, moments = trained(SPLITS[k])
    for rank in two_ranks:
        assert relative(rank[f"w{k}"], weights) < 1e-5
        np.testing.assert_allclose(rank[f"l{k}"], losses, rtol=1e-5)
        assert relative(rank[f"m{k}"], moments) < 1e-5     # each rank updated half: gathered for checkpoints
    initial = np.concatenate([ps.data for ps in StyleModel(CFG, np.random.default_rng(0)).parameter_sets()])
    assert relative(weights, initial) > 1e-3           # training moved them: the comparison can fail


def test_the_ranks_end_with_the_same_weights(two_ranks):
    """Each rank updates its part of the weights and sends it to the others, so every rank holds the
    same weights and moments (to round-off, although the all-gather copies bits: nothing here relies
    on that)."""
    for k in range(len(SPLITS)):
        assert relative(two_ranks[1][f"w{k}"], two_ranks[0][f"w{k}"]) < 1e-6
        assert relative(two_ranks[1][f"m{k}"], two_ranks[0][f"m{k}"]) < 1e-6


def test_more_ranks_than_cores_still_train(tmp_path):
    """Oversubscribed (three ranks on a machine of fewer cores, as on CI's two): the job runs."""
    code = RANKS_TRAIN.format(n=3).replace("enumerate(SPLITS)", "enumerate(SPLITS[:1])")
    proc = mpiexec(3, code, tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    weights, _, moments = trained(SPLITS[0])
    assert relative(np.load(tmp_path / "rank2.npz")["w0"], weights) < 1e-5
    assert relative(np.load(tmp_path / "rank1.npz")["m0"], moments) < 1e-5


def test_without_mpiexec_there_are_no_ranks_and_no_mpi4py(monkeypatch):
    from minifilm.train import mpi
    for key in mpi.LAUNCHER_SIZES:
        monkeypatch.delenv(key, raising=False)
    assert mpi.world() is None
    monkeypatch.setenv("PMI_SIZE", "1")                # a launcher's single rank: one process too
    assert mpi.world() is None
    code = "import sys, minifilm.train.trainer, minifilm.pipeline.train_small; print('mpi4py' in sys.modules)"
    env = {k: v for k, v in os.environ.items() if k not in mpi.LAUNCHER_SIZES}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert proc.stdout.strip() == "False", proc.stderr


def test_a_minibatch_smaller_than_the_ranks_is_one_clear_error():
    from minifilm.errors import InputError
    from minifilm.train.mpi import Ranks

    class World:                                       # what Ranks asks of a communicator
        def Get_rank(self):
            return 0

        def Get_size(self):
            return 4

    with pytest.raises(InputError, match="mpiexec -n 4: a minibatch of 2 samples"):
        model = StyleModel(CFG, np.random.default_rng(0))
        Ranks(World()).bind(model, ChunkedAdam(model.parameter_sets()), batch_size=2)


DIVERGING = """
import numpy as np
from minifilm.model.style_model import StyleModel
from minifilm.train import mpi
from minifilm.train.trainer import TrainingDiverged
from test_mpi import trained
ranks = mpi.world()
backward = StyleModel.backward


def backward_with_a_nan(self, *args, **kw):      # rank 1's rows give Psi's first gradient a NaN
    out = backward(self, *args, **kw)
    if ranks.rank == 1:
        self.film.params.grad[0] = np.nan
    return out


StyleModel.backward = backward_with_a_nan
try:
    trained(4, ranks)
except TrainingDiverged as error:      # each rank its own file: the ranks' printed lines may interleave
    open(f"rank{ranks.rank}.txt", "w").write(str(error))
"""


def test_a_gradient_not_finite_on_one_rank_stops_every_rank_before_the_step(tmp_path):
    """A NaN in one rank's gradient makes the summed gradient NaN, held in one rank's part only:
    every rank stops at the same step with the same error naming the network, before any weight
    changes; no rank waits for another forever."""
    proc = mpiexec(2, DIVERGING, tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    said = [(tmp_path / f"rank{r}.txt").read_text() for r in (0, 1)]
    assert "step 0" in said[0] and "gradient of the film network is not finite (nan)" in said[0]
    assert said[1] == said[0]
