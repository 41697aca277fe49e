"""Style packs (minifilm/runtime/style_pack.py): a round trip, adding and replacing, and every kind
of bad pack refused with one StylePackError naming the folder and what is wrong."""
import json

import numpy as np
import pytest

from minifilm.runtime.style_pack import StylePack, StylePackError, load_pack, load_pack_or_empty, with_pack
from minifilm.runtime.walk_checks import WalkReport

D = 8


def a_pack(tmp_path, names=("Strut", "Limp")):
    pack = StylePack.empty()
    for i, n in enumerate(names):
        pack = pack.with_style(n, np.full(D, float(i + 1)), {"taught_from": [{"file": f"{n}.bvh"}]})
    return pack.save(tmp_path / "pack")


def test_round_trip_and_merge_with_the_network_styles(tmp_path):
    folder = a_pack(tmp_path)
    pack = load_pack(folder, film_dim=D, reserved={"Neutral": None})
    assert pack.names == ["Strut", "Limp"]
    assert pack.info["Limp"]["taught_from"] == [{"file": "Limp.bvh"}]
    np.testing.assert_array_equal(pack.styles["Limp"], np.full(D, 2.0))
    lib = with_pack({"Neutral": np.zeros(D)}, pack)
    assert lib.names == ["Neutral", "Strut", "Limp"]
    np.testing.assert_allclose(lib.blend([("Neutral", 0.5), ("Limp", 0.5)]), np.full(D, 1.0))


def test_adding_and_replacing(tmp_path):
    folder = a_pack(tmp_path)
    pack = load_pack(folder)
    with pytest.raises(StylePackError, match="already has a style 'Strut'"):
        pack.with_style("Strut", np.zeros(D), {})
    with pytest.raises(StylePackError, match="no style 'Nope' to replace"):
        pack.with_style("Nope", np.zeros(D), {}, replace=True)
    pack.with_style("Strut", np.zeros(D), {}, replace=True).save(folder)
    again = load_pack(folder)
    assert again.names == ["Strut", "Limp"] and not again.styles["Strut"].any()
    assert load_pack_or_empty(tmp_path / "none").names == []


def write_json(folder, doc):
    (folder / "pack.json").write_text(json.dumps(doc))


@pytest.mark.parametrize("damage, message", [
    ("no folder", "not a folder"),
    ("no npz", "no styles.npz"),
    ("no json", "no pack.json"),
    ("json not json", "pack.json"),
    ("wrong format", "not a style pack description"),
    ("wrong version", "pack version"),
    ("names differ", "do not belong together"),
    ("dim in json", "FiLM vectors of"),
    ("dim as text", r"'film_dim' is '8', not a whole number"),
    ("npz corrupt", "styles.npz"),
    ("npz nan", "non-finite"),
])
def test_bad_packs_are_one_clear_error(tmp_path, damage, message):
    folder = a_pack(tmp_path)
    doc = json.loads((folder / "pack.json").read_text())
    if damage == "no folder":
        folder = tmp_path / "missing"
    elif damage == "no npz":
        (folder / "styles.npz").unlink()
    elif damage == "no json":
        (folder / "pack.json").unlink()
    elif damage == "json not json":
        (folder / "pack.json").write_text("{not json")
    elif damage == "wrong format":
        write_json(folder, {**doc, "format": "something else"})
    elif damage == "wrong version":
        write_json(folder, {**doc, "version": 99})
    elif damage == "names differ":
        write_json(folder, {**doc, "styles": doc["styles"][::-1]})
    elif damage == "dim in json":
        write_json(folder, {**doc, "film_dim": 3})
    elif damage == "dim as text":
        write_json(folder, {**doc, "film_dim": str(doc["film_dim"])})
    elif damage == "npz corrupt":
        (folder / "styles.npz").write_bytes(b"PK\x03\x04 broken")
    elif damage == "npz nan":
        films = np.ones((2, D))
        films[0, 3] = np.nan
        np.savez(folder / "styles.npz", names=np.array(["Strut", "Limp"]), films=films)
    with pytest.raises(StylePackError, match=message) as e:
        load_pack(folder, film_dim=D)
    assert "style pack" in str(e.value)


def test_a_pack_for_another_network_or_taking_its_names_is_refused(tmp_path):
    folder = a_pack(tmp_path)
    with pytest.raises(StylePackError, match="the network needs 2048"):
        load_pack(folder, film_dim=2048)
    with pytest.raises(StylePackError, match="already the network's own"):
        load_pack(folder, film_dim=D, reserved={"Limp": None})


def test_walk_report_says_what_is_wrong_in_words():
    ok = WalkReport(steps_per_s=1.6, toe_on_floor=0.97, hips=0.92, path_mean=0.2, clip_steps_per_s=1.7, clip_hips=0.93)
    assert ok.problems() == [] and ok.words().startswith("it walks")
    bad = WalkReport(steps_per_s=0.1, toe_on_floor=0.4, hips=0.7, path_mean=3.0, clip_steps_per_s=1.7, clip_hips=0.93)
    words = bad.words()
    assert words.startswith("WARNING") and "hardly steps" in words and "leave the floor" in words
    assert "hips at 0.70 m" in words and "leaves the path" in words
    slow = WalkReport(steps_per_s=0.9, toe_on_floor=0.95, hips=0.92, path_mean=0.2, clip_steps_per_s=1.7, clip_hips=0.92)
    assert slow.problems() == ["it steps 0.90/s, the clip 1.70/s"]
