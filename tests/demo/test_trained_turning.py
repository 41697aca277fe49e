"""A trained run's body follows the steered heading while walking (W+E), driven as the demo drives
it (the run's own position bias, start frames and the turn correction of its source's options,
minifilm/runtime/heading.py); the paper's loop alone, on the same run, does not."""
import numpy as np

from demo_helpers import tiny_source  # noqa: F401  (fixture)
from minifilm.runtime.control import CommandScript
from minifilm.runtime.controller import Controller
from minifilm.runtime.root_frames import floor_angle

TURN_RATE = 120.0     # deg/s: the demo's Q / E
SECONDS = 5.0


def heading_errors(source, options) -> np.ndarray:
    """Degrees between each style's facing and the heading after SECONDS of W+E."""
    names = source.library.names
    films = np.stack([source.library[n] for n in names])
    x = np.stack([source.starts[n][0] for n in names])
    p = np.stack([source.starts[n][1] for n in names])
    ctrl = Controller(source.network, source.layout, fps=source.fps, **options)
    n = int(round(SECONDS * source.fps))
    scripts = [CommandScript([(0.0, 1.3, 0.0, 0.0), (SECONDS, 1.3, -TURN_RATE * SECONDS, 0.0)]) for _ in names]
    r = ctrl.run(scripts, n, films, phases=p, start_x=x)
    heading = np.radians(-TURN_RATE * (n - 1) / source.fps)
    return floor_angle(r.root_facing[:, -1], np.array([np.sin(heading), np.cos(heading)]))


def test_on_a_trained_run_the_body_follows_the_heading_within_30_degrees(tiny_source):
    assert "heading_follow" in tiny_source.options                   # the demo's source turns it on
    followed = heading_errors(tiny_source, tiny_source.options)
    alone = heading_errors(tiny_source, {k: v for k, v in tiny_source.options.items() if k != "heading_follow"})
    assert np.all(followed <= 30.0), followed
    assert alone.max() > 30.0, alone                                  # the case the correction is for
