"""One HTTP/1.x request head, read strictly: what the demo's HTTP front (``http_front.py``) answers.

The demo serves a handful of files to a browser, so the reader accepts exactly what a browser or
``curl`` sends and refuses the rest with the status that says why, before anything is served:

- a request line ``METHOD SP /target SP HTTP/1.x`` (``HTTP/1.0`` or ``HTTP/1.1``), the target a
  path (``/...``); anything else is 400, a line over :data:`MAX_LINE` bytes 414;
- a method is upper-case letters (methods are case-sensitive: ``get`` is not ``GET``) -- 400
  otherwise; which methods are *served* is the front's business (405 for the others);
- header lines ``Name: value``, the name a token, no folded continuation lines (400); more than
  :data:`MAX_HEADERS` of them or one over :data:`MAX_LINE` bytes is 431;
- no body: a ``Transfer-Encoding`` or a ``Content-Length`` other than 0 is 400 (the demo's
  requests have none, and a body the server does not read would be taken for the next request).

Header values are kept as Latin-1 text (bytes 1:1), so no byte sequence can fail to decode.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import List, Optional, Tuple

MAX_LINE = 8192         # bytes in the request line or one header line (as the websockets package)
MAX_HEADERS = 128       # header lines in one request (as the websockets package)
MAX_HEAD = MAX_LINE * 2 + MAX_HEADERS * 128   # bytes a head may take before it must have ended

_TOKEN = re.compile(rb"[!#$%&'*+\-.^_`|~0-9A-Za-z]+")
_METHOD = re.compile(r"[A-Z]+")


class BadRequest(ValueError):
    """A request the front answers with ``status`` and ``text`` and then closes the connection on."""

    def __init__(self, status: int, text: str):
        super().__init__(text)
        self.status, self.text = status, text


@dataclass
class Request:
    """A request head: ``method``, ``target`` (as sent), ``version`` ("HTTP/1.1"), ``headers``."""
    method: str
    target: str
    version: str
    headers: List[Tuple[str, str]]

    @property
    def path(self) -> str:
        """The target without its query string."""
        return self.target.split("?", 1)[0]

    def get_all(self, name: str) -> List[str]:
        """Every value of the header ``name`` (case-insensitive), in order."""
        name = name.lower()
        return [v for k, v in self.headers if k.lower() == name]

    @property
    def keep_alive(self) -> bool:
        """Whether the client expects the connection to stay open after the answer (HTTP/1.1
        unless it says ``Connection: close``; HTTP/1.0 connections are closed)."""
        if self.version != "HTTP/1.1":
            return False
        tokens = {t.strip().lower() for v in self.get_all("Connection") for t in v.split(",")}
        return "close" not in tokens


def head_end(buffer: bytes) -> Optional[int]:
    """Where the first request head in ``buffer`` ends (the index after its blank line), None
    when it has not ended yet, or BadRequest when it can no longer end within the limits."""
    end = buffer.find(b"\r\n\r\n")
    if end >= 0:
        return end + 4
    first_line_end = buffer.find(b"\r\n")
    if first_line_end < 0 and len(buffer) > MAX_LINE:
        raise BadRequest(414, f"the request line is longer than {MAX_LINE} bytes")
    if len(buffer) > MAX_HEAD:
        raise BadRequest(431, f"the request head is longer than {MAX_HEAD} bytes")
    return None


def parse_head(head: bytes) -> Request:
    """The :class:`Request` of ``head`` (one request head, its blank line included), or BadRequest."""
    lines = head[:-4].split(b"\r\n") if head.endswith(b"\r\n\r\n") else head.split(b"\r\n")
    request_line, header_lines = lines[0], lines[1:]
    if len(request_line) > MAX_LINE:
        raise BadRequest(414, f"the request line is longer than {MAX_LINE} bytes")
    parts = request_line.decode("latin-1").split(" ")
    if len(parts) != 3:
        raise BadRequest(400, "not an HTTP request line (METHOD /path HTTP/1.1)")
    method, target, version = parts
    if not _METHOD.fullmatch(method):
        raise BadRequest(400, f"{method[:20]!r} is not an HTTP method (methods are upper case, as GET)")
    if version not in ("HTTP/1.0", "HTTP/1.1"):
        raise BadRequest(400 if not version.startswith("HTTP/") else 505,
                         f"unsupported protocol {version[:20]!r} (HTTP/1.1 or HTTP/1.0)")
    if not target.startswith("/") or any(c <= " " or c == "\x7f" for c in target):
        raise BadRequest(400, "the request target must be a path (/...)")
    if len(header_lines) > MAX_HEADERS:
        raise BadRequest(431, f"more than {MAX_HEADERS} header lines")
    headers = []
    for line in header_lines:
        if len(line) > MAX_LINE:
            raise BadRequest(431, f"a header line is longer than {MAX_LINE} bytes")
        if line[:1] in (b" ", b"\t"):
            raise BadRequest(400, "folded header lines are not accepted")
        name, colon, value = line.partition(b":")
        if not colon or not _TOKEN.fullmatch(name):
            raise BadRequest(400, "a header line must be 'Name: value'")
        if b"\r" in value or b"\n" in value or b"\x00" in value:
            raise BadRequest(400, "a header value holds a line break or NUL")
        headers.append((name.decode("ascii"), value.strip(b" \t").decode("latin-1")))
    request = Request(method, target, version, headers)
    lengths = request.get_all("Content-Length")
    if request.get_all("Transfer-Encoding") or any(v != "0" for v in lengths) or len(lengths) > 1:
        raise BadRequest(400, "the demo's requests have no body (no Content-Length, no Transfer-Encoding)")
    return request
