"""Retargeting between rigs (docs/retargeting.md): roles, chain spreading, pose transfer, feet, the command,
and one clear error for each kind of bad rig."""
import json
import subprocess
import sys

import numpy as np
import pytest

from minifilm.evaluation.retargeting import (bone_direction_errors, contact_agreement, round_trip_errors, skating,
                                             standing_height)
from minifilm.motion.bvh import read_bvh
from minifilm.body.humanoid import find_humanoid
from minifilm.body.roles import BUILTIN_ROLES, RigError, roles_from_mapping
from minifilm.body import load_rig, read_source, retarget_motion
from minifilm.body.pose import UP, canonical_pose, chain_overlaps, rest_positions
from minifilm.motion.skeletons import STYLE100
from minifilm.phases.label import label
from minifilm.synthetic.generator import generate_style


# ----------------------------------------------------------------------------------------------
# chains of different lengths
# ----------------------------------------------------------------------------------------------

def test_chain_overlaps_spread_two_bones_over_four():
    W = chain_overlaps([1.0, 1.0], [1.0, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(W, [[1, 0], [1, 0], [0, 1], [0, 1]])
    W = chain_overlaps([1.0, 1.0, 1.0, 1.0], [3.0, 1.0])    # target bone 0 covers 3/4 of the chain
    np.testing.assert_allclose(W, [[1 / 3, 1 / 3, 1 / 3, 0], [0, 0, 0, 1]])
    W = chain_overlaps([2.0, 1.0], [1.0, 1.0])              # the source's joint at 2/3
    np.testing.assert_allclose(W, [[1, 0], [1 / 3, 2 / 3]])
    np.testing.assert_allclose(chain_overlaps([0.0, 1.0, 1.0], [1.0, 0.0, 1.0]).sum(axis=1), 1.0)


# ----------------------------------------------------------------------------------------------
# rest poses
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["100style", "bandai", "cmu"])
def test_canonical_pose_stands_every_builtin_rig_up(name):
    """Bandai's zero pose has every bone along x, CMU's arms are raised: in the canonical pose all
    stand with the spine up, arms out to the sides and legs down."""
    rig = load_rig(name)
    m, r = rig.template, rig.roles
    C = canonical_pose(m, r)
    idx = {n: i for i, n in enumerate(m.names)}
    P0 = rest_positions(m)
    # positions of the canonical pose: FK with world rotations C
    P = np.zeros_like(P0)
    for j in range(m.n_joints):
        p = int(m.parents[j])
        if p >= 0:
            P[j] = P[p] + C[p] @ m.offsets[j]

    def direction(a, b):
        v = P[idx[b]] - P[idx[a]]
        return v / np.linalg.norm(v)

    assert direction(r.hips, r.chest) @ UP > 0.99
    for side, sign in (("left", 1), ("right", -1)):
        limb = r.limb(side)
        assert direction(limb.shoulder, limb.wrist) @ [sign, 0, 0] > 0.99
        assert direction(limb.upleg, limb.ankle) @ [0, -1, 0] > 0.99
        assert direction(limb.ankle, limb.toe) @ [0, 0, 1] > 0.6          # forward, pitched down
    assert np.linalg.norm(P0[idx[r.left.upleg]] - P0[idx[r.right.upleg]]) > 0.05


# ----------------------------------------------------------------------------------------------
# the pose transfer copies world bone directions
# ----------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def synthetic_walk():
    clip = generate_style("Neutral", "FW", 3.0, np.random.default_rng(1))
    return clip.motion


@pytest.mark.parametrize("target", ["bandai", "cmu"])
def test_limb_directions_are_copied_exactly_without_planting(synthetic_walk, target):
    rig = load_rig(target)
    out = retarget_motion(synthetic_walk, rig, BUILTIN_ROLES["100style"], plant=False)
    errors = bone_direction_errors(synthetic_walk, BUILTIN_ROLES["100style"], out, rig.roles)
    for bone in ("left upleg-knee", "right knee-ankle", "left shoulder-elbow", "right elbow-wrist", "spine", "neck"):
        assert np.max(errors[bone]) < 1e-3, (bone, np.max(errors[bone]))      # degrees
    assert out.names == rig.template.names and out.channels == rig.template.channels


def test_round_trip_on_synthetic_motion_is_within_a_centimetre(synthetic_walk):
    style, bandai = load_rig("100style"), load_rig("bandai")
    there = retarget_motion(synthetic_walk, bandai, style.roles, plant=False)
    back = retarget_motion(there, style, bandai.roles, plant=False)
    d = round_trip_errors(synthetic_walk, style.roles, back, style.roles)
    assert max(np.percentile(v, 95) for v in d.values()) < 0.03
    # the root's path is scaled by the ratio of leg lengths, and comes back
    P0, _ = there.world()
    assert 0.5 < np.ptp(P0[:, bandai.template.names.index("Hips"), 2]) / np.ptp(synthetic_walk.world()[0][:, 0, 2]) < 1.0


# ----------------------------------------------------------------------------------------------
# real files
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("rel", ["bvh/bandai1/dataset-1_walk_normal_001.bvh", "bandai2/dataset-2_run_active_001.bvh",
                                 "bvh/xia/neutral_01_000.bvh", "bvh/cmu/08_01_trimmed.bvh",
                                 # a turn on the spot: 0.909 contact agreement before the tip took the
                                 # source tip's height beside a contact
                                 "bandai2/dataset-2_walk-turn-right_exhausted_009.bvh"])
def test_real_file_onto_100style_keeps_directions_contacts_and_height(shared_data, rel):
    target = load_rig("100style")
    m, roles = read_source(shared_data / rel)
    out = retarget_motion(m, target, roles)
    errors = bone_direction_errors(m, roles, out, target.roles)
    for bone, e in errors.items():
        if not bone.endswith("ankle-toe"):     # feet keep each rig's own flat-foot pitch (docs/retargeting.md)
            assert np.median(e) < 5.0, (bone, np.median(e))
    assert contact_agreement(m, roles, out, target.roles) >= 0.95
    assert skating(out, target.roles) <= skating(m, roles) + 0.01
    assert 1.4 <= standing_height(out, target.roles) <= 2.1
    labels = label(out, STYLE100)                   # local phases can be extracted from the result
    assert np.all(np.isfinite(labels.phases.phase))


def test_bandai_round_trip_without_planting_within_3cm(shared_data):
    bandai, style = load_rig("bandai"), load_rig("100style")
    m, roles = read_source(shared_data / "bvh/bandai1/dataset-1_walk_normal_001.bvh")
    back = retarget_motion(retarget_motion(m, style, roles, plant=False), bandai, style.roles, plant=False)
    d = round_trip_errors(m, roles, back, bandai.roles)
    for joint, v in d.items():
        assert np.median(v) < 0.03 and np.percentile(v, 95) < 0.03, joint


# ----------------------------------------------------------------------------------------------
# bad rigs: one clear error each
# ----------------------------------------------------------------------------------------------

def bvh_text(joints):
    """BVH text of (name, parent index, offset in cm) joints, two frames at rest."""
    children = {i: [k for k, (_, p, _) in enumerate(joints) if p == i] for i in range(len(joints))}
    lines = ["HIERARCHY"]

    def emit(i, depth):
        name, p, off = joints[i]
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if p < 0 else 'JOINT'} {name}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {off[0]} {off[1]} {off[2]}")
        lines.append(f"{pad}  CHANNELS {6 if p < 0 else 3}" + (" Xposition Yposition Zposition" if p < 0 else "")
                     + " Zrotation Xrotation Yrotation")
        for c in children[i]:
            emit(c, depth + 1)
        if not children[i]:
            lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET 0 -3 0", pad + "  }"])
        lines.append(pad + "}")

    emit(0, 0)
    n = sum(6 if p < 0 else 3 for _, p, _ in joints)
    lines += ["MOTION", "Frames: 2", "Frame Time: 0.0333333"] + [" ".join(["0"] * n)] * 2
    return "\n".join(lines) + "\n"


QUADRUPED = [("Pelvis", -1, (0, 60, 0)), ("Spine", 0, (0, 0, 30)), ("Neck", 1, (0, 10, 30)), ("Head", 2, (0, 5, 15)),
             ("FrontLeg_L", 1, (10, 0, 25)), ("FrontKnee_L", 4, (0, -30, 0)), ("FrontPaw_L", 5, (0, -28, 0)),
             ("FrontLeg_R", 1, (-10, 0, 25)), ("FrontKnee_R", 7, (0, -30, 0)), ("FrontPaw_R", 8, (0, -28, 0)),
             ("BackLeg_L", 0, (10, 0, 0)), ("BackKnee_L", 10, (0, -30, 0)), ("BackPaw_L", 11, (0, -28, 0)),
             ("BackLeg_R", 0, (-10, 0, 0)), ("BackKnee_R", 13, (0, -30, 0)), ("BackPaw_R", 14, (0, -28, 0)),
             ("Tail", 0, (0, 5, -20))]
SNAKE = [("Root", -1, (0, 10, 0))] + [(f"Seg{i}", i, (0, 0, 20)) for i in range(8)]
NO_FEET = [("Hips", -1, (0, 90, 0)), ("Spine", 0, (0, 20, 0)), ("Chest", 1, (0, 20, 0)), ("Neck", 2, (0, 15, 0)),
           ("Head", 3, (0, 10, 0)),
           ("LeftArm", 2, (15, 10, 0)), ("LeftForeArm", 5, (28, 0, 0)), ("LeftHand", 6, (25, 0, 0)),
           ("RightArm", 2, (-15, 10, 0)), ("RightForeArm", 8, (-28, 0, 0)), ("RightHand", 9, (-25, 0, 0)),
           ("LeftUpLeg", 0, (10, -5, 0)), ("RightUpLeg", 0, (-10, -5, 0))]


@pytest.mark.parametrize("joints, what", [(QUADRUPED, "humanoid"), (SNAKE, "humanoid"), (NO_FEET, "humanoid")],
                         ids=["quadruped", "single chain", "no feet"])
def test_non_humanoid_rigs_are_refused_with_one_clear_error(tmp_path, joints, what):
    path = tmp_path / "rig.bvh"
    path.write_text(bvh_text(joints))
    with pytest.raises(RigError, match=what) as info:
        read_source(path)
    assert "--map" in str(info.value) and str(path) in str(info.value)
    with pytest.raises(RigError, match=what):
        load_rig(path)


def test_a_map_naming_missing_joints_is_refused(tmp_path):
    rig = load_rig("100style")                       # the file: the built-in 100STYLE rig's template
    mapping = {"hips": "Hips", "spine": ["Chest", "Chest4"], "neck": ["Neck", "Head"],
               "left": {"shoulder": "LeftShoulder", "elbow": "LeftElbow", "wrist": "LeftWrist", "upleg": "LeftHip",
                        "knee": "LeftKnee", "ankle": "LeftFoot"},
               "right": {"shoulder": "RightShoulder", "elbow": "RightElbow", "wrist": "RightWrist",
                         "upleg": "RightHip", "knee": "RightKnee", "ankle": "RightAnkle"}}
    with pytest.raises(RigError, match=r"names joints the file does not have: \['LeftFoot'\]"):
        roles_from_mapping(mapping, rig.template)
    mapping["left"]["ankle"] = "LeftAnkle"
    roles = roles_from_mapping(mapping, rig.template)
    assert roles.chest == "Chest4" and roles.left.toe is None
    mapping["left"]["elbow"] = "LeftWrist"
    mapping["left"]["wrist"] = "LeftElbow"
    with pytest.raises(RigError, match="is not below"):
        roles_from_mapping(mapping, rig.template)


def renamed_with_map(m, tmp_path):
    """``m`` with every joint renamed to jNN (no convention knows them) and a JSON map naming its
    parts by the 100STYLE roles: (renamed Motion, map path)."""
    from minifilm.motion.motion import Motion
    rename = {n: f"j{i:02d}" for i, n in enumerate(m.names)}
    renamed = Motion([rename[n] for n in m.names], m.parents, m.offsets, m.channels, m.rotations, m.translations,
                     m.frame_time, "renamed")
    r = BUILTIN_ROLES["100style"]
    limb = lambda lb: {k: rename[getattr(lb, k)] for k in ("collar", "shoulder", "elbow", "wrist", "upleg", "knee",
                                                            "ankle", "toe")}
    mapping = {"hips": rename[r.hips], "spine": [rename[n] for n in r.spine], "neck": [rename[n] for n in r.neck],
               "left": limb(r.left), "right": limb(r.right)}
    map_path = tmp_path / "map.json"
    map_path.write_text(json.dumps(mapping))
    return renamed, map_path


def test_a_map_makes_an_unrecognised_rig_usable(tmp_path, synthetic_walk):
    """Renamed joints no convention knows: the map names them and the file retargets."""
    from minifilm.motion.bvh_write import write_bvh
    renamed, map_path = renamed_with_map(synthetic_walk, tmp_path)
    m = synthetic_walk
    path = tmp_path / "renamed.bvh"
    write_bvh(renamed, path)
    motion, roles = read_source(path, map_path)
    out = retarget_motion(motion, load_rig("bandai"), roles)
    assert out.n_frames == m.n_frames and np.all(np.isfinite(out.rotations))


def test_a_rig_known_only_by_its_map_gets_the_unit_body_size_gives(tmp_path, synthetic_walk, monkeypatch):
    """The unit of a file humanoid.py cannot read comes from the map's legs by body_size's own rule
    (thigh + shin = 0.49 of the stature). The body is made 2.0 m tall, in centimetres: the hips'
    standing height (12 % longer than thigh + shin) over 0.49 would make it 2.25 m, out of the
    1.4-2.1 m range, and the file would be rescaled to 1.7 m instead of read in centimetres."""
    from minifilm.body import units as body_size
    from minifilm.motion.bvh_write import write_bvh
    from minifilm.body.humanoid import HumanoidError
    from minifilm.body import read as read_module
    m = body_size.scaled(synthetic_walk, 1.0)
    thigh_and_shin = body_size.leg_length(m, find_humanoid(m))
    m = body_size.scaled(m, 2.0 * body_size.LEG_FRACTION / thigh_and_shin)      # a 2.0 m body, metres
    renamed, map_path = renamed_with_map(m, tmp_path)
    mapping = json.loads(map_path.read_text())
    path = tmp_path / "renamed.bvh"
    write_bvh(renamed, path, scale=0.01)                                         # centimetres
    raw = read_bvh(path, scale=1.0)
    expected = read_module.Body(raw).unit               # humanoid.py finds it by structure: the reference
    assert expected.metres_per_unit == 0.01 and expected.stature == pytest.approx(2.0)

    def unrecognised(motion):
        raise HumanoidError(f"{motion.source}: not a humanoid skeleton that minifilm recognises")
    monkeypatch.setattr(read_module, "find_humanoid", unrecognised)     # only the map knows this rig
    roles = roles_from_mapping(mapping, raw)
    assert body_size.unit_from_legs(raw, roles).stature == pytest.approx(expected.stature, rel=1e-9)
    assert read_module.Body(raw).metres_per_unit(roles) == expected.metres_per_unit
    motion, _ = read_source(path, map_path)
    np.testing.assert_allclose(motion.offsets, raw.offsets * 0.01)


# ----------------------------------------------------------------------------------------------
# the command
# ----------------------------------------------------------------------------------------------

def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "minifilm", *map(str, args)], capture_output=True, text=True,
                          timeout=600)


def test_retarget_command_writes_the_target_rig_in_its_channel_order(shared_data, tmp_path):
    src = shared_data / "bvh" / "bandai1" / "dataset-1_walk_normal_001.bvh"
    r = run_cli("retarget", src, "--to", "100style", "--out", tmp_path / "out")
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "out" / "dataset-1_walk_normal_001.bvh").read_text()
    header = (shared_data / "100style" / "Neutral_FR_first3frames.bvh").read_text()
    channels = lambda t: [line.split() for line in t.splitlines() if line.strip().startswith(("CHANNELS", "ROOT",
                                                                                                  "JOINT"))]
    assert channels(text) == channels(header)
    m = read_bvh(tmp_path / "out" / "dataset-1_walk_normal_001.bvh")
    assert m.n_frames == read_bvh(src).n_frames


@pytest.mark.parametrize("joints", [QUADRUPED, SNAKE])
def test_retarget_command_refuses_a_non_humanoid_in_one_line(tmp_path, joints):
    path = tmp_path / "animal.bvh"
    path.write_text(bvh_text(joints))
    r = run_cli("retarget", path, "--to", "100style", "--out", tmp_path / "out")
    assert r.returncode == 2 and r.stderr.startswith("error: ") and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "out" / "animal.bvh").exists()
    r = run_cli("retarget", path, "--to", "nowhere", "--out", tmp_path / "out")
    assert r.returncode == 2 and "nowhere: no such rig" in r.stderr


def test_retarget_command_refuses_a_map_naming_missing_joints(shared_data, tmp_path):
    r = BUILTIN_ROLES["cmu"]
    limb = lambda lb: {k: getattr(lb, k) for k in ("shoulder", "elbow", "wrist", "upleg", "knee", "ankle")}
    mapping = {"hips": r.hips, "spine": list(r.spine), "neck": list(r.neck), "left": limb(r.left),
               "right": dict(limb(r.right), ankle="RightAnkle")}
    map_path = tmp_path / "map.json"
    map_path.write_text(json.dumps(mapping))
    out = run_cli("retarget", shared_data / "bvh" / "xia" / "old_13_000.bvh", "--to", "100style",
                  "--out", tmp_path / "out", "--map", map_path)
    assert out.returncode == 2 and out.stderr.count("\n") == 1, out.stderr
    assert "names joints the file does not have: ['RightAnkle']" in out.stderr and str(map_path) in out.stderr


def test_view_on_draws_a_file_on_the_standard_character(shared_data, tmp_path):
    """minifilm view --on 100style: the Bandai walk drawn on the 100STYLE rig, titled so."""
    from minifilm.cli.view import tracks_on
    track, = tracks_on([shared_data / "bvh" / "bandai1" / "dataset-1_walk_normal_001.bvh"], "100style")
    assert track.name == "dataset-1_walk_normal_001 on 100style"
    assert track.positions.shape[1] == 28 and track.contacts is not None      # the 100STYLE joints, contacts found
    r = run_cli("view", shared_data / "bvh" / "xia" / "old_13_000.bvh", "--on", "100style", "--gif",
                tmp_path / "on.gif", "--every", "8")
    assert r.returncode == 0 and (tmp_path / "on.gif").stat().st_size > 0, r.stderr
