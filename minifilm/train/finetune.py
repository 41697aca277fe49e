"""Fine-tuning Ψ alone on new styles (Sec. 5.3.2, Figure 11): Ω and Φ stay frozen."""
from __future__ import annotations

from minifilm.train.checkpoint import CheckpointError
from minifilm.train.trainer import TrainConfig, Trainer


def finetune(checkpoint_path, train_data, val_data=None, config: TrainConfig | None = None,
             style_names=(), build_model=None):
    """Fine-tune Ψ for new styles (Sec. 5.3.2): Φ and Ω frozen at a trained checkpoint.

    Starts a new run (fresh optimiser and rng from config.seed) with freeze = (gating, motion).
    build_model: as :meth:`Trainer.resume` (the comparison's FiLM variants pass
    minifilm.baselines.variants.model_from_checkpoint; default: the paper's StyleModel).
    """
    cfg = config or TrainConfig()
    cfg = TrainConfig.from_dict({**cfg.to_dict(), "freeze": ["gating", "motion"]})
    trainer = Trainer.resume(checkpoint_path, cfg, restore_optimizer=False, build_model=build_model)
    if trainer.model.film is None:
        raise CheckpointError(f"checkpoint {checkpoint_path}: has no FiLM generator to fine-tune")
    if style_names:
        trainer.style_names = list(style_names)
    trainer.fit(train_data, val_data)
    return trainer
