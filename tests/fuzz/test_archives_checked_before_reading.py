"""Every .npz a command reads is checked from its headers before its data is read: an array of the
wrong shape, or one the file does not hold (padding), is refused with one line naming the file and
the array, at a small fraction of the memory reading it would take. The arrays here are 64 MB of
zeros, deflated to kilobytes on disk (as a forged archive can be), and the peak memory of the
refused read is held under 16 MB (a few MB are the files' real arrays, read before the check or
after: the tiny run's checkpoint is 1.5 MB); reading the forged array would take the whole 64 MB.
A data set cache refused so is built again and written anew, and a command says "loaded" only when
it loaded one."""
import shutil
import tracemalloc

import numpy as np
import pytest

from minifilm.dataset.build import build_dataset
from minifilm.dataset.dataset import Dataset
from minifilm.dataset.stats import NormStats
from minifilm.errors import InputError
from minifilm.pipeline.run_folder import RunFolder
from minifilm.runtime.style_pack import StylePack, load_pack
from minifilm.train.checkpoint import load_checkpoint

BOMB = 16_000_000          # float32 zeros: 64 MB in memory
PEAK = 16 << 20


def members(path):
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def forged(path, **changes):
    """Rewrite the archive ``path`` deflated, with the arrays ``changes`` put in (or added)."""
    arrays = {**members(path), **changes}
    path.unlink()
    with open(path, "wb") as f:
        np.savez_compressed(f, **arrays)
    return path


def refused_cheaply(call, *mentions):
    tracemalloc.start()
    try:
        with pytest.raises(InputError) as e:
            call()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    text = str(e.value)
    assert "\n" not in text and all(str(m) in text for m in mentions), text
    assert peak < PEAK, f"{peak / 2**20:.0f} MiB read before refusing: {text}"
    return text


def bomb(*shape):
    return np.zeros(shape, np.float32)


RUN_CASES = {
    "style library, vectors too long": ("styles.npz", lambda a: dict(films=bomb(2, BOMB // 2)), "films",
                                        lambda r: r.styles()),
    "style library, padded": ("styles.npz", lambda a: dict(padding=bomb(BOMB)), "padding", lambda r: r.styles()),
    "start frames, rows too long": ("starts.npz", lambda a: dict(x=bomb(2, BOMB // 2)), "'x'", lambda r: r.starts()),
    "start frames, padded": ("starts.npz", lambda a: dict(padding=bomb(BOMB)), "padding", lambda r: r.starts()),
    "checkpoint, a parameter's shape": ("model.npz", lambda a: {"motion.W0": bomb(BOMB)}, "motion.W0",
                                        lambda r: load_checkpoint(r.path / "model.npz")),
    "checkpoint, padded": ("model.npz", lambda a: {"motion.padding": bomb(BOMB)}, "motion.padding",
                           lambda r: r.network()),
    "checkpoint, statistics": ("model.npz", lambda a: {"stats.x_std": bomb(BOMB)}, "stats.x_std",
                               lambda r: r.network()),
    "checkpoint, optimiser moment": ("model.npz", lambda a: {"adam.m.0": bomb(BOMB, 2)}, "adam.m.0",
                                     lambda r: load_checkpoint(r.path / "model.npz")),
}


@pytest.mark.parametrize("case", RUN_CASES)
def test_a_run_s_archives_are_checked_before_reading(run, case):
    name, change, mention, load = RUN_CASES[case]
    path = forged(run / name, **change(members(run / name)))
    refused_cheaply(lambda: load(RunFolder.load(run)), path, mention)


@pytest.mark.parametrize("change,mention", [(dict(films=bomb(1, BOMB)), "films"), (dict(extra=bomb(BOMB)), "extra")])
def test_a_style_pack_is_checked_before_reading(tmp_path, change, mention):
    folder = tmp_path / "pack"
    StylePack.empty().with_style("Mine", np.ones(2048, np.float32), {"taught_from": []}).save(folder)
    forged(folder / "styles.npz", **change)
    refused_cheaply(lambda: load_pack(folder, film_dim=2048), folder / "styles.npz", mention)


def test_a_statistics_file_is_checked_before_reading(tiny_run, tmp_path):
    path = tmp_path / "stats.npz"
    RunFolder.load(tiny_run).model_and_stats()[1].save(path)
    forged(path, x_std=bomb(BOMB))
    refused_cheaply(lambda: NormStats.load(path), path, "x_std")


@pytest.mark.parametrize("member", ["padding", "train/x", "val/clips"])
def test_a_data_set_cache_is_checked_before_reading_and_built_again(tiny_run, tmp_path, capsys, member):
    data = shutil.copytree(tiny_run / "data", tmp_path / "data")
    cache = tmp_path / "cache"
    first = build_dataset(data, cache_dir=cache, progress=False, clip_seconds=1.0, workers=1)
    assert not first.loaded
    width = {"padding": (BOMB,), "train/x": (4, BOMB // 4), "val/clips": (1, 10, BOMB // 10)}[member]
    path = forged(first.cache_path, **{member: bomb(*width)})
    refused_cheaply(lambda: Dataset.load(path), path, member)
    capsys.readouterr()
    again = build_dataset(data, cache_dir=cache, progress=False, clip_seconds=1.0, workers=1)
    assert not again.loaded and "cannot be used" in capsys.readouterr().err
    assert member not in members(path) or members(path)[member].shape != width        # written anew
    assert build_dataset(data, cache_dir=cache, progress=False, clip_seconds=1.0, workers=1).loaded
