"""The pieces of the comparison variants against independent computations: the Catmull-Rom phase
function (Holden et al. 2017), the one-hot input (as extra input columns), the residual adapters
(as explicit matrices), the variants' data path, and training a variant with train.Trainer."""
import numpy as np
import pytest

from minifilm.baselines.phase_function import catmull_rom_weights
from minifilm.baselines.runtime import variant_network
from minifilm.baselines.style_modulation import CPResidualAdapter, OneHotShift, ResidualAdapter
from minifilm.baselines.variants import VARIANTS, build_variant
from minifilm.dataset.stats import NormStats
from minifilm.model.config import ModelConfig
from minifilm.nn import functional as F
from minifilm.runtime.network import RuntimeNetwork


# ---- phase function ----------------------------------------------------------------------
def holden_cubic(y0, y1, y2, y3, mu):
    """The PFNN paper's Catmull-Rom formula, written out as there (Holden et al. 2017, Eq. 3)."""
    return (y1 + mu * (0.5 * y2 - 0.5 * y0) + mu ** 2 * (y0 - 2.5 * y1 + 2 * y2 - 0.5 * y3)
            + mu ** 3 * (1.5 * y1 - 1.5 * y2 + 0.5 * y3 - 0.5 * y0))


def test_catmull_rom_matches_the_pfnn_formula():
    rng = np.random.default_rng(0)
    values = rng.standard_normal((4, 3))
    for phase in rng.random(50):
        k1 = int(np.floor(4 * phase)) % 4
        mu = 4 * phase - np.floor(4 * phase)
        want = holden_cubic(*(values[(k1 + s) % 4] for s in (-1, 0, 1, 2)), mu)
        got = catmull_rom_weights(np.array([phase])) @ values
        np.testing.assert_allclose(got[0], want, atol=1e-12)


def test_catmull_rom_interpolates_control_points_and_is_cyclic_and_smooth():
    w = catmull_rom_weights(np.array([0.0, 0.25, 0.5, 0.75]))
    np.testing.assert_allclose(w, np.eye(4), atol=1e-15)                 # passes through the control points
    phases = np.random.default_rng(1).random(100)
    np.testing.assert_allclose(catmull_rom_weights(phases).sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(catmull_rom_weights(phases + 3.0), catmull_rom_weights(phases), atol=1e-12)
    # C1 across the segment joints and the wrap at 1 -> 0: one-sided slopes agree
    eps = 1e-7
    for knot in (0.25, 0.5, 0.75, 1.0):
        left = (catmull_rom_weights(np.array([knot - eps])) - catmull_rom_weights(np.array([knot - 2 * eps]))) / eps
        right = (catmull_rom_weights(np.array([knot + 2 * eps])) - catmull_rom_weights(np.array([knot + eps]))) / eps
        np.testing.assert_allclose(left, right, atol=1e-4)   # a kink would differ by O(1)


def test_phase_function_rejects_bad_shapes():
    with pytest.raises(ValueError, match="phase must be"):
        catmull_rom_weights(np.zeros((3, 2)))


# ---- one-hot ---------------------------------------------------------------------------------
def test_onehot_shift_equals_extra_input_columns():
    """Σ_k α_k (W_k [x; e_s] + b_k) with the one-hot rows appended to W_k = plain layer + shift."""
    rng = np.random.default_rng(2)
    K, S, I, H, B = 3, 4, 5, 6, 7
    onehot = OneHotShift(K, S, H, I + S, rng, dtype=np.float64)
    W = rng.standard_normal((K, I, H))
    b = rng.standard_normal((K, H))
    x = rng.standard_normal((B, I))
    alpha = rng.dirichlet(np.ones(K), size=B)
    style = rng.integers(0, S, B)
    W_ext = np.concatenate([W, onehot.params.params["E"]], axis=1)          # (K, I + S, H)
    x_ext = np.concatenate([x, np.eye(S)[style]], axis=1)
    want, _ = F.expert_linear_forward(x_ext, alpha, W_ext, b)
    got = F.expert_linear_forward(x, alpha, W, b)[0] + onehot.forward(style, alpha)
    np.testing.assert_allclose(got, want, atol=1e-12)


# ---- adapters --------------------------------------------------------------------------------
def test_residual_adapter_is_identity_plus_a_per_style_matrix():
    rng = np.random.default_rng(3)
    ad = ResidualAdapter(3, 4, rng, dtype=np.float64)
    np.testing.assert_array_equal(ad.forward(np.ones((2, 4)), np.array([0, 2])), np.ones((2, 4)))  # starts as identity
    ad.params.data[:] = rng.standard_normal(ad.params.size)
    h = rng.standard_normal((5, 4))
    style = np.array([1, 0, 1, 2, 2])
    out = ad.forward(h, style)
    for i in range(5):
        A, a = ad.params.params["A"][style[i]], ad.params.params["a"][style[i]]
        np.testing.assert_allclose(out[i], h[i] + h[i] @ A + a, atol=1e-12)


def test_cp_adapter_equals_the_full_phase_dependent_matrix():
    """A_s(φ) = Σ_r c_r(φ) u_r v_rᵀ built explicitly as an (H, H) matrix per sample."""
    rng = np.random.default_rng(4)
    S, H, R = 2, 5, 3
    ad = CPResidualAdapter(S, H, R, rng, dtype=np.float64)
    ad.params.data[:] = rng.standard_normal(ad.params.size)
    P = ad.params.params
    phase = rng.random(6)
    w = catmull_rom_weights(phase)
    h = rng.standard_normal((6, H))
    style = np.array([0, 1, 1, 0, 1, 0])
    out = ad.forward(h, style, w)
    for i in range(6):
        s = style[i]
        # the control-point tensor (4, H, H) of the CP decomposition, then the spline over it
        tensor = np.einsum("kr,hr,rg->khg", P["C"][s], P["U"][s], P["V"][s])
        A = sum(w[i, k] * tensor[k] for k in range(4))
        np.testing.assert_allclose(out[i], h[i] + h[i] @ A + P["a"][s], atol=1e-12)


def test_style_ids_are_checked():
    model = build_variant("LPN one-hot", ModelConfig.tiny(z_dim=40), np.random.default_rng(0), n_styles=3)
    x, p = np.zeros((2, 24), np.float32), np.zeros((2, 8), np.float32)
    with pytest.raises(ValueError, match="style"):
        model.forward(x, p, None)
    with pytest.raises(ValueError, match="0..2"):
        model.forward(x, p, None, style=np.array([0, 3]))
    pfnn = build_variant("PFNN one-hot", ModelConfig.tiny(z_dim=40), np.random.default_rng(0), n_styles=3)
    with pytest.raises(ValueError, match="global phase"):
        pfnn.forward(x, p, None, style=np.array([0, 1]))


# ---- the one inference path equals the batched forward ---------------------------------------
@pytest.mark.parametrize("name", VARIANTS)
def test_runtime_network_matches_forward(name):
    rng = np.random.default_rng(5)
    cfg = ModelConfig.tiny(z_dim=40)
    model = build_variant(name, cfg, rng, n_styles=3)
    for ps in model.parameter_sets():
        ps.data += 0.1 * rng.standard_normal(ps.size).astype(ps.data.dtype)
    cb = getattr(model, "backbone_config", cfg)
    x = rng.standard_normal((1, cb.x_dim)).astype(np.float32)
    p = (rng.random((1, 1)) if cb.phase_dim == 1 else rng.standard_normal((1, cb.phase_dim))).astype(np.float32)
    clip = rng.standard_normal((1, cfg.clip_frames, cfg.clip_channels)).astype(np.float32)
    z = model.forward(x, p, clip, style=np.array([2]))
    style = np.array([2]) if model.takes_style_ids else model.film_parameters(clip)[0]
    net = variant_network(model, NormStats.identity(cb.x_dim, cb.z_dim, cb.phase_dim))
    np.testing.assert_allclose(net.predict(x, p, style)[0], z[0], atol=1e-5)


def test_lpn_film_variant_runs_in_the_runtime_network():
    """build_variant('LPN FiLM') is a StyleModel: the run-time network takes it as it is."""
    rng = np.random.default_rng(6)
    cfg = ModelConfig.tiny(z_dim=40)
    model = build_variant("LPN FiLM", cfg, rng, with_film_generator=False)
    net = RuntimeNetwork.from_model(model, NormStats.identity(cfg.x_dim, cfg.z_dim))
    x = rng.standard_normal((1, cfg.x_dim)).astype(np.float32)
    p = rng.standard_normal((1, 8)).astype(np.float32)
    film = rng.standard_normal(cfg.film_dim).astype(np.float32)
    np.testing.assert_allclose(net.predict(x, p, film), model.forward_with_film(x, p, film), atol=1e-4)
