"""Validation of every message a page sends (minifilm/demo/protocol.py): what is accepted, and that
anything else is refused with a message saying why (the server then replies ``error`` and drops it)."""
import json

import pytest

from minifilm.demo.protocol import (MAX_MESSAGE_BYTES, InputMessage, PingMessage, ProtocolError, ResetMessage,
                                    SettingsMessage, StyleMessage, parse_message)

STYLES = {"Neutral", "Zombie", "Old"}


def parse(obj):
    return parse_message(obj if isinstance(obj, (str, bytes)) else json.dumps(obj), STYLES)


def test_valid_messages_parse():
    m = parse({"type": "input", "move": [0, 1], "turn": -0.5, "speed": 1, "seq": 7})
    assert m == InputMessage((0.0, 1.0), -0.5, 1.0, 7)
    m = parse({"type": "style", "weights": {"Neutral": 0.2, "Zombie": 0.3, "Old": 0.5}, "seconds": 0})
    assert isinstance(m, StyleMessage) and m.seconds == 0.0 and dict(m.weights) == pytest.approx(
        {"Neutral": 0.2, "Zombie": 0.3, "Old": 0.5})
    assert parse({"type": "style", "weights": {"Old": 1}}).seconds == 1.0          # the default transition
    assert parse({"type": "settings", "footLock": True}) == SettingsMessage(True, None)
    assert parse({"type": "settings", "fit": False, "footLock": False}) == SettingsMessage(False, False)
    assert parse({"type": "reset"}) == ResetMessage()
    assert parse({"type": "ping", "t": 3.5}) == PingMessage(3.5)


def test_weights_within_the_tolerance_are_rescaled_to_sum_exactly_one():
    m = parse({"type": "style", "weights": {"Neutral": 0.5004, "Zombie": 0.5}})
    assert sum(w for _, w in m.weights) == pytest.approx(1.0, abs=1e-15)
    assert parse({"type": "style", "weights": {"Zombie": 1.0}}).weights == (("Zombie", 1.0),)


@pytest.mark.parametrize("text, why", [
    ("{not json", "not valid JSON"),
    ("", "not valid JSON"),
    ("[1, 2]", "JSON object"),
    ('"input"', "JSON object"),
    ("[" * 2000 + "]" * 2000, "not valid JSON"),                       # nesting deep enough to recurse
    ('{"type": "input", "type": "reset"}', "duplicate"),
    ('{"type": "input", "move": [0, NaN], "turn": 0, "speed": 0}', "not valid JSON"),
    ('{"type": "input", "move": [0, Infinity], "turn": 0, "speed": 0}', "not valid JSON"),
    ('{"type": "input", "move": [0, 1], "turn": -Infinity, "speed": 0}', "not valid JSON"),
    ('{"type": "input", "move": [0, 1e999], "turn": 0, "speed": 0}', "too large for a float"),
    ('{"type": "ping", "t": 1' + "0" * 400 + "}", "401 digits"),          # an integer too large for a float
], ids=lambda v: v[:40] if isinstance(v, str) else v)
def test_malformed_and_non_finite_messages_are_refused(text, why):
    with pytest.raises(ProtocolError, match=why):
        parse(text)


def test_oversized_and_binary_messages_are_refused():
    big = json.dumps({"type": "reset", "seq": 1, "pad": "x" * MAX_MESSAGE_BYTES})
    with pytest.raises(ProtocolError, match=f"limit is {MAX_MESSAGE_BYTES}"):
        parse(big)
    # the limit is in bytes: 2,000 three-byte characters are 6,000 bytes
    with pytest.raises(ProtocolError, match="limit"):
        parse(json.dumps({"type": "reset", "x": "\u20ac" * 2000}, ensure_ascii=False))
    with pytest.raises(ProtocolError, match="binary"):
        parse(b'{"type": "reset"}')


@pytest.mark.parametrize("message, why", [
    ({"type": "teleport"}, "unknown message type"),
    ({"move": [0, 1]}, "unknown message type"),
    ({"type": 3}, "unknown message type"),
    ({"type": "input", "move": [0, 1], "turn": 0}, "missing field"),
    ({"type": "input", "move": [0, 1], "turn": 0, "speed": 0, "jump": True}, "unknown field"),
    ({"type": "input", "move": [0, 1, 2], "turn": 0, "speed": 0}, "move must be"),
    ({"type": "input", "move": "up", "turn": 0, "speed": 0}, "move must be"),
    ({"type": "input", "move": [0, "1"], "turn": 0, "speed": 0}, "must be a number"),
    ({"type": "input", "move": [0, True], "turn": 0, "speed": 0}, "must be a number"),
    ({"type": "input", "move": [0, 1.5], "turn": 0, "speed": 0}, r"in \[-1, 1\]"),
    ({"type": "input", "move": [0, 1], "turn": 2, "speed": 0}, r"turn must be in"),
    ({"type": "input", "move": [0, 1], "turn": 0, "speed": -0.1}, r"speed must be in"),
    ({"type": "input", "move": [0, 1], "turn": 0, "speed": None}, "must be a number"),
    ({"type": "style", "weights": {"Ninja": 1}}, "unknown style"),
    ({"type": "style", "weights": {}}, "non-empty"),
    ({"type": "style", "weights": ["Zombie"]}, "non-empty object"),
    ({"type": "style", "weights": {"Zombie": 1.5, "Old": -0.5}}, ">= 0"),
    ({"type": "style", "weights": {"Zombie": -0.0001, "Old": 1.0001}}, ">= 0"),
    ({"type": "style", "weights": {"Zombie": 0.5, "Old": 0.4}}, "sum to 1"),
    ({"type": "style", "weights": {"Zombie": 0, "Old": 0}}, "sum to 1"),
    ({"type": "style", "weights": {"Zombie": 1}, "seconds": 60}, r"seconds must be in \[0, 10\]"),
    ({"type": "style", "weights": {"Zombie": 1}, "seconds": -1}, "seconds must be in"),
    ({"type": "settings"}, "footLock and/or fit"),
    ({"type": "settings", "fit": 1}, "true or false"),
    ({"type": "reset", "seq": -1}, "seq must be"),
    ({"type": "reset", "seq": 1.5}, "seq must be"),
    ({"type": "reset", "seq": 2 ** 60}, "seq must be"),
    ({"type": "ping"}, "missing field"),
])
def test_bad_fields_are_refused_with_the_reason(message, why):
    with pytest.raises(ProtocolError, match=why):
        parse(message)


def test_an_error_names_the_sequence_number_of_the_bad_message():
    with pytest.raises(ProtocolError) as e:
        parse({"type": "style", "weights": {"Ninja": 1}, "seq": 41})
    assert e.value.seq == 41 and str(e.value).startswith("style: ")


def test_long_names_are_cut_in_the_reply():
    with pytest.raises(ProtocolError) as e:
        parse({"type": "x" * 1000})
    assert len(str(e.value)) < 200
