"""Dropout sites with named, reusable keep-masks.

Every network of the model applies dropout "before each layer" (Sec. 4.3, rate 0.3). A gradient
check needs the *same* masks on every evaluation of the loss, so each dropout site has a name and
a forward pass can be given the masks to use (``masks={name: bool array}``). The masks a pass
actually used are kept in ``used`` so a caller can replay them. Masks are drawn from an explicit
``np.random.Generator`` when not given.
"""
from __future__ import annotations

import numpy as np

from minifilm.nn.functional import dropout_backward, dropout_forward


def dropout_site(x, p, name, train, rng, masks, used):
    """Inverted dropout on x at site `name`. Returns (out, cache) for `dropout_site_backward`.

    x      (B, ...) activations
    p      drop probability
    masks  dict name -> boolean keep-mask of x's shape, or None (draw from rng)
    used   dict that receives the mask this call used (only when dropout is active)
    """
    if not train or p == 0.0:
        return dropout_forward(x, p, train=False)
    mask = None if masks is None else masks.get(name)
    if mask is None:
        if rng is None:
            raise ValueError(f"dropout site '{name}': training needs an rng or a fixed mask")
        mask = rng.random(x.shape) >= p
    elif mask.shape != x.shape:
        raise ValueError(f"dropout site '{name}': mask shape {mask.shape} != activation shape {x.shape}")
    used[name] = mask
    return dropout_forward(x, p, mask=mask, train=True)


def dropout_site_backward(dout, cache):
    return dropout_backward(dout, cache)
