"""The demo page's view and panel in headless Chromium, driven with real key presses and clicks
(``minifilm demo --port 0`` in a process of its own, as in test_demo_browser.py).

Checked: the camera swings behind the body's facing, not the steered heading, while Q runs the
heading ahead of the body; the path ahead (predicted trajectory and the held keys' path) is drawn
and the checkbox and T hide and show it; the "real time" row gives the steps per second and says
when the loop is behind or dropped steps (slow motion); at 800 x 600 (and larger) every control of
the panel is in the window (foot locking and "back to the start" included) and a speed note moves
none of the read-outs; the character has the same colour on every connection. Every wait is for a
condition, never for a length of time, so a loaded machine is only slower.
"""
import io
import math

import numpy as np
import pytest
from demo_helpers import RELEASED, DemoPage

from minifilm.demo.frame_loop import MAX_BATCH
from minifilm.demo.process import DemoProcess

Image = pytest.importorskip("PIL.Image", reason="screenshots are read with Pillow")
HAS_RELEASED = (RELEASED / "Xmean.bin").is_file()


@pytest.fixture(scope="module")
def server(request):
    # the released network when it is there (its calibration is not waited for: nothing here
    # depends on speeds), else a miniature run, whose body hardly turns at all: both let the
    # heading run ahead of the body on Q
    source = ["--params", RELEASED] if HAS_RELEASED else ["--run", request.getfixturevalue("tiny_run")]
    s = DemoProcess(*source, "--max-characters", 4)
    yield s
    s.stop()


@pytest.fixture
def page(browser, server):
    p = DemoPage(browser, server.url)
    yield p
    p.close()


def bearing(v) -> float:
    return math.atan2(v[0], v[1])          # (sin theta, cos theta) -> theta, as steering.py


def apart(a: float, b: float) -> float:
    """Degrees between two angles (radians), 0..180."""
    return abs(math.degrees(math.remainder(a - b, 2 * math.pi)))


def test_the_camera_follows_the_bodys_facing_not_the_heading(page):
    """Q turns the heading at 120 deg/s; the body follows later (or, on a miniature run, hardly at
    all). Whenever the heading is well ahead of the body, the camera swings towards the place behind
    the body, and once the body is still it is there."""
    look = "(() => ({cam: minifilmDemo.camera(), facing: minifilmDemo.frame.facing}))()"
    page.wait("minifilmDemo.camera().goal !== null")
    page.page.keyboard.down("KeyQ")
    seen = []
    try:
        for _ in range(400):                    # until 10 drawn frames with the heading > 45 deg ahead
            cam = page.js("minifilmDemo.camera()")
            if apart(bearing(cam["facing"]), bearing(cam["heading"])) > 45:
                seen.append(cam)
                if len(seen) >= 10:
                    break
            page.page.wait_for_timeout(50)
    finally:
        page.page.keyboard.up("KeyQ")
    assert len(seen) >= 10, "the heading never ran 45 degrees ahead of the body"
    for cam in seen:                            # the facing and heading of the frame the camera was aimed by
        behind_body = bearing(cam["facing"]) + math.pi + cam["offset"]
        behind_heading = bearing(cam["heading"]) + math.pi + cam["offset"]
        assert apart(cam["goal"], behind_body) < 1e-6, cam
        assert apart(cam["goal"], behind_heading) > 45, cam
    # nothing held: once the body has stopped turning, the camera is behind it (smoothly reached)
    for _ in range(600):
        a = page.js(look)
        page.page.wait_for_timeout(200)
        b = page.js(look)
        body_still = apart(bearing(a["facing"]), bearing(b["facing"])) < 0.5 and b["cam"]["facing"] == b["facing"]
        if body_still and apart(b["cam"]["azimuth"], bearing(b["facing"]) + math.pi + b["cam"]["offset"]) < 3:
            break
    else:
        raise AssertionError(f"the camera did not come to rest behind the body: {b}")
    assert page.errors() == []


PATH_INK = np.array([0x2b, 0x30, 0x40])         # the predicted trajectory's dots and ticks (demo.js)


def path_pixels(page) -> int:
    image = np.array(Image.open(io.BytesIO(page.page.locator("#view canvas").screenshot())).convert("RGB")).astype(int)
    return int((np.abs(image - PATH_INK).max(axis=-1) <= 10).sum())


def test_the_path_ahead_is_drawn_and_the_checkbox_and_t_toggle_it(page):
    page.wait("minifilmDemo.pathAhead().dots.length === 6")
    drawn = page.js("minifilmDemo.pathAhead()")
    root = page.js("minifilmDemo.frame.root")
    assert drawn["visible"] is True and page.page.is_checked("#path")
    assert np.hypot(drawn["dots"][0][0] - root[0], drawn["dots"][0][2] - root[1]) < 0.3   # from the character
    assert len(drawn["path"]) == 3 * 11
    shown = path_pixels(page)
    assert shown > 30, shown                                             # dots and ticks on screen
    page.page.keyboard.press("KeyT")
    assert page.js("minifilmDemo.pathAhead().visible") is False and not page.page.is_checked("#path")
    since = page.js("performance.now()")
    page.wait(f"minifilmDemo.drawIntervals({since}).length >= 2")      # drawn since
    hidden = path_pixels(page)
    assert hidden < shown / 3, (shown, hidden)
    page.page.click("#path")                                             # the checkbox brings it back...
    assert page.js("minifilmDemo.pathAhead().visible") is True
    page.page.keyboard.press("KeyT")                                     # ...and T still works after it
    assert page.js("minifilmDemo.pathAhead().visible") is False
    page.page.keyboard.press("KeyT")
    # held W: the keys' path reaches a metre or so ahead of the character, along its heading
    page.page.keyboard.down("KeyW")
    try:
        page.wait("minifilmDemo.frame.commanded > 0")
        f = page.js("minifilmDemo.frame")
        path = np.reshape(page.js("minifilmDemo.frame.path"), (-1, 2))
        assert (path[-1] - path[0]) @ np.array(f["heading"]) > 0.5 * f["reachable"]
    finally:
        page.page.keyboard.up("KeyW")
    assert page.errors() == []


PANEL_CONTROLS = ("#panel input, #panel select, #panel button, #panel summary, #panel td, #panel canvas, "
                  "#panel label, #speedNote")


def boxes(page, selector=PANEL_CONTROLS):
    """[id or tag, left, top, right, bottom, shown] of every element matched (shown: drawn, not
    inside a folded section; the browser still lays those out, hidden)."""
    return page.js(f"""[...document.querySelectorAll({selector!r})].map(e => {{
        const r = e.getBoundingClientRect();
        return [e.id || e.tagName + ':' + e.textContent.trim().slice(0, 20), r.left, r.top, r.right, r.bottom,
                r.width > 0 && r.height > 0 && e.checkVisibility()];
    }})""")


@pytest.mark.parametrize("width,height", [(800, 600), (1024, 768), (1280, 900)])
def test_the_whole_panel_is_in_the_window(browser, server, width, height):
    p = DemoPage(browser, server.url, width, height)
    try:
        panel = p.js("(() => { const e = document.getElementById('panel'); return [e.scrollHeight, e.clientHeight,"
                     " e.scrollWidth, e.clientWidth]; })()")
        assert panel[0] <= panel[1] and panel[2] <= panel[3], panel           # nothing below or beside the fold
        shown = [b for b in boxes(p) if b[5]]
        outside = [b for b in shown if b[1] < 0 or b[2] < 0 or b[3] > width or b[4] > height]
        assert outside == [], outside
        names = {b[0] for b in shown}
        for needed in ("footLock", "fit", "reset", "commanded", "reachable", "actual", "path", "body", "sticks",
                       "style", "search", "cam-follow", "phase0"):
            assert needed in names, (needed, sorted(names))
        # a folded section opens with a click on its title; foot locking and the reset stay in view
        folded = p.js("[...document.querySelectorAll('#panel details:not([open])')].map(d => d.id)")
        assert (width, height) != (800, 600) or folded == ["sec-blend", "sec-record"], folded
        if "sec-blend" in folded:
            p.page.click("#sec-blend summary")
            assert p.js("document.getElementById('sec-blend').open") is True
        p.page.locator("#triangle").wait_for(state="visible")
        for b in boxes(p, "#footLock, #reset"):
            assert b[5] and 0 <= b[2] and b[4] <= height, b
        # keys still reach the page after that click
        p.page.keyboard.press("KeyT")
        assert p.js("minifilmDemo.pathAhead().visible") is False
        assert p.errors() == []
    finally:
        p.close()


NOTE = ("Neutral 50 % + Old 50 % goes at most 1.80 m/s this way (its speed calibration): the 2.80 m/s asked "
        "for is scaled to 1.71")


def rewriting(**fields):
    """A route for the page's socket through the test: after the page's first input message, every
    frame from the server carries ``fields`` (as the server sends them in the case shown)."""
    import json

    def route(ws):
        server = ws.connect_to_server()
        state = {"on": False}

        def to_server(message):
            if '"input"' in message:
                state["on"] = True
            server.send(message)

        def to_page(message):
            if state["on"] and '"type":"frame"' in message:
                f = json.loads(message)
                f.update(fields)
                message = json.dumps(f)
            ws.send(message)
        ws.on_message(to_server)
        server.on_message(to_page)
    return route


with_speed_note = rewriting(speedNote=NOTE, reachable=1.7123, maxSpeed=1.8, commanded=12.3456)


def test_a_speed_note_moves_none_of_the_read_outs(browser, server):
    p = DemoPage(browser, server.url, 800, 600, route=with_speed_note)
    try:
        p.wait("document.getElementById('commanded').textContent.endsWith('m/s')")
        before = boxes(p)
        p.page.keyboard.down("KeyW")                    # the first input: from now on the frames carry the note
        p.wait(f"document.getElementById('speedNote').textContent === {NOTE!r}")
        p.wait("document.getElementById('commanded').textContent === '12.35 m/s'")
        after = boxes(p)
        p.page.keyboard.up("KeyW")
        moved = [(a, b) for a, b in zip(before, after) if np.abs(np.subtract(a[1:5], b[1:5])).max() > 0.5]
        assert len(before) == len(after) and moved == [], moved
        assert p.js("document.getElementById('reachable').textContent") == "1.71 m/s"
        note = boxes(p, "#speedNote")[0]
        assert note[5] and note[4] <= 600
        assert p.errors() == []
    finally:
        p.close()


def test_the_character_has_the_same_colour_on_every_connection(browser, server):
    first = DemoPage(browser, server.url)
    try:
        ident, colour = first.js("minifilmDemo.hello.id"), first.js("minifilmDemo.shownColour()")
    finally:
        first.close()
    second = DemoPage(browser, server.url)
    try:
        assert second.js("minifilmDemo.hello.id") != ident                 # another character...
        assert second.js("minifilmDemo.shownColour()") == colour            # ...the same colour
    finally:
        second.close()


def test_the_real_time_row_says_the_steps_per_second_and_when_it_falls_behind(browser, server):
    p = DemoPage(browser, server.url)
    try:      # as the server sends it: its own steps per second, no warning while none is dropped
        # the read-outs are redrawn 10 times a second from the newest frame: wait for one that shows it
        # (and that made steps in its last second: on a loaded machine a second can pass without one)
        p.wait("(() => { const f = minifilmDemo.frame, row = document.getElementById('realtime'); return f && "
               "f.stepsPerSecond > 0 && row.textContent.startsWith(`${f.stepsPerSecond} steps / s`) && "
               "row.classList.contains('warn') === (f.dropped > 0); })()", timeout=120)
        rate, fps = p.js("minifilmDemo.frame.stepsPerSecond"), p.js("minifilmDemo.hello.fps")
        # a batch runs steps that fell due up to MAX_BATCH steps before it: after a stall of a
        # loaded machine a second of the clock may hold that many more than fps, never more
        assert 0 < rate <= fps + MAX_BATCH + 1, rate
    finally:
        p.close()
    cases = [(dict(stepsPerSecond=48, behind=20, dropped=0), "48 steps / s, 20 behind, catching up", False),
             (dict(stepsPerSecond=31, behind=30, dropped=12),
              "31 steps / s: 12 dropped in the last second, slow motion (the machine is too busy)", True)]
    for fields, said, warned in cases:
        p = DemoPage(browser, server.url, route=rewriting(**fields))
        try:
            p.wait("document.getElementById('commanded').textContent.endsWith('m/s')")
            p.page.keyboard.down("KeyW")                # the first input: from now on the frames say so
            p.wait(f"document.getElementById('realtime').textContent === {said!r}")
            p.page.keyboard.up("KeyW")
            assert ("warn" in p.js("document.getElementById('realtime').className")) is warned
            assert p.errors() == []
        finally:
            p.close()
