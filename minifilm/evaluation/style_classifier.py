"""A style classifier for generated motion: its "style recognition accuracy" is how often it names
the style a character was asked for (Sec. 5).

Trained on real clips of the dataset, applied to windows of generated rollouts: if the model
reproduces a style, the classifier recognises it. Input = a window of per-frame joint blocks
(the clip features y of Sec. 3.2: every joint's position, forward, up and velocity relative to
that frame's own root, normalised with the training statistics), summarised by the mean and the
standard deviation over time (2 x 12 J numbers: the pose a style holds and how much it moves).
The classifier is a small MLP (one ReLU hidden layer; hidden=0 gives multinomial logistic
regression), written with minifilm.nn and trained with its Adam on the softmax cross-entropy.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from minifilm.features.compute import joint_features
from minifilm.motion.kinematics import look_rotation, velocities
from minifilm.nn import functional as F
from minifilm.nn.fast_optim import ChunkedAdam
from minifilm.nn.params import Parameters


# ---------------------------------------------------------------------------- windows
def window_summary(windows: np.ndarray) -> np.ndarray:
    """(M, T, C) windows -> (M, 2C): [mean over time, std over time]."""
    w = np.asarray(windows, dtype=np.float64)
    if w.ndim != 3:
        raise ValueError(f"window_summary: windows must be (M, T, C), got {w.shape}")
    return np.concatenate([w.mean(axis=1), w.std(axis=1)], axis=1)


def cut_windows(block: np.ndarray, window: int, stride: int) -> np.ndarray:
    """(N, C) consecutive frames -> (M, window, C) windows every `stride` frames (M may be 0)."""
    firsts = np.arange(0, block.shape[0] - window + 1, stride)
    return block[firsts[:, None] + np.arange(window)[None, :]]


def split_windows(split, layout, normalizer, window: int, stride: int):
    """Windows of normalised joint blocks from the rows of a dataset split.

    The joint block of x (``layout.x_joints``) of row i is frame i's clip feature, so runs of
    consecutive rows (same file, frame numbers increasing by one) are pieces of clips of any
    length. split: a :class:`minifilm.dataset.build.Split`. Returns (windows (M, window, 12 J), style (M,)).
    """
    if len(split) == 0:
        return np.empty((0, window, layout.clip_dim)), np.empty(0, dtype=np.int64)
    wins, styles = [], []
    for a, b in zip(*split.runs()):
        block = normalizer.normalize_clip(np.asarray(split.x[a:b, layout.x_joints], dtype=np.float64), layout.x_joints)
        w = cut_windows(block, window, stride)
        wins.append(w)
        styles.append(np.full(len(w), int(split.style[a])))
    return np.concatenate(wins), np.concatenate(styles)


def rollout_blocks(rollout, warmup_seconds: float = 1.0) -> np.ndarray:
    """Per-frame clip features (B, F', 12 J) of a :class:`minifilm.runtime.controller.Rollout`, in raw units.

    The root is the rollout's own root (floor position, facing -> LookRotation), as in the data;
    velocities are backward differences of the generated positions (as the dataset computes them).
    Frames before ``warmup_seconds`` (the mean start pose) are dropped.
    """
    B, n, J = rollout.positions.shape[:3]
    k0 = min(int(round(warmup_seconds * rollout.fps)), n - 2)
    out = []
    for b in range(B):
        P = rollout.positions[b]
        root_pos = np.zeros((n, 3))
        root_pos[:, [0, 2]] = rollout.root_positions[b]
        facing = np.zeros((n, 3))
        facing[:, [0, 2]] = rollout.root_facing[b]
        block = joint_features(P, rollout.rotations[b], velocities(P, rollout.fps), root_pos,
                               look_rotation(facing))
        out.append(block[k0:])
    return np.stack(out)


# ---------------------------------------------------------------------------- the classifier
class StyleClassifier:
    """Softmax classifier on window summaries: logits = W1 relu(W0 s + b0) + b1 (hidden > 0) or
    W0 s + b0 (hidden = 0), s the standardised summary (standardisation fitted in :meth:`fit`).

    n_in: summary length (2 x 12 J); n_classes: number of styles.
    """

    def __init__(self, n_in: int, n_classes: int, hidden: int = 64, rng: Optional[np.random.Generator] = None,
                 dtype=np.float64):
        rng = rng or np.random.default_rng(0)
        self.hidden = int(hidden)
        dims = [n_in, hidden, n_classes] if hidden > 0 else [n_in, n_classes]
        shapes = {}
        for l in range(len(dims) - 1):
            shapes[f"W{l}"], shapes[f"b{l}"] = (dims[l], dims[l + 1]), (dims[l + 1],)
        self.params = Parameters(shapes, dtype=dtype)
        for l in range(len(dims) - 1):                      # He / Glorot-style scaled normal weights
            self.params.params[f"W{l}"][...] = rng.normal(0, np.sqrt(2.0 / (dims[l] + dims[l + 1])),
                                                          (dims[l], dims[l + 1]))
        self.n_layers = len(dims) - 1
        self.mean = np.zeros(n_in)
        self.std = np.ones(n_in)

    # -- forward / backward ------------------------------------------------------------
    def logits(self, s: np.ndarray, keep_caches: bool = False) -> np.ndarray:
        """s (B, n_in) standardised summaries -> (B, n_classes) logits."""
        P = self.params.params
        h = np.asarray(s, dtype=self.params.dtype)
        caches = []
        for l in range(self.n_layers):
            h, c = F.linear_forward(h, P[f"W{l}"], P[f"b{l}"])
            caches.append(c)
            if l < self.n_layers - 1:
                h, c = F.relu_forward(h)
                caches.append(c)
        if keep_caches:
            self._caches = caches
        return h

    def loss(self, s: np.ndarray, y: np.ndarray, weight_decay: float = 0.0) -> float:
        """Mean cross-entropy of labels y (B,) (+ weight_decay/2 * sum W^2); gradients into
        ``params.grads`` (overwritten). Cross-entropy through the softmax: dlogits = (p - onehot) / B."""
        y = np.asarray(y, dtype=np.int64)
        logits = self.logits(s, keep_caches=True)
        p, _ = F.softmax_forward(logits)
        B = len(y)
        loss = -np.mean(np.log(np.maximum(p[np.arange(B), y], 1e-300)))
        d = p.copy()
        d[np.arange(B), y] -= 1.0
        d /= B
        self.params.zero_grad()
        G = self.params.grads
        caches = self._caches
        for l in reversed(range(self.n_layers)):
            if l < self.n_layers - 1:
                d = F.relu_backward(d, caches[2 * l + 1])
            d, dW, db = F.linear_backward(d, caches[2 * l])
            G[f"W{l}"] += dW
            G[f"b{l}"] += db
        if weight_decay:
            for l in range(self.n_layers):
                W = self.params.params[f"W{l}"]
                loss += 0.5 * weight_decay * float(np.sum(W.astype(np.float64) ** 2))
                G[f"W{l}"] += weight_decay * W
        return float(loss)

    # -- training / prediction ---------------------------------------------------------
    def fit(self, summaries: np.ndarray, labels: np.ndarray, epochs: int = 200, lr: float = 3e-3,
            batch_size: int = 64, weight_decay: float = 1e-3, rng: Optional[np.random.Generator] = None):
        """Standardise with these summaries' statistics, then Adam on minibatches. Returns the
        per-epoch mean losses."""
        rng = rng or np.random.default_rng(0)
        X = np.asarray(summaries, dtype=np.float64)
        y = np.asarray(labels, dtype=np.int64)
        if X.ndim != 2 or y.shape != (len(X),) or len(X) == 0:
            raise ValueError(f"StyleClassifier.fit: summaries {X.shape} must be (N>0, n_in) with labels (N,)")
        self.mean = X.mean(axis=0)
        self.std = np.where(X.std(axis=0) > 1e-8, X.std(axis=0), 1.0)
        S = (X - self.mean) / self.std
        opt = ChunkedAdam([self.params], lr=lr)
        history = []
        for _ in range(epochs):
            order = rng.permutation(len(S))
            total = 0.0
            for a in range(0, len(S), batch_size):
                idx = order[a:a + batch_size]
                total += self.loss(S[idx], y[idx], weight_decay) * len(idx)
                opt.step()
            history.append(total / len(S))
        return history

    def predict_proba(self, summaries: np.ndarray) -> np.ndarray:
        """(N, n_in) raw summaries -> (N, n_classes) class probabilities."""
        S = (np.asarray(summaries, dtype=np.float64) - self.mean) / self.std
        p, _ = F.softmax_forward(self.logits(S))
        return p

    def predict(self, summaries: np.ndarray) -> np.ndarray:
        return np.argmax(self.predict_proba(summaries), axis=1)


def train_style_classifier(ds, window_seconds: float = 0.75, stride_seconds: float = 0.25,
                           hidden: int = 64, epochs: int = 80, seed: int = 0):
    """Fit a classifier on the training split of a :class:`minifilm.dataset.build.Dataset`; its accuracy on
    windows of the held-out rows (val + test, never seen in training) is the ceiling for rollouts.

    Returns (classifier, info) with info = {'window': frames, 'stride': frames, 'train_acc',
    'heldout_acc', 'heldout_per_style': {name: acc}, 'n_train', 'n_heldout'}.
    """
    window = max(2, int(round(window_seconds * ds.fps)))
    stride = max(1, int(round(stride_seconds * ds.fps)))
    Xw, y = split_windows(ds.train, ds.layout, ds.stats, window, stride)
    held = [split_windows(ds.split(n), ds.layout, ds.stats, window, stride) for n in ("val", "test")]
    Hw = np.concatenate([h[0] for h in held])
    hy = np.concatenate([h[1] for h in held])
    Xs = window_summary(Xw)
    clf = StyleClassifier(Xs.shape[1], len(ds.styles), hidden, np.random.default_rng(seed))
    clf.fit(Xs, y, epochs=epochs, rng=np.random.default_rng(seed + 1))
    info = {"window": window, "stride": stride, "n_train": int(len(y)), "n_heldout": int(len(hy)),
            "train_acc": float(np.mean(clf.predict(Xs) == y))}
    if len(hy):
        pred = clf.predict(window_summary(Hw))
        info["heldout_acc"] = float(np.mean(pred == hy))
        info["heldout_per_style"] = {name: float(np.mean(pred[hy == s] == s))
                                     for s, name in enumerate(ds.styles) if np.any(hy == s)}
    else:
        info["heldout_acc"], info["heldout_per_style"] = float("nan"), {}
    return clf, info


def classify_rollout(clf: StyleClassifier, ds, rollout, warmup_seconds: float = 1.0, window: int = 45,
                     stride: int = 15) -> np.ndarray:
    """Class probabilities of every window of every character: (B, M, n_classes)."""
    blocks = ds.stats.normalize_clip(rollout_blocks(rollout, warmup_seconds), ds.layout.x_joints)
    return np.stack([clf.predict_proba(window_summary(cut_windows(b, window, stride))) for b in blocks])
