"""The frame loop (minifilm/demo/frame_loop.py): a character per page up to the limit, every member
stepped each frame and its frame delivered, and nothing a character or a page does stops it.
(No timing is asserted here: the frame rate is measured by benchmarks/demo_soak.py.)"""
import json
import threading
import time

import pytest

from minifilm.demo.frame_loop import Stage, StageFull


class FakeCharacter:
    def __init__(self, ident, fail=False):
        self.ident, self.fail, self.n = ident, fail, 0

    def step(self):
        if self.fail:
            raise RuntimeError("a bug in one character")
        self.n += 1
        return {"type": "frame", "n": self.n}, (["reset"] if self.n == 2 else [])


def inbox():
    got = []
    return got, lambda text, is_frame: got.append((json.loads(text), is_frame))


def test_a_character_per_page_up_to_the_limit_then_a_clear_refusal():
    stage = Stage(FakeCharacter, fps=60, max_characters=2)
    a = stage.join(inbox()[1])
    b = stage.join(inbox()[1])
    assert {a.ident, b.ident} == {1, 2} and stage.count == 2
    with pytest.raises(StageFull, match="all 2 characters .* in use .* close another demo tab"):
        stage.join(inbox()[1])
    stage.leave(a)                                     # a page closed: its character is free again
    c = stage.join(inbox()[1])
    assert stage.count == 2 and c.ident not in (a.ident, b.ident)


def test_each_frame_goes_to_its_own_page_with_its_time_and_notices():
    stage = Stage(FakeCharacter, fps=60, max_characters=4)
    got_a, deliver_a = inbox()
    got_b, deliver_b = inbox()
    stage.join(deliver_a)
    stage.join(deliver_b)
    for _ in range(3):
        stage.tick()
    frames = [m for m, is_frame in got_a if is_frame]
    assert [f["n"] for f in frames] == [1, 2, 3] and all("frameMs" in f and "t" in f for f in frames)
    assert [m for m, is_frame in got_a if not is_frame] == [{"type": "notice", "message": "reset"}]
    assert len([m for m, f in got_b if f]) == 3 and stage.ticks == 3


def test_a_failing_character_or_page_does_not_stop_the_others(capsys):
    stage = Stage(lambda i: FakeCharacter(i, fail=i == 1), fps=60)
    got, deliver = inbox()
    stage.join(inbox()[1])                             # ident 1: its step raises

    def broken(text, is_frame):
        raise ConnectionError("the page went away")
    stage.join(broken)
    stage.join(deliver)
    for _ in range(3):
        stage.tick()
    assert len(got) >= 3 and stage.errors == 6
    assert "a bug in one character" in capsys.readouterr().err


def test_the_loop_runs_on_its_own_thread_and_stops():
    stage = Stage(FakeCharacter, fps=60)
    three = threading.Event()
    got = []

    def deliver(text, is_frame):
        got.append(text)
        if len(got) >= 3:
            three.set()
    stage.start()
    stage.join(deliver)
    assert three.wait(10)
    stage.stop()
    assert stage._thread is None
    n = len(got)
    time.sleep(0.1)                                    # six frames' time: nothing more arrives
    assert len(got) == n
