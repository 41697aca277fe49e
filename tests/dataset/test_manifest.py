"""100STYLE folder scanning: the download keeps one sub-folder per style."""
import pytest

from minifilm.dataset.manifest import scan_100style


def _touch(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("not read by the scan")


def test_scan_finds_files_in_style_subfolders(tmp_path):
    _touch(tmp_path / "Aeroplane" / "Aeroplane_FW.bvh")
    _touch(tmp_path / "Aeroplane" / "Aeroplane_ID.bvh")
    _touch(tmp_path / "Zombie" / "Zombie_BR.bvh")
    _touch(tmp_path / "Zombie" / "notes.bvh")
    got = [(f.path.relative_to(tmp_path).as_posix(), f.style, f.gait) for f in scan_100style(tmp_path)]
    assert got == [("Aeroplane/Aeroplane_FW.bvh", "Aeroplane", "FW"),
                   ("Aeroplane/Aeroplane_ID.bvh", "Aeroplane", "ID"),
                   ("Zombie/Zombie_BR.bvh", "Zombie", "BR")]


def test_scan_rejects_two_copies_of_one_file(tmp_path):
    _touch(tmp_path / "Zombie_FW.bvh")
    _touch(tmp_path / "backup" / "Zombie_FW.bvh")
    with pytest.raises(ValueError, match="Zombie_FW.bvh is both"):
        scan_100style(tmp_path)
