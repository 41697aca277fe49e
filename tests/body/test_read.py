"""One file, one look for its body (minifilm/body/read.py): every reader finds the humanoid parts of
a file at most once, and what is found (or not found) is kept."""
import pytest

from humanoid_rigs import quadruped, stick_human
from minifilm.body import read as read_module
from minifilm.body.parts import HumanoidError
from minifilm.body.rig import HumanoidRig
from minifilm.motion.bvh_write import write_bvh
from minifilm.body import load_rig


@pytest.fixture
def looks(monkeypatch):
    """The motions the humanoid finder was asked about, in order."""
    asked = []
    finder = read_module.find_humanoid

    def counting(motion):
        asked.append(motion)
        return finder(motion)
    monkeypatch.setattr(read_module, "find_humanoid", counting)
    return asked


@pytest.fixture
def stick_file(tmp_path):
    """A humanoid whose names are no built-in skeleton's, in centimetres."""
    path = tmp_path / "stick.bvh"
    write_bvh(stick_human(), path, scale=0.01)
    return path


def test_each_reader_looks_once(stick_file, looks):
    motion, humanoid, unit = read_module.read_in_metres(stick_file)
    assert humanoid is not None and unit.metres_per_unit == 0.01 and len(looks) == 1
    motion, rig, unit = read_module.load_for_phases(stick_file)
    assert isinstance(rig, HumanoidRig) and len(looks) == 2
    motion, roles = read_module.read_source(stick_file)
    assert roles.hips == "root" and len(looks) == 3
    rig = load_rig(stick_file)
    assert rig.roles == roles and len(looks) == 4


def test_a_body_keeps_what_it_found(looks):
    body = read_module.Body(stick_human())
    assert body.unit.stature > 1.0 and body.roles().head == "head" and body.metres_per_unit(body.roles()) > 0
    assert body.humanoid is body.humanoid and len(looks) == 1
    dog = read_module.Body(quadruped())
    for _ in range(3):
        with pytest.raises(HumanoidError):
            dog.humanoid
    assert not dog.is_humanoid and len(looks) == 2         # the failure too is found once


@pytest.mark.parametrize("metres_per_unit", [1.0, 0.001])
def test_a_built_in_skeleton_saved_in_another_unit_is_read_in_its_own(tmp_path, metres_per_unit):
    """A 100STYLE walk saved in metres (or millimetres) instead of the skeleton's centimetres: each
    reader of built-in skeleton files (the phase recipe, the data set, teaching) reads it in its own
    unit, so its contacts are the centimetre file's. Read in centimetres, its body would be 1.7 cm
    (or 17 m) tall and every frame a contact (or none)."""
    import numpy as np
    from minifilm.dataset.file_rows import load_motion
    from minifilm.dataset.manifest import MotionFile
    from minifilm.motion.skeletons import STYLE100
    from minifilm.phases.label import label
    from minifilm.pipeline.teach_released import read_clip
    from minifilm.synthetic.generator import generate_style
    walk = generate_style("Neutral", "FW", 4.0, np.random.default_rng(0)).motion
    write_bvh(walk, tmp_path / "cm.bvh", scale=0.01)
    write_bvh(walk, tmp_path / "other.bvh", scale=metres_per_unit)
    expected, skeleton, unit = read_module.load_for_phases(tmp_path / "cm.bvh")
    assert skeleton is STYLE100 and unit is None
    contacts = label(expected, STYLE100).contacts
    assert 0.2 < contacts.mean() < 0.8                       # a walk: each foot down part of the time
    motion, skeleton, unit = read_module.load_for_phases(tmp_path / "other.bvh")
    assert skeleton is STYLE100 and unit.metres_per_unit == metres_per_unit and "usual" in unit.how
    said = []
    for reading in (motion, load_motion(MotionFile(tmp_path / "other.bvh", "Neutral", "FW"), STYLE100, None),
                    read_clip(tmp_path / "other.bvh", log=said.append)[0]):
        # the files hold 6 (or 4) decimals of each length: the same body to a tenth of a millimetre
        np.testing.assert_allclose(reading.world()[0], expected.world()[0], atol=1e-4)
        # (a frame on a contact's threshold may go either way with the last digits: 1 % allowed)
        assert np.mean(np.abs(label(reading, STYLE100).contacts - contacts)) <= 0.01
    assert len(said) == 1 and "usual" in said[0]             # teaching says which unit it read


def test_teaching_refuses_a_one_frame_file_naming_it(tmp_path):
    """One frame holds no motion: refused when read, naming the file (not the labeller's internals)."""
    import numpy as np
    from minifilm.pipeline.teach_released import ClipError, read_clip
    from minifilm.synthetic.generator import generate_style
    write_bvh(generate_style("Neutral", "FW", 1.0, np.random.default_rng(0)).motion.slice(0, 1), tmp_path / "one.bvh")
    with pytest.raises(ClipError, match=r"one\.bvh: 1 frame: too short to teach a style"):
        read_clip(tmp_path / "one.bvh", log=lambda line: None)


def test_a_file_saved_z_up_is_one_error_not_a_walk_without_steps(tmp_path):
    """A 100STYLE walk turned a quarter about x (z up): its names fit the skeleton, but labelled as
    it lies its feet are never down. Every reader of built-in skeleton files refuses it, saying why."""
    import numpy as np
    from scipy.spatial.transform import Rotation
    from minifilm.dataset.file_rows import load_motion
    from minifilm.dataset.manifest import MotionFile
    from minifilm.motion.skeletons import STYLE100
    from minifilm.synthetic.generator import generate_style
    walk = generate_style("Neutral", "FW", 2.0, np.random.default_rng(0)).motion
    quarter = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    walk.rotations[:, 0] = quarter @ walk.rotations[:, 0]
    walk.translations[:, 0] = walk.translations[:, 0] @ quarter.T
    walk._fk_cache = None                                       # (the positions change with the rotation)
    write_bvh(walk, tmp_path / "zup.bvh")
    with pytest.raises(HumanoidError, match=r"zup\.bvh: the body does not stand along y"):
        read_module.load_for_phases(tmp_path / "zup.bvh")
    with pytest.raises(HumanoidError, match="does not stand along y"):
        load_motion(MotionFile(tmp_path / "zup.bvh", "Neutral", "FW"), STYLE100, None)
