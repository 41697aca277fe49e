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

    def step(self, steps=1, now=None):
        if self.fail:
            raise RuntimeError("a bug in one character")
        self.n += steps
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


# ---- the clock: simulation time follows wall time (a fake clock: nothing here is timed) -------------

from minifilm.demo.frame_loop import MAX_BATCH, FrameClock  # noqa: E402


def test_on_time_one_step_is_due_per_period_and_none_before():
    c = FrameClock(1 / 60)
    assert c.due(10.0) == 1
    c.ran(1, 10.0)
    assert c.due(10.0 + 0.5 / 60) == 0 and c.behind(10.0 + 0.5 / 60) == 0
    assert c.due(10.0 + 1 / 60) == 1
    c.ran(1, 10.0 + 1 / 60)
    assert c.next_due == pytest.approx(10.0 + 2 / 60)


def test_a_slow_machine_gets_the_steps_it_missed_as_one_batch_so_60_steps_run_per_wall_second():
    c, now, ran = FrameClock(1 / 60), 0.0, 0
    c.restart(0.0)
    while now < 10.0:                    # the loop only gets to run every 50 ms (a busy machine)
        n = c.due(now)
        c.ran(n, now)
        ran += n
        now += 0.05
    assert 2 <= n <= 4 and c.dropped == 0                   # about three steps a pass
    assert ran == pytest.approx(60 * 10.0, abs=3)          # the simulation kept up with the clock
    assert c.rate(now - 0.05) == pytest.approx(60, abs=3)


def test_a_stall_longer_than_a_batch_drops_the_rest_and_says_so():
    c = FrameClock(1 / 60)
    c.restart(0.0)
    c.ran(c.due(0.0), 0.0)
    assert c.behind(2.0) == 120                             # two seconds without a pass
    n = c.due(2.0)
    assert n == MAX_BATCH and c.dropped == 120 - MAX_BATCH and c.recently_dropped(2.5) == 120 - MAX_BATCH
    c.ran(n, 2.0)
    assert c.behind(2.0) == 0 and c.recently_dropped(3.5) == 0
    with pytest.raises(ValueError):
        FrameClock(0.0)


def test_a_batch_steps_every_character_that_many_times_and_sends_one_frame_with_the_timing():
    stage = Stage(FakeCharacter, fps=60)
    got, deliver = inbox()
    stage.join(deliver)
    stage.tick(now=1.0, steps=4)
    frames = [m for m, is_frame in got if is_frame]
    assert [f["n"] for f in frames] == [4] and frames[0]["steps"] == 4
    assert {"behind", "dropped", "stepsPerSecond"} <= set(frames[0]) and stage.steps == 4 and stage.ticks == 1


class SlowCharacter(FakeCharacter):
    """A character whose step takes ``seconds`` of the stage's fake clock."""

    def __init__(self, ident, clock, seconds):
        super().__init__(ident)
        self.clock, self.seconds = clock, seconds

    def step(self, steps=1, now=None):
        self.clock[0] += self.seconds
        return super().step(steps, now)


def run_one_pass(step_seconds):
    """One pass of the loop as ``Stage._run`` makes it, on a fake clock; the frame it sends."""
    clock = [5.0]
    stage = Stage(lambda ident: SlowCharacter(ident, clock, step_seconds), fps=60, clock=lambda: clock[0])
    got, deliver = inbox()
    stage.join(deliver)
    stage.frames.restart(clock[0])
    now = clock[0]
    n = stage.frames.due(now)
    stage.tick(now, steps=n)
    stage.frames.ran(n, now)
    return [m for m, is_frame in got if is_frame][0]


def test_a_frame_on_time_says_nothing_is_behind():
    # the step of the batch being sent is not "behind": a machine that keeps up shows 0, not 1
    assert run_one_pass(0.001)["behind"] == 0


def test_a_frame_that_took_longer_than_the_period_says_how_many_steps_fell_due_meanwhile():
    # the step took 2.5 periods: at sending, steps 1 and 2 are due and not run
    assert run_one_pass(2.5 / 60)["behind"] == 2
