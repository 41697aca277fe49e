"""A data set is one rig: a file of another rig among many is named from the headers alone, before
any file is read, labelled or featurised (the survey, minifilm/dataset/survey.py), wherever it
sits in the list, and the skeleton is the majority's, not the first file's."""
from pathlib import Path

import pytest

import minifilm.dataset.build as build
from minifilm.dataset.build import build_dataset
from minifilm.dataset.manifest import MotionFile
from minifilm.errors import DataError


def _files(shared_data, foreign_at):
    good = sorted((shared_data / "bandai2").glob("dataset-2_walk_*.bvh"))[:24]
    files = [MotionFile(p, p.name.split("_")[2], "walk") for p in good]
    files.insert(foreign_at, MotionFile(shared_data / "bvh/xia/neutral_01_000.bvh", "neutral", "walk"))
    return files


@pytest.mark.parametrize("foreign_at", [0, 12, 24])
def test_one_file_of_another_rig_is_named_before_any_file_is_read(shared_data, monkeypatch, foreign_at):
    loaded = []
    # every file is read, labelled and featurised in _build (here or in its worker processes)
    monkeypatch.setattr(build, "_build", lambda files, *a, **k: loaded.extend(files))
    with pytest.raises(DataError) as e:
        build_dataset(_files(shared_data, foreign_at), fps=30.0, progress=False)
    text = str(e.value)
    assert "1 of 25 files" in text and "neutral_01_000.bvh" in text and "'bandai'" in text, text
    assert "minifilm retarget" in text and "--rig " in text and "\n" not in text
    assert loaded == []                                   # nothing read in full, labelled or featurised


def test_the_survey_reads_joint_names_as_the_parser_does(shared_data):
    from minifilm.dataset.survey import survey
    from minifilm.motion.bvh import read_bvh
    path = shared_data / "bvh/cmu/08_01_trimmed.bvh"
    s = survey([MotionFile(path, "x", "walk")], None)[Path(path)]
    assert list(s.names) == read_bvh(path).names and s.n_joints == len(s.names)
