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
