"""The player's data: quantisation error bound, size budget, lanes, and safe inlining."""
import base64
import json
import re

import numpy as np

from minifilm.viewer import Track, track_from_motion
from minifilm.viewer.encode import decode_positions, encode_track, quantise
from minifilm.viewer.html import lane_offsets, page_html

from viewer_helpers import synthetic_walker


def test_quantised_positions_are_within_half_a_step():
    track = track_from_motion(synthetic_walker(n_frames=300, speed=3.0))  # walks 30 m from the origin
    root, rel, step = quantise(track)
    back = decode_positions(root, rel, step)
    assert np.abs(back - track.positions).max() <= step / 2 + 1e-12
    assert step / 2 < 5e-5  # a 1.6 m figure: below 0.05 mm
    assert rel.dtype == np.int16 and root.dtype == np.float32


def test_encoded_arrays_decode_to_the_same_numbers():
    track = track_from_motion(synthetic_walker(n_frames=20))
    data = encode_track(track, offset=[1.0, 0.0, -2.0])
    root = np.frombuffer(base64.b64decode(data["root"]), "<f4").reshape(20, 3)
    rel = np.frombuffer(base64.b64decode(data["rel"]), "<i2").reshape(20, track.n_joints, 3)
    assert np.abs(decode_positions(root, rel, data["step"]) - track.positions).max() <= data["step"] / 2 + 1e-12
    assert data["parents"] == list(track.parents) and data["offset"] == [1.0, 0.0, -2.0]


def test_eight_characters_ten_seconds_sixty_fps_fit_in_five_megabytes():
    # 21 joints, as a Bandai skeleton after dropping its zero-length End Sites and static root.
    base = synthetic_walker(n_frames=600, fps=60.0)
    P, _ = base.world()
    P = np.concatenate([P, P[:, :5] + 0.01], axis=1)  # 16 + 5 = 21 joints
    parents = np.concatenate([base.parents, [2, 5, 9, 13, 15]])
    tracks = [Track(f"style {i}", P + [i * 0.1, 0, 0], parents, 60.0) for i in range(8)]
    size = len(page_html(tracks).encode("utf-8"))
    assert size <= 5_000_000, f"{size / 1e6:.2f} MB"


def test_lanes_run_across_the_walking_direction():
    along_z = [track_from_motion(synthetic_walker(n_frames=30)) for _ in range(3)]  # walks along +z
    for t in along_z:
        t.trail[:, 0] = t.trail[0, 0]          # a straight path: lanes exactly `size` apart
    offsets = lane_offsets(along_z, size=1.5)
    starts = np.array([t.trail[0] for t in along_z]) + offsets
    np.testing.assert_allclose(starts[:, 0], [-1.5, 0.0, 1.5])
    np.testing.assert_allclose(starts[:, 2], 0.0, atol=1e-12)


def test_characters_on_curved_paths_keep_to_their_own_lanes():
    # three walkers along +z, each swerving up to 1 m sideways (as on a figure-eight)
    tracks = []
    for i, sway in enumerate([1.0, -1.0, 0.5]):
        t = track_from_motion(synthetic_walker(n_frames=120))
        side = sway * np.sin(np.linspace(0.0, np.pi, len(t.trail)))
        t.positions = t.positions + np.stack([side, 0 * side, 0 * side], axis=1)[:, None]
        t.trail = t.trail + np.stack([side, 0 * side, 0 * side], axis=1)
        tracks.append(t)
    size = 1.5
    offsets = lane_offsets(tracks, size)
    xs = [(t.trail + o)[:, 0] for t, o in zip(tracks, offsets)]
    for a, b in zip(xs, xs[1:]):                          # neighbouring lanes, left to right
        assert b.min() - a.max() >= size - 1e-9
    assert np.isclose(min(x.min() for x in xs) + max(x.max() for x in xs), 0.0)  # centred


def test_names_cannot_break_out_of_the_page():
    evil = "</script><script>alert(1)</script> {{JS}}"
    page = page_html([track_from_motion(synthetic_walker(n_frames=5), name=evil)], title=evil)
    assert page.count("<script>alert(1)") == 0
    blob = re.search(r'<script type="application/json" id="minifilm-data">(.*?)</script>', page, re.S).group(1)
    assert json.loads(blob)["characters"][0]["name"] == evil
