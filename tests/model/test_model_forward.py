"""The style model's forward pass against an independent NumPy computation written from the
paper (Eq. 2-4) with loops and per-sample blended weights, plus run-time paths."""
import numpy as np
import pytest

from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.dataset.stats import NormStats
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import blend_film


def elu(v):
    return np.where(v > 0, v, np.exp(np.minimum(v, 0)) - 1)


def reference_forward(model, x, p, clip, biased_ln=False):
    """Eq. (2)-(4) one sample at a time, from the parameter arrays."""
    cfg = model.config
    G, M, Fp = model.gating.params.params, model.motion.params.params, model.film.params.params
    out = []
    for b in range(x.shape[0]):
        # Ω
        h = elu(p[b] @ G["W0"] + G["b0"])
        h = elu(h @ G["W1"] + G["b1"])
        logits = h @ G["W2"] + G["b2"]
        alpha = np.exp(logits) / np.exp(logits).sum()
        # Ψ: direct convolution sums, zero padded, then pair-wise max
        def conv(y, W, bias):
            k = W.shape[0]
            T = y.shape[0]
            res = np.zeros((T, W.shape[2]))
            for t in range(T):
                for j in range(k):
                    s = t + j - k // 2
                    if 0 <= s < T:
                        res[t] += y[s] @ W[j]
            return res + bias
        def pool(y):
            return np.array([np.maximum(y[2 * i], y[2 * i + 1]) for i in range(y.shape[0] // 2)])
        y = pool(np.maximum(conv(clip[b], Fp["conv0_W"], Fp["conv0_b"]), 0))
        y = pool(np.maximum(conv(y, Fp["conv1_W"], Fp["conv1_b"]), 0))
        y = np.maximum(y.reshape(-1) @ Fp["dense0_W"] + Fp["dense0_b"], 0)
        film = y @ Fp["dense1_W"] + Fp["dense1_b"]
        H = cfg.hidden
        g1, b1, g2, b2 = film[:H], film[H:2 * H], film[2 * H:3 * H], film[3 * H:]
        # Φ with weights blended per sample
        h = x[b]
        for l, (g, be) in enumerate([(g1, b1), (g2, b2), (None, None)]):
            W = np.einsum("k,kio->io", alpha, M[f"W{l}"])
            bias = np.einsum("k,ko->o", alpha, M[f"b{l}"])
            h = h @ W + bias
            if g is not None:
                n = h.size
                sd = np.sqrt(((h - h.mean()) ** 2).sum() / (n if biased_ln else n - 1))
                h = elu(g * (h - h.mean()) / (sd + (0.0 if biased_ln else cfg.ln_eps)) + be)
        out.append(h)
    return np.array(out)


@pytest.fixture
def setup():
    rng = np.random.default_rng(5)
    cfg = ModelConfig.tiny()
    model = StyleModel(cfg, rng, dtype=np.float64)
    for ps in model.parameter_sets():
        ps.data += 0.05 * rng.standard_normal(ps.size)
    B = 4
    x = rng.standard_normal((B, cfg.x_dim))
    p = rng.standard_normal((B, cfg.phase_dim))
    clip = rng.standard_normal((B, cfg.clip_frames, cfg.clip_channels))
    return model, x, p, clip, rng


def test_forward_matches_independent_computation(setup):
    model, x, p, clip, _ = setup
    np.testing.assert_allclose(model.forward(x, p, clip), reference_forward(model, x, p, clip), rtol=1e-10, atol=1e-12)


def test_gating_weights_are_a_distribution(setup):
    model, x, p, clip, _ = setup
    alpha = model.gating.forward(p)
    assert alpha.shape == (4, model.config.n_experts)
    np.testing.assert_allclose(alpha.sum(axis=1), 1.0)
    assert (alpha > 0).all()


def test_precomputed_film_and_the_runtime_path_agree(setup):
    model, x, p, clip, _ = setup
    z = model.forward(x, p, clip)
    film = model.film_parameters(clip)
    np.testing.assert_allclose(model.forward_with_film(x, p, film), z, rtol=1e-12)
    stats = NormStats.identity(model.config.x_dim, model.config.z_dim, model.config.phase_dim)
    net = RuntimeNetwork.from_model(model, stats, dtype=np.float64)      # the batch-1 path
    for b in range(x.shape[0]):
        np.testing.assert_allclose(net.predict(x[b:b + 1], p[b:b + 1], film[b])[0], z[b], rtol=1e-10, atol=1e-12)
    # runtime layer norm (biased, no eps) against the reference
    zr = reference_forward(model, x, p, clip, biased_ln=True)
    released_style = RuntimeNetwork.from_model(model, stats, runtime_layer_norm=True, dtype=np.float64)
    np.testing.assert_allclose(released_style.predict(x[:1], p[:1], film[0])[0], zr[0], rtol=1e-10)


def test_film_blending(setup):
    model, x, p, clip, _ = setup
    films = model.film_parameters(clip)[:3]
    np.testing.assert_allclose(blend_film(films, [0, 1, 0]), films[1])
    np.testing.assert_allclose(blend_film(films, [0.2, 0.3, 0.5]), 0.2 * films[0] + 0.3 * films[1] + 0.5 * films[2])
    with pytest.raises(ValueError, match="sum to 1"):
        blend_film(films, [0.5, 0.5, 0.5])
    # a style vector shared by the batch equals the same vector repeated per sample
    v = blend_film(films, [0.2, 0.3, 0.5])
    np.testing.assert_allclose(model.forward_with_film(x, p, v), model.forward_with_film(x, p, np.tile(v, (4, 1))))


def test_dropout_masks_replay_and_eval_is_deterministic(setup):
    model, x, p, clip, rng = setup
    z_eval = model.forward(x, p, clip)
    np.testing.assert_array_equal(model.forward(x, p, clip), z_eval)
    z_train = model.forward(x, p, clip, train=True, rng=rng)
    masks = model.used_masks
    assert not np.allclose(z_train, z_eval)
    np.testing.assert_array_equal(model.forward(x, p, clip, train=True, masks=masks), z_train)
    keep = masks["motion0"].mean()
    assert 0.5 < keep < 0.9                      # rate 0.3
    with pytest.raises(ValueError, match="rng"):
        model.forward(x, p, clip, train=True)
    with pytest.raises(ValueError, match="shape"):
        model.forward(x, p, clip, train=True, rng=rng, masks={"motion0": np.ones((1, 2), bool)})


def test_bad_clip_shape_is_named(setup):
    model, x, p, clip, _ = setup
    with pytest.raises(ValueError, match="clip must be"):
        model.forward(x, p, clip[:, :-1])


def test_film_starts_near_identity():
    """Initial Ψ output bias puts γ at 1 and β at 0 (see film_generator.py)."""
    cfg = ModelConfig.tiny()
    model = StyleModel(cfg, np.random.default_rng(0))
    film = model.film_parameters(np.zeros((1, cfg.clip_frames, cfg.clip_channels), np.float32))[0]
    H = cfg.hidden
    np.testing.assert_allclose(film[:H], 1.0)
    np.testing.assert_allclose(film[H:2 * H], 0.0)


def test_backward_follows_what_the_last_forward_pass_left(setup):
    """Backward reads the cache of the last forward pass: the path through Ψ only after
    forward(x, p, clip) (and not once Ψ has run again on other clips), a shared FiLM vector's
    gradient summed over the batch, and nothing at all after a forward pass that failed (no
    stale caches of the pass before)."""
    model, x, p, clip, _ = setup
    dz = np.ones((x.shape[0], model.config.z_dim))
    for backward in (model.backward, model.backward_with_film):
        with pytest.raises(RuntimeError, match="preceding forward"):
            backward(dz)                                   # no forward pass yet
    model.forward(x, p, clip)
    assert model.backward(dz)["clip"].shape == clip.shape
    film = model.film_parameters(clip)
    model.forward_with_film(x, p, film[0])
    assert model.backward_with_film(dz)[2].shape == film[0].shape
    with pytest.raises(RuntimeError, match="backward_with_film after forward_with_film"):
        model.backward(dz)                                 # Ψ did not run in this pass
    model.forward(x, p, clip)
    model.film_parameters(clip[:2])                        # Ψ ran again, on other clips
    with pytest.raises(RuntimeError, match="backward_with_film after forward_with_film"):
        model.backward(dz)
    model.forward(x, p, clip)
    with pytest.raises(ValueError, match="clip must be"):
        model.forward(x, p, clip[:, :-1])
    with pytest.raises(RuntimeError, match="preceding forward"):
        model.backward(dz)
