"""Fuzz family: a skeleton in any unit, wherever one comes in. ``view``, ``retarget`` (source and
target), and ``generate --skeleton-bvh`` read it through one rule (minifilm/body/units.py, body_unit): the unit
that makes the body of human height, even when its joint names are those of a built-in skeleton
usually written in another unit; all-zero offsets (no size at all) are refused in one line.

Cases: every real layout (5) x every common unit (7) read back, plus random scalings that are no
common unit, all-zero and near-zero offsets, and generate end to end in millimetres and metres."""
import numpy as np
import pytest

from harness import outcome
from minifilm.cli import main
from minifilm.errors import InputError
from minifilm.body.read import read_in_metres
from minifilm.body.units import KNOWN_UNITS, STATURE_RANGE, standing_height
from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.motion import Motion
from minifilm.body import load_rig, read_source

LAYOUTS = ("100style/Neutral_FR_first3frames.bvh", "bandai2/dataset-2_walk_normal_001.bvh",
           "bvh/bandai1/dataset-1_walk_normal_001.bvh", "bvh/xia/neutral_01_000.bvh", "bvh/cmu/08_01_trimmed.bvh")


def _in_metres(shared_data, rel):
    m, h, unit = read_in_metres(shared_data / rel)
    assert h is not None
    return m.slice(0, 40) if m.n_frames > 40 else m


def _zeroed(m: Motion) -> Motion:
    """``m`` with every offset and the root's translation zero: a skeleton collapsed to a point."""
    return Motion(list(m.names), m.parents.copy(), np.zeros_like(m.offsets), list(m.channels), m.rotations.copy(),
                  np.zeros_like(m.translations), m.frame_time, m.source)


@pytest.mark.parametrize("rel", LAYOUTS)
def test_every_layout_in_every_common_unit_is_read_at_its_true_size(shared_data, tmp_path, rel):
    m = _in_metres(shared_data, rel)
    lo, hi = STATURE_RANGE
    for name, unit in KNOWN_UNITS:
        path = tmp_path / f"in_{unit:g}.bvh"
        write_bvh(m, path, scale=unit)
        back, h, found = read_in_metres(path)
        assert found.metres_per_unit == pytest.approx(unit), (name, found.how)
        assert lo <= found.stature <= hi
        height = standing_height(back.world()[0], h, back.fps)
        assert 1.3 < height < 2.2, (name, height)
        motion, roles = read_source(path)                 # retarget's source: the same unit
        assert np.allclose(motion.offsets, back.offsets)
        assert load_rig(path).bvh_scale == pytest.approx(unit)   # retarget's target: the same


def test_scalings_that_are_no_common_unit_are_made_human(shared_data, tmp_path):
    rng = np.random.default_rng(5)
    m = _in_metres(shared_data, LAYOUTS[0])
    for k in 10.0 ** rng.uniform(-4, 2, size=12):
        path = tmp_path / "odd.bvh"
        write_bvh(m, path, scale=float(k))
        back, h, found = read_in_metres(path)
        assert STATURE_RANGE[0] <= found.stature <= STATURE_RANGE[1], (k, found.how)


@pytest.mark.parametrize("rel", LAYOUTS)
def test_all_zero_offsets_are_refused_in_one_line(shared_data, tmp_path, rel):
    path = tmp_path / "point.bvh"
    write_bvh(_zeroed(_in_metres(shared_data, rel)), path, scale=0.01)
    outcome(lambda: read_source(path), InputError, mentions=(str(path),))
    outcome(lambda: load_rig(path), InputError)
    _, h, unit = read_in_metres(path)
    assert h is None                                     # the viewer draws it as the point it is


def _generate(run, skeleton, out, capsys):
    capsys.readouterr()
    try:
        main(["generate", "--run", str(run), "--seconds", "0.5", "--skeleton-bvh", str(skeleton), "--out", str(out)])
        code = 0
    except SystemExit as e:
        code = e.code
    return code, capsys.readouterr()


@pytest.mark.parametrize("unit", [0.001, 1.0])
def test_generate_converts_a_skeleton_in_another_unit(tiny_run, tmp_path, capsys, unit):
    run_skeleton = tiny_run / "skeleton.bvh"
    ref = read_in_metres(run_skeleton)[0]
    path = tmp_path / "skeleton_other_unit.bvh"
    write_bvh(ref, path, scale=unit)
    code, io = _generate(tiny_run, path, tmp_path / "out.bvh", capsys)
    assert code in (0, None), io.err
    assert "--skeleton-bvh" in io.out and ("millimetres" in io.out or "metres" in io.out)
    out, h, _ = read_in_metres(tmp_path / "out.bvh")
    feet = out.world()[0][:, [h.left_toe_tip, h.right_toe_tip], 1]
    assert abs(float(feet.min())) < 0.1, feet.min()                 # on the floor, not 1 m under it
    assert 1.3 < standing_height(out.world()[0], h, out.fps) < 2.2


def test_generate_refuses_a_skeleton_without_size(tiny_run, tmp_path, capsys):
    path = tmp_path / "point.bvh"
    write_bvh(_zeroed(read_bvh(tiny_run / "skeleton.bvh", scale=0.01)), path, scale=0.01)
    code, io = _generate(tiny_run, path, tmp_path / "out.bvh", capsys)
    assert code not in (0, None)
    lines = [line for line in io.err.splitlines() if line.strip()]
    assert len(lines) == 1 and "--skeleton-bvh" in lines[0] and "size" in lines[0], io.err
    assert not (tmp_path / "out.bvh").exists()
