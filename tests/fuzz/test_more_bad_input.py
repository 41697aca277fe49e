"""Bad input found by an audit after the fuzz suite was written: each is one clear error naming
the file or argument (and, for the command line, one `error:` line with exit code 2)."""
import shutil

import numpy as np
import pytest

from minifilm import cli
from minifilm.dataset.manifest import read_manifest
from minifilm.errors import InputError
from minifilm.runtime.released import ReleasedFormatError, load_released
from minifilm.runtime.style_library import StyleLibrary, StyleLibraryError, UnknownStyleError


def error_line(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    return err


def test_a_manifest_not_in_utf8_is_named(tmp_path, tiny_run):
    shutil.copy(tiny_run / "data" / "Neutral_FW.bvh", tmp_path / "a.bvh")
    (tmp_path / "m.csv").write_bytes(b"file,style,gait\na.bvh,Caf\xe9,FW\n")
    with pytest.raises(ValueError, match=r"m\.csv: not UTF-8 text"):
        read_manifest(tmp_path / "m.csv")


def test_a_manifest_listing_the_same_frames_twice_is_refused(tmp_path, tiny_run):
    shutil.copy(tiny_run / "data" / "Neutral_FW.bvh", tmp_path / "a.bvh")
    (tmp_path / "m.csv").write_text("file,style,gait\na.bvh,A,FW\na.bvh,A,FW\n")
    with pytest.raises(ValueError, match="line 3: .*listed already on line 2"):
        read_manifest(tmp_path / "m.csv")
    (tmp_path / "ok.csv").write_text("file,style,gait,start,end\na.bvh,A,FW,0,100\na.bvh,A,FW,100,200\n")
    assert len(read_manifest(tmp_path / "ok.csv")) == 2          # two ranges of one file are fine


def test_style_libraries_without_styles_or_names_are_refused(tmp_path):
    StyleLibrary().save(tmp_path / "empty.npz")
    with pytest.raises(StyleLibraryError, match="holds no styles"):
        StyleLibrary.load(tmp_path / "empty.npz")
    with pytest.raises(ValueError, match="is empty or blank"):
        StyleLibrary().add("  ", np.zeros(4))


def test_run_json_values_are_checked(tiny_run, tmp_path, capsys):
    import json
    for key, value, why in (("fps", 1e6, "frames per second"), ("fps", 0, "frames per second"),
                            ("bvh_scale", -1, "bvh_scale"), ("position_bias", float("nan"), "position_bias")):
        run = tmp_path / f"run_{key}_{value}"
        shutil.copytree(tiny_run, run)
        meta = json.loads((run / "run.json").read_text())
        meta[key] = value
        (run / "run.json").write_text(json.dumps(meta))
        err = error_line(["generate", "--run", str(run), "--seconds", "1", "--out", str(tmp_path / "o.bvh")], capsys)
        assert "run.json" in err and why in err, err
    assert not (tmp_path / "o.bvh").exists()


def test_released_statistics_with_a_zero_std_name_the_file(shared_data, tmp_path):
    folder = tmp_path / "released"
    shutil.copytree(shared_data / "released-lpn", folder)
    std = np.fromfile(folder / "Xstd.bin", "<f4")
    std[3] = 0.0
    std.tofile(folder / "Xstd.bin")
    with pytest.raises(ReleasedFormatError, match=r"Xstd\.bin"):
        load_released(folder)


def test_an_unknown_released_style_is_an_input_error(shared_data):
    styles = load_released(shared_data / "released-lpn").styles
    with pytest.raises(UnknownStyleError, match="Bogus.*known styles: Aeroplane"):
        styles["Bogus"]
    assert isinstance(UnknownStyleError("x"), InputError) and "Neutral" in styles
