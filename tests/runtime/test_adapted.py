"""Styles with an adapter on the one inference path (minifilm/runtime/adapted.py): a row without an
adapted style is Φ bit for bit, a row with one is the fitted form's Φ, a blend gives the adapter
the style's weight, and the adapters' files are checked before they are used."""
import json

import numpy as np
import pytest

from minifilm.dataset.stats import NormStats
from minifilm.model.adapters import StyleAdapter
from minifilm.model.config import ModelConfig
from minifilm.model.style_model import StyleModel
from minifilm.runtime.adapted import AdaptedLibrary, AdaptedNetwork, AdapterChange, with_adapters
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import StyleLibrary
from minifilm.runtime.style_pack import StylePack, StylePackError, load_pack
from minifilm.train.adapter_fit import AdapterRows, FrozenPhi, adapted_phi_forward

CFG = ModelConfig(x_dim=9, z_dim=7, phase_dim=8, n_experts=3, hidden=6, gating_hidden=5, clip_frames=9,
                  clip_channels=3, conv_filters=3, conv_kernel=3, film_dense=6)
SIZES = [9, 6, 6, 7]


def toy(dtype=np.float64, runtime_layer_norm=True):
    model = StyleModel(CFG, np.random.default_rng(0), dtype=dtype, with_film_generator=False)
    for ps in (model.motion.params, model.gating.params):
        ps.data += 0.1 * np.random.default_rng(1).standard_normal(ps.size).astype(dtype)
    stats = NormStats.identity(CFG.x_dim, CFG.z_dim, CFG.phase_dim)
    return model, RuntimeNetwork.from_model(model, stats, runtime_layer_norm=runtime_layer_norm, dtype=dtype)


def adapters(dtype=np.float64, seed=2):
    rng = np.random.default_rng(seed)
    out = [StyleAdapter("lowrank", SIZES, 3, rank=2, dtype=dtype, rng=rng), StyleAdapter("residual", SIZES, 3, dtype=dtype)]
    for a in out:
        a.params.data[...] = 0.3 * rng.standard_normal(a.params.size)
    return out


def inputs(B, seed=3):
    rng = np.random.default_rng(seed)
    film = 0.3 * rng.standard_normal((B, 4 * CFG.hidden))
    film[:, :6] += 1
    film[:, 12:18] += 1
    return rng.standard_normal((B, CFG.x_dim)), rng.standard_normal((B, 8)), film


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("B", [1, 3, 8])          # 3: the runtime's few-rows branch
def test_rows_without_an_adapted_style_are_the_network_bit_for_bit(dtype, B):
    _, net = toy(dtype)
    adapted = AdaptedNetwork(net, adapters(dtype))
    x, p, film = inputs(B)
    cond = np.concatenate([film, np.zeros((B, 2))], axis=1).astype(dtype)
    assert np.array_equal(adapted.predict(x, p, cond), net.predict(x, p, film.astype(dtype)))
    assert np.array_equal(adapted.predict(x, p, cond[0]), net.predict(x, p, film[0].astype(dtype)))   # one shared
    # a batch in which some rows hold an adapted style: the others are still the network's rows
    cond[B // 2:, -1] = 0.7
    out = adapted.predict(x, p, cond)
    whole = net.predict(x, p, film.astype(dtype))
    assert np.array_equal(out[:B // 2], whole[:B // 2])
    assert not np.allclose(out[B // 2:], whole[B // 2:])


def test_the_runtime_applies_what_was_fitted():
    """The runtime's layout (experts side by side) with adapters against the fitted form's Φ
    (minifilm/train/adapter_fit.py), in float64: the same function, summed in another order."""
    model, net = toy()
    phi = FrozenPhi.of(model, np.float64)
    B = 6
    x, p, film = inputs(B)
    for a, s in zip(adapters(), (np.linspace(0.2, 1.0, B), np.ones(B))):
        rows = AdapterRows.make(model, phi, x, p, np.zeros((B, CFG.z_dim)), np.arange(B))
        fitted, _ = adapted_phi_forward(rows, film, phi, a, s)
        cond = np.concatenate([film, s[:, None]], axis=1)
        np.testing.assert_allclose(AdaptedNetwork(net, [a]).predict(x, p, cond), fitted, rtol=1e-10, atol=1e-12)


def test_a_blend_gives_the_adapter_the_style_weight():
    films = StyleLibrary({"Plain": np.full(24, 0.5), "Other": np.linspace(0, 1, 24), "Taught": np.full(24, 2.0)})
    lib = AdaptedLibrary(films, ["Taught"])
    assert lib.dim == 25 and lib["Plain"][-1] == 0 and lib["Taught"][-1] == 1
    for w in (0.0, 0.3, 1.0):
        c = lib.blend([("Plain", 1 - w), ("Taught", w)])
        assert np.array_equal(c[:24], films.blend([("Plain", 1 - w), ("Taught", w)]))    # FiLM part: bit for bit
        assert c[24] == np.float32(w)
    # a blend of styles without an adapter: share exactly 0, FiLM part as the plain library's
    c = lib.blend([("Plain", 0.4), ("Other", 0.6)])
    assert c[24] == 0 and np.array_equal(c[:24], films.blend([("Plain", 0.4), ("Other", 0.6)]))
    s = lib.schedule([(0.0, "Plain"), (0.5, "Taught")], 90, fps=60.0, transition_seconds=0.5)
    np.testing.assert_array_equal(s[:, :24], films.schedule([(0.0, "Plain"), (0.5, "Taught")], 90, 60.0, 0.5))
    assert s[0, 24] == 0 and s[-1, 24] == 1 and np.all(np.diff(s[:, 24]) >= 0)


def test_the_adapter_change_is_its_share_times_the_whole_change():
    rng = np.random.default_rng(4)
    h, x, alpha = rng.standard_normal((5, 6)), rng.standard_normal((5, 9)), rng.dirichlet(np.ones(3), 5)
    low, res = adapters()
    for w in (0.25, 0.6):
        part = AdapterChange([low, res], np.array([[w, 0.0]] * 5))
        whole = AdapterChange([low, res], np.array([[1.0, 0.0]] * 5))
        np.testing.assert_allclose(part.experts(0, 0, x, alpha), w * whole.experts(0, 0, x, alpha), rtol=1e-12)
        part = AdapterChange([low, res], np.array([[0.0, w]] * 5))
        whole = AdapterChange([low, res], np.array([[0.0, 1.0]] * 5))
        np.testing.assert_allclose(part.hidden(1, h) - h, w * (whole.hidden(1, h) - h), rtol=1e-12)


def test_with_adapters_leaves_a_network_without_them_alone():
    _, net = toy()
    lib = StyleLibrary({"A": np.ones(24)})
    assert with_adapters(net, lib, {}) == (net, lib)
    with pytest.raises(ValueError, match="does not hold"):
        with_adapters(net, lib, {"B": adapters()[0]})
    with pytest.raises(ValueError, match="does not fit"):
        AdaptedNetwork(net, [StyleAdapter("residual", [9, 5, 5, 7], 3)])


# ---- the files ----------------------------------------------------------------------------------
def pack_with_adapter(tmp_path, kind="lowrank"):
    a = adapters(np.float32)[0 if kind == "lowrank" else 1]
    pack = StylePack.empty().with_style("Plain", np.ones(24), {}).with_style("Taught", np.full(24, 2.0), {},
                                                                              adapter=a)
    return pack.save(tmp_path / "pack"), a


@pytest.mark.parametrize("kind", ["lowrank", "residual"])
def test_a_pack_keeps_its_adapters(tmp_path, kind):
    _, net = toy(np.float32)
    folder, a = pack_with_adapter(tmp_path, kind)
    pack = load_pack(folder, film_dim=24, network=net)
    assert list(pack.adapters) == ["Taught"] and pack.adapters["Taught"].kind == kind
    for k, v in a.params.params.items():
        assert np.array_equal(pack.adapters["Taught"].params.params[k], v)
    # replacing the style without an adapter drops it
    pack.with_style("Taught", np.full(24, 3.0), {}, replace=True).save(folder)
    assert load_pack(folder, film_dim=24, network=net).adapters == {} and not (folder / "adapters.json").exists()


def edit_json(folder, change):
    doc = json.loads((folder / "adapters.json").read_text())
    change(doc["adapters"][0])
    (folder / "adapters.json").write_text(json.dumps(doc))


@pytest.mark.parametrize("change, message", [
    (lambda e: e.update(style="Nobody"), "not one of the folder's styles"),
    (lambda e: e.update(kind="magic"), "kind 'magic'"),
    (lambda e: e.update(rank=500), "rank 500"),
    (lambda e: e.update(sizes=[9, 6, 6, 8]), "the network has"),
    (lambda e: e["arrays"].update(P0=[3, 9, 50]), "not those of a lowrank adapter"),
    (lambda e: e.update(dtype="object"), "dtype 'object'"),
])
def test_a_wrong_adapter_description_is_one_error_naming_the_folder(tmp_path, change, message):
    _, net = toy(np.float32)
    folder, _ = pack_with_adapter(tmp_path)
    edit_json(folder, change)
    with pytest.raises(StylePackError, match=message) as e:
        load_pack(folder, film_dim=24, network=net)
    assert str(folder) in str(e.value)


def test_an_archive_larger_than_its_description_is_refused_before_it_is_read(tmp_path):
    _, net = toy(np.float32)
    folder, a = pack_with_adapter(tmp_path)
    arrays = {f"0.{k}": v for k, v in a.params.params.items()}
    arrays["0.P0"] = np.zeros((3, 9, 2000), np.float32)          # the header declares far more than described
    np.savez(folder / "adapters.npz", **arrays)
    with pytest.raises(StylePackError, match="more than"):
        load_pack(folder, film_dim=24, network=net)


@pytest.mark.parametrize("damage, message", [
    (lambda f, a: np.savez(f / "adapters.npz", **{f"0.{k}": v for k, v in a.params.params.items() if k != "Q2"}),
     "do not belong together"),
    (lambda f, a: np.savez(f / "adapters.npz", **{f"0.{k}": (np.full_like(v, np.nan) if k == "P1" else v)
                                                   for k, v in a.params.params.items()}), "expected finite"),
    (lambda f, a: (f / "adapters.json").unlink(), "without adapters.json"),
])
def test_damaged_adapter_files_are_refused(tmp_path, damage, message):
    _, net = toy(np.float32)
    folder, a = pack_with_adapter(tmp_path)
    damage(folder, a)
    with pytest.raises(StylePackError, match=message):
        load_pack(folder, film_dim=24, network=net)


def test_a_pack_with_adapters_needs_the_network(tmp_path):
    folder, _ = pack_with_adapter(tmp_path)
    with pytest.raises(StylePackError, match="need the network"):
        load_pack(folder, film_dim=24)
