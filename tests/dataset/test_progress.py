"""The progress line: a line every tenth into a file or pipe; on a terminal one line rewritten in
place, at most five times a second (a rollout updates it every frame), and ended with a newline."""
import io

from minifilm.dataset import progress


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_on_a_terminal_the_line_is_rewritten_at_most_five_times_a_second(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: clock[0])
    screen = Terminal()
    monkeypatch.setattr(progress.sys, "stderr", screen)
    bar = progress.Progress(1000, "generate", unit="frames")
    for done in range(1, 1001):          # 1,000 updates, 10 ms apart: 10 s in all
        clock[0] += 0.01
        bar.update(done)
    shown = screen.getvalue()
    assert shown.count("\r") == 50 and shown.endswith("\n") and shown.count("\n") == 1
    assert "[generate] 1000/1000 frames,  10.0 s, eta   0.0 s" in shown


def test_into_a_file_a_line_every_tenth_and_the_last(monkeypatch):
    log = io.StringIO()
    monkeypatch.setattr(progress.sys, "stderr", log)
    bar = progress.Progress(95, "dataset")
    for done in range(1, 96):
        bar.update(done)
    done = [int(line.split()[1].split("/")[0]) for line in log.getvalue().splitlines()]
    assert done[0] == 1 and done[-1] == 95                      # the first item, and the end
    gaps = [b - a for a, b in zip(done, done[1:-1])]            # (the last line comes whatever the gap)
    assert all(10 <= g <= 11 for g in gaps) and len(done) <= 11 # a tenth of 95 items apart: 9.5, rounded up
