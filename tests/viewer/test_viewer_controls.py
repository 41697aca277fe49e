"""The HTML player's keys after a click on its controls, and its names with many characters side by
side (headless Chromium, real mouse clicks and key presses, the page opened from disk).

Checked: after a click on any checkbox (or the speed and follow lists), Space plays/pauses
without toggling that checkbox, the arrows step one frame, B and K switch the body and the
sticks; with eight characters side by side (as the training job's player shows its eight styles)
no two names overlap on screen at any window size, and where the page says a name is drawn is
where three.js's own ray test finds it.
"""
import numpy as np
import pytest

from minifilm.viewer import track_from_motion, write_html
from viewer_helpers import foot_contacts, synthetic_walker

# the training job's eight synthetic styles (minifilm/synthetic/styles.py), long names included
NAMES = ["Neutral", "PendulumHands", "LeftHop", "Limp", "HandsAbove", "Crouched", "Swimming", "Drunk"]


def open_player(browser, path, width=960, height=540):
    page = browser.new_page(viewport={"width": width, "height": height})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.goto(path.resolve().as_uri())
    page.wait_for_function("window.minifilmPlayer && window.minifilmPlayer.ready", timeout=30000)
    return page, errors


@pytest.fixture(scope="module")
def one_walker(tmp_path_factory):
    walker = synthetic_walker(n_frames=60, fps=30.0)
    P, _ = walker.world()
    feet = [walker.names.index("LeftFootSite"), walker.names.index("RightFootSite")]
    path = tmp_path_factory.mktemp("keys") / "player.html"
    write_html([track_from_motion(walker, name="walker", contacts=foot_contacts(P, 30.0, feet), contact_joints=feet)],
               path, title="keys test")
    return path


@pytest.fixture(scope="module")
def eight_up(tmp_path_factory):
    tracks = [track_from_motion(synthetic_walker(n_frames=60, fps=30.0, speed=0.8 + 0.1 * i), name=n)
              for i, n in enumerate(NAMES)]
    path = tmp_path_factory.mktemp("eight") / "player.html"
    write_html(tracks, path, title="eight styles")
    return path


@pytest.mark.parametrize("control", ["body", "sticks", "contacts", "trail", "labels", "speed", "follow"])
def test_keys_drive_the_player_after_a_click_on_a_control(browser, one_walker, control):
    page, errors = open_player(browser, one_walker)
    try:
        player = lambda expr: page.evaluate(f"window.minifilmPlayer.{expr}")   # noqa: E731
        page.keyboard.press("Space")                                   # paused, on a known frame
        assert player("playing") is False
        page.evaluate("window.minifilmPlayer.setFrame(5)")
        is_box = control not in ("speed", "follow")
        if is_box:
            before = page.is_checked(f"#{control}")
            page.click(f"#{control}")
            assert page.is_checked(f"#{control}") is not before         # the click itself toggled it
        else:
            page.select_option(f"#{control}", index=1)
            page.click(f"#{control}")                                 # opens the list...
            page.keyboard.press("Escape")                               # ...and closes it, focused
        state = page.is_checked(f"#{control}") if is_box else None
        page.keyboard.press("ArrowRight")
        assert player("frame") == 6
        page.keyboard.press("ArrowLeft")
        page.keyboard.press("ArrowLeft")
        assert player("frame") == 4
        page.keyboard.press("Space")
        assert player("playing") is True
        page.keyboard.press("Space")
        assert player("playing") is False
        if is_box:
            assert page.is_checked(f"#{control}") is state              # Space did not toggle the box
        body = page.is_checked("#body")
        page.keyboard.press("KeyB")
        assert page.is_checked("#body") is not body
        sticks = page.is_checked("#sticks")
        page.keyboard.press("KeyK")
        assert page.is_checked("#sticks") is not sticks
        assert errors == []
    finally:
        page.close()


def overlapping(boxes):
    shown = [(i, b) for i, b in enumerate(boxes) if b is not None]
    return [(i, j) for a, (i, p) in enumerate(shown) for j, q in shown[a + 1:]
            if p[0] < q[2] and q[0] < p[2] and p[1] < q[3] and q[1] < p[3]]


@pytest.mark.parametrize("width,height", [(360, 640), (800, 600), (1280, 720), (1920, 1080)])
def test_eight_names_never_overlap(browser, eight_up, width, height):
    page, errors = open_player(browser, eight_up, width, height)
    try:
        page.evaluate("window.minifilmPlayer.pause()")
        for frame in (0, 30, 59):
            page.evaluate(f"window.minifilmPlayer.setFrame({frame})")
            boxes = page.evaluate("window.minifilmPlayer.labelBoxes()")
            assert len(boxes) == 8 and all(b is not None for b in boxes), boxes
            assert overlapping(boxes) == [], (frame, boxes)
            for i, (left, top, right, bottom) in enumerate(boxes):
                assert right - left > 10 and bottom - top > 5
                x, y = (left + right) / 2, (top + bottom) / 2
                assert page.evaluate(f"window.minifilmPlayer.labelsAt({x}, {y})") == [i]   # drawn there...
                for outside in ((left - 3, y), (right + 3, y), (x, top - 3), (x, bottom + 3)):
                    assert i not in page.evaluate(f"window.minifilmPlayer.labelsAt({outside[0]}, {outside[1]})")
        # zoomed far out, the characters a few pixels apart: still no name covers another
        page.mouse.move(width / 3, height / 2)
        for _ in range(6):
            page.mouse.wheel(0, 800)
        page.evaluate("window.minifilmPlayer.setFrame(10)")
        boxes = page.evaluate("window.minifilmPlayer.labelBoxes()")
        assert overlapping(boxes) == [], boxes
        spread = np.ptp([(b[1] + b[3]) / 2 for b in boxes])
        assert spread > 0                                              # the names were stacked
        assert errors == []
    finally:
        page.close()
