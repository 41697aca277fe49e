"""Idle work in the frame loop (minifilm/demo/frame_loop.py, ``Stage.idle_work``: the speed
calibrations): slices run only in the time a frame leaves before the next is due, so no frame waits
for more than one slice that took longer than expected. Driven by a fake clock: the
loop's own ``_run`` with a ``sleep`` that moves the clock (nothing here depends on the machine)."""
from minifilm.demo.frame_loop import PROBE_AFTER, SPARE_MARGIN, Stage

PERIOD = 1 / 60


class FakeTime:
    """A clock that moves only when slept on or worked in; stops the stage after ``until`` seconds."""

    def __init__(self, until: float):
        self.t, self.until, self.stage = 0.0, until, None

    def clock(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += max(seconds, 0.0)
        if self.t >= self.until:
            self.stage._stop.set()


class TimedCharacter:
    """Takes ``cost`` seconds of the fake clock per step; notes how late each pass ran it (its
    time minus when its first step fell due)."""

    def __init__(self, ident, time: FakeTime, cost: float):
        self.ident, self.time, self.cost, self.late = ident, time, cost, []

    def step(self, steps=1, now=None):
        self.late.append(now - self.time.stage.frames.next_due)
        self.time.t += self.cost
        return {"type": "frame"}, []


class Work:
    """Slices of the given lengths (seconds of the fake clock); stops the stage when done if told."""

    def __init__(self, time: FakeTime, lengths, stop_when_done=False):
        self.time, self.lengths, self.stop_when_done, self.ran = time, list(lengths), stop_when_done, []

    def pending(self) -> bool:
        return bool(self.lengths)

    def run_slice(self) -> None:
        length = self.lengths.pop(0)
        self.ran.append((self.time.t, length))
        self.time.t += length
        if not self.lengths and self.stop_when_done:
            self.time.stage._stop.set()


def staged(seconds: float, step_cost: float, slices, connected=True, stop_when_done=False):
    time = FakeTime(seconds)
    stage = Stage(lambda i: TimedCharacter(i, time, step_cost), fps=60, clock=time.clock, sleep=time.sleep)
    time.stage = stage
    character = stage.join(lambda text, is_frame: None) if connected else None
    stage.idle_work = work = Work(time, slices, stop_when_done)
    stage._run()
    return stage, character, work


def test_slices_fill_the_time_between_frames_and_no_frame_is_late():
    # a 1 ms frame leaves 15.7 ms: two 5 ms slices fit (each with its breath and margin), a third not
    stage, character, work = staged(1.99, 0.001, [0.005] * 10_000)
    frames = len(character.late)
    assert frames == 120 and stage.steps == 120                   # every frame of 2 s, one step each
    assert max(character.late) < 1e-9                               # none ran after it fell due
    assert stage.slices == len(work.ran) and 2 * frames - 2 <= stage.slices <= 2 * frames
    assert stage.late_slices == 0
    for start, length in work.ran:                                  # each slice ended in its frame's spare time
        due = (int(start / PERIOD) + 1) * PERIOD
        assert start + length <= due - SPARE_MARGIN + 1e-9


def test_a_slice_longer_than_expected_delays_one_frame_by_at_most_its_own_length():
    # the 42nd slice, the second of its frame (starting 7 ms after the frame), takes 12 ms, not 5
    slices = [0.005] * 41 + [0.012] + [0.005] * 10_000
    stage, character, work = staged(1.99, 0.001, slices)
    late = [x for x in character.late if x > 1e-9]
    assert len(late) == 1 and 0 < late[0] <= 0.012                  # the one frame after the long slice
    assert stage.late_slices == 1
    # one slow slice (the scheduler paused it) does not stop the others: two a frame again after it
    frame_of = [int(start / PERIOD + 1e-9) for start, _ in work.ran]
    after = frame_of[42:]
    assert len(after) >= 2 * (frame_of[-1] - frame_of[42])


def test_slices_that_never_fit_are_tried_only_once_in_a_while_while_a_page_is_connected():
    # 20 ms is more than any frame leaves: the first one (not timed yet) runs, then one more each
    # time PROBE_AFTER has passed without a slice (the machine may have become less busy)
    stage, character, work = staged(1.99, 0.002, [0.020] * 100)
    assert 2 <= stage.slices <= 1 + 1.99 / PROBE_AFTER
    late = [x for x in character.late if x > 1e-9]
    assert len(late) == stage.slices and max(late) <= 0.020         # each delays one frame, by at most itself
    assert len(character.late) >= 115                               # the frames went on
    starts = [start for start, _ in work.ran]
    assert all(b - a > PROBE_AFTER for a, b in zip(starts, starts[1:]))


def test_with_nobody_connected_the_slices_run_back_to_back():
    stage, _, work = staged(100.0, 0.002, [0.005] * 50, connected=False, stop_when_done=True)
    assert stage.slices == 50 and not work.lengths
    starts = [start for start, _ in work.ran]
    gaps = [b - a for a, b in zip(starts, starts[1:])]
    assert max(gaps) <= 0.005 + 0.001 + 1e-9                       # one slice and the event loop's ms


def test_no_idle_work_is_no_slice():
    time = FakeTime(0.49)
    stage = Stage(lambda i: TimedCharacter(i, time, 0.002), fps=60, clock=time.clock, sleep=time.sleep)
    time.stage = stage
    character = stage.join(lambda text, is_frame: None)
    stage._run()
    assert stage.slices == 0 and len(character.late) == 30 and max(character.late) < 1e-9
