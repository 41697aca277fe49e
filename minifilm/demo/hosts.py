"""Which ``Host`` and ``Origin`` headers the demo server answers: an allow-list, on for every bind address.

DNS rebinding: a web page the user visits elsewhere can make its own domain name resolve to this
machine, and the browser then sends that page's requests here with ``Host: evil.example:PORT``.
Checking the Host header against names this server is known by stops it, whatever interface the
server listens on (``--host 0.0.0.0`` included: that is when other machines *and* every page open
in this machine's browser can reach it). Names are compared, never resolved. Allowed:

- any loopback address, however spelled (``127.0.0.1``, ``127.1``, ``::1``, ``[::1]``) and
  ``localhost``;
- the address the server is bound to, and the address a connection actually arrived at (an IP
  literal; a rebinding attack needs a name);
- the machine's host name (``socket.gethostname()``, with and without its domain);
- the names the user adds (``--allow-host NAME``, repeatable);

and the port must be the server's. A request with no Host, or two Host headers, is refused with
400 (the server decides which; see ``server.py``), as is a WebSocket whose browser page came from
anywhere else (its ``Origin``).
"""
from __future__ import annotations

import ipaddress
import socket
from typing import Iterable, Optional, Tuple
from urllib.parse import urlsplit

#: The longest host name the allow-list accepts (DNS: 253 characters).
MAX_NAME = 253


def parse_ip(text: str):
    """``text`` as an IP address (IPv4 shorthand such as ``127.1`` included), or None."""
    text = text.strip("[]")
    try:
        return ipaddress.ip_address(text)
    except ValueError:
        pass
    if ":" in text or not text or not all(c in "0123456789abcdefx." for c in text.lower()):
        return None
    try:              # inet_aton reads the shorthand forms browsers and curl accept (127.1, 0x7f.1)
        return ipaddress.ip_address(socket.inet_aton(text))
    except OSError:
        return None


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and every spelling of a loopback address."""
    host = host.strip().lower().rstrip(".")
    if host == "localhost" or host.endswith(".localhost"):
        return True
    ip = parse_ip(host)
    return ip is not None and _unmapped(ip).is_loopback


def is_unspecified(host: str) -> bool:
    """True for the "every interface" addresses (``0.0.0.0``, ``::``)."""
    ip = parse_ip(host)
    return ip is not None and ip.is_unspecified


def _unmapped(ip):
    mapped = getattr(ip, "ipv4_mapped", None)
    return mapped if mapped is not None else ip


def check_name(name: str, option: str = "--allow-host") -> str:
    """A host name or address the user allows, lower-cased; ValueError naming what is wrong."""
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"{option}: give a host name or address, not an empty string")
    name = name.strip().lower().rstrip(".")
    if parse_ip(name) is not None:
        return name.strip("[]")
    labels = name.split(".")
    if len(name) > MAX_NAME or not name.isascii() or \
            not all(label and all(c.isalnum() or c in "-_" for c in label) for label in labels):
        raise ValueError(f"{option}: {name[:60]!r} is not a host name (letters, digits, '-' and '.') "
                         "or an IP address")
    return name


def split_host(value: str) -> Optional[Tuple[str, Optional[int]]]:
    """A Host header's ``(host, port)`` (port None when absent), or None when it is malformed."""
    value = value.strip().lower()
    if not value or len(value) > MAX_NAME + 8:
        return None
    if value.startswith("["):
        end = value.find("]")
        if end < 0:
            return None
        host, rest = value[1:end], value[end + 1:]
        if rest and not rest.startswith(":"):
            return None
        port = rest[1:] if rest else None
    elif value.count(":") > 1:        # a bare IPv6 address is not a valid Host header
        return None
    else:
        host, _, port = value.partition(":")
        port = port if ":" in value else None
    if port is not None:
        if not port.isdigit() or not port.isascii() or len(port) > 5:
            return None
        port = int(port)
    return host.rstrip("."), port


class HostAllowList:
    """The names and addresses a request to the server bound at ``bound`` (an address or a name),
    on ``port``, may use in its Host header or its page's Origin."""

    def __init__(self, bound: str, extra: Iterable[str] = ()):
        self.bound = bound.strip().lower()
        names = {"localhost", self.bound.strip("[]")}
        try:
            host = socket.gethostname().lower()
        except OSError:
            host = ""
        if host:
            names |= {host, host.split(".", 1)[0]}
        names |= {check_name(n) for n in extra}
        self.names = frozenset(n.strip("[]").rstrip(".") for n in names if n)
        self.port: Optional[int] = None       # set once the server is listening

    def allows(self, host_header: str, local_address: Optional[str] = None) -> bool:
        """True when ``host_header`` (``host[:port]``) names this server; ``local_address``: the
        address the request's connection arrived at."""
        parsed = split_host(host_header)
        if parsed is None:
            return False
        host, port = parsed
        if port is None:
            port = 80
        if self.port is not None and port != self.port:
            return False
        if host in self.names or is_loopback(host):
            return True
        ip = parse_ip(host)
        if ip is None:
            return False
        for known in (self.bound, local_address):
            other = parse_ip(known) if known else None
            if other is not None and not other.is_unspecified and _unmapped(other) == _unmapped(ip):
                return True
        return False

    def allows_origin(self, origin: str, local_address: Optional[str] = None) -> bool:
        """True when a page at ``origin`` (``http://host:port``) is this server's own page."""
        try:
            parts = urlsplit(origin.strip())
        except ValueError:
            return False
        if parts.scheme != "http" or parts.path not in ("", "/") or parts.query or parts.username is not None:
            return False
        return self.allows(parts.netloc, local_address)
