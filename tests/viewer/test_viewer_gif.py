"""GIF writer: frame count, size, timing, content, and that what is drawn is the BVH's kinematics."""
import numpy as np
import pytest

from minifilm.motion.bvh import read_bvh
from minifilm.viewer import project, track_from_bvh, track_from_motion, write_gif

from viewer_helpers import foot_contacts, synthetic_walker

pytest.importorskip("matplotlib", reason="the GIF writer needs matplotlib (pip install 'minifilm[viz]')")
Image = pytest.importorskip("PIL.Image", reason="the GIF writer needs Pillow (pip install 'minifilm[viz]')")

SMALL = (160, 200)


def read_gif(path):
    """(frames (N, H, W, 3) uint8, delays in ms (N,)) of a GIF file."""
    frames, delays = [], []
    with Image.open(path) as im:
        for k in range(im.n_frames):
            im.seek(k)
            frames.append(np.array(im.convert("RGB")))
            delays.append(im.info["duration"])
    return np.stack(frames), np.array(delays)


def chromatic(rgb):
    """Bool mask of saturated pixels (the skeletons; background, grid and text are grey)."""
    rgb = rgb.astype(int)
    return rgb.max(axis=-1) - rgb.min(axis=-1) > 40


def test_synthetic_gif_has_every_frame_at_its_size_and_rate(tmp_path, walker):
    path = tmp_path / "walker.gif"
    r = write_gif(track_from_motion(walker), path, size=SMALL)
    frames, delays = read_gif(path)
    assert frames.shape == (36, 200, 160, 3) and r.n_frames == 36 and r.size == (160, 200)
    assert delays.sum() == 1200  # 36 frames at 30 fps, to the millisecond
    assert [p.name for p in tmp_path.iterdir()] == ["walker.gif"]  # no temporary file left


def test_a_name_in_a_script_the_font_lacks_is_drawn_without_a_warning(tmp_path, walker):
    """A style named 疲れた: its title is drawn (boxes where the font has no glyph), and matplotlib's
    per-glyph warnings, which name its own source files, are not printed."""
    import warnings
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        write_gif(track_from_motion(walker, name="疲れた"), tmp_path / "tired.gif", size=SMALL)
        write_gif(track_from_motion(walker, name="疲れた"), tmp_path / "again.gif", size=SMALL)
    assert [str(w.message) for w in caught if "Glyph" in str(w.message)] == []
    assert (tmp_path / "tired.gif").stat().st_size > 1000


def test_frames_are_not_blank_and_change(tmp_path, walker):
    frames, _ = read_gif(write_gif(track_from_motion(walker), tmp_path / "w.gif", size=SMALL).path)
    for f in frames:
        assert len(np.unique(f.reshape(-1, 3), axis=0)) > 8  # not one colour
        assert chromatic(f).sum() > 300  # a coloured skeleton is there
    changed = [(frames[k] != frames[k + 1]).any(axis=-1).sum() for k in range(len(frames) - 1)]
    assert min(changed) > 20  # every frame differs from the next by more than the clock text


def test_fewer_colours_make_a_smaller_gif_of_the_same_frames(tmp_path, walker):
    """``colours`` bounds the palette (docs/img's retargeting GIFs use 32) and the file shrinks."""
    track = track_from_motion(walker)
    full = write_gif(track, tmp_path / "full.gif", size=SMALL).path
    few = write_gif(track, tmp_path / "few.gif", size=SMALL, colours=16).path
    frames, _ = read_gif(few)
    assert frames.shape == read_gif(full)[0].shape
    assert max(len(np.unique(f.reshape(-1, 3), axis=0)) for f in frames) <= 16
    assert chromatic(frames[0]).sum() > 300                   # the skeleton keeps its colour
    assert few.stat().st_size < full.stat().st_size
    for bad in (1, 257, 2.5):
        with pytest.raises(ValueError, match="colours"):
            write_gif(track, tmp_path / "bad.gif", size=SMALL, colours=bad)
    assert not (tmp_path / "bad.gif").exists()


def test_drawn_joints_are_the_projected_bvh_forward_kinematics(tmp_path, bandai_walk):
    motion = read_bvh(bandai_walk)
    P, _ = motion.world()  # (F, J, 3): the reference, computed without the viewer
    track = track_from_bvh(bandai_walk)
    idx = [motion.names.index(n) for n in track.joint_names]
    r = write_gif(track, tmp_path / "bandai.gif", seconds=1.0, size=SMALL)
    assert r.n_frames == 30
    np.testing.assert_array_equal(r.frames[:, 0], np.arange(30))  # 30 fps source, every frame
    hips = motion.names.index("Hips")
    for k in range(r.n_frames):
        cam = r.cameras[0][k]
        expected = project(P[k, idx], cam)
        np.testing.assert_allclose(r.drawn[0][k], expected, rtol=0, atol=1e-12)
        # The camera follows the walking root: it aims at the hips' floor position (smoothed).
        assert np.hypot(cam.target[0] - P[k, hips, 0], cam.target[2] - P[k, hips, 2]) < 0.1
    # And the points are where the image shows the skeleton (checked on the decoded GIF).
    frames, _ = read_gif(r.path)
    hit, shifted = _bone_hits(frames, r.pixels[0], track.bones)
    assert hit > 0.9, f"only {hit:.0%} of bone midpoints are on a coloured pixel"
    assert shifted < 0.5  # the same check 40 px to the side fails: it can tell


def _bone_hits(frames, pixels, bones):
    """Fraction of bone midpoints (longer than 6 px) with a coloured pixel within 1 px, and the
    same for midpoints shifted 40 px sideways (a control that must mostly miss)."""
    hits = {0: [], 40: []}
    for k, frame in enumerate(frames):
        mask = chromatic(frame)
        a, b = pixels[k][bones[:, 0]], pixels[k][bones[:, 1]]
        long = np.linalg.norm(a - b, axis=1) > 6
        for shift in hits:
            for x, y in 0.5 * (a + b)[long] + [shift, 0]:
                c, rr = int(x), int(y)
                if 1 <= rr < frame.shape[0] - 1 and 1 <= c < frame.shape[1] - 1:
                    hits[shift].append(mask[rr - 1:rr + 2, c - 1:c + 2].any())
    return np.mean(hits[0]), np.mean(hits[40])


def test_synthetic_motion_drawn_numbers_and_pixels(tmp_path, walker):
    track = track_from_motion(walker)
    P, _ = walker.world()
    r = write_gif(track, tmp_path / "w.gif", size=SMALL)
    for k in range(r.n_frames):
        np.testing.assert_allclose(r.drawn[0][k], project(P[k], r.cameras[0][k]), atol=1e-12)
    hit, shifted = _bone_hits(read_gif(r.path)[0], r.pixels[0], track.bones)
    assert hit > 0.9 and shifted < 0.5


def test_characters_side_by_side_with_their_own_cameras(tmp_path, walker, xia_walk):
    turning = track_from_motion(synthetic_walker(n_frames=60, fps=30.0, turn=1.0), name="turning")
    xia = track_from_bvh(xia_walk, name="xia")  # 120 fps, 327 frames: the GIF runs at 40 fps
    r = write_gif([track_from_motion(walker, name="straight"), turning, xia], tmp_path / "three.gif",
                  size=SMALL, columns=2)
    frames, delays = read_gif(r.path)
    assert r.fps == pytest.approx(40.0, rel=1e-3) and frames.shape == (109, 400, 320, 3)  # 2 x 2 panels, ceil(327 / 3)
    assert abs(delays.sum() - 327 / 120 * 1000) <= 10
    np.testing.assert_array_equal(r.frames[:, 2], np.arange(0, 327, 3))
    # The 30 fps walker shows its frame nearest to the clock, then holds its last one.
    nearest = np.floor(np.arange(109) / r.fps * 30.0 + 0.5)
    np.testing.assert_array_equal(r.frames[:, 0], np.minimum(nearest, 35))
    for i, t in enumerate([walker, None, None]):
        centre = np.array([80 + 160 * (i % 2), 100 + 200 * (i // 2)])
        root = r.pixels[i][0][0]  # joint 0 of every track is its hips (followed root)
        assert np.abs(root - centre).max() < 60, f"panel {i}: root drawn at {root}, panel centre {centre}"
    # The empty fourth panel stays empty (white).
    assert not chromatic(frames[0][200:, 160:]).any()


def test_contacts_are_marked_only_in_contact(tmp_path, walker):
    P, _ = walker.world()
    feet = [walker.names.index("LeftFootSite"), walker.names.index("RightFootSite")]
    contacts = foot_contacts(P, 30.0, feet)
    track = track_from_motion(walker, contacts=contacts, contact_joints=feet)
    r = write_gif(track, tmp_path / "c.gif", size=SMALL)
    frames, _ = read_gif(r.path)
    rgb = frames.astype(int)
    yellow = (rgb[..., 0] > 200) & (rgb[..., 1] > 160) & (rgb[..., 2] < 90)  # CONTACT_FACE #ffd000
    for k in range(r.n_frames):
        on = track.contact_joints[contacts[k] >= 0.5]
        if len(on):
            x, y = r.pixels[0][k][on[0]].astype(int)
            assert yellow[k, y - 3:y + 4, x - 3:x + 4].any(), f"frame {k}: no contact mark at the foot"
        else:
            assert not yellow[k].any(), f"frame {k}: a contact mark without contact"
    assert contacts.any(axis=1).sum() >= 5 and (~contacts.any(axis=1)).sum() >= 5  # both cases tested
    off = read_gif(write_gif(track, tmp_path / "off.gif", size=SMALL, contacts=False).path)[0].astype(int)
    assert not ((off[..., 0] > 200) & (off[..., 1] > 160) & (off[..., 2] < 90)).any()


def test_trail_toggle(tmp_path):
    track = track_from_motion(synthetic_walker(n_frames=45, turn=0.8))
    with_trail = read_gif(write_gif(track, tmp_path / "a.gif", size=SMALL).path)[0]
    without = read_gif(write_gif(track, tmp_path / "b.gif", size=SMALL, trail=False).path)[0]
    assert (with_trail[0] == without[0]).all()  # no path walked yet at frame 0
    assert chromatic(with_trail[-1]).sum() > chromatic(without[-1]).sum() + 30
