"""minifilm.body.units: every real file (and renamed copies the built-ins do not know) at its
true size; the unit inferred from the body's legs; non-humanoids in centimetres, saying so."""
import numpy as np
import pytest

from humanoid_rigs import (CMU_CONVERSION_FROM_MB, CMU_CONVERSION_FROM_XIA, quadruped, renamed_bvh,
                           scrambled)
from minifilm.body.read import Body, read_in_metres
from minifilm.body.units import scaled, standing_height
from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.body.humanoid import find_humanoid

REAL = ["100style/Neutral_FR_first3frames.bvh", "bandai2/dataset-2_walk_normal_001.bvh",
        "bandai2/dataset-2_run_active_002.bvh", "bvh/bandai1/dataset-1_walk_normal_001.bvh",
        "bvh/xia/neutral_01_000.bvh", "bvh/xia/old_13_000.bvh", "bvh/cmu/08_01_trimmed.bvh"]


def _height(path):
    m, h, unit = read_in_metres(path)
    assert h is not None, unit.how
    return standing_height(m.world()[0], h, m.fps), unit


@pytest.mark.parametrize("rel", REAL)
def test_every_real_file_stands_at_a_human_height(shared_data, rel):
    height, unit = _height(shared_data / rel)
    assert 1.4 <= height <= 2.1, (height, unit.how)
    assert 1.4 <= unit.stature <= 2.1


@pytest.mark.parametrize("source, mapping, unit", [
    ("bvh/xia/neutral_01_000.bvh", CMU_CONVERSION_FROM_XIA, 0.0254 / 0.45),   # CMU ASF units
    ("bvh/cmu/08_01_trimmed.bvh", CMU_CONVERSION_FROM_MB, 0.01)])             # centimetres
def test_the_cmu_conversion_layout_is_drawn_at_its_true_size(shared_data, tmp_path, source, mapping, unit):
    path = renamed_bvh(shared_data / source, tmp_path / "renamed.bvh", mapping)
    height, found = _height(path)
    assert found.metres_per_unit == pytest.approx(unit, rel=1e-12)
    assert "from its legs" in found.how                     # no built-in skeleton knows these names
    original, _ = _height(shared_data / source)
    assert height == pytest.approx(original, rel=1e-9)      # the same body as under its own names


@pytest.mark.parametrize("factor, unit", [(10.0, 0.001), (0.01, 1.0), (1 / 2.54, 0.0254), (1 / 30.48, 0.3048)])
def test_the_unit_is_inferred_from_the_legs(shared_data, factor, unit):
    # 100STYLE (centimetres) rewritten in millimetres, metres, inches, feet, under names no
    # built-in skeleton has
    cm = read_bvh(shared_data / "100style/Neutral_FR_first3frames.bvh", scale=1.0)
    other = scaled(scrambled(cm), factor)
    found = Body(other).unit
    assert found.metres_per_unit == pytest.approx(unit)
    assert found.stature == pytest.approx(Body(cm).unit.stature, rel=1e-9)


def test_a_body_of_no_common_unit_is_scaled_to_a_typical_height(shared_data):
    cm = read_bvh(shared_data / "100style/Neutral_FR_first3frames.bvh", scale=1.0)
    found = Body(scaled(scrambled(cm), 4.0)).unit           # 7 m tall in cm, 0.7 m in mm
    assert found.stature == pytest.approx(1.7) and "scaled to 1.7 m" in found.how
    m = scaled(scaled(scrambled(cm), 4.0), found.metres_per_unit)
    assert 1.4 <= standing_height(m.world()[0], find_humanoid(m), m.fps) <= 2.1


def test_a_non_humanoid_is_read_in_centimetres_and_says_why(tmp_path):
    path = tmp_path / "dog.bvh"
    write_bvh(quadruped(), path, scale=0.01)                # metres -> centimetres in the file
    m, h, unit = read_in_metres(path)
    assert h is None and unit.metres_per_unit == 0.01
    assert "centimetres assumed" in unit.how and "on the floor like a foot" in unit.how
    dog = quadruped().world()[0][0]                           # metres, as built
    assert np.ptp(m.world()[0][0, :, 1]) == pytest.approx(np.ptp(dog[:, 1]), abs=1e-6)


def test_standing_height_reads_a_head_top_site_when_there_is_one(shared_data):
    # 100STYLE models the top of the head (HeadSite, 17 cm above Head): the height is that site's
    # above the floor (3 frames: the 95th percentile of 3 values, the floor their 2nd percentile)
    m, h, _ = read_in_metres(shared_data / "100style/Neutral_FR_first3frames.bvh")
    assert m.names[h.head_top] == "HeadSite"
    P = m.world()[0]
    floor = np.percentile(P[:, [h.left_toe_tip, h.right_toe_tip, h.left_ankle, h.right_ankle], 1].min(axis=1), 2)
    assert standing_height(P, h, m.fps) == pytest.approx(np.percentile(P[:, h.head_top, 1], 95) - floor)
    # without the site, the head joint plus a fifth of the leg stands in (about the same here)
    from dataclasses import replace
    assert standing_height(P, replace(h, head_top=None), m.fps) == pytest.approx(standing_height(P, h, m.fps),
                                                                                  abs=0.1)


def test_scaling_reuses_the_forward_kinematics_exactly(shared_data):
    raw = read_bvh(shared_data / "bvh/xia/neutral_01_000.bvh", scale=1.0)
    raw.world()                                              # computed once, in file units
    fast = scaled(raw, 0.0254 / 0.45)
    slow = read_bvh(shared_data / "bvh/xia/neutral_01_000.bvh", scale=0.0254 / 0.45)
    np.testing.assert_allclose(fast.world()[0], slow.world()[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.world()[1], slow.world()[1], rtol=0, atol=1e-12)
