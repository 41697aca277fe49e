"""Frame schedule of animations: counts, subsampling, mixed frame rates, GIF delays."""
import numpy as np
import pytest

from minifilm.viewer import track_from_motion
from minifilm.viewer.timeline import GIF_MAX_FPS, gif_durations_ms, schedule

from viewer_helpers import synthetic_walker


def _track(n, fps, name="t"):
    return track_from_motion(synthetic_walker(n_frames=n, fps=fps), name=name)


def test_one_track_shows_every_frame_once():
    s = schedule([_track(37, 30.0)])
    assert s.fps == 30.0 and s.n_frames == 37
    np.testing.assert_array_equal(s.frames[:, 0], np.arange(37))


def test_every_keeps_every_nth_frame():
    s = schedule([_track(37, 30.0)], every=4)
    assert s.fps == 7.5
    np.testing.assert_array_equal(s.frames[:, 0], np.arange(0, 37, 4))  # ceil(37 / 4) = 10 frames


def test_gif_rate_cap_picks_every_for_fast_sources():
    s = schedule([_track(240, 120.0)], max_fps=GIF_MAX_FPS)
    assert s.fps == 40.0  # every 3rd frame: 120 fps GIF frames would be shown at 100 ms each
    np.testing.assert_array_equal(s.frames[:, 0], np.arange(0, 240, 3))
    assert schedule([_track(60, 30.0)], max_fps=GIF_MAX_FPS).fps == 30.0


def test_mixed_rates_and_lengths_follow_one_clock():
    slow, fast = _track(30, 30.0, "slow"), _track(60, 120.0, "fast")  # 1.0 s and 0.5 s
    s = schedule([slow, fast])
    assert s.fps == 120.0 and s.n_frames == 120
    np.testing.assert_array_equal(s.frames[:, 0], np.minimum((np.arange(120) + 2) // 4, 29))  # nearest frame
    np.testing.assert_array_equal(s.frames[:60, 1], np.arange(60))
    assert np.all(s.frames[60:, 1] == 59)  # ended: holds its last frame


def test_seconds_and_fps_override():
    s = schedule([_track(30, 30.0)], fps=10.0, seconds=2.0)
    assert s.n_frames == 20
    np.testing.assert_array_equal(s.frames[:10, 0], np.arange(0, 30, 3))
    with pytest.raises(ValueError, match="fps or every, not both"):
        schedule([_track(30, 30.0)], fps=10.0, every=2)
    with pytest.raises(ValueError, match="every must be a positive whole number"):
        schedule([_track(30, 30.0)], every=0)


def test_rounded_bvh_frame_times_neither_add_nor_drop_frames():
    # "Frame Time: 0.0333333" is 30.00003 fps: 6 s must still be 180 frames, not 181.
    track = track_from_motion(synthetic_walker(n_frames=273, fps=1 / 0.0333333))
    assert schedule([track], seconds=6.0).n_frames == 180
    assert schedule([track]).n_frames == 273
    # A 30 fps clip on a 120.0048 fps clock ("Frame Time: .0083333") still shows every frame.
    fast = track_from_motion(synthetic_walker(n_frames=1200, fps=1 / 0.0083333))
    s = schedule([fast, track], every=4)
    np.testing.assert_array_equal(s.frames[:273, 1], np.arange(273))


def test_gif_delays_are_centiseconds_that_keep_time():
    d = gif_durations_ms(30, 30.0)
    assert all(ms % 10 == 0 for ms in d)
    assert set(d) == {30, 40}
    assert sum(d) == 1000
    assert sum(gif_durations_ms(400, 40.0)) == 10000
