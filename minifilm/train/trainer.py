"""Training of the style model (Sec. 4.3): the Trainer, its settings and its checkpoints.

    loss = L_mse + L_bll                                  Eq. (5)-(7)
    minibatches hold one style; styles visited in a fixed cycle; one epoch = one pass through
    the shortest style's training frames; Adam, lr 1e-4, dropout 0.3 (Sec. 4.3); batch 32 (the
    paper gives none: the original code's)

Which style clip each sample reads, and what the paper and the original say about it: batches.py,
the one place that tells it. Data comes in as plain arrays (minifilm.dataset.arrays.TrainData), already
normalised; the bone-length loss needs the joint-position columns of z and the parent list,
which the caller takes from the feature layout. The minibatches are built in batches.py; fine-tuning
Ψ alone (Sec. 5.3.2) is finetune.py.

Robustness: a NaN or inf in a loss or a gradient stops training with TrainingDiverged naming
the step and the quantity, *before* the optimiser touches the weights; checkpoints are written
atomically (minifilm.train.checkpoint), so the last good one stays intact. Resuming restores the
model, the optimiser moments and the random generator, so a resumed run continues exactly as
an uninterrupted one would.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from minifilm.dataset.arrays import TrainData
from minifilm.dataset.stats import NormStats
from minifilm.model.style_model import StyleModel
from minifilm.nn.fast_optim import ChunkedAdam
from minifilm.train.batches import draw_clips, draw_shared_clips, epoch_batches
from minifilm.train.epoch import EpochLosses, Minibatch
from minifilm.train.objective import all_finite, objective
from minifilm.train.checkpoint import (NETWORKS, CheckpointError, build_style_model, load_checkpoint,
                                       load_model_arrays, model_arrays, save_checkpoint, subset)


class TrainingDiverged(RuntimeError):
    """A loss or gradient became NaN / inf; the weights were not updated with it."""


@dataclass
class TrainConfig:
    """Settings of a training run (the paper: 90 epochs, Adam lr 1e-4; batch 32 is the original
    code's, the paper gives no batch size).

    lr_schedule         "constant" (the paper) or "cosine": the learning rate falls from lr to
                        lr * lr_floor along half a cosine over the `epochs` of the run
    freeze              networks not updated: () for training, ("gating", "motion") to fine-tune Ψ
    input_noise         std of Gaussian noise added to the normalised inputs x and p of every
                        training minibatch (0: none, the paper). At run time the network reads its
                        own slightly wrong predictions. For train_small's model, one seed each,
                        0.1-0.2 kept more styles stepping but stretched more bones in 60 s
                        rollouts (benchmarks/trained_rollout.py): not a clear win, so off by default
    clips_per_batch     None: every sample gets its own clip of the minibatch's style, drawn at
                        random (as the original). n: the minibatch draws n clips of its style and
                        its samples share them, so Ψ runs on n clips instead of batch_size (for
                        speed). What the paper and the original do: batches.py
    checkpoint_path     where to write a checkpoint after every `checkpoint_every` epochs (None: never)
    progress            a one-line progress display on stderr (None: only when stderr is a terminal)
    """

    epochs: int = 90
    batch_size: int = 32
    lr: float = 1e-4
    seed: int = 0
    bll_weight: float = 1.0
    input_noise: float = 0.0
    lr_schedule: str = "constant"
    lr_floor: float = 0.1
    freeze: tuple = ()
    clips_per_batch: int | None = None
    checkpoint_path: str | None = None
    checkpoint_every: int = 1
    progress: bool | None = None
    eval_batch: int = 512

    def __post_init__(self):
        self.freeze = tuple(self.freeze)
        bad = [n for n in self.freeze if n not in NETWORKS]
        if bad:
            raise ValueError(f"TrainConfig.freeze: unknown network(s) {bad}; choose from {NETWORKS}")
        if self.input_noise < 0:
            raise ValueError(f"TrainConfig.input_noise must be >= 0, got {self.input_noise}")
        if self.lr_schedule not in ("constant", "cosine"):
            raise ValueError(f"TrainConfig.lr_schedule must be 'constant' or 'cosine', got {self.lr_schedule!r}")
        if not 0.0 <= self.lr_floor <= 1.0:
            raise ValueError(f"TrainConfig.lr_floor must be in [0, 1], got {self.lr_floor}")
        if self.clips_per_batch is not None and self.clips_per_batch < 1:
            raise ValueError(f"TrainConfig.clips_per_batch must be None or >= 1, got {self.clips_per_batch}")
        if self.batch_size < 1 or self.epochs < 0 or self.lr <= 0:
            raise ValueError(f"TrainConfig: need batch_size >= 1, epochs >= 0, lr > 0 (got "
                             f"{self.batch_size}, {self.epochs}, {self.lr})")

    def to_dict(self):
        d = asdict(self)
        d["freeze"] = list(self.freeze)
        return d

    @classmethod
    def from_dict(cls, d):
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


# ---- the trainer --------------------------------------------------------------------------
@dataclass
class Trainer:
    """Holds the model, the optimiser, the random generator and the loss history.

    positions_idx (J, 3) and parents (J,): joint-position columns of z and the skeleton's parent
    list for the bone-length loss (None: train with MSE only). ranks: None (one process, the
    default) or the ranks of an ``mpiexec`` job (minifilm.train.mpi.world()), which then share
    every minibatch.
    """

    model: StyleModel
    stats: NormStats
    config: TrainConfig = field(default_factory=TrainConfig)
    positions_idx: np.ndarray | None = None
    parents: np.ndarray | None = None
    style_names: list = field(default_factory=list)
    ranks: object = None

    def __post_init__(self):
        for net in NETWORKS:
            sub = getattr(self.model, net)
            if sub is not None:
                sub.params.trainable = net not in self.config.freeze
        self.optimizer = ChunkedAdam(self.model.parameter_sets(), lr=self.config.lr)   # fast form of nn/optim.py::Adam
        if self.ranks is not None:          # under mpiexec: one flat buffer to sum, a part per rank (train/mpi.py)
            self.ranks.bind(self.model, self.optimizer, self.config.batch_size)
        self.rng = np.random.default_rng(self.config.seed)
        self.epoch = 0
        self.step = 0
        self.history: list = []

    # -- losses ------------------------------------------------------------------------
    def losses(self, pred, target):
        """(mse, bll, dpred) for one minibatch."""
        return objective(pred, target, self.config.bll_weight, self.positions_idx, self.parents,
                         self.stats.z_mean, self.stats.z_std)

    def _check_finite(self, where, quantities):
        for name, value in quantities:
            if not all_finite(value):
                raise TrainingDiverged(f"step {self.step} ({where}): {name} is not finite "
                                       f"({'nan' if np.any(np.isnan(value)) else 'inf'}); weights not updated")

    def learning_rate(self, epoch: float) -> float:
        """The learning rate at a (fractional) epoch of the run: constant, or half a cosine from
        lr at epoch 0 to lr * lr_floor at the last epoch (config.epochs)."""
        c = self.config
        if c.lr_schedule == "constant" or c.epochs <= 0:
            return c.lr
        u = min(max(epoch / c.epochs, 0.0), 1.0)
        return c.lr * (c.lr_floor + (1.0 - c.lr_floor) * 0.5 * (1.0 + math.cos(math.pi * u)))

    def _shares_clips(self) -> bool:
        """Clip sharing is on and the model conditions on clips (not on style ids)."""
        return self.config.clips_per_batch is not None and not getattr(self.model, "takes_style_ids", False)

    def _style_kw(self, style_ids):
        """Style ids for models whose style modulation is indexed by style (the one-hot and
        residual-adapter variants of minifilm.baselines.variants); nothing for FiLM models."""
        return {"style": style_ids} if getattr(self.model, "takes_style_ids", False) else {}

    # -- one epoch ---------------------------------------------------------------------
    def minibatches(self, data: TrainData):
        """The epoch's minibatches, drawn with the trainer's generator as :meth:`train_epoch` uses
        them: style-balanced (batches.epoch_batches), each sample with a clip of its style (shared
        by the batch when config.clips_per_batch is set), inputs in the model's dtype with the
        configured input noise. Yields :class:`Minibatch`; under ``mpiexec`` this rank's share of
        each (train/mpi.py: its rows, and their rows of the dropout masks drawn for the whole)."""
        dtype = self.model.dtype
        batches = epoch_batches(data.style, self.config.batch_size, self.rng)
        for i, (s, idx) in enumerate(batches):
            kw = self._style_kw(data.style[idx])
            if self._shares_clips():
                clip_idx, kw["clip_index"] = draw_shared_clips(data, s, self.config.clips_per_batch, len(idx),
                                                               self.rng)
            else:
                clip_idx = draw_clips(data, data.style[idx], self.rng)
            # the gathers copy already; a cast copies again only when the data are in another dtype
            x, p, z = (a[idx].astype(dtype, copy=False) for a in (data.x, data.p, data.z))
            clips = data.clips[clip_idx].astype(dtype, copy=False)
            if self.config.input_noise > 0:
                x = x + (self.config.input_noise * self.rng.standard_normal(x.shape)).astype(dtype)
                p = p + (self.config.input_noise * self.rng.standard_normal(p.shape)).astype(dtype)
            where = f"epoch {self.epoch + 1}, batch {i + 1}, style {self._name(s)}"
            b = Minibatch(i, len(batches), int(s), x, p, z, clips, kw, where)
            yield b if self.ranks is None else self.ranks.share(b, self.rng)   # this rank's rows of it

    def train_epoch(self, data: TrainData):
        """One epoch of style-balanced minibatches, :meth:`train_step` on each; returns
        {'mse', 'bll', 'per_style'} means."""
        losses = EpochLosses(self)
        for b in self.minibatches(data):
            mse, bll = self.train_step(b)
            losses.add(b, mse, bll)
        return losses.summary()

    def train_step(self, b: Minibatch):
        """One minibatch: forward, the losses, every gradient by hand, Adam. Returns (mse, bll).
        examples/train_small.py spells out the same lines in its loop."""
        self.model.zero_grad()
        pred = self.model.forward(b.x, b.p, b.clips, train=True, rng=self.rng, **b.kw)   # Eq. (4)
        mse, bll, dpred = self.losses(pred, b.z)                  # Eq. (5)-(7) and dL/dz
        self.model.backward(dpred, need_input_grads=False)   # Ψ, Φ, Ω in reverse; inputs are data
        mse, bll = self.sum_over_ranks(b, mse, bll)
        self.update(b, mse, bll)
        return mse, bll

    def sum_over_ranks(self, b: Minibatch, mse: float, bll: float):
        """Under ``mpiexec`` (``self.ranks``, train/mpi.py): the gradients and losses of this rank's
        rows summed over the ranks into the minibatch's (each rank keeps its part of the summed
        gradient). In one process: as they are."""
        if self.ranks is None:
            return mse, bll
        return self.ranks.sum_gradients(b, mse, bll)

    def update(self, b: Minibatch, mse: float, bll: float) -> None:
        """After the backward pass: stop on a NaN or inf before any weight changes, then Adam's
        step at this point's learning rate, counted."""
        self.check_finite(b, mse, bll)
        self.optimizer.lr = self.learning_rate(self.epoch + b.index / b.count)
        if self.ranks is None:
            self.optimizer.step()                           # minifilm/nn/fast_optim.py
        else:                                               # this rank's part, then the parts shared
            self.ranks.step(self.optimizer)
        self.step += 1

    def check_finite(self, b: "Minibatch", mse: float, bll: float) -> None:
        """TrainingDiverged naming the minibatch and the quantity when a loss or a network's
        gradient is NaN or inf (called after the backward pass, before the optimiser step)."""
        self._check_finite(b.where, [("MSE loss", mse), ("bone-length loss", bll)])
        if self.ranks is not None:      # under mpiexec each rank holds a part of the sum: the ranks' verdict
            for net, kind in self.ranks.nonfinite.items():
                raise TrainingDiverged(f"step {self.step} ({b.where}): gradient of the {net} network is not "
                                       f"finite ({kind}); weights not updated")
            return
        self._check_finite(b.where, [(f"gradient of the {net} network", getattr(self.model, net).params.grad)
                                     for net in NETWORKS if getattr(self.model, net) is not None])

    def end_epoch(self, train_losses: dict, val: TrainData | None = None) -> dict:
        """After an epoch's steps: count it, evaluate ``val``, record the history, checkpoint."""
        self.epoch += 1
        if self.ranks is not None:          # each rank updated its part of Adam's moments: all of them
            self.ranks.gather_moments(self.optimizer)
        record = {"epoch": self.epoch, "step": self.step, "train": train_losses}
        if val is not None:
            record["val"] = self.evaluate(val)
        self.history.append(record)
        if self.config.checkpoint_path and self.epoch % self.config.checkpoint_every == 0:
            self.save(self.config.checkpoint_path)
        return record

    # -- evaluation --------------------------------------------------------------------
    def evaluate(self, data: TrainData):
        """Mean MSE and BLL over all frames of `data` (no dropout), overall and per style.

        Each style is weighted equally overall (as in Eq. 5 and 7). Clips are drawn with a
        generator seeded from the run seed, so the numbers are comparable across epochs and do
        not disturb the training generator.
        """
        rng = np.random.default_rng([self.config.seed, 1])
        dtype = self.model.dtype
        films = self._clip_films(data)
        sums = {}
        for s in np.unique(data.style):
            frames = np.nonzero(data.style == s)[0]
            for a in range(0, len(frames), self.config.eval_batch):
                idx = frames[a:a + self.config.eval_batch]
                clip_idx = draw_clips(data, data.style[idx], rng)
                x, p = data.x[idx].astype(dtype), data.p[idx].astype(dtype)
                if films is not None:       # Ψ is deterministic here: each clip's FiLM vector once
                    pred = self.model.forward_with_film(x, p, films[clip_idx])
                else:
                    pred = self.model.forward(x, p, data.clips[clip_idx].astype(dtype),
                                              **self._style_kw(data.style[idx]))
                mse, bll, _ = self.losses(pred, data.z[idx].astype(dtype))
                acc = sums.setdefault(int(s), [0.0, 0.0, 0])
                acc[0] += mse * len(idx)
                acc[1] += bll * len(idx)
                acc[2] += len(idx)
        return self._summarise(sums)

    def _clip_films(self, data: TrainData, chunk: int = 64):
        """Ψ(clip) (M, 4H) of every clip of ``data`` without dropout, for models conditioned on
        clips; None for the one-hot and adapter variants (they read style ids)."""
        if getattr(self.model, "takes_style_ids", False) or getattr(self.model, "film", None) is None:
            return None
        dtype = self.model.dtype
        return np.concatenate([self.model.film_parameters(data.clips[a:a + chunk].astype(dtype))
                               for a in range(0, len(data.clips), chunk)])

    def _summarise(self, sums):
        per_style = {self._name(s): {"mse": m / n, "bll": b / n} for s, (m, b, n) in sorted(sums.items())}
        mse = float(np.mean([v["mse"] for v in per_style.values()])) if per_style else float("nan")
        bll = float(np.mean([v["bll"] for v in per_style.values()])) if per_style else float("nan")
        return {"mse": mse, "bll": bll, "loss": mse + bll, "per_style": per_style}

    def _name(self, s):
        return self.style_names[s] if s < len(self.style_names) else str(s)


    # -- the run -----------------------------------------------------------------------
    def fit(self, train: TrainData, val: TrainData | None = None, epochs: int | None = None):
        """Train until `epochs` (default config.epochs) epochs are done in total; returns history."""
        target = self.config.epochs if epochs is None else epochs
        while self.epoch < target:
            self.end_epoch(self.train_epoch(train), val)
        return self.history

    # -- checkpoints -------------------------------------------------------------------
    def save(self, path):
        """Atomic checkpoint: model, optimiser, rng state, stats, configs, epoch and history."""
        meta = {"model_config": self.model.config.to_dict(), "train_config": self.config.to_dict(),
                "epoch": self.epoch, "step": self.step, "history": self.history,
                "rng_state": self.rng.bit_generator.state, "style_names": list(self.style_names),
                "has_film_generator": self.model.film is not None,
                "variant": ({"name": self.model.name, "n_styles": getattr(self.model, "n_styles", None)}
                            if hasattr(self.model, "name") else None),
                "positions_idx": None if self.positions_idx is None else np.asarray(self.positions_idx).tolist(),
                "parents": None if self.parents is None else np.asarray(self.parents).tolist()}
        arrays = {**model_arrays(self.model), **self.stats.to_arrays("stats."),
                  **{f"adam.{k}": v for k, v in self.optimizer.state_dict().items()}}
        save_checkpoint(path, meta, arrays)

    @classmethod
    def resume(cls, path, config: TrainConfig | None = None, restore_optimizer=True, build_model=None):
        """Rebuild a Trainer from a checkpoint: model, stats, optimiser state, rng, history.

        config: replaces the stored TrainConfig (e.g. more epochs). restore_optimizer=False starts
        a fresh optimiser and rng (used for fine-tuning, which is a new run). build_model: the
        checkpoint's metadata -> a freshly built model to load the weights into; the default
        builds the paper's StyleModel (minifilm.train.checkpoint.build_style_model), the
        comparison passes its own builder for its variants.
        """
        meta, arrays = load_checkpoint(path)
        try:
            tcfg = config or TrainConfig.from_dict(meta["train_config"])
            stats = NormStats.from_arrays(arrays, "stats.")
            model = (build_model or build_style_model)(meta)
        except (KeyError, ValueError, TypeError, AttributeError) as e:
            raise CheckpointError(f"checkpoint {path}: bad configuration or statistics ({type(e).__name__}: {e})") from None
        load_model_arrays(model, arrays, path)
        pos, par = _bone_indices(meta, model.config.z_dim, path)
        names = meta.get("style_names", [])
        if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
            raise CheckpointError(f"checkpoint {path}: 'style_names' must be a list of strings")
        trainer = cls(model, stats, tcfg, positions_idx=pos, parents=par, style_names=names)
        if restore_optimizer:
            try:
                trainer.optimizer.load_state_dict(subset(arrays, "adam"))
                trainer.rng.bit_generator.state = meta["rng_state"]
            except (KeyError, ValueError, TypeError) as e:
                raise CheckpointError(f"checkpoint {path}: optimiser or rng state unusable ({e})") from e
            trainer.epoch, trainer.step = int(meta["epoch"]), int(meta["step"])
            if trainer.epoch < 0 or trainer.step < 0:
                raise CheckpointError(f"checkpoint {path}: epoch {trainer.epoch} and step {trainer.step} must be >= 0")
            trainer.history = list(meta.get("history", []))
        return trainer


def _bone_indices(meta: dict, z_dim: int, path):
    """The checkpoint's positions_idx (J, 3) columns of z and parents (J,) for the bone-length loss
    (Eq. 6-7), checked: whole numbers, columns inside z, parents before their joints."""
    pos, par = meta.get("positions_idx"), meta.get("parents")
    if pos is None or par is None:
        return None, None
    try:
        pos, par = np.asarray(pos), np.asarray(par)
        ok = (pos.dtype.kind in "iu" and par.dtype.kind in "iu" and pos.ndim == 2 and pos.shape[1] == 3
              and par.shape == (len(pos),) and pos.size and 0 <= pos.min() and pos.max() < z_dim
              and all(-1 <= p < j for j, p in enumerate(par.tolist())))
    except (ValueError, TypeError):
        ok = False
    if not ok:
        raise CheckpointError(f"checkpoint {path}: 'positions_idx' / 'parents' do not describe a skeleton in "
                              f"z's {z_dim} columns")
    return pos.astype(np.int64), par.astype(np.int64)


def train(model, train_data, val_data, stats, positions_idx=None, parents=None, config=None,
          style_names=()):
    """Train `model` from scratch; returns the Trainer (history in .history)."""
    trainer = Trainer(model, stats, config or TrainConfig(), positions_idx, parents, list(style_names))
    trainer.fit(train_data, val_data)
    return trainer
