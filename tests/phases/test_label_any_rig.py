"""The labelling recipe on any humanoid rig (minifilm/body/rig.py, read.py; minifilm/phases/label.py): built-in
skeletons label as the plain recipe does; renamed (CMU conversion) and scrambled rigs get
contacts and local phases that follow the steps; non-humanoid and feetless rigs are one error."""
import numpy as np
import pytest

from humanoid_rigs import CMU_CONVERSION_FROM_XIA, quadruped, renamed_bvh, scrambled, without
from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.body.humanoid import HumanoidError, find_humanoid
from minifilm.motion.skeletons import builtin_skeleton
from minifilm.body.read import load_for_phases
from minifilm.body.rig import HumanoidRig, humanoid_rig
from minifilm.phases.contacts import foot_contacts, gait_contacts, humanoid_contacts
from minifilm.phases.label import FEW_CONTACTS, label
from minifilm.phases.local_phases import extract_local_phases

#: (file under the shared data, the built-in skeleton its names fit)
BUILTIN = [("bandai2/dataset-2_walk_normal_001.bvh", "bandai"), ("bvh/cmu/08_01_trimmed.bvh", "cmu-mb"),
           ("bvh/xia/neutral_01_000.bvh", "cmu")]
#: real walks and runs labelled on their humanoid parts
FILES = ["bandai2/dataset-2_walk_normal_001.bvh", "bandai2/dataset-2_run_normal_001.bvh",
         "bvh/bandai1/dataset-1_walk_normal_001.bvh", "bvh/xia/neutral_01_000.bvh", "bvh/cmu/08_01_trimmed.bvh"]

_cache = {}


def _rig_labels(path):
    """(motion, rig, labels on the humanoid rig) of a real file, computed once per file."""
    if path not in _cache:
        motion, _, _ = load_for_phases(path)
        rig = humanoid_rig(motion, find_humanoid(motion))
        _cache[path] = motion, rig, label(motion, rig)
    return _cache[path]


def _wraps(phase):
    """How many times a phase in cycles goes from near 1 back to near 0."""
    return int(np.sum(np.diff(phase) < -0.5))


def _onsets(contact):
    """How many times a 0/1 contact signal touches down."""
    return int(np.sum(np.diff(contact) > 0.5))


@pytest.mark.parametrize("rel,name", BUILTIN)
def test_builtin_skeletons_label_as_the_plain_recipe(shared_data, rel, name):
    motion, rig, unit = load_for_phases(shared_data / rel)
    sk = builtin_skeleton(name)
    assert rig == sk and unit is None
    plain = read_bvh(shared_data / rel, scale=sk.bvh_scale)
    # the reader scales the positions it computed in the file's units (to find the body) where the
    # plain read computes them from scaled lengths: the same numbers but for rounding in the last bit
    np.testing.assert_allclose(motion.world()[0], plain.world()[0], rtol=1e-12, atol=1e-12)
    # the recipe written out by hand: the paper's contacts on the toe tips (where they find next to
    # none, as on 08_01 whose toes slide at 0.2 m/s, the gait rule), then the phases
    positions, sensors = motion.world()[0], sk.contact_indices(motion)
    contacts = foot_contacts(positions[:, sensors], motion.fps)
    rule = "paper" if contacts.mean(axis=0).min() >= FEW_CONTACTS else "gait"
    if rule == "gait":
        contacts = gait_contacts(positions, sensors, sk.hips_index(motion), motion.fps)
    assert rule == ("gait" if "08_01" in rel else "paper")
    phases = extract_local_phases(motion, sk, contacts, ("pca", "pca", "contact", "contact"))
    got = label(motion, rig)
    assert got.contact_rule == rule and 0.1 < got.contacts.mean() < 0.7    # a walk's stances found
    np.testing.assert_array_equal(got.contacts, contacts)
    np.testing.assert_array_equal(got.phases.phase, phases.phase)
    np.testing.assert_array_equal(got.vectors, phases.vectors())


def test_a_hopping_styles_lifted_foot_keeps_the_papers_rule():
    """A foot that never steps (LeftHop's right foot: its phase is not taken from contacts) is no
    sign that the paper's thresholds missed its stances; unnamed, the same clip gets the gait rule."""
    from minifilm.motion.skeletons import STYLE100
    from minifilm.synthetic.generator import generate_style
    hop = generate_style("LeftHop", "FW", 4.0, np.random.default_rng(0)).motion
    named = label(hop, STYLE100, "LeftHop")
    assert named.contact_rule == "paper" and named.contacts[:, 0].mean() < FEW_CONTACTS   # [right, left]
    assert named.contacts[:, 1].mean() > 0.2
    assert label(hop, STYLE100).contact_rule == "gait"


@pytest.mark.parametrize("rel,name", BUILTIN)
def test_the_estimated_front_agrees_with_the_builtin_axis(shared_data, rel, name):
    motion, _, _ = load_for_phases(shared_data / rel)
    axis = np.array(humanoid_rig(motion, find_humanoid(motion)).facing_axis)
    assert abs(np.linalg.norm(axis) - 1) < 1e-12
    assert axis @ np.array(builtin_skeleton(name).facing_axis) > 0.95, axis      # within 18 degrees


@pytest.mark.parametrize("rel", FILES)
def test_phases_on_the_humanoid_parts_follow_the_steps(shared_data, rel):
    motion, rig, labels = _rig_labels(shared_data / rel)
    assert isinstance(rig, HumanoidRig)
    np.testing.assert_array_equal(labels.contacts, humanoid_contacts(motion, rig.humanoid)[0])
    ph = labels.phases.phase
    assert ph.shape == (motion.n_frames, 4) and np.all((ph >= 0) & (ph < 1))
    for slot, column in ((2, 1), (3, 0)):                     # left foot <- left contacts, right <- right
        steps = _onsets(labels.contacts[:, column])
        assert steps >= 1, rel
        assert abs(_wraps(ph[:, slot]) - steps) <= 2, (rel, slot, _wraps(ph[:, slot]), steps)
    seconds = motion.n_frames / motion.fps
    for slot in (0, 1):                                       # the hands swing about once per stride
        assert 1 <= _wraps(ph[:, slot]) <= 3 * seconds, (rel, slot, _wraps(ph[:, slot]), seconds)
    assert np.all(np.median(labels.phases.amplitude, axis=0) > 0), rel


@pytest.mark.parametrize("rel", FILES)
def test_a_scrambled_rig_is_labelled_from_its_structure(shared_data, rel):
    motion, rig, labels = _rig_labels(shared_data / rel)
    scrambled_motion = scrambled(motion)
    rig_s = humanoid_rig(scrambled_motion, find_humanoid(scrambled_motion))
    assert rig_s.humanoid.method == "structure"
    assert rig_s.phase_indices().tolist() == rig.phase_indices().tolist()
    got = label(scrambled_motion, rig_s)                      # the parts found in the motion
    np.testing.assert_array_equal(got.contacts, labels.contacts)
    # (the scrambled motion's positions are computed again from its lengths, the labelled one's
    # were scaled from the file's units: the phases agree but for rounding, far inside 1e-9)
    np.testing.assert_allclose(got.vectors, labels.vectors, atol=1e-9)
    np.testing.assert_allclose(label(scrambled_motion, humanoid_rig(scrambled_motion, rig_s.humanoid)).vectors,
                               labels.vectors, atol=1e-9)


def test_the_cmu_conversion_layout(shared_data, tmp_path):
    src = shared_data / "bvh/xia/neutral_01_000.bvh"
    path = renamed_bvh(src, tmp_path / "conv.bvh", CMU_CONVERSION_FROM_XIA)
    motion, rig, unit = load_for_phases(path)
    assert isinstance(rig, HumanoidRig) and "LHipJoint" in motion.names and "LeftAnkle" in motion.names
    assert [motion.names[j] for j in rig.phase_indices()] == ["LeftWrist", "RightWrist", "LeftToe", "RightToe"]
    assert unit.metres_per_unit == pytest.approx(0.0254 / 0.45)            # the built-in CMU unit, from the legs
    _, _, original = _rig_labels(src)
    labels = label(motion, rig)
    np.testing.assert_array_equal(labels.contacts, original.contacts)
    np.testing.assert_allclose(labels.vectors, original.vectors, atol=1e-9)


def test_a_quadruped_is_one_error(tmp_path):
    path = tmp_path / "dog.bvh"
    write_bvh(quadruped(human_names=True), path)
    with pytest.raises(HumanoidError, match="dog.bvh"):
        load_for_phases(path)
    dog = quadruped()
    with pytest.raises(HumanoidError):
        label(dog, humanoid_rig(dog, find_humanoid(dog)))


def test_a_rig_without_feet_is_one_error(shared_data, tmp_path):
    motion = read_bvh(shared_data / "bvh/xia/neutral_01_000.bvh", scale=0.0254 / 0.45)
    feetless = without(motion, {"LeftToeBase", "RightToeBase", "LeftFoot", "RightFoot"})
    path = tmp_path / "feetless.bvh"
    write_bvh(feetless, path, scale=0.0254 / 0.45)
    with pytest.raises(HumanoidError, match="feetless.bvh"):
        load_for_phases(path)
    feetless = scrambled(feetless)
    with pytest.raises(HumanoidError):
        label(feetless, humanoid_rig(feetless, find_humanoid(feetless)))
