"""PLACEHOLDER until the full example exists: train a small gated-expert network from minifilm.nn.

A gating layer turns the input into blend weights alpha = softmax(x Wg + bg) over K experts
(Sec. 4.1 in miniature); two ExpertLinear + ELU layers and a Linear output fit a known smooth
function of 3 numbers, with hand-written backprop and Adam. Prints the training loss per epoch and
the final held-out loss against the baseline that always predicts the mean.
"""
import time

import numpy as np

from minifilm.nn import ELU, Adam, ExpertLinear, Linear, Parameters, Softmax

# ---- settings ---------------------------------------------------------------------------------
seed = 0
n_train, n_val = 4000, 1000
n_experts, hidden = 4, 32
epochs, batch_size, lr = 15, 32, 3e-3


def target(x):
    """The function to learn: R^3 -> R^2, smooth."""
    return np.stack([np.sin(np.pi * x[:, 0]) * np.cos(np.pi * x[:, 1]),
                     x[:, 2] ** 2 - 0.5 * x[:, 0]], axis=1)


# ---- data -------------------------------------------------------------------------------------
rng = np.random.default_rng(seed)
x_all = rng.uniform(-1, 1, size=(n_train + n_val, 3)).astype(np.float32)
y_all = target(x_all).astype(np.float32)
x_train, y_train, x_val, y_val = x_all[:n_train], y_all[:n_train], x_all[n_train:], y_all[n_train:]

# ---- network: all weights in one flat buffer --------------------------------------------------
params = Parameters({**Linear.param_shapes(3, n_experts, "gate."),
                     **ExpertLinear.param_shapes(n_experts, 3, hidden, "e0."),
                     **ExpertLinear.param_shapes(n_experts, hidden, hidden, "e1."),
                     **Linear.param_shapes(hidden, 2, "out.")})
gate = Linear(3, n_experts, rng, parameters=params, prefix="gate.")
e0 = ExpertLinear(n_experts, 3, hidden, rng, parameters=params, prefix="e0.")
e1 = ExpertLinear(n_experts, hidden, hidden, rng, parameters=params, prefix="e1.")
out = Linear(hidden, 2, rng, parameters=params, prefix="out.")
softmax, act0, act1 = Softmax(), ELU(), ELU()
optimiser = Adam([params], lr=lr)


def forward(x):
    alpha = softmax.forward(gate.forward(x))                     # (B, K) expert blend weights
    h = act0.forward(e0.forward(x, alpha))                       # (B, hidden)
    h = act1.forward(e1.forward(h, alpha))
    return out.forward(h)                                        # (B, 2)


def backward(dy):
    """Backprop in reverse order of forward; alpha gets gradient from both expert layers."""
    dh = act1.backward(out.backward(dy))
    dh, dalpha1 = e1.backward(dh)
    _, dalpha0 = e0.backward(act0.backward(dh))
    gate.backward(softmax.backward(dalpha0 + dalpha1))


def mse(pred, y):
    return float(np.mean((pred - y) ** 2))


# ---- training ---------------------------------------------------------------------------------
print(f"minifilm.nn placeholder example: {params.size} parameters, {n_experts} experts, "
      f"{n_train} training / {n_val} held-out samples")
start = time.perf_counter()
for epoch in range(1, epochs + 1):
    order = rng.permutation(n_train)
    losses = []
    for i in range(0, n_train, batch_size):
        idx = order[i:i + batch_size]
        pred = forward(x_train[idx])
        losses.append(mse(pred, y_train[idx]))
        params.zero_grad()
        backward(2 * (pred - y_train[idx]) / pred.size)         # d mean((pred - y)^2) / d pred
        optimiser.step()
    print(f"epoch {epoch:2d}  mean batch MSE {np.mean(losses):.5f}  held-out MSE {mse(forward(x_val), y_val):.5f}")

baseline = mse(np.broadcast_to(y_train.mean(axis=0), y_val.shape), y_val)
final = mse(forward(x_val), y_val)
print(f"held-out MSE {final:.5f} vs {baseline:.5f} for predicting the training mean "
      f"({baseline / final:.0f}x lower), {time.perf_counter() - start:.1f} s")
