"""The HTML player in a real browser (headless Chromium, opened from disk with file://).

Checked: it loads with no console error and no request outside the file; the canvas is not blank
and changes with time; the joint positions the page shows equal the BVH forward kinematics within
the int16 quantisation step the page itself reports (about 0.05 mm for a person).
"""
import io

import numpy as np
import pytest

from minifilm.motion.bvh import read_bvh
from minifilm.viewer import track_from_bvh, track_from_motion, write_html

from repo_paths import need_data
from viewer_helpers import foot_contacts, synthetic_walker

Image = pytest.importorskip("PIL.Image", reason="screenshots are compared with Pillow")
LOCAL = ("file:", "data:", "blob:")


class Page:
    """A player page opened in the browser, with everything it logged and requested."""

    def __init__(self, browser, path):
        self.messages, self.requests = [], []
        self.page = browser.new_page(viewport={"width": 960, "height": 540})
        self.page.on("console", lambda m: self.messages.append((m.type, m.text)))
        self.page.on("pageerror", lambda e: self.messages.append(("pageerror", str(e))))
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.goto(path.resolve().as_uri())
        self.page.wait_for_function("window.minifilmPlayer && window.minifilmPlayer.ready", timeout=15000)

    def js(self, expression, arg=None):
        return self.page.evaluate(expression, arg)

    def canvas(self) -> np.ndarray:
        """(H, W, 3) screenshot of the WebGL canvas."""
        png = self.page.locator("canvas").screenshot()
        return np.array(Image.open(io.BytesIO(png)).convert("RGB"))

    def errors(self):
        return [m for m in self.messages if m[0] in ("error", "pageerror")]


@pytest.fixture(scope="module")
def scene(browser, tmp_path_factory, shared_data):
    """One page with a real Bandai walk (30 fps) and a synthetic walker with foot contacts."""
    bvh = need_data(shared_data / "bandai2" / "dataset-2_walk_normal_001.bvh", "a real BVH")
    walker = synthetic_walker(n_frames=90, fps=60.0, turn=0.5)
    P, _ = walker.world()
    feet = [walker.names.index("LeftFootSite"), walker.names.index("RightFootSite")]
    tracks = [track_from_bvh(bvh, name="bandai normal"),
              track_from_motion(walker, name="walker", contacts=foot_contacts(P, 60.0, feet), contact_joints=feet)]
    path = tmp_path_factory.mktemp("html") / "player.html"
    write_html(tracks, path, title="viewer test")
    page = Page(browser, path)
    yield dict(page=page, bvh=bvh, walker=walker, tracks=tracks, path=path)
    page.page.close()


def test_page_loads_offline_without_errors(scene):
    page = scene["page"]
    assert page.errors() == []
    outside = [u for u in page.requests if not u.startswith(LOCAL)]
    assert outside == [], f"requests outside the file: {outside}"
    assert page.requests[0] == scene["path"].resolve().as_uri()
    assert page.js("minifilmPlayer.characters.map(c => c.name)") == ["bandai normal", "walker"]
    # Player clock at the highest rate (60 fps), as long as the longest track (273 frames at 30 fps).
    assert page.js("[minifilmPlayer.fps, minifilmPlayer.nFrames]") == [60.0, 546]


def test_canvas_is_not_blank_and_moves(scene):
    page = scene["page"]
    page.js("minifilmPlayer.play()")
    first, frame0 = page.canvas(), page.js("minifilmPlayer.frame")
    page.page.wait_for_timeout(600)
    second, frame1 = page.canvas(), page.js("minifilmPlayer.frame")
    assert frame1 != frame0  # the clock runs
    for image in (first, second):
        assert len(np.unique(image.reshape(-1, 3), axis=0)) > 50
        rgb = image.astype(int)
        assert (rgb.max(axis=-1) - rgb.min(axis=-1) > 60).sum() > 500  # coloured skeletons drawn
    assert (np.abs(first.astype(int) - second.astype(int)).max(axis=-1) > 30).sum() > 200
    # Two chosen moments differ too (independent of timing).
    page.js("minifilmPlayer.pause()")
    page.js("minifilmPlayer.setFrame(0)")
    a = page.canvas()
    page.js("minifilmPlayer.setFrame(45)")
    b = page.canvas()
    assert (np.abs(a.astype(int) - b.astype(int)).max(axis=-1) > 30).sum() > 200


@pytest.mark.parametrize("frame", [0, 37, 301, 545])
def test_shown_joints_are_the_bvh_forward_kinematics(scene, frame):
    page = scene["page"]
    page.js("minifilmPlayer.pause()")
    assert page.js("f => minifilmPlayer.setFrame(f)", frame) == frame
    motion = read_bvh(scene["bvh"])
    P, _ = motion.world()  # reference positions, computed without the viewer
    W, _ = scene["walker"].world()
    for i, (track, reference, fps) in enumerate([(scene["tracks"][0], P, 30.0), (scene["tracks"][1], W, 60.0)]):
        f = page.js("i => minifilmPlayer.characterFrame(i)", i)
        assert f == min(int(np.floor(frame / 60.0 * fps + 0.5)), track.n_frames - 1)
        names = motion.names if i == 0 else scene["walker"].names
        idx = [names.index(n) for n in track.joint_names]
        shown = np.array(page.js("i => minifilmPlayer.shownJoints(i)", i))
        step = page.js("i => minifilmPlayer.characters[i].step", i)
        assert step / 2 < 5e-5  # quantisation error bound: below 0.05 mm
        np.testing.assert_allclose(shown, reference[f, idx], rtol=0, atol=step / 2 + 1e-9)
        # In the scene, each character is only moved sideways into its lane.
        world = np.array(page.js("i => minifilmPlayer.shownWorldJoints(i)", i))
        offset = np.array(page.js("i => minifilmPlayer.characters[i].offset", i))
        np.testing.assert_allclose(world - offset, shown, atol=1e-9)


def test_toggles_change_the_picture(scene):
    page = scene["page"]
    page.js("minifilmPlayer.pause()")
    page.js("minifilmPlayer.setFrame(300)")
    page.js("minifilmPlayer.setFollow('off')")
    base = page.canvas()
    for name in ("trail", "labels"):
        page.js("n => minifilmPlayer.setToggle(n, false)", name)
        off = page.canvas()
        page.js("n => minifilmPlayer.setToggle(n, true)", name)
        assert (np.abs(base.astype(int) - off.astype(int)).max(axis=-1) > 30).sum() > 20, name
    assert page.errors() == []


def test_contacts_toggle_recolours_the_feet(scene):
    page = scene["page"]
    page.js("minifilmPlayer.pause()")
    contacts = scene["tracks"][1].contacts
    g = int(np.nonzero(contacts.any(axis=1))[0][0])  # the walker runs at the player's 60 fps
    page.js("g => minifilmPlayer.setFrame(g)", g)
    page.js("minifilmPlayer.setFollow(1)")
    on = page.canvas()
    page.js("minifilmPlayer.setToggle('contacts', false)")
    off = page.canvas()
    page.js("minifilmPlayer.setToggle('contacts', true)")

    def yellow(im):
        rgb = im.astype(int)
        return ((rgb[..., 0] > 180) & (rgb[..., 1] > 140) & (rgb[..., 2] < 80)).sum()
    assert yellow(on) > 10 and yellow(off) == 0


def test_the_mannequin_is_drawn_by_default_and_the_sticks_are_a_toggle(scene):
    """The shaded body (mannequin.js): limbs, joints, head and shadow per character, no console
    error; K shows the sticks, B hides the body, and the picture changes with each."""
    page = scene["page"]
    page.js("minifilmPlayer.pause()")
    page.js("minifilmPlayer.setFrame(120)")
    joints = sum(c["nJoints"] for c in page.js("minifilmPlayer.characters"))
    n = len(page.js("minifilmPlayer.characters"))
    meshes = page.js("minifilmPlayer.visibleMeshes()")
    # per character up to a limb per bone (J - 1) and a ball per joint (J) (none for joints inside
    # the head: an end site above it, the eyes), a head, a nose and a shadow
    assert joints + 3 * n <= meshes["body"] <= 2 * joints + 2 * n and meshes["sticks"] == 0, meshes
    body = page.canvas()
    page.page.keyboard.press("KeyB")                   # body off: the sticks take its place
    assert page.js("minifilmPlayer.visibleMeshes()") == {"body": 0, "sticks": 2 * joints - n}
    sticks = page.canvas()
    page.page.keyboard.press("KeyK")                   # sticks on as well: nothing left off...
    page.page.keyboard.press("KeyB")                   # ...body back, sticks kept
    assert page.js("minifilmPlayer.visibleMeshes()") == {"body": meshes["body"], "sticks": 2 * joints - n}
    page.js("minifilmPlayer.setToggle('sticks', false)")
    # a body covers more of the picture than sticks do
    background = np.array([0xf4, 0xf5, 0xf7])
    covered = lambda im: (np.abs(im.astype(int) - background).max(axis=-1) > 40).sum()  # noqa: E731
    assert covered(body) > 1.5 * covered(sticks), (covered(body), covered(sticks))
    assert page.errors() == []
