"""The training objective of one minibatch, L = L_mse + w L_bll (Eq. 5-7), as one function, and the
finiteness test the Trainer applies to its losses and gradients before an update."""
from __future__ import annotations

import numpy as np

from minifilm.model.losses import bone_length_loss, mse_loss


def objective(pred, target, bll_weight=1.0, positions_idx=None, parents=None, z_mean=None, z_std=None):
    """(mse, bll, dpred) for one minibatch: pred, target (B, D) -> two floats and dL/dpred (B, D).

    The bone-length term needs the joint-position columns ``positions_idx`` (J, 3) of z, the
    ``parents`` (J,) and the output statistics ``z_mean``, ``z_std`` (D,); without them (or with
    ``bll_weight`` 0) it is 0. Both terms are means over the minibatch's rows."""
    mse, dpred = mse_loss(pred, target)
    bll = 0.0
    if positions_idx is not None and bll_weight:
        bll, dbll = bone_length_loss(pred, target, positions_idx, parents, z_mean, z_std)
        bll *= bll_weight
        dpred = dpred + bll_weight * dbll
    return mse, bll, dpred


def all_finite(value) -> bool:
    """Whether every number of ``value`` is finite: the sum first (one pass, no temporary; any NaN or
    inf makes it NaN or inf), and only when that is not finite -- a NaN, an inf, or finite numbers
    whose sum overflows -- the exact test, number by number."""
    value = np.asarray(value)
    with np.errstate(over="ignore", invalid="ignore"):
        total = np.sum(value)
    return bool(np.isfinite(total)) or bool(np.all(np.isfinite(value)))
