"""An honest BVH file too large to read is refused from its header, before it is read, with the
memory reading it would take: by read_bvh itself, so by every command that reads BVH (view,
retarget, phases, dataset, finetune of a run or of the released network, generate's skeleton).

The file is a real take (Bandai) repeated to 5,000 frames (6.6 MB); the limit is lowered to 16 MB
for the test, so the file plays the part of a take of hours against a machine's memory."""
import tracemalloc

import pytest

from minifilm.motion import bvh as bvh_module
from minifilm.motion.bvh import BVHError, bvh_header, read_bvh
from test_names_and_outputs import one_error

FRAMES = 5000


@pytest.fixture(scope="module")
def long_take(shared_data, tmp_path_factory):
    text = (shared_data / "bandai2" / "dataset-2_walk_normal_001.bvh").read_text()
    head, _, motion = text.partition("MOTION")
    frames = [line for line in motion.strip().splitlines()[2:] if line.strip()]
    body = "\n".join((frames * (FRAMES // len(frames) + 1))[:FRAMES])
    path = tmp_path_factory.mktemp("long") / "dataset-2_walk_normal_001.bvh"
    path.write_text(f"{head}MOTION\nFrames: {FRAMES}\nFrame Time: 0.0333333\n{body}\n")
    return path


@pytest.fixture
def small_limit(monkeypatch):
    monkeypatch.setattr(bvh_module, "MAX_MOTION_BYTES", 16 << 20)


def estimate(path):
    frames, _, joints = bvh_header(path)
    return (bvh_module.READ_BYTES_PER_CHARACTER * path.stat().st_size
            + bvh_module.READ_BYTES_PER_JOINT_FRAME * frames * joints)


def test_the_estimate_is_true(long_take):
    """The peak of reading the file lies under the estimate and above half of it (the estimate is
    measured on longer takes and rounded up: 5-20 % above their peaks)."""
    tracemalloc.start()
    try:
        read_bvh(long_take)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert 0.5 * estimate(long_take) < peak < estimate(long_take), (peak, estimate(long_take))


def test_read_bvh_refuses_before_reading(long_take, small_limit):
    tracemalloc.start()
    try:
        with pytest.raises(BVHError) as e:
            read_bvh(long_take)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < long_take.stat().st_size / 4, f"{peak / 2**20:.1f} MiB read before refusing"
    text = str(e.value)
    need = round(estimate(long_take) / 2**20)
    assert f"{FRAMES:,} frames of 27 joints (6 MiB)" in text and f"would need about {need} MiB" in text
    assert "more than 16 MiB" in text and "hostile" not in text and "cut it into shorter files" in text


def test_a_header_declaring_frames_its_file_cannot_hold_is_named_so(long_take, tmp_path):
    forged = tmp_path / "forged.bvh"
    forged.write_text(long_take.read_text().replace(f"Frames: {FRAMES}", "Frames: 400000000", 1))
    with pytest.raises(BVHError, match="400,000,000 frames of .* more than its .* characters can hold"):
        read_bvh(forged)


COMMANDS = {
    "view": ["view", "{take}", "--html", "{tmp}/v.html"],
    "retarget": ["retarget", "{take}", "--to", "100style", "--out", "{tmp}/onto"],
    "phases": ["phases", "{take}", "--out", "{tmp}/p.png"],
    "dataset": ["dataset", "{folder}", "--no-cache", "--workers", "1"],
    "finetune a run": ["finetune", "--run", "{run}", "--name", "Long", "--steps", "5", "{take}"],
    "finetune the released network": ["finetune", "--params", "{released}", "--name", "Long", "--out", "{tmp}/pack",
                                      "{take}"],
    "generate on a skeleton": ["generate", "--params", "{released}", "--style", "Neutral", "--seconds", "0.2",
                               "--skeleton-bvh", "{take}", "--out", "{tmp}/g.bvh"],
}


@pytest.mark.parametrize("command", COMMANDS)
def test_every_reader_refuses_early_with_the_estimate(long_take, shared_data, run, tmp_path, capsys, small_limit,
                                                     command):
    (tmp_path / "folder").mkdir()
    (tmp_path / "folder" / long_take.name).symlink_to(long_take)
    names = dict(take=long_take, tmp=tmp_path, folder=tmp_path / "folder", run=run,
                 released=shared_data / "released-lpn")
    one_error([a.format(**names) for a in COMMANDS[command]], capsys, "dataset-2_walk_normal_001.bvh",
              f"{FRAMES:,} frames of 27 joints", "would need about")
