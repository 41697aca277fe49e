"""A taught style's adapter (minifilm/pipeline/teach_adapter.py): when it is fitted, the replay is
the unmodified network's own motion, the fit brings Φ nearer the clip while the replayed motion
stays, and with a pack holding an adapter every released style walks bit for bit as without it."""
import numpy as np
import pytest

from minifilm import cli
from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.teach_adapter import LOSS_RATIO, AdapterPlan, adapter_kind, released_controller, replay_rows
from minifilm.runtime.adapted import with_adapters
from minifilm.runtime.style_pack import StylePack, load_pack, with_pack
from minifilm.train.adapter_fit import AdapterSettings

LAYOUT = FeatureLayout.for_skeleton(STYLE100)


def test_when_a_style_gets_an_adapter():
    auto, own = AdapterPlan(), 0.03
    assert adapter_kind(auto, far=True, loss=0.01, own_loss=own) == "lowrank"
    assert adapter_kind(auto, far=False, loss=own, own_loss=own) is None               # the network's own kind of motion
    assert adapter_kind(auto, far=False, loss=1.01 * LOSS_RATIO * own, own_loss=own) == "lowrank"
    assert adapter_kind(AdapterPlan("off"), far=True, loss=1.0, own_loss=own) is None
    assert adapter_kind(AdapterPlan("residual"), far=False, loss=0.0, own_loss=own) == "residual"
    with pytest.raises(ValueError, match="expected one of auto, off, residual, lowrank"):
        AdapterPlan("big")


@pytest.fixture(scope="module")
def rel(shared_data):
    from minifilm.runtime.released import load_released
    return load_released(shared_data / "released-lpn")


def test_the_replay_is_the_networks_own_motion(rel):
    films = np.stack([rel.styles[n] for n in ("Zombie", "Old")])
    x, p, z, style = replay_rows(lambda n: released_controller(n, LAYOUT), rel.network, films, 1.2, seconds=1.5)
    assert x.shape == (60, LAYOUT.x_dim) and z.shape == (60, LAYOUT.z_dim) and sorted(set(style)) == [0, 1]
    # the targets are what Φ predicts for the recorded inputs (the same inputs again, in a batch of
    # another size: float32 sums in another order, hence the tolerance, 1e-4 of the outputs' spread)
    again = rel.network.predict(x, p, films[style])
    np.testing.assert_allclose(again, z, atol=1e-4 * np.std(z))


def small_clip(rel, seconds=6.0):
    from minifilm.pipeline.refit_released import generated_motions
    motion, = generated_motions(rel, ["Zombie"], seconds, script="straight")
    return motion


def test_teaching_with_an_adapter_fits_the_clip_and_keeps_the_other_styles(rel, shared_data, tmp_path, capsys):
    """Zombie's own walk taught with Zombie hidden, the adapter forced on and small settings: the
    adapter lowers the loss on the clip's held-out rows, the replayed motion moves little, the pack
    keeps it, and ``generate`` walks a released style bit for bit as without the pack."""
    from minifilm.pipeline.teach_released import teach
    from minifilm.train.film_fit import FitSettings
    known = {n: rel.styles[n] for n in list(rel.styles)[:12] if n != "Zombie"}
    plan = AdapterPlan("lowrank", AdapterSettings(rank=4, steps=40, batch=64, every=10), replay_styles=4,
                       replay_seconds=2.0)
    taught = teach(rel, LAYOUT, "Taught", [small_clip(rel)], ["zombie.bvh"], known=known, require_steps=False,
                   settings=FitSettings(steps=20, every=5), prior_weights=(1.0,), motion=None, adapter=plan,
                   log=lambda line: None)
    a = taught.adapter_info
    assert taught.adapter is not None and a["kind"] == "lowrank" and a["rank"] == 4
    assert a["holdout_loss"] < a["holdout_loss_film_alone"]
    assert a["replay_loss"] < 0.1 * a["holdout_loss_film_alone"]
    pack = tmp_path / "pack"
    StylePack.empty().with_style("Taught", taught.film, taught.pack_info(), adapter=taught.adapter).save(pack)
    StylePack.empty().with_style("Taught", taught.film, taught.pack_info()).save(tmp_path / "no-adapter")
    loaded = load_pack(pack, film_dim=2048, reserved=rel.styles, network=rel.network)
    assert loaded.info["Taught"]["adapter"]["kind"] == "lowrank"
    network, library = with_adapters(rel.network, with_pack(rel.styles, loaded), loaded.adapters)
    x = np.tile(rel.stats.x_mean, (2, 1))
    p = np.tile(rel.stats.p_mean, (2, 1))
    assert not np.allclose(network.predict(x, p, library["Taught"]), rel.network.predict(x, p, taught.film))
    # the demo drives the same network and library; a released style's calibration is the one it
    # has without the pack (the shipped calibrations stay valid), the adapted style's is its own
    from minifilm.demo.calibration_cache import calibration_key, style_digest
    from minifilm.demo.source import DemoSource
    plain, adapted = DemoSource.released(shared_data / "released-lpn"), DemoSource.released(shared_data / "released-lpn",
                                                                                           pack=pack)
    assert adapted.network.film_dim == 2049 and calibration_key(adapted) == calibration_key(plain)
    assert style_digest(adapted, "Old") == style_digest(plain, "Old")
    assert style_digest(adapted, "Taught") != style_digest(DemoSource.released(shared_data / "released-lpn",
                                                                               pack=tmp_path / "no-adapter"), "Taught")
    # generate: a released style (and a blend of two) with the pack holding an adapter, bit for bit
    for style in (["--style", "Old"], ["--style", "Old", "--style2", "Zombie", "--blend", "0.3"]):
        outs = []
        for extra in ([], ["--styles", pack]):
            out = tmp_path / f"walk{len(outs)}.bvh"
            with pytest.raises(SystemExit) as done:
                cli.main([str(v) for v in ["generate", "--params", shared_data / "released-lpn", *style, "--seconds", "1",
                                           "--no-calibrate", "--out", out, *extra]])
            assert done.value.code == 0, capsys.readouterr().err
            outs.append(out.read_bytes())
        assert outs[0] == outs[1]

