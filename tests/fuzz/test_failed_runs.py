"""A training that fails keeps what was there: an earlier run in the same folder stays a run, and
a folder made for the failed run is removed."""
import shutil

import pytest

from minifilm.errors import InputError
from minifilm.motion.bvh_write import write_bvh
from minifilm.pipeline.run_folder import RunFolder
from minifilm.pipeline.train_small import Settings, run
from minifilm.synthetic.generator import default_dataset


@pytest.fixture
def data_with_a_two_frame_file(tmp_path):
    folder = tmp_path / "bad_data"
    folder.mkdir()
    clips = default_dataset(styles=["Neutral", "LeftHop"], gaits=["FW"], seconds=4.0)
    write_bvh(clips[0].motion, folder / f"{clips[0].style}_FW.bvh")
    write_bvh(clips[1].motion.slice(0, 2), folder / f"{clips[1].style}_FW.bvh")   # too short to use
    return folder


def test_a_failed_training_keeps_the_earlier_run_in_its_folder(tiny_run, tmp_path, data_with_a_two_frame_file):
    victim = tmp_path / "victim"
    shutil.copytree(tiny_run, victim)
    before = {p.name: p.read_bytes() for p in victim.iterdir() if p.is_file()}
    with pytest.raises(InputError, match="_FW.bvh"):
        run(Settings(out=victim).quick(), data=data_with_a_two_frame_file)
    RunFolder.load(victim).styles()                        # still a run, with its library
    assert {p.name: p.read_bytes() for p in victim.iterdir() if p.is_file()} == before


def test_a_failed_training_into_a_new_folder_leaves_no_folder(tmp_path, data_with_a_two_frame_file):
    out = tmp_path / "new_run"
    with pytest.raises(InputError):
        run(Settings(out=out).quick(), data=data_with_a_two_frame_file)
    assert not out.exists()


def test_whole_file_splits_need_three_files_per_style(tmp_path, tiny_run):
    # one file per style: the automatic choice splits every file into segments instead, and an
    # explicit --split files is refused before training (no validation or test frames)
    from dataclasses import replace
    data = tmp_path / "one_file_each"
    data.mkdir()
    for name in ("Neutral_FW.bvh", "LeftHop_FW.bvh"):
        shutil.copy(tiny_run / "data" / name, data / name)
    quick = replace(Settings(out=tmp_path / "auto").quick(), epochs=1, generate_seconds=0.5)
    run(quick, data=data)                                            # auto: segments, a complete run
    RunFolder.load(tmp_path / "auto")
    with pytest.raises(InputError, match="val and test split.*at least three files"):
        run(replace(quick, out=tmp_path / "files", split="files"), data=data)
    assert not (tmp_path / "files").exists()
