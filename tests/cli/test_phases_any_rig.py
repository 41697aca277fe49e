"""`minifilm phases` on humanoid files no built-in skeleton fits: the CMU conversion's names and a
rig whose joint names say nothing. The plot (and the animation) are written; a dog is one error."""
import pytest

from humanoid_rigs import CMU_CONVERSION_FROM_XIA, quadruped, renamed_bvh
from minifilm import cli
from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh

PNG = b"\x89PNG\r\n\x1a\n"


def run(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main([str(a) for a in argv])
    return stop.value.code, capsys.readouterr()


def scrambled_bvh(src, dst):
    """A copy of ``src`` whose joints are called ``bone_00``, ``bone_01``, ... in file order."""
    names = read_bvh(src, scale=1.0).names
    return renamed_bvh(src, dst, {n: f"bone_{i:02d}" for i, n in enumerate(names)})


def test_phases_of_the_cmu_conversion_layout(shared_data, tmp_path, capsys):
    path = renamed_bvh(shared_data / "bvh/xia/neutral_01_000.bvh", tmp_path / "conv.bvh", CMU_CONVERSION_FROM_XIA)
    code, out = run(["phases", path, "--out", tmp_path / "p.png"], capsys)
    assert code == 0, out.err
    assert (tmp_path / "p.png").read_bytes()[:8] == PNG
    assert "any humanoid (parts found by names)" in out.out and "CMU ASF units" in out.out


def test_phases_of_a_scrambled_rig_with_its_animation(shared_data, tmp_path, capsys):
    path = scrambled_bvh(shared_data / "bandai2/dataset-2_walk_normal_001.bvh", tmp_path / "s.bvh")
    assert "Hips" not in path.read_text()
    code, out = run(["phases", path, "--out", tmp_path / "p.png", "--animation", tmp_path / "p.gif",
                     "--stop", "1"], capsys)
    assert code == 0, out.err
    assert (tmp_path / "p.png").read_bytes()[:8] == PNG
    assert (tmp_path / "p.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    assert "parts found by structure" in out.out and "centimetres" in out.out


def test_phases_of_a_dog_is_one_error(tmp_path, capsys):
    path = tmp_path / "dog.bvh"
    write_bvh(quadruped(human_names=True), path)
    code, out = run(["phases", path, "--out", tmp_path / "p.png"], capsys)
    errors = [line for line in out.err.splitlines() if line.startswith("error:")]
    assert code == 2 and len(errors) == 1, out.err
    assert "dog.bvh" in errors[0] and "humanoid" in errors[0]
    assert not (tmp_path / "p.png").exists()
