"""The style-pack commands on the authors' released network: generate reads a pack (its style, and
blends with the network's), bad packs and wrong options are one clear error line, and finetune
--params refuses a --replace of a style the pack does not hold before any work."""
import numpy as np
import pytest

from minifilm import cli
from minifilm.runtime.released import load_released
from minifilm.runtime.style_pack import StylePack


@pytest.fixture(scope="module")
def params(shared_data):
    return shared_data / "released-lpn"


@pytest.fixture(scope="module")
def pack(params, tmp_path_factory):
    rel = load_released(params)
    film = 0.5 * rel.styles["Neutral"] + 0.5 * rel.styles["Old"]       # a vector the network can walk with
    folder = tmp_path_factory.mktemp("packs") / "mine"
    StylePack.empty().with_style("Mine", film, {"taught_from": [], "clip": {"steps_per_s": 1.8, "hips": 0.9}}).save(folder)
    return folder


def run(argv, capsys):
    with pytest.raises(SystemExit) as done:
        cli.main([str(a) for a in argv])
    out = capsys.readouterr()
    return done.value.code, out.out, out.err


def test_generate_uses_a_pack_style_and_blends_it(params, pack, tmp_path, capsys):
    code, out, err = run(["generate", "--params", params, "--styles", pack, "--list-styles"], capsys)
    assert code == 0 and out.split()[-1] == "Mine" and len(out.split()) == 101
    code, out, err = run(["generate", "--params", params, "--styles", pack, "--style", "Mine", "--style2", "Zombie",
                          "--blend", "0.3", "--seconds", "0.3", "--no-calibrate", "--out", tmp_path / "m.bvh"], capsys)
    assert code == 0, err
    assert "Mine + 0.3 Zombie" in out and (tmp_path / "m.bvh").is_file()


@pytest.mark.parametrize("argv, message", [
    (["generate", "--params", "{params}", "--styles", "{tmp}/nothing", "--style", "X"], "nothing"),
    (["generate", "--params", "{params}", "--styles", "{tmp}", "--style", "X"], "no styles.npz"),
    (["generate", "--run", "{tmp}", "--styles", "{pack}"], "--styles"),
    (["generate", "--params", "{params}", "--styles", "{pack}", "--style", "Unknown", "--seconds", "0.2"], "Unknown"),
    (["finetune", "--params", "{params}", "--name", "New", "{tmp}/x.bvh"], "needs --out"),
    (["finetune", "--params", "{params}", "--name", "Nope", "--replace", "--out", "{pack}", "{tmp}/x.bvh"],
     "no style 'Nope' to replace"),
    (["finetune", "--params", "{params}", "--name", "Mine", "--out", "{pack}", "{tmp}/x.bvh"], "already has a style"),
    (["finetune", "--params", "{params}", "--name", "Zombie", "--out", "{tmp}/p", "{tmp}/x.bvh"],
     "already has a style of that name"),
])
def test_bad_packs_and_options_are_one_line(params, pack, tmp_path, capsys, argv, message):
    (tmp_path / "x.bvh").write_text("not read: the options are checked first\n")
    argv = [a.format(params=params, pack=pack, tmp=tmp_path) for a in argv]
    code, out, err = run(argv, capsys)
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err, err


def test_the_network_folder_is_only_read(params, pack):
    before = sorted(p.name for p in params.iterdir())
    assert "styles.npz" not in before and "pack.json" not in before
    assert np.isfinite(load_released(params).styles["Neutral"]).all()


def test_the_demo_source_holds_the_pack_styles_and_caches_them_by_their_vector(params, pack, tmp_path):
    from minifilm.demo.calibration_cache import CalibrationCache
    from minifilm.demo.calibrations import Calibrations
    from minifilm.demo.source import DemoSource
    from minifilm.runtime.calibration import CALIBRATION_COMMANDS, CALIBRATION_DIRECTIONS, SpeedCalibration
    source = DemoSource.released(params, calibrate=True, pack=pack)
    assert source.library.names[-1] == "Mine" and len(source.library) == 101
    assert source.pack_names == ("Mine",) and "style pack" in source.name
    cache = CalibrationCache(source, where=tmp_path, shipped=None)
    c = np.array(CALIBRATION_COMMANDS)
    cal = SpeedCalibration(c, np.stack([0.4 * c] * len(CALIBRATION_DIRECTIONS)), CALIBRATION_DIRECTIONS)
    calibrations = Calibrations(source, background=False, cache=cache, log=lambda m: None)
    calibrations._store("Mine", cal)
    calibrations._store("Neutral", cal)
    assert set(CalibrationCache(source, where=tmp_path, shipped=None).load()) == {"Mine", "Neutral"}
    # another pack with a style of the same name and another vector: its entry is not used for it
    rel = load_released(params)
    other = tmp_path / "other"
    StylePack.empty().with_style("Mine", rel.styles["Zombie"], {"taught_from": []}).save(other)
    again = DemoSource.released(params, calibrate=True, pack=other)
    assert set(CalibrationCache(again, where=tmp_path, shipped=None).load()) == {"Neutral"}
