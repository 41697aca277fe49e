"""A long ``generate`` shows how far it has come (an hour of motion takes minutes); a short one
prints no progress at all."""
import re

from in_process import minifilm_here

LINE = re.compile(r"^\[generate\] (\d+)/(\d+) frames, +[\d.]+ s, eta +[\d.na]+ s", re.M)


def generate(run, seconds, out, capsys):
    code, printed = minifilm_here(["generate", "--run", run, "--seconds", seconds, "--out", out], capsys)
    assert code == 0, printed.err
    return printed.err


def test_a_motion_over_a_minute_shows_its_frames_done_about_every_tenth(tiny_run, tmp_path, capsys):
    seen = [(int(a), int(b)) for a, b in LINE.findall(generate(tiny_run, 61, tmp_path / "long.bvh", capsys))]
    frames = seen[-1][1]
    assert frames >= 61 * 24 and all(total == frames for _, total in seen)       # every line: of all the frames
    done = [d for d, _ in seen]
    assert done[-1] == frames and done == sorted(set(done))                     # rising to the end, no repeats
    assert 10 <= len(done) <= 12                                                # (not on a terminal: a line a tenth)
    assert (tmp_path / "long.bvh").is_file()


def test_a_short_motion_prints_no_progress(tiny_run, tmp_path, capsys):
    assert LINE.search(generate(tiny_run, 5, tmp_path / "short.bvh", capsys)) is None
