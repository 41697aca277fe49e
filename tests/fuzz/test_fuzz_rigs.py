"""Fuzz family: humanoid rigs whose necks, collars and spines are named or branch unusually.

The humanoid finder reads the torso off the hierarchy (the chest is where the arms and the head's
chain part), so whatever the names say, every such rig gets the parts a person reading its
hierarchy would name, retargeting roles that pass their own check, and a retarget onto 100STYLE
without a joint map. A rig that is no humanoid gets one line that says how to make it usable in
words every command can follow (no option the command lacks).

Cases: 300 generated rigs (spine 1-5 joints, arms off any of them, 0-3 neck joints of any name,
collars or none, four arm naming conventions) by names and by structure alone; every real layout
with its neck renamed 10 ways; the 100STYLE skeleton with its collars moved to each spine joint
and the joints above renamed; spines renamed to meaningless names; the CMU layout through the
commands (retarget, view --on)."""
import numpy as np
import pytest

from harness import outcome
from humanoid_rigs import (CMU_LAYOUT_FROM_100STYLE, NECK_NAMES, branching_humans, quadruped, renamed,
                           reparented, scrambled)
from minifilm.cli import main
from minifilm.errors import InputError
from minifilm.body.read import read_in_metres
from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.body.humanoid import find_humanoid, humanoid_by_structure
from minifilm.body import load_rig, retarget_motion
from minifilm.body.roles import roles_from_humanoid

N_GENERATED = 300
STYLE100 = "100style/Neutral_FR_first3frames.bvh"
#: per real layout: (its neck joint, the chest a reader names, the head)
REAL = {STYLE100: ("Neck", "Chest4", "Head"),
        "bandai2/dataset-2_walk_normal_001.bvh": ("Neck", "Chest", "Head"),
        "bvh/bandai1/dataset-1_run_normal_001.bvh": ("Neck", "Chest", "Head"),
        "bvh/xia/neutral_01_000.bvh": ("Neck", "Spine1", "Head"),
        "bvh/cmu/08_01_trimmed.bvh": ("neck", "chest", "head")}


def _described(h, names):
    return {r: (None if n is None else names[n]) for r, n in h.roles().items()}


def _agrees(found, expected, label):
    wrong = {r: (found.get(r), n) for r, n in expected.items() if found.get(r) != n}
    extra = [r for r in found if r.startswith("spine") and r not in expected]
    assert not wrong and not extra, f"{label}: (found, expected) {wrong}, spine roles too many: {extra}"


@pytest.fixture(scope="module")
def target():
    return load_rig("100style")


def test_generated_rigs_by_names_and_by_structure():
    cases = branching_humans(N_GENERATED, seed=11)
    assert len(cases) == N_GENERATED
    for label, m, expected in cases:
        _agrees(_described(find_humanoid(m), m.names), expected, label)
        s = scrambled(m, seed=len(label))
        _agrees(_described(humanoid_by_structure(s), m.names), expected, label + " (structure)")
        roles = roles_from_humanoid(m, find_humanoid(m))
        assert roles.chest == expected[max(k for k in expected if k.startswith("spine"))]
        assert roles.head == "Head"


def test_generated_rigs_retarget_onto_100style_without_a_map(target):
    for label, m, _ in branching_humans(40, seed=12):
        out = retarget_motion(m, target, roles_from_humanoid(m, find_humanoid(m)), plant=False)
        P = out.world()[0]
        assert np.isfinite(P).all(), label
        head, hips = out.names.index("Head"), out.names.index("Hips")
        assert (P[:, head, 1] - P[:, hips, 1] > 0.3).all(), label          # the head stays above the hips


@pytest.mark.parametrize("rel", sorted(REAL))
def test_every_real_layout_with_its_neck_renamed(shared_data, target, rel):
    neck, chest, head = REAL[rel]
    m = read_in_metres(shared_data / rel)[0]
    m = m.slice(0, min(m.n_frames, 20))
    for new in [n for n in NECK_NAMES if n not in m.names]:       # (Xia has a Neck1 already)
        r = renamed(m, {neck: new})
        h = find_humanoid(r)
        assert (r.names[h.chest], r.names[h.head]) == (chest, head), new
        assert retarget_motion(r, target, roles_from_humanoid(r, h), plant=False).n_frames == r.n_frames


@pytest.mark.parametrize("collar_parent", ["Chest", "Chest2", "Chest3", "Chest4"])
@pytest.mark.parametrize("rename_above", [False, True])
def test_100style_with_its_collars_on_any_spine_joint(shared_data, target, collar_parent, rename_above):
    m = read_bvh(shared_data / STYLE100, scale=0.01)
    chain = ["Chest", "Chest2", "Chest3", "Chest4"]
    above = chain[chain.index(collar_parent) + 1:]
    names = {n: f"cervical{i}" for i, n in enumerate(above)} if rename_above else {}
    r = reparented(m, {"LeftCollar": collar_parent, "RightCollar": collar_parent}, names)
    h = find_humanoid(r)
    assert [r.names[j] for j in h.spine] == chain[:chain.index(collar_parent) + 1]
    assert r.names[h.neck] == names.get(above[0], above[0]) if above else r.names[h.neck] == "Neck"
    assert (r.names[h.left_collar], r.names[h.right_collar]) == ("LeftCollar", "RightCollar")
    assert retarget_motion(r, target, roles_from_humanoid(r, h), plant=False).n_frames == 3


def test_spines_of_meaningless_names(shared_data, target):
    m = read_bvh(shared_data / STYLE100, scale=0.01)
    for k, name in enumerate(["bone_a", "torso_part", "x1", "Spine"]):
        r = renamed(m, {"Chest": name, "Chest2": f"{name}_2", "Chest3": f"{name}_3"})
        h = find_humanoid(r)
        assert r.names[h.chest] == "Chest4" and r.names[h.neck] == "Neck", name
        retarget_motion(r, target, roles_from_humanoid(r, h), plant=False)


def _cli(argv, capsys):
    capsys.readouterr()
    try:
        main([str(a) for a in argv])
        code = 0
    except SystemExit as e:
        code = e.code or 0
    return code, capsys.readouterr()


def test_the_cmu_layout_through_the_commands(shared_data, tmp_path, capsys):
    m = reparented(read_bvh(shared_data / STYLE100, scale=0.01), *CMU_LAYOUT_FROM_100STYLE)
    path = tmp_path / "cmu_layout.bvh"
    write_bvh(m, path, scale=0.01)
    code, io = _cli(["retarget", path, "--to", "100style", "--out", tmp_path / "out"], capsys)
    assert code == 0 and (tmp_path / "out" / "cmu_layout.bvh").is_file(), io.err
    # the same body on the same-sized skeleton: each end and the neck where the file has it (the
    # file's spine is two joints shorter and its neck three long, so the bend is shared out
    # differently: 3-7 cm; a limb or the head on the wrong chain is 20 cm and more off)
    out = read_bvh(tmp_path / "out" / "cmu_layout.bvh", scale=0.01)
    for name in ("Head", "Neck", "RightWrist", "LeftWrist", "RightAnkle", "LeftAnkle"):
        off = np.linalg.norm(out.world()[0][:, out.names.index(name)] - m.world()[0][:, m.names.index(name)], axis=-1)
        assert off.max() < 0.10, (name, off.max())
    code, io = _cli(["view", path, "--on", "100style", "--html", tmp_path / "on.html"], capsys)
    assert code == 0 and (tmp_path / "on.html").is_file(), io.err


@pytest.mark.parametrize("command", ["retarget", "view"])
def test_a_non_humanoid_is_told_what_to_do_in_words_every_command_follows(tmp_path, capsys, command):
    path = tmp_path / "dog.bvh"
    write_bvh(quadruped(), path, scale=0.01)
    argv = {"retarget": ["retarget", path, "--to", "100style", "--out", tmp_path / "out"],
            "view": ["view", path, "--on", "100style", "--html", tmp_path / "on.html"]}[command]
    code, io = _cli(argv, capsys)
    lines = [line for line in io.err.splitlines() if line.strip()]
    assert code != 0 and len(lines) == 1, io.err
    assert "minifilm retarget" in lines[0] and "--map" in lines[0]        # the way, as a whole command
    assert lines[0].index("minifilm retarget") < lines[0].index("--map")
    outcome(lambda: find_humanoid(quadruped()), InputError)


def test_finetune_takes_the_cmu_layout_onto_a_run_without_a_map(shared_data, tmp_path, tiny_run):
    """finetune's way in (pipeline.run_rig.retarget_onto_run): the CMU layout on the run's skeleton."""
    from minifilm.pipeline.run_rig import retarget_onto_run
    m = reparented(read_bvh(shared_data / STYLE100, scale=0.01), *CMU_LAYOUT_FROM_100STYLE)
    path = tmp_path / "cmu_layout.bvh"
    write_bvh(m, path, scale=0.01)
    said = []
    out = retarget_onto_run(path, tiny_run, log=said.append)
    assert out.n_frames == 3 and np.isfinite(out.world()[0]).all()
    assert said and "retargeted onto it" in said[0]
