"""The demo page in a real browser: headless Chromium, and ``minifilm demo --port 0`` in a process
of its own on 127.0.0.1, as a user runs it (in the test's process, the test's multi-threaded BLAS
and the browser driver's work on the GIL slowed the frame loop several times over).

Checked: it loads with no console error and makes no request off 127.0.0.1; holding W for 2 s
of the character's time (120 network steps) walks its root at least 1 m along its facing; holding D moves it to its right;
choosing another style changes the motion; the blend triangle at a corner is exactly that
style (the frames carry a fingerprint of the FiLM vector that made them); toggles and a gamepad
reach the server; closing the tab frees the character for another page. The motion checks need
the authors' released network (a miniature model trained in a second does not follow commands);
without it the page is served from a miniature run folder and they skip. Every wait is for a
condition (the frames the page shows), never for a length of wall time: keys are held for a number
of the character's steps (``DemoPage.hold``), so a loaded machine is only slower.
"""
import importlib.util
import io
import time

import numpy as np
import pytest
from demo_helpers import RELEASED, DemoPage
from repo_paths import need_data

from minifilm.demo.client import DemoClient
from minifilm.demo.process import DemoProcess

Image = pytest.importorskip("PIL.Image", reason="screenshots are read with Pillow")
HAS_RELEASED = (RELEASED / "Xmean.bin").is_file()
NEEDS_RELEASED = f"needs the released network at {RELEASED}: a miniature run does not follow commands"


@pytest.fixture
def released():
    """For the tests that steer: the released network must be there (skipped on a user's machine
    without the shared data, failed in CI, which has it; see repo_paths.need_data)."""
    need_data(RELEASED / "Xmean.bin", NEEDS_RELEASED)


@pytest.fixture(scope="module")
def server(request):
    source = ["--params", RELEASED] if HAS_RELEASED else ["--run", request.getfixturevalue("tiny_run")]
    s = DemoProcess(*source, "--max-characters", 4)
    if HAS_RELEASED:       # the start style's speed calibration (from the package) is read on a thread: wait for it
        with DemoClient(s.url) as page:
            page.wait_for(lambda m: m.get("type") == "frame" and m["calibration"]["state"] != "measuring", 900)
    yield s
    s.stop()


@pytest.fixture
def page(browser, server):
    p = DemoPage(browser, server.url)
    yield p
    p.close()


def settle(page, steps=36):
    """Let the character go on for ``steps`` network steps (its own time: 36 are 0.6 s of motion)."""
    page.steps_on(steps)


def unfold(page, section):
    """Open a folded section of the panel as a user does, with a click on its title (a short
    window starts with some folded)."""
    if not page.js(f"document.getElementById('{section}').open"):
        page.page.click(f"#{section} summary")
    assert page.js(f"document.getElementById('{section}').open")


def right_of(facing):
    return np.array([-facing[1], facing[0]])        # the character's right (see minifilm/demo/steering.py)


def test_page_loads_without_errors_and_requests_nothing_off_this_machine(page, server):
    assert page.errors() == []
    local = f"http://127.0.0.1:{server.port}/"
    outside = [u for u in page.requests if not (u.startswith(local) or u.startswith("data:"))]
    assert outside == [], f"requests off the demo server: {outside}"
    assert page.requests[0] == local and page.sockets == [f"ws://127.0.0.1:{server.port}/ws"]
    hello = page.js("minifilmDemo.hello")
    assert len(hello["styles"]) == (100 if HAS_RELEASED else 2) and hello["fps"] == pytest.approx(60, rel=1e-6)
    # every style, plus the entry that shows a blend (empty value, hidden until there is one)
    assert page.js("[...document.getElementById('style').options].filter(o => o.value).length") == len(hello["styles"])
    image = np.array(Image.open(io.BytesIO(page.page.locator("#view canvas").screenshot())).convert("RGB")).astype(int)
    assert ((image.max(axis=-1) - image.min(axis=-1)) > 60).sum() > 300     # the coloured skeleton is drawn
    assert page.errors() == []


def test_holding_w_for_two_seconds_walks_a_metre_along_the_facing(page, released):
    settle(page)
    before, after = page.hold("KeyW", 120)
    step = np.subtract(after["root"], before["root"])
    assert step @ np.array(before["facing"]) >= 1.0, (before, after)
    assert page.frame()["ack"] is not None and page.errors() == []


def test_holding_d_moves_the_character_to_its_right(page, released):
    settle(page)
    before, after = page.hold("KeyD", 120)
    step = np.subtract(after["root"], before["root"])
    facing = np.array(before["facing"])
    assert step @ right_of(facing) > 0.3 and step @ right_of(facing) > abs(step @ facing), (before, after)


def test_choosing_another_style_changes_the_motion(page, released):
    joints = page.js("minifilmDemo.hello.joints")
    wrists = [joints.index("LeftWrist"), joints.index("RightWrist")]
    head = joints.index("Head")

    def hands_below_head(steps=60):
        """The mean over ten frames spread over ``steps`` network steps (a second of motion)."""
        values = []
        for _ in range(10):
            p = np.array(page.steps_on(steps // 10)["positions"]).reshape(-1, 3)
            values.append(p[head, 1] - p[wrists, 1].mean())
        return float(np.mean(values))

    page.page.keyboard.down("KeyW")
    settle(page, 60)
    neutral = hands_below_head()
    page.page.select_option("#style", "ArmsAboveHead")
    page.wait("minifilmDemo.frame.weights.ArmsAboveHead === 1")
    settle(page, 60)
    raised = hands_below_head()
    page.page.keyboard.up("KeyW")
    assert neutral > 0.5 and raised < neutral - 0.4, (neutral, raised)   # the hands go up above the head


def test_the_blend_triangle_at_a_corner_is_exactly_that_style(page):
    hello = page.js("minifilmDemo.hello")
    names = (hello["styles"] * 3)[:3]
    unfold(page, "sec-blend")
    page.page.select_option("#corner0", names[0])
    page.page.select_option("#corner1", names[1])
    page.page.select_option("#corner2", names[2])
    page.js("minifilmDemo.send({type: 'settings', fit: true})")          # the corner selects sent a blend
    page.page.locator("#triangle").scroll_into_view_if_needed()
    x, y = page.js("minifilmDemo.corner(1)")
    page.page.mouse.click(x, y)                                          # a real click on the left corner
    page.wait(f"JSON.stringify(minifilmDemo.frame.weights) === '{{\"{names[1]}\":1}}'")
    assert page.frame()["target"] == {names[1]: 1.0}
    assert page.frame()["film"] == hello["films"][names[1]]              # bit for bit the pure style's vector
    # the middle of the triangle: a third of each, as the paper's barycentric blend
    corners = np.array([page.js(f"minifilmDemo.corner({i})") for i in range(3)])
    page.page.mouse.click(*corners.mean(axis=0))
    expected = {}
    for name in names:                                                   # a style at two corners counts twice
        expected[name] = expected.get(name, 0.0) + 1 / 3
    page.wait(f"Object.keys(minifilmDemo.frame.target).length === {len(expected)} && "
              f"!('{names[1]}' in minifilmDemo.frame.target && minifilmDemo.frame.target['{names[1]}'] === 1)")
    target = page.frame()["target"]
    assert target.keys() == expected.keys() and all(abs(target[n] - w) < 0.02 for n, w in expected.items())


def test_toggles_reach_the_server(page):
    assert page.frame()["fit"] is True and page.frame()["footLock"] is False
    page.page.check("#footLock")
    page.page.uncheck("#fit")
    page.wait("minifilmDemo.frame.footLock === true && minifilmDemo.frame.fit === false")
    assert page.errors() == []


GAMEPAD = """
navigator.getGamepads = () => [{ connected: true, axes: [0, -1, 0, 0],
                                buttons: Array.from({length: 8}, () => ({ value: 0, pressed: false })) }];
"""


def test_a_gamepads_left_stick_moves_the_character(browser, server):
    p = DemoPage(browser, server.url, init_script=GAMEPAD)                   # a pad held forward, from the start
    try:
        p.wait("minifilmDemo.frame.commanded > 0")
        f = p.frame()
        assert f["velocity"] == pytest.approx(list(f["commanded"] * np.array(f["heading"])), abs=1e-3)
    finally:
        p.close()


PAD_TURNING_AND_RUNNING = """
navigator.getGamepads = () => [{ connected: true, axes: [0, -1, 1, 0],
                                buttons: Array.from({length: 8}, (_, i) => ({ value: i === 7 ? 1 : 0,
                                                                             pressed: i === 7 })) }];
"""


def test_a_gamepads_right_stick_turns_and_its_trigger_runs(browser, server):
    # right stick fully right: the heading turns (clockwise seen from above, as E) at the turn rate
    # per step of the character; right trigger fully pressed: the commanded speed is the run speed
    p = DemoPage(browser, server.url, init_script=PAD_TURNING_AND_RUNNING, keep_frames=True)
    try:
        run_speed, rate = p.js("minifilmDemo.hello.speeds.run"), p.js("minifilmDemo.hello.turnRate")
        fps = p.js("minifilmDemo.hello.fps")
        held = lambda: [f for f in p.frames if f["commanded"] > 0.99 * run_speed]  # noqa: E731
        p.wait(lambda: held() and held()[-1]["n"] >= held()[0]["n"] + 75, timeout=120, poll=0.1)
        # two frames 15-75 steps apart (a quarter to 1.25 s of the character's time: a turn of
        # 30-150 degrees, whose direction a heading read modulo a full turn still shows). Frames
        # are never more than a batch (30 steps) apart, so such a pair is there however loaded
        # the machine; the page's clock plays no part
        first = held()[0]
        later = next(f for f in held() if first["n"] + 15 <= f["n"] <= first["n"] + 75)
        theta = lambda f: np.arctan2(*f["heading"])                # heading (sin θ, cos θ); right lowers θ
        turned = np.degrees(np.angle(np.exp(1j * (theta(later) - theta(first)))))
        expected = -rate * (later["n"] - first["n"]) / fps
        assert abs(turned - expected) < 0.5, (turned, expected)   # (headings are sent to 1e-4)
        assert p.frame()["commanded"] == pytest.approx(run_speed, rel=1e-3)
        assert p.errors() == []
    finally:
        p.close()


def test_closing_the_tab_frees_its_character(browser, server):
    tab = DemoPage(browser, server.url)
    others = [DemoClient(server.url) for _ in range(3)]           # with the tab: all 4 characters taken
    try:
        with DemoClient(server.url) as fifth:
            assert fifth.hello["type"] == "refused" and "in use" in fifth.hello["message"]
        tab.close()                                                # the tab's character is freed
        for _ in range(100):
            with DemoClient(server.url) as again:
                if again.hello["type"] == "hello":
                    break
            time.sleep(0.05)                                       # the server has not seen the close yet
        assert again.hello["type"] == "hello"
    finally:
        for c in others:
            c.close()


# ---- the page as a user reads it ------------------------------------------------------------

DASH = "\u2014"


def readouts(page) -> dict:
    return page.js("Object.fromEntries([...document.querySelectorAll('#readouts td')].map(t => [t.id, t.textContent]))")


def test_read_outs_show_a_dash_until_they_have_data(page):
    # no key pressed yet: the page has sent nothing, so there is no input -> motion time to show
    settle(page, 90)
    assert page.js("minifilmDemo.sent") == 0 and page.js("minifilmDemo.latencyMs") is None
    values = readouts(page)
    assert values["latency"] == DASH, values
    assert values["fps"].endswith(" / s") and values["commanded"].endswith(" m/s"), values
    page.hold("KeyW", 30)
    page.wait(f"document.getElementById('latency').textContent !== '{DASH}'")
    assert readouts(page)["latency"].endswith(" ms") and page.js("minifilmDemo.latencyMs") > 0


def test_the_trail_stays_drawn_after_ten_seconds_of_walking(page, released):
    # ten seconds of the character's walk, and on until 100 frames have reached the page (a point
    # each): a loaded machine sends one frame per batch of up to 30 steps, so 600 steps may bring
    # only 20; the page's clock plays no part
    page.hold("KeyW", 600, until="minifilmDemo.trail().count >= 100", until_timeout=600)
    trail = page.js("minifilmDemo.trail()")
    points = np.array(trail["points"]).reshape(-1, 3)
    assert trail["count"] == len(points) >= 100                       # drawn: the whole kept path
    assert np.hypot(*(points[-1, [0, 2]] - points[0, [0, 2]])) > 4.0   # and it reaches far from the start
    # three.js draws the line only if its bounds are in view (or it is never culled)
    assert trail["inView"] and (trail["boundsHoldLast"] or not trail["culled"]), trail
    assert page.errors() == []


def test_back_to_the_start_leaves_no_stray_segment(page, released):
    page.hold("KeyW", 180)
    page.page.click("#reset")
    page.wait("minifilmDemo.frame.ack !== null && Math.hypot(...minifilmDemo.frame.root) < 0.3")
    settle(page, 30)
    page.wait("minifilmDemo.trail().count > 5")                       # a point per frame the page gets
    points = np.array(page.js("minifilmDemo.trail()")["points"]).reshape(-1, 3)[:, [0, 2]]
    steps = np.hypot(*np.diff(points, axis=0).T)
    assert len(points) > 5 and np.hypot(*points[0]) < 0.3, points[:3]   # the path starts again at the start
    assert steps.max() < 0.2, steps.max()                                # no line back from where it was


def test_the_mannequin_draws_and_the_sticks_are_a_toggle(page):
    meshes = page.js("minifilmDemo.visibleMeshes()")
    J = len(page.js("minifilmDemo.hello.parents"))
    assert meshes["body"] >= 2 * J and meshes["sticks"] == 0, meshes  # limbs, joints, head, shadow
    page.page.keyboard.press("KeyK")                                    # sticks on, over the body
    page.wait("minifilmDemo.visibleMeshes().sticks > 0")
    page.page.keyboard.press("KeyB")                                    # body off: sticks only
    page.wait("minifilmDemo.visibleMeshes().body === 0")
    page.page.uncheck("#sticks")                                        # neither: the sticks stay
    assert page.js("minifilmDemo.visibleMeshes().sticks") == 2 * J - 1
    page.page.check("#body")
    image = np.array(Image.open(io.BytesIO(page.page.locator("#view canvas").screenshot())).convert("RGB")).astype(int)
    assert ((image.max(axis=-1) - image.min(axis=-1)) > 40).sum() > 1000   # a shaded body, not thin lines
    assert page.errors() == []


def test_the_picker_and_the_label_show_the_mix_after_a_blend(page):
    names = page.js("minifilmDemo.hello.styles")
    a, b, c = (["Neutral", "Old", "Zombie"] if "Old" in names else (names * 3)[:3])
    assert page.js("minifilmDemo.label().text") == page.js("Object.keys(minifilmDemo.frame.target)[0]")
    page.js(f"minifilmDemo.setCorners(['{a}', '{b}', '{c}'])")
    page.js("minifilmDemo.setBlend([0.6, 0.4, 0])")
    expected = f"{a} 60 % + {b} 40 %" if a != b else a
    page.wait(f"document.getElementById('style').selectedOptions[0].textContent === '{expected}'", timeout=30)
    # once the 1 s transition is over (longer in wall time when a busy machine slows the frame loop)
    page.wait(f"minifilmDemo.label().text === '{expected}'", timeout=30)
    label, root = page.js("minifilmDemo.label().position"), page.frame()["root"]
    assert abs(label[0] - root[0]) < 0.3 and abs(label[2] - root[1]) < 0.3 and label[1] > 1.2   # above the head
    page.page.select_option("#style", c)                                  # one style again
    page.wait(f"document.getElementById('style').selectedOptions[0].textContent === '{c}'", timeout=30)


def test_the_search_box_filters_the_styles_and_names_the_held_out_ones(page, released):
    assert page.js("minifilmDemo.search('zomb')") == ["Zombie"]
    assert page.js("document.getElementById('found').textContent") == "1 of 100 styles"
    # the five fine-tuned ids say what they are, and are found by it
    assert page.js("minifilmDemo.search('held-out')") == ["095", "096", "097", "098", "099"]
    shown = page.js("[...document.querySelectorAll('#style option')].filter(o => !o.hidden).map(o => o.textContent)")
    names = ["Roadrunner", "ShieldedLeft", "Skip", "Star", "WildArms"]
    assert shown == [f"09{5 + i} (probably {n}, held-out)" for i, n in enumerate(names)]
    assert page.js("minifilmDemo.search('skip')") == ["097"]
    page.page.fill("#search", "arms above")
    page.page.press("#search", "Enter")                                  # Enter picks the first one left
    page.wait("minifilmDemo.frame.target.ArmsAboveHead === 1")
    page.page.fill("#search", "")
    page.page.dispatch_event("#search", "input")
    assert page.js("[...document.querySelectorAll('#style option')].filter(o => !o.hidden).length") == 100


def test_the_camera_switch_moves_the_camera(page):
    def seen_from():
        """(mode, cosine of the camera's bearing from the character with its heading, camera position)"""
        cam = page.js("minifilmDemo.camera()")
        offset = np.subtract(cam["position"], cam["target"])[[0, 2]]
        return cam["mode"], offset @ np.array(page.frame()["heading"]) / np.hypot(*offset), cam["position"]

    def until(check, timeout=20.0):      # the camera swings over about a second of drawn frames
        for _ in range(int(timeout / 0.1)):
            seen = seen_from()
            if check(*seen):
                return seen
            page.page.wait_for_timeout(100)
        raise AssertionError(f"camera not there within {timeout} s: {seen}")

    until(lambda mode, along, _: mode == "follow" and along < -0.5)                  # behind the character
    page.page.keyboard.press("Digit2")
    _, _, front = until(lambda mode, along, _: mode == "front" and along > 0.9)        # in front of it
    page.page.click("#cam-side")
    _, _, side = until(lambda mode, along, _: mode == "side" and abs(along) < 0.2)     # beside it
    assert np.linalg.norm(np.subtract(front, side)) > 1.0
    page.page.keyboard.press("KeyP")                                     # pause: the picture stops
    assert page.js("minifilmDemo.paused") is True
    shown = page.js("minifilmDemo.shownJoints()")
    settle(page, 30)
    assert page.js("minifilmDemo.shownJoints()") == shown
    page.page.keyboard.press("KeyP")
    assert page.js("minifilmDemo.paused") is False and page.errors() == []


def test_record_downloads_a_bvh_that_minifilm_reads_back(page, tmp_path):
    from minifilm.motion.bvh import read_bvh
    page.wait("minifilmDemo.frame.n > 330", timeout=60)                 # the character has shown over 5 s
    unfold(page, "sec-record")
    page.page.select_option("#recordSeconds", "5")
    with page.page.expect_download(timeout=120000) as download:
        page.page.click("#record")
    path = tmp_path / download.value.suggested_filename
    download.value.save_as(path)
    assert path.suffix == ".bvh" and path.name.startswith("minifilm-")
    motion = read_bvh(path)
    assert motion.n_frames == 300 and motion.frame_time == pytest.approx(1 / 60, rel=1e-4)
    P, _ = motion.world()
    height = P[:, :, 1].max(axis=1) - P[:, :, 1].min(axis=1)            # whatever the file's unit
    assert np.all(height > 0) and height.std() / height.mean() < 0.2   # one upright body all along
    rec = page.js("minifilmDemo.lastRecording")
    assert rec["frames"] == 300 and rec["seconds"] == pytest.approx(5.0)
    assert "saved" in page.js("document.getElementById('recordStatus').textContent")
    # then the GIF (drawn on the server in a process of its own), or a note saying why there is none
    page.wait("minifilmDemo.lastRecording.gif !== 'coming'", timeout=240)
    rec = page.js("minifilmDemo.lastRecording")
    has_gif_tools = all(importlib.util.find_spec(m) is not None for m in ("PIL", "matplotlib"))
    if has_gif_tools:
        assert rec["gif"] > 1000 and page.js("document.querySelector('#recordStatus a').download") == rec["name"] + ".gif"
    else:
        assert rec["gif"] is None and "BVH only" in rec["note"]
    assert page.errors() == []
