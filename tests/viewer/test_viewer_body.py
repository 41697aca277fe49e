"""The mannequin's body plan (minifilm/viewer/body.py): which bone is torso, neck, head, arm or leg
comes from the humanoid finder, for every real layout and for rigs that vary where the collars,
the neck and the spine branch; in the page (headless Chromium) the head sphere sits on the neck
and every limb has its segments, drawn thinner than the balls at its joints (no coinciding
surfaces, which z-fight into dark saw-tooth bands)."""
import numpy as np
import pytest

from humanoid_rigs import CMU_LAYOUT_FROM_100STYLE, branching_humans, quadruped, reparented
from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.viewer import track_from_bvh, track_from_motion, write_html
from minifilm.viewer.body import body_plan, body_plan_of_positions

ARM = ("collar", "arm")
LEG = ("pelvis", "leg")

# Per real file, what a person reading its header calls each drawn bone (written by hand).
EXPECTED = {
    "100style/Neutral_FR_first3frames.bvh": dict(
        head="Head", neck="Neck", torso=("Chest", "Chest2", "Chest3", "Chest4"), necks=("Neck", "Head"),
        arm=("LeftCollar", "LeftShoulder", "LeftElbow", "LeftWrist"), leg=("LeftHip", "LeftKnee", "LeftAnkle")),
    "bandai2/dataset-2_walk_normal_001.bvh": dict(
        head="Head", neck="Neck", torso=("Spine", "Chest"), necks=("Neck", "Head"),
        arm=("Shoulder_L", "UpperArm_L", "LowerArm_L", "Hand_L"), leg=("UpperLeg_L", "LowerLeg_L", "Foot_L")),
    "bvh/bandai1/dataset-1_walk_normal_001.bvh": dict(
        head="Head", neck="Neck", torso=("Spine", "Chest"), necks=("Neck", "Head"),
        arm=("Shoulder_R", "UpperArm_R", "LowerArm_R", "Hand_R"), leg=("UpperLeg_R", "LowerLeg_R", "Foot_R")),
    # Xia's zero-length helpers (LowerBack, Neck, LeftShoulder, LHipJoint) are not drawn
    "bvh/xia/old_13_000.bvh": dict(
        head="Head", neck="Neck1", torso=("Spine", "Spine1"), necks=("Neck1", "Head"),
        arm=("LeftArm", "LeftForeArm", "LeftHand"), leg=("LeftUpLeg", "LeftLeg", "LeftFoot")),
    "bvh/cmu/08_01_trimmed.bvh": dict(
        head="head", neck="neck", torso=("abdomen", "chest"), necks=("neck", "head"),
        arm=("lCollar", "lShldr", "lForeArm", "lHand"), leg=("lButtock", "lThigh", "lShin", "lFoot"),
        inhead=("leftEye", "rightEye")),
}


def _named(track):
    return dict(zip(track.joint_names, track.body["parts"]))


def _check(track, e):
    parts, names = _named(track), track.joint_names
    assert names[track.body["head"]] == e["head"] and names[track.body["neck"]] == e["neck"]
    assert [parts[n] for n in e["torso"]] == ["torso"] * len(e["torso"])
    assert [parts[n] for n in e["necks"]] == ["neck"] * len(e["necks"])
    assert parts[e["arm"][0]] == "collar" and all(parts[n] == "arm" for n in e["arm"][1:]), parts
    assert parts[e["leg"][0]] == "pelvis" and all(parts[n] == "leg" for n in e["leg"][1:]), parts
    assert all(parts[n] == "inhead" for n in e.get("inhead", ()))


@pytest.mark.parametrize("rel", sorted(EXPECTED))
def test_every_real_layout_gets_its_parts(shared_data, rel):
    _check(track_from_bvh(shared_data / rel), EXPECTED[rel])


def test_every_shared_file_gets_a_body(shared_data):
    files = sorted(shared_data.glob("**/*.bvh"))
    assert len(files) > 400
    for path in files:
        plan = body_plan(read_bvh(path))
        assert plan["parts"] is not None, path.name
        assert set(plan["parts"]) >= {"hips", "torso", "neck", "collar", "arm", "pelvis", "leg"}, path.name


def test_the_cmu_layout_collars_under_chest2(shared_data, tmp_path):
    """Collars off Chest2 while Chest3 and Chest4 lead up the neck: the head is on the neck chain,
    the arms are arms (not the neck) on both sides."""
    m = reparented(read_bvh(shared_data / "100style/Neutral_FR_first3frames.bvh", scale=0.01), *CMU_LAYOUT_FROM_100STYLE)
    path = write_bvh(m, tmp_path / "cmu_layout.bvh", scale=0.01) or tmp_path / "cmu_layout.bvh"
    _check(track_from_bvh(path), dict(head="Head", neck="Neck", torso=("Chest", "Chest2"),
                                      necks=("lowerneck", "upperneck", "Neck", "Head"),
                                      arm=("LeftCollar", "LeftShoulder", "LeftElbow", "LeftWrist"),
                                      leg=("LeftHip", "LeftKnee", "LeftAnkle")))


def test_rigs_that_branch_anywhere():
    """Spines of 1-5 joints with the arms off any of them, necks of any name, with and without
    collars: the drawn parts are those the hierarchy gives (the generator's expectation)."""
    for label, m, e in branching_humans(60, seed=3):
        parts = _named(track_from_motion(m))
        spine = [e[k] for k in sorted(e) if k.startswith("spine")]
        assert all(parts[n] == "torso" for n in spine), label
        arm = [e["left_collar"], e["left_shoulder"], e["left_elbow"], e["left_wrist"]]
        assert parts[next(n for n in arm if n)] == "collar", label
        assert all(parts[n] == "arm" for n in arm[2:]), label
        neck = [n for n, p in zip(m.names, parts.values()) if p == "neck"]
        assert neck[-1] == "Head" and not set(neck) & set(spine + arm), label


def test_positions_alone_give_the_same_plan(shared_data):
    """A network's output has no motion behind it: its positions and drawing parents give the plan."""
    t = track_from_bvh(shared_data / "100style/Neutral_FR_first3frames.bvh")
    assert body_plan_of_positions(t.positions, t.parents, t.joint_names) == t.body
    t = track_from_bvh(shared_data / "bvh/cmu/08_01_trimmed.bvh")
    assert body_plan_of_positions(t.positions[:1], t.parents, ["?"] * t.n_joints) == t.body   # by structure


def test_a_quadruped_gets_no_body():
    assert track_from_motion(quadruped()).body == {"parts": None}


def test_the_page_draws_the_cmu_layout_right(browser, shared_data, tmp_path):
    """In the page: the head sphere on the neck (above Head, along Neck -> Head), not on a shoulder;
    the left arm drawn with all its segments; every limb thinner than the balls at both its ends."""
    m = reparented(read_bvh(shared_data / "100style/Neutral_FR_first3frames.bvh", scale=0.01), *CMU_LAYOUT_FROM_100STYLE)
    bvh = tmp_path / "cmu_layout.bvh"
    write_bvh(m, bvh, scale=0.01)
    tracks = [track_from_bvh(bvh), track_from_motion(quadruped(), name="dog")]
    page_path = tmp_path / "player.html"
    write_html(tracks, page_path)
    page = browser.new_page(viewport={"width": 640, "height": 400})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(page_path.resolve().as_uri())
    page.wait_for_function("window.minifilmPlayer && window.minifilmPlayer.ready", timeout=15000)
    page.evaluate("minifilmPlayer.pause()")
    body = page.evaluate("minifilmPlayer.body(0)")
    joints = np.array(page.evaluate("minifilmPlayer.shownJoints(0)"))
    names = tracks[0].joint_names
    at = {n: joints[names.index(n)] for n in ("Head", "Neck", "LeftShoulder", "RightShoulder")}
    head = np.array(body["head"])
    along = (at["Head"] - at["Neck"]) / np.linalg.norm(at["Head"] - at["Neck"])
    assert np.dot(head - at["Head"], along) > 0.02                       # above the head joint
    assert np.linalg.norm(head - at["Head"]) < 0.15
    assert min(np.linalg.norm(head - at[s]) for s in ("LeftShoulder", "RightShoulder")) > 0.2
    drawn = {(p, j) for p, j, _ in body["limbs"]}
    arm = [names.index(n) for n in ("LeftCollar", "LeftShoulder", "LeftElbow", "LeftWrist")]
    chest = names.index("Chest2")
    assert {(chest, arm[0]), (arm[0], arm[1]), (arm[1], arm[2]), (arm[2], arm[3])} <= drawn
    for p, j, r in body["limbs"]:
        assert r < 0.95 * body["balls"][j] and r < 0.95 * body["balls"][p], (names[p], names[j])
    # the dog is no humanoid: no body, its sticks stay
    assert page.evaluate("minifilmPlayer.body(1)")["plan"] is None
    assert page.evaluate("minifilmPlayer.body(1)")["limbs"] == []
    assert page.evaluate("minifilmPlayer.visibleMeshes()")["sticks"] > 0
    assert errors == []
    page.close()


def test_the_released_networks_skeleton_as_the_demo_draws_it():
    """The released network's character (the 100STYLE skeleton's exported joints, as the demo's
    hello gives them): its positions and the layout's parents give the full body plan."""
    from minifilm.features.layout import FeatureLayout
    from minifilm.motion.skeletons import STYLE100
    from minifilm.synthetic.generator import rest_motion
    layout = FeatureLayout.for_skeleton(STYLE100)
    m = rest_motion()
    P = m.world()[0][:, STYLE100.joint_indices(m)]
    plan = body_plan_of_positions(P, layout.parents, layout.joint_names)
    names = list(layout.joint_names)
    parts = dict(zip(names, plan["parts"]))
    assert names[plan["head"]] == "Head" and names[plan["neck"]] == "Neck"
    assert [parts[n] for n in ("Chest", "Chest2", "Chest3", "Chest4")] == ["torso"] * 4
    assert [parts[n] for n in ("LeftCollar", "LeftShoulder", "LeftElbow", "LeftWrist")] == ["collar"] + ["arm"] * 3
    assert [parts[n] for n in ("RightHip", "RightKnee", "RightAnkle", "RightToe")] == ["pelvis"] + ["leg"] * 3
