"""The demo's messages, both ways, and the validation of every message a page sends.

One WebSocket per page; every message is one JSON object in a text frame. Page -> server
(at most ``MAX_MESSAGE_BYTES``; any message may carry ``"seq"``, an integer the server echoes as
``ack`` in the frames, so a page can tell when its input took effect):

    {"type": "input", "move": [right, forward], "turn": t, "speed": s}
        move: each in [-1, 1], relative to the character's heading (W = [0, 1], D = [1, 0]);
        turn in [-1, 1], > 0 turns the heading to the character's right (E); speed in [0, 1]
        from walking (0) to running (1). The last input holds until the next one.
    {"type": "style", "weights": {"Neutral": 1}, "seconds": 1.0}
        known style names, weights >= 0 summing to 1 (within ``WEIGHT_TOLERANCE``; rescaled to
        exactly 1); seconds of smoothstep transition from the current mix, in [0, 10], default 1.
    {"type": "settings", "footLock": true, "fit": false}    either or both
    {"type": "reset"}                                       back to the origin
    {"type": "ping", "t": 12.5}                             answered with {"type": "pong", "t": 12.5}
    {"type": "record", "seconds": 10, "gif": true}          the last seconds as BVH (and GIF), answered
                                                            with "recording" (see minifilm/demo/record.py)

Server -> page: ``hello`` (once, what the page needs to draw), ``frame`` (every frame: the pose,
the predicted trajectory and the held input's path, the read-outs; see
:meth:`~minifilm.demo.character.Character.frame_message`), ``error``
(a message was refused and dropped; names why), ``notice`` (something happened, e.g. the character
was reset), ``refused`` (no free character: the connection is closed), ``pong``.

A message that is not valid JSON, too long, of an unknown type, with unknown or missing fields,
a non-finite or out-of-range number (JSON's NaN / Infinity included), an unknown style, or
negative weights raises :class:`ProtocolError`; the server replies with an ``error`` message and
drops it. Nothing here touches the character: parsing is pure, so it is tested on its own.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Collection, Dict, Optional, Sequence, Tuple, Union

from minifilm.files.names import few
from minifilm.files.reading import bounded_int, finite_float

PROTOCOL_VERSION = 1
#: The largest page message the server reads and answers (an error reply above it).
MAX_MESSAGE_BYTES = 4096
#: The transport's own limit: a frame above it closes the connection (code 1009), unread.
TRANSPORT_MAX_BYTES = 65536
#: How far from 1 the sum of blend weights may be.
WEIGHT_TOLERANCE = 1e-3
MAX_TRANSITION_SECONDS = 10.0
_MAX_SEQ = 2 ** 53 - 1           # integers a JavaScript number holds exactly


class ProtocolError(ValueError):
    """A page message the server refuses; ``seq`` is its sequence number when it had a valid one."""

    def __init__(self, message: str, seq: Optional[int] = None):
        super().__init__(message)
        self.seq = seq


@dataclass(frozen=True)
class InputMessage:
    move: Tuple[float, float]      # (right, forward), each in [-1, 1]
    turn: float                    # [-1, 1], > 0 to the right
    speed: float                   # [0, 1], walk .. run
    seq: Optional[int] = None


@dataclass(frozen=True)
class StyleMessage:
    weights: Tuple[Tuple[str, float], ...]   # (name, weight >= 0), weights summing to exactly 1
    seconds: float = 1.0
    seq: Optional[int] = None


@dataclass(frozen=True)
class SettingsMessage:
    foot_lock: Optional[bool] = None
    fit: Optional[bool] = None
    seq: Optional[int] = None


@dataclass(frozen=True)
class ResetMessage:
    seq: Optional[int] = None


#: The longest stretch a page may ask for by a record message, seconds.
MAX_RECORD_SECONDS = 30.0


@dataclass(frozen=True)
class RecordMessage:
    """The page asks for its character's last ``seconds`` as BVH (and GIF if ``gif``); answered by
    minifilm/demo/record.py::answer_record."""

    seconds: float
    gif: bool = False
    seq: Optional[int] = None


@dataclass(frozen=True)
class PingMessage:
    t: float
    seq: Optional[int] = None


Message = Union[InputMessage, StyleMessage, SettingsMessage, ResetMessage, PingMessage]

#: type -> (required fields, optional fields); "type" and "seq" are allowed everywhere
_FIELDS = {
    "input": ({"move", "turn", "speed"}, set()),
    "style": ({"weights"}, {"seconds"}),
    "settings": (set(), {"footLock", "fit"}),
    "reset": (set(), set()),
    "ping": ({"t"}, set()),
    "record": ({"seconds"}, {"gif"}),       # handled by minifilm/demo/record.py
}


def parse_message(data: Union[str, bytes], styles: Collection[str]) -> Message:
    """One page message -> a Message, or ProtocolError saying what is wrong with it.

    ``styles``: the names a style message may use.
    """
    if not isinstance(data, str):
        raise ProtocolError("binary messages are not accepted: send JSON text")
    if len(data) > MAX_MESSAGE_BYTES or len(data.encode("utf-8")) > MAX_MESSAGE_BYTES:
        raise ProtocolError(f"message of {len(data.encode('utf-8'))} bytes: the limit is {MAX_MESSAGE_BYTES}")
    try:
        obj = json.loads(data, parse_constant=_no_constant, parse_int=bounded_int, parse_float=finite_float,
                         object_pairs_hook=_unique_keys)
    except (ValueError, RecursionError) as e:
        raise ProtocolError(f"not valid JSON ({str(e)[:120]})") from None
    if not isinstance(obj, dict):
        raise ProtocolError(f"a message must be a JSON object, got {type(obj).__name__}")
    seq = _seq(obj.get("seq"))
    kind = obj.get("type")
    if not isinstance(kind, str) or kind not in _FIELDS:
        raise ProtocolError(f"unknown message type {str(kind)[:40]!r}; expected one of {sorted(_FIELDS)}", seq)
    required, optional = _FIELDS[kind]
    missing = required - set(obj)
    extra = set(obj) - required - optional - {"type", "seq"}
    if missing:
        raise ProtocolError(f"{kind}: missing field(s) {few(sorted(missing))}", seq)
    if extra:
        raise ProtocolError(f"{kind}: unknown field(s) {few(sorted(extra))}", seq)
    try:
        if kind == "input":
            move = obj["move"]
            if not isinstance(move, list) or len(move) != 2:
                raise ProtocolError("move must be [right, forward]")
            return InputMessage((_number(move[0], "move[0]", -1, 1), _number(move[1], "move[1]", -1, 1)),
                                _number(obj["turn"], "turn", -1, 1), _number(obj["speed"], "speed", 0, 1), seq)
        if kind == "style":
            seconds = _number(obj.get("seconds", 1.0), "seconds", 0, MAX_TRANSITION_SECONDS)
            return StyleMessage(_weights(obj["weights"], styles), seconds, seq)
        if kind == "settings":
            if not obj.keys() & {"footLock", "fit"}:
                raise ProtocolError("give footLock and/or fit")
            return SettingsMessage(_flag(obj, "footLock"), _flag(obj, "fit"), seq)
        if kind == "reset":
            return ResetMessage(seq)
        if kind == "record":
            return RecordMessage(_number(obj["seconds"], "seconds", 0.1, MAX_RECORD_SECONDS),
                                 bool(_flag(obj, "gif")), seq)
        return PingMessage(_number(obj["t"], "t", -1e15, 1e15), seq)
    except ProtocolError as e:
        raise ProtocolError(f"{kind}: {e}", seq) from None


def _no_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


def _unique_keys(pairs):
    keys = [k for k, _ in pairs]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ValueError(f"duplicate key(s) {[k[:40] for k in dup]}")
    return dict(pairs)


def _seq(value) -> Optional[int]:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= _MAX_SEQ:
        raise ProtocolError(f"seq must be an integer in [0, 2^53), got {str(value)[:40]}")
    return value


def _number(value, name: str, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProtocolError(f"{name} must be a number, got {type(value).__name__}")
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise ProtocolError(f"{name} must be finite, got {str(value)[:40]}")
    if not low <= v <= high:
        raise ProtocolError(f"{name} must be in [{low:g}, {high:g}], got {v:g}")
    return v


def _flag(obj: dict, name: str) -> Optional[bool]:
    if name not in obj:
        return None
    if not isinstance(obj[name], bool):
        raise ProtocolError(f"{name} must be true or false, got {str(obj[name])[:40]}")
    return obj[name]


def _weights(value, styles: Collection[str]) -> Tuple[Tuple[str, float], ...]:
    if not isinstance(value, dict) or not value:
        raise ProtocolError("weights must be a non-empty object {style name: weight}")
    unknown = [k for k in value if k not in styles]
    if unknown:
        raise ProtocolError(f"unknown style(s) {[k[:40] for k in unknown[:5]]}")
    w = {name: _number(v, f"weights[{name!r}]", -math.inf, math.inf) for name, v in value.items()}
    negative = [n for n, v in w.items() if v < 0]
    if negative:
        raise ProtocolError(f"weights must be >= 0, got {[(n, w[n]) for n in negative[:5]]}")
    total = sum(w.values())
    if abs(total - 1.0) > WEIGHT_TOLERANCE:
        raise ProtocolError(f"weights must sum to 1 (within {WEIGHT_TOLERANCE:g}), got {total:.6g}")
    return tuple((n, v / total) for n, v in w.items())


# ---------------------------------------------------------------------------------------------
# Server -> page
# ---------------------------------------------------------------------------------------------

def encode(message: dict) -> str:
    """Compact JSON text; non-finite numbers are a bug here (the frame guard removes them)."""
    return json.dumps(message, separators=(",", ":"), allow_nan=False)


def error(message: str, seq: Optional[int] = None) -> str:
    return encode({"type": "error", "message": message, "seq": seq})


def notice(message: str) -> str:
    return encode({"type": "notice", "message": message})


def refused(message: str) -> str:
    return encode({"type": "refused", "message": message})


def pong(t: float, seq: Optional[int] = None) -> str:
    return encode({"type": "pong", "t": t, "seq": seq})


def weights_dict(weights: Sequence[Tuple[str, float]], decimals: int = 4) -> Dict[str, float]:
    return {n: round(float(w), decimals) for n, w in weights}
