"""The page's record button on the server side (minifilm/demo/record.py): the history each page's
character keeps, the "record" message, and the BVH (and GIF) it is answered with."""
import json
from types import SimpleNamespace

import numpy as np
import pytest
from demo_helpers import tiny_source  # noqa: F401  (a fixture)

from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import Character, DemoSettings
from minifilm.demo.protocol import ProtocolError, parse_message
from minifilm.demo.record import MAX_RECORD_SECONDS, FrameHistory, RecordMessage, answer_record, bvh_scale
from minifilm.motion.bvh import read_bvh
from minifilm.runtime.start_state import root_joint_indices


def state(k: int, root=None) -> SimpleNamespace:
    """A Controller state of one character whose every number says which frame it is."""
    root = np.array([0.01 * k, 0.0]) if root is None else np.asarray(root, dtype=float)
    return SimpleNamespace(out_pos=np.full((1, 3, 3), float(k)), out_fwd=np.full((1, 3, 3), k + 0.5),
                           out_up=np.full((1, 3, 3), k + 0.25), contacts=np.full((1, 2), k % 2), root=root[None])


def test_the_history_keeps_the_last_seconds_in_order():
    h = FrameHistory(n_joints=3, fps=10.0, seconds=2.0)        # 20 frames
    for k in range(35):
        h.capture(state(k))
    P, F, U, C = h.last(1.0)
    assert P.shape == (10, 3, 3) and list(P[:, 0, 0]) == list(range(25, 35))
    assert np.all(F[:, 0, 0] == P[:, 0, 0] + 0.5) and np.all(U[:, 0, 0] == P[:, 0, 0] + 0.25)
    assert list(h.last(60.0)[0][:, 0, 0]) == list(range(15, 35))   # at most what it keeps
    assert list(C[:, 0]) == [k % 2 for k in range(25, 35)]


def test_a_jump_of_the_root_starts_the_history_again():
    h = FrameHistory(n_joints=3, fps=10.0, seconds=2.0)
    for k in range(8):
        h.capture(state(k))
    h.capture(state(100, root=[5.0, 5.0]))                     # "back to the start" (or a guard reset)
    h.capture(state(101, root=[5.01, 5.0]))
    assert list(h.last(2.0)[0][:, 0, 0]) == [100, 101]
    h.capture(state(102, root=[np.nan, 5.0]))                  # a frame the guard will undo
    assert list(h.last(2.0)[0][:, 0, 0]) == [102]


@pytest.mark.parametrize("text, problem", [
    ('{"type": "record"}', "missing field"),
    ('{"type": "record", "seconds": 0}', "seconds must be in"),
    ('{"type": "record", "seconds": 31}', "seconds must be in"),
    ('{"type": "record", "seconds": NaN}', "not valid JSON"),
    ('{"type": "record", "seconds": 5, "gif": "yes"}', "gif must be true or false"),
    ('{"type": "record", "seconds": 5, "path": "/etc/passwd"}', "unknown field"),
])
def test_a_bad_record_message_is_refused_with_the_reason(text, problem):
    with pytest.raises(ProtocolError, match=problem):
        parse_message(text, {"Neutral"})


def test_a_record_message_parses():
    assert parse_message('{"type": "record", "seconds": 5, "seq": 3}', {"Neutral"}) == RecordMessage(5.0, False, 3)
    assert parse_message('{"type": "record", "seconds": 30, "gif": true}', {"Neutral"}).gif is True
    assert MAX_RECORD_SECONDS == 30.0


@pytest.fixture(scope="module")
def stepped(tiny_source):
    """A character of the miniature run stepped for 1.5 s, its frames kept as the server keeps them."""
    source = tiny_source
    character = Character(0, source, Calibrations(source, first=[], background=False),
                          DemoSettings(style=source.default_style()))
    history = FrameHistory(source.layout.n_joints, source.fps)
    shown = []
    for _ in range(int(1.5 * source.fps)):
        character.step()
        history.capture(character.ctrl.state)
        shown.append(character.ctrl.state.out_pos[0].copy())
    return source, history, np.array(shown)


def test_the_recording_is_a_bvh_of_the_frames_shown(stepped, tmp_path):
    source, history, shown = stepped
    n = int(round(1.0 * source.fps))
    answers = answer_record(source, history, RecordMessage(1.0, gif=False, seq=7))
    assert len(answers) == 1
    reply = json.loads(answers[0])
    assert reply["type"] == "recording" and reply["seq"] == 7 and reply["frames"] == n and reply["gif"] is False
    path = tmp_path / "recording.bvh"
    path.write_text(reply["bvh"])
    motion = read_bvh(path, scale=bvh_scale(source))
    assert motion.n_frames == n and motion.frame_time == pytest.approx(1 / source.fps, rel=1e-5)
    # the file's joints are where the page showed them (the skeleton fit keeps bone lengths, so
    # within a few centimetres), frame for frame
    P, _ = motion.world()
    exported = P[:, root_joint_indices(source.layout, source.skeleton)]
    error = np.linalg.norm(exported - shown[-n:], axis=-1)
    assert np.median(error) < 0.03, np.median(error)
    assert np.linalg.norm(exported - shown[-n - 10:-10], axis=-1).mean() > np.mean(error)   # not any frames


def test_no_gif_without_the_drawing_tools_says_so(stepped, monkeypatch):
    source, history, _ = stepped

    def missing(path, kind):
        raise ImportError("matplotlib is not installed")
    monkeypatch.setattr("minifilm.demo.record.check_output_tools", missing)
    sent = []
    bvh, gif = answer_record(source, history, RecordMessage(0.5, gif=True, seq=4), send=sent.append)
    assert sent == [bvh, gif]                                   # each handed on as it was ready
    bvh, gif = json.loads(bvh), json.loads(gif)
    assert bvh["type"] == "recording" and bvh["gif"] is True and bvh["bvh"].startswith("HIERARCHY")
    assert gif["type"] == "recordingGif" and gif["seq"] == 4 and gif["gif"] is None
    assert "BVH only" in gif["note"] and "matplotlib" in gif["note"]


def test_too_little_to_record_is_an_error_not_a_crash(tiny_source):
    history = FrameHistory(tiny_source.layout.n_joints, tiny_source.fps)
    [reply] = [json.loads(m) for m in answer_record(tiny_source, history, RecordMessage(5.0, gif=True, seq=2))]
    assert reply["type"] == "error" and reply["seq"] == 2 and "nothing to record" in reply["message"]


def test_the_gif_is_drawn_from_the_recorded_bvh(stepped):
    pytest.importorskip("matplotlib", reason="the GIF needs matplotlib")
    Image = pytest.importorskip("PIL.Image", reason="the GIF needs Pillow")
    import base64
    import io
    source, history, _ = stepped
    reply = json.loads(answer_record(source, history, RecordMessage(1.0, gif=True))[1])
    assert reply["type"] == "recordingGif" and reply["note"] == "", reply.get("note")
    gif = Image.open(io.BytesIO(base64.b64decode(reply["gif"])))
    every = int(source.fps // 15)
    assert gif.format == "GIF" and gif.n_frames == -(-int(round(source.fps)) // every)   # 1 s at about 15 fps


def test_a_gif_that_takes_too_long_leaves_the_bvh_alone_and_says_so(stepped, monkeypatch):
    pytest.importorskip("matplotlib", reason="the GIF needs matplotlib")
    pytest.importorskip("PIL.Image", reason="the GIF needs Pillow")
    source, history, _ = stepped
    monkeypatch.setattr("minifilm.demo.record.GIF_TIMEOUT", 0.01)    # no process draws a GIF that fast
    bvh, gif = (json.loads(m) for m in answer_record(source, history, RecordMessage(0.5, gif=True, seq=3)))
    assert bvh["type"] == "recording" and bvh["bvh"].startswith("HIERARCHY")
    assert gif["type"] == "recordingGif" and gif["gif"] is None and "took more than" in gif["note"], gif
