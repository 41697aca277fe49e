"""Data-parallel training under MPI: the minibatch split across the ranks, the gradients summed.

    python examples/train_small.py                       one process: the plain loop (the default)
    mpiexec -n 2 python examples/train_small.py          two ranks on this machine's cores
    mpiexec -hosts a,b -n 16 minifilm train ...          sixteen ranks on two machines

Every rank runs the same script with the same seed, so every rank draws the same minibatches and
the same dropout masks (:meth:`Ranks.share`). Each rank keeps its rows of the minibatch and computes
the forward and backward pass on them into the model's one flat gradient buffer. Then
(:meth:`Ranks.sum_gradients`, :meth:`Ranks.step`):

1. ``Reduce_scatter`` sums the ranks' buffers and leaves each rank one N-th of the sum: its part;
2. each rank takes Adam's step on its part of the weights (Adam updates every number on its own);
3. ``Allgather`` gives every rank every part of the new weights.

Steps 1 and 3 move as many bytes as one ``Allreduce`` of the gradients (an all-reduce is a
reduce-scatter and an all-gather), and Adam's step, a fifth of a step's time in one process, is
shared instead of repeated on every rank. The simpler form, an ``Allreduce`` and the whole Adam
step on every rank, trained the main job's steps 1.10-1.14x as fast on two ranks as one process,
this one 1.23-1.25x (benchmarks/mpi_training.py, the same machine and hour); on many ranks the
repeated step would not shrink at all (docs/scaling.md). Large trainings call this sharding of
the optimiser's work and state "ZeRO stage 1".

Why the sum is the minibatch's gradient: the losses are means over the minibatch's B rows
(Eq. 5-7), so the gradient of the whole is the sum over ranks of (n_r / B) x the gradient of the
mean over the n_r rows of rank r. Only the order of the float32 additions differs from one process
(tests/train/test_mpi.py: 1e-5 relative after 20 steps).

With style clips shared by the minibatch (TrainConfig.clips_per_batch) the rows are split at clip
boundaries where there are at least as many clips as ranks, so each rank runs Ψ (the costly part)
on its own clips only.

Rank 0 alone prints and writes files; the stages before and after training run on rank 0 while the
other ranks lend it their cores for its maps (``mpi4py.futures.MPICommExecutor``), and what they
need comes by broadcast (:meth:`Ranks.from_rank0`). mpi4py is optional (``pip install -e .[mpi]``):
without ``mpiexec`` nothing of it is imported. When a rank dies, ``mpiexec`` stops the others.
"""
from __future__ import annotations

import contextlib
import os
import sys
import traceback
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from minifilm.errors import InputError, MissingDependencyError
from minifilm.nn.fast_optim import adam_span
from minifilm.train.objective import all_finite

#: Environment variables that MPI launchers set in every rank: MPICH and Intel MPI (Hydra),
#: Open MPI, and PMIx launchers such as Slurm's srun.
LAUNCHER_SIZES = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_SIZE")


class Span(NamedTuple):
    """Where one trainable parameter set lies in the flat buffers: its network's name, [first, end)
    in the buffers, and its numbers in this rank's part, as slices of the set and of the part."""
    net: str
    first: int
    end: int
    in_set: slice
    in_part: slice


class StoppedOnRank0(SystemExit):
    """Rank 0 failed before training (it says why); the other ranks end quietly with its code."""


def world():
    """:class:`Ranks` over every rank when this process was started by ``mpiexec -n N`` with N > 1;
    None otherwise (one process: mpi4py is not imported)."""
    sizes = [os.environ[k] for k in LAUNCHER_SIZES if k in os.environ]
    if not sizes or max(int(s) if s.isdigit() else 1 for s in sizes) < 2:
        return None
    try:
        from mpi4py import MPI      # here: an optional extra, loaded only under mpiexec
    except ImportError:
        raise MissingDependencyError("started by mpiexec, but mpi4py is not installed: "
                                     'pip install -e ".[mpi]" (mpi4py and mpich)') from None
    return Ranks(MPI.COMM_WORLD) if MPI.COMM_WORLD.Get_size() > 1 else None


class Ranks:
    """The ranks of one data-parallel training: this rank's number, their count, and the few
    collective steps the training needs."""

    def __init__(self, comm):
        from mpi4py import MPI      # here: an optional extra, loaded only under mpiexec
        self.MPI, self.comm = MPI, comm
        self.rank, self.size = comm.Get_rank(), comm.Get_size()
        self.grad = None                    # the model's gradients, one flat buffer (bind)
        self.together = False               # past from_rank0: the ranks now wait on each other

    # ---- before training ---------------------------------------------------------------------
    def from_rank0(self, make):
        """``make(executor)`` on rank 0, with the other ranks as its executor's workers; its result
        on every rank. When it fails, rank 0 raises the error and the others StoppedOnRank0."""
        from mpi4py.futures import MPICommExecutor     # here: an optional extra (see above)
        failed = result = None
        with MPICommExecutor(self.comm, root=0) as executor:
            if executor is not None:        # rank 0; the others serve its maps until it is done
                try:
                    result = make(executor)
                except BaseException as error:          # noqa: B036 (re-raised below, after telling)
                    failed = error
        code = self.comm.bcast(None if failed is None else getattr(failed, "code", 2), root=0)
        if failed is not None:
            raise failed
        if code is not None:
            raise StoppedOnRank0(code if isinstance(code, int) else 2)
        # pkl5: arrays travel as their own buffers, and a data set over 2 GB in one message is fine
        from mpi4py.util import pkl5    # here: an optional extra (see above)
        result = pkl5.Intracomm(self.comm).bcast(result, root=0)
        self.together = True
        return result

    def bind(self, model, optimizer, batch_size: int) -> None:
        """Put the model's trainable weights and gradients into one flat buffer each (one
        collective call per step), give this rank its part of them, and learn where the model
        draws dropout masks. InputError when a minibatch cannot give every rank a row."""
        if getattr(model, "film", None) is None or getattr(model, "takes_style_ids", False):
            raise InputError("mpiexec: data-parallel training needs the style model with its FiLM generator Ψ")
        if batch_size < self.size:
            raise InputError(f"mpiexec -n {self.size}: a minibatch of {batch_size} samples cannot give every "
                             f"rank a row; use at most {batch_size} ranks")
        sets = [(i, ps) for i, ps in enumerate(optimizer.sets) if ps.trainable]
        n = sum(ps.size for _, ps in sets)
        # equal parts, the buffers padded with zeros: Allgather took 0.11 ms for the main job's
        # weights where Allgatherv, with a count per rank, took 0.29 (MPICH 5, two ranks)
        part = -(-n // self.size)
        self.data, self.grad = np.zeros(part * self.size, model.dtype), np.zeros(part * self.size, model.dtype)
        self.lo, self.hi = self.rank * part, (self.rank + 1) * part       # this rank's part of the buffers
        self.part = np.zeros(part, dtype=model.dtype)   # this rank's part of the summed gradient
        names = {id(getattr(model, net).params): net for net in ("gating", "motion", "film")}
        self.spans, start = {}, 0                   # Adam's set index -> where the set lies (Span)
        for i, ps in sets:
            end = start + ps.size
            ps.bind(self.data[start:end], self.grad[start:end])
            lo = max(start, self.lo)
            hi = max(lo, min(end, self.hi))         # [lo, hi): the set's numbers in this rank's part
            self.spans[i] = Span(names.get(id(ps), f"set {i}"), start, end, slice(lo - start, hi - start),
                                 slice(lo - self.lo, hi - self.lo))
            start = end
        self.nonfinite = {}
        self.model, self.sites = model, dropout_sites(model)

    # ---- a step ------------------------------------------------------------------------------
    def share(self, b, rng):
        """This rank's part of minibatch ``b`` (a train.epoch.Minibatch): its rows, the clips they
        use, and their rows of the dropout masks, drawn from ``rng`` for the whole minibatch as one
        process's forward pass draws them; ``b.share`` is n_r / B."""
        B, M = len(b.x), len(b.clips)
        clip_index = b.kw.get("clip_index", np.arange(B))     # one clip per sample: clip b for row b
        masks = {}
        if self.model.config.dropout > 0:
            p_drop = self.model.config.dropout
            for site, (per_clip, row_shape) in self.sites.items():
                masks[site] = rng.random(((M if per_clip else B), *row_shape)) >= p_drop
        order = np.argsort(clip_index, kind="stable")         # rows grouped by clip
        if M >= self.size:                                    # whole clips to each rank
            lo, hi = self.rank * M // self.size, (self.rank + 1) * M // self.size
            rows = order[(clip_index[order] >= lo) & (clip_index[order] < hi)]
        else:                                                 # a clip may serve several ranks
            rows = order[self.rank * B // self.size:(self.rank + 1) * B // self.size]
        clips = np.unique(clip_index[rows])
        masks = {site: m[clips if self.sites[site][0] else rows] for site, m in masks.items()}
        kw = {**b.kw, "clip_index": np.searchsorted(clips, clip_index[rows]), "masks": masks}
        return replace(b, x=b.x[rows], p=b.p[rows], z=b.z[rows], clips=b.clips[clips], kw=kw,
                       share=len(rows) / B)

    def sum_gradients(self, b, mse: float, bll: float):
        """This rank's part of the minibatch's gradient (``self.part``) and the minibatch's
        (mse, bll): sums over ranks of share x this rank's (its losses are means over its rows).
        With them, per network, whether any number of the summed gradient is NaN or inf
        (``self.nonfinite``, {network: 'nan' | 'inf'}), the same on every rank."""
        MPI = self.MPI
        self.grad *= self.model.dtype.type(b.share)
        self.comm.Reduce_scatter_block(self.grad, self.part, op=MPI.SUM)
        totals = [mse * b.share, bll * b.share]
        for span in self.spans.values():           # this rank's count of NaN and inf, per set
            mine = self.part[span.in_part]
            finite = all_finite(mine)               # one pass; the counts only when it is not
            totals += [0, 0] if finite else [np.count_nonzero(np.isnan(mine)), np.count_nonzero(np.isinf(mine))]
        totals = np.array(totals, dtype=np.float64)
        self.comm.Allreduce(MPI.IN_PLACE, totals, op=MPI.SUM)
        self.nonfinite = {}
        for k, span in enumerate(self.spans.values()):
            nan, inf = totals[2 + 2 * k:4 + 2 * k]
            if nan or inf:
                self.nonfinite.setdefault(span.net, "nan" if nan else "inf")
        return float(totals[0]), float(totals[1])

    def step(self, adam) -> None:
        """Adam's step (a minifilm.nn.fast_optim.ChunkedAdam) on this rank's part of the weights,
        from its part of the summed gradient; then every rank gets every part (Allgather)."""
        for i, step_size, eps_hat in adam.advance():
            mine = self.spans[i].in_set
            if mine.stop > mine.start:               # set i has numbers in this rank's part
                adam_span(adam.sets[i].data[mine], self.part[self.spans[i].in_part], adam.m[i][mine],
                          adam.v[i][mine], adam.scratch(self.data.dtype), adam.beta1, adam.beta2, step_size, eps_hat)
        self.comm.Allgather(self.MPI.IN_PLACE, self.data)

    def gather_moments(self, adam) -> None:
        """Every rank's part of Adam's moments m and v to every rank, before a checkpoint is
        written (each rank updates only its part of them)."""
        for moments in (adam.m, adam.v):
            flat = np.zeros_like(self.data)
            for i, span in self.spans.items():
                flat[span.first:span.end] = moments[i]
            self.comm.Allgather(self.MPI.IN_PLACE, flat)
            for i, span in self.spans.items():
                moments[i][...] = flat[span.first:span.end]


def dropout_sites(model) -> dict:
    """{site: (per clip?, shape of one row)} in the order one training forward pass draws them (Ψ's
    sites on the clips first, then Ω's and Φ's on the samples), from a pass on one sample."""
    c, dtype = model.config, model.dtype
    model.forward(np.zeros((1, c.x_dim), dtype), np.zeros((1, c.phase_dim), dtype),
                  np.zeros((1, c.clip_frames, c.clip_channels), dtype), train=True, rng=np.random.default_rng(0))
    sites = {s: (True, m.shape[1:]) for s, m in model.film.used_masks.items()}
    for net in (model.gating, model.motion):
        sites.update({s: (False, m.shape[1:]) for s, m in net.used_masks.items()})
    return sites


@contextlib.contextmanager
def one_job(ranks):
    """Under mpiexec, an error or Ctrl-C on one rank once training has begun ends every rank
    (MPI_Abort), after saying what it was: the others would otherwise wait for it in the next
    all-reduce forever. In one process, and before the data set is shared, errors pass as usual."""
    try:
        yield
    except StoppedOnRank0:
        raise
    except BaseException as error:                      # noqa: B036 (every rank must stop)
        if ranks is None or not ranks.together:
            raise
        if isinstance(error, (OSError, ValueError)):    # the user's input or disk: one line
            print(f"error (MPI rank {ranks.rank}): {error}", file=sys.stderr, flush=True)
        elif not isinstance(error, (KeyboardInterrupt, SystemExit)):
            traceback.print_exc()
        ranks.comm.Abort(130 if isinstance(error, KeyboardInterrupt) else 2)
