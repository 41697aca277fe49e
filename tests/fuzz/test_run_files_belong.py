"""Archives with two members of one name are refused wherever an .npz is read, a file of another
run placed in a run folder is named for what it is, and a huge JSON number is one clear line.

Members are enumerated from the run's own archives, so every array of every archive is
duplicated once; the foreign-file family swaps every file of a run, and every pair, for the
other run's copy."""
import io
import itertools
import json
import shutil
import warnings
import zipfile
from dataclasses import replace

import numpy as np
import pytest

from minifilm.files import read_npz
from minifilm.errors import InputError
from minifilm.files.reading import MAX_JSON_DIGITS, parse_json
from in_process import minifilm_here
from test_names_and_outputs import one_error

ARCHIVES = ("styles.npz", "starts.npz", "model.npz")
RUN_FILES = ("run.json", "styles.npz", "starts.npz", "model.npz")


@pytest.fixture(scope="module")
def other_run(tmp_path_factory):
    """A second tiny run of the same shape (another training: another id and checkpoint)."""
    from minifilm.pipeline.train_small import Settings, run
    out = tmp_path_factory.mktemp("other_run")
    s = replace(Settings(out=out).quick(), styles=("Neutral", "LeftHop"), gaits=("FW",), seconds_per_clip=6.0,
                epochs=2, generate_seconds=0.5)
    run(s)
    return out


def members(path):
    with zipfile.ZipFile(path) as z:
        return [i.filename for i in z.infolist()]


def with_a_second(path, member):
    """Rewrite the archive at ``path`` with ``member`` twice, the second copy of other values."""
    with zipfile.ZipFile(path) as z:
        items = [(i.filename, z.read(i)) for i in z.infolist()]
    data = dict(items)[member]
    array = np.lib.format.read_array(io.BytesIO(data), allow_pickle=False)
    changed = io.BytesIO()
    np.lib.format.write_array(changed, np.zeros_like(array) if array.dtype.kind in "fiub" else array,
                              allow_pickle=False)
    with warnings.catch_warnings(), zipfile.ZipFile(path, "w") as z:
        warnings.simplefilter("ignore")                       # zipfile warns of the duplicate name: the point
        for name, payload in items + [(member, changed.getvalue())]:
            z.writestr(name, payload)


def archive_cases(tiny_run):
    return [(a, m) for a in ARCHIVES for m in members(tiny_run / a)]


def test_every_member_of_every_archive_twice_is_refused(tiny_run, tmp_path, capsys):
    tried = 0
    for archive, member in archive_cases(tiny_run):
        folder = tmp_path / f"{archive}-{member}"
        shutil.copytree(tiny_run, folder, ignore=shutil.ignore_patterns("cache", "generated", "*.png"))
        with_a_second(folder / archive, member)
        with pytest.raises(InputError, match=f"two members named '{member}'"):
            read_npz(folder / archive, archive)
        line = one_error(["generate", "--run", folder, "--seconds", "0.5", "--out", tmp_path / "o.bvh"], capsys,
                         archive, "two members named")
        assert member in line
        tried += 1
    assert tried == len(archive_cases(tiny_run)) and tried >= 10
    assert not (tmp_path / "o.bvh").exists()


def test_a_data_set_cache_with_two_members_is_rebuilt_not_guessed(tiny_run, tmp_path, capsys):
    code, out = minifilm_here(["dataset", tiny_run / "data", "--cache", tmp_path / "cache", "--clip-seconds", "1"], capsys)
    assert code == 0, out.err[-400:]
    cache = next((tmp_path / "cache").glob("dataset-*.npz"))
    with_a_second(cache, "meta.npy")
    from minifilm.dataset.cache import cached_key
    assert cached_key(cache) is None                       # so the build starts again
    code, out = minifilm_here(["dataset", tiny_run / "data", "--cache", tmp_path / "cache", "--clip-seconds", "1"], capsys)
    assert code == 0 and "built" in out.out, out.out[-400:]


# ---- a run's files belong together ----------------------------------------------------------------
def swap_cases():
    return [c for k in (1, 2) for c in itertools.combinations(RUN_FILES, k)]


@pytest.mark.parametrize("swapped", swap_cases(), ids=lambda c: "+".join(c))
def test_another_run_s_files_are_named(run, other_run, tmp_path, capsys, swapped):
    for name in swapped:
        shutil.copy(other_run / name, run / name)
    line = one_error(["generate", "--run", run, "--seconds", "0.5", "--out", tmp_path / "o.bvh"], capsys, "run folder")
    if len(swapped) == 1:
        assert f"{swapped[0]} is" in line and ("another run's" in line or "not the checkpoint" in line), line
    else:
        assert "different runs" in line or all(f"{n} is" in line for n in swapped) or "another run's" in line, line
    assert not (tmp_path / "o.bvh").exists()


def strip_ids(folder):
    """The run as minifilm wrote runs before they had ids."""
    meta = json.loads((folder / "run.json").read_text())
    meta.pop("run_id"), meta.pop("checkpoint")
    (folder / "run.json").write_text(json.dumps(meta))
    for name in ("styles.npz", "starts.npz"):
        with np.load(folder / name, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files if k != "run_id"}
        np.savez(folder / name, **arrays)


def test_an_old_run_without_ids_still_loads_and_finetunes(run, tmp_path, capsys):
    strip_ids(run)
    code, out = minifilm_here(["generate", "--run", run, "--seconds", "0.5", "--out", tmp_path / "o.bvh"], capsys)
    assert code == 0, out.err[-500:]
    code, out = minifilm_here(["finetune", "--run", run, "--name", "Proud", "--steps", "2", run / "data" / "Neutral_FW.bvh"],
                       capsys)
    assert code == 0, out.err[-500:]


def test_an_old_run_names_a_style_library_without_start_frames_as_foreign(run, tmp_path, capsys):
    strip_ids(run)
    with np.load(run / "styles.npz", allow_pickle=False) as z:
        films = z["films"]
    np.savez(run / "styles.npz", names=np.array(["Zombie", "Proud"]), films=films)
    one_error(["generate", "--run", run, "--list-styles"], capsys, "styles.npz is another run's", "start frame")


def test_finetune_keeps_the_run_s_files_together(run, tmp_path, capsys):
    code, out = minifilm_here(["finetune", "--run", run, "--name", "Proud", "--steps", "2", run / "data" / "Neutral_FW.bvh"],
                       capsys)
    assert code == 0, out.err[-500:]
    meta = json.loads((run / "run.json").read_text())
    for name in ("styles.npz", "starts.npz"):
        with np.load(run / name, allow_pickle=False) as z:
            assert str(z["run_id"]) == meta["run_id"], name
    code, out = minifilm_here(["generate", "--run", run, "--style", "Proud", "--seconds", "0.5", "--out", tmp_path / "o.bvh"],
                       capsys)
    assert code == 0, out.err[-500:]


# ---- huge JSON numbers ------------------------------------------------------------------------------
@pytest.mark.parametrize("digits", [MAX_JSON_DIGITS + 1, 4301, 100_000])
def test_a_huge_json_number_is_one_clear_line(run, tmp_path, capsys, digits):
    text = (run / "run.json").read_text().replace('"position_bias": ', '"position_bias": ' + "9" * digits + ", \"x\": ", 1)
    (run / "run.json").write_text(text)
    line = one_error(["generate", "--run", run, "--list-styles"], capsys, "run.json", "digits")
    assert "set_int_max_str_digits" not in line
    with pytest.raises(InputError, match="digits") as e:
        parse_json('{"seed": ' + "1" * digits + "}", "map.json")
    assert "set_int_max_str_digits" not in str(e.value)
    with pytest.raises(InputError, match="too large"):
        parse_json('{"fps": 1e999}', "meta.json")


def test_a_huge_number_in_a_joint_map_or_a_demo_message(tiny_run, tmp_path, capsys):
    joint_map = tmp_path / "map.json"
    joint_map.write_text('{"hips": "Hips", "n": ' + "7" * 5000 + "}")
    line = one_error(["retarget", tiny_run / "data" / "Neutral_FW.bvh", "--to", "100style", "--out", tmp_path / "o",
                      "--map", joint_map], capsys, "map.json")
    assert "set_int_max_str_digits" not in line
    from minifilm.demo.protocol import ProtocolError, parse_message
    with pytest.raises(ProtocolError, match="digits") as e:
        parse_message('{"type": "input", "seq": ' + "1" * 4000 + "}", ["Neutral"])
    assert "set_int_max_str_digits" not in str(e.value)
