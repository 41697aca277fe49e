"""The demo server: the page and one WebSocket per page on one port, the frame loop beside it.

Transport: the ``websockets`` package (the ``demo`` extra, never a core dependency). It is pure
Python on asyncio with no dependencies of its own, maintained, and its ``process_request`` hook
answers plain HTTP requests on the same port, so the page, its files and the live connection need
nothing else. A WebSocket is one connection both ways whose lifetime *is* the page's: the
character is made when it opens and freed when it closes (a closed tab, a reload). Server-Sent
Events plus POSTs would need two channels per page, a session id to tie them together and a
timeout to notice a page that went away.

Per connection: a character joins the stage (or the page gets ``refused`` and the connection
closes with 1013 when all are taken); the page's messages are validated
(:func:`minifilm.demo.protocol.parse_message`) and queued for the character, a bad one answered
with ``error`` and dropped, and a page over its message budget (``budget.py``) is told, then
disconnected; one sender task sends the page its messages in order, and of the
frames only the newest, so a slow page skips frames instead of slowing the loop.

Every WebSocket frame a page sends, control frames included, takes from its budget before the
transport answers it (``budget.py``). HTTP: every connection is read by the front (``http_front.py``) first: only GET of the site's
exact paths (``page_files.py``), HEAD of them without the body, 405 for other methods, pipelined
and kept-alive requests answered in order; only ``GET /ws`` reaches ``websockets``. Opening a
connection and each request take from the client address's budget (``budget.py``). On every bind
address, requests must name this server in their ``Host`` header (``hosts.py``: a web page elsewhere
cannot reach the server by a DNS name that points here), and a WebSocket opened by a browser must
come from this server's own page (its ``Origin``), so another site open in the same browser cannot
drive the character. A
request with no Host, two Host or two Origin headers is answered 400.
"""
from __future__ import annotations

import asyncio
import collections
import logging
import signal
import threading
from typing import Callable, Optional

from minifilm.demo.budget import AddressBudgets, budgeted_connection
from minifilm.demo.calibrations import Calibrations
from minifilm.demo.character import Character, DemoSettings
from minifilm.demo.http_front import REASONS, WEBSOCKET_PATH, plain, with_http_front
from minifilm.demo.hosts import HostAllowList, is_loopback, is_unspecified, parse_ip  # noqa: F401 (is_loopback: cli)
from minifilm.demo.protocol import (MAX_MESSAGE_BYTES, PROTOCOL_VERSION, TRANSPORT_MAX_BYTES, PingMessage,
                                    ProtocolError, encode, error, parse_message, pong, refused)
from minifilm.demo.record import FrameHistory, RecordMessage, answer_record
from minifilm.demo.page_files import Site
from minifilm.demo.source import DemoSource
from minifilm.demo.frame_loop import Stage, StageFull
from minifilm.demo.style_mix import film_digest
from minifilm.viewer.body import body_plan_of_positions

MAX_QUEUED = 64          # control messages (errors, notices) waiting for a slow page; older ones go
CLOSE_TIMEOUT = 2.0      # seconds a closed page has to answer the close; then its connection is dropped


def websockets_modules():
    """(serve, ConnectionClosed, Response, Headers, connection class) from ``websockets``, or
    ImportError naming the extra."""
    try:
        # an optional extra (minifilm[demo]): imported only when the demo runs
        from websockets.asyncio.server import ServerConnection, serve
        from websockets.datastructures import Headers
        from websockets.exceptions import ConnectionClosed, ProtocolError
        from websockets.frames import Opcode
        from websockets.http11 import Response
    except ImportError as e:
        raise ImportError(f"minifilm demo needs the websockets package (13 or newer), which is not installed: "
                          f"pip install 'minifilm[demo]' ({e})") from None
    return serve, ConnectionClosed, Response, Headers, budgeted_connection(ServerConnection, ProtocolError, Opcode)


def check_bind_host(host: str) -> str:
    """The ``--host`` to listen on, or ValueError: an empty one would listen on every interface
    and print an unusable URL (say 0.0.0.0 for that)."""
    if not isinstance(host, str) or not host.strip():
        raise ValueError("--host: give an address or name to listen on (127.0.0.1: this machine only; "
                         "0.0.0.0: every interface), not an empty string")
    return host.strip()


def url_host(bound: str) -> str:
    """The host part of a URL a browser on this machine can open for a server bound at ``bound``."""
    ip = parse_ip(bound)
    if ip is None:
        return bound
    if ip.is_unspecified:
        return "[::1]" if ip.version == 6 else "127.0.0.1"
    return f"[{ip}]" if ip.version == 6 else str(ip)


#: The released network's styles 095-099 were fine-tuned on the five styles held out of training
#: (docs/original-code.md §8.1; which number is which style is not documented).
HELD_OUT_IDS = ("095", "096", "097", "098", "099")
HELD_OUT_STYLES = ("Roadrunner", "ShieldedLeft", "Skip", "Star", "WildArms")


def held_out(names) -> dict:
    """For the page: the styles fine-tuned on held-out data, and what is known of them ({} when
    the source has none)."""
    ids = [n for n in HELD_OUT_IDS if n in names]
    if len(ids) != len(HELD_OUT_IDS):
        return {}
    return {"ids": ids, "styles": list(HELD_OUT_STYLES),
            "note": "fine-tuned on the five styles held out of training (" + ", ".join(HELD_OUT_STYLES)
                    + "); which number is which style is not documented"}


def _local_address(connection) -> str:
    """The address a connection arrived at ("" when unknown)."""
    try:
        return str(connection.local_address[0])
    except (AttributeError, TypeError, IndexError, OSError):
        return ""


class Outbox:
    """What waits to be sent to one page: control messages in order, and the newest frame."""

    def __init__(self):
        self.control = collections.deque(maxlen=MAX_QUEUED)
        self.frame: Optional[str] = None
        self.dropped_frames = 0
        self.ready = asyncio.Event()

    def put(self, text: str, is_frame: bool) -> None:
        if is_frame:
            if self.frame is not None:
                self.dropped_frames += 1
            self.frame = text
        else:
            self.control.append(text)
        self.ready.set()

    async def take(self) -> list:
        await self.ready.wait()
        self.ready.clear()
        out = list(self.control)
        self.control.clear()
        if self.frame is not None:
            out.append(self.frame)
            self.frame = None
        return out


class DemoServer:
    """The demo for ``source`` on ``host:port`` (port 0: any free port; see ``url`` once started).

    Run it with :meth:`run` (blocks; the command line) or :meth:`start` / :meth:`stop` (a thread of
    its own; tests and benchmarks).
    """

    def __init__(self, source: DemoSource, settings: DemoSettings, host: str = "127.0.0.1", port: int = 8765,
                 max_characters: int = 4, background_calibration: bool = True, allow_hosts=(),
                 calibration_cache=None):
        if settings.style not in source.library:
            raise ValueError(f"--style {settings.style!r} is not one of the {len(source.library)} styles: "
                             f"{', '.join(source.library.names)}")
        self.modules = websockets_modules()
        host = check_bind_host(host)
        self.source, self.settings, self.host, self.port = source, settings, host, int(port)
        self.hosts = HostAllowList(host, allow_hosts)
        self.calibrations = Calibrations(source, first=[settings.style], background=background_calibration,
                                         cache=calibration_cache, begin=False)      # begun once listening
        self.stage = Stage(lambda ident: Character(ident, source, self.calibrations, settings), source.fps,
                           max_characters)
        # the calibrations are measured in the frame loop's idle time, a slice at a time (calibrations.py)
        self.stage.idle_work, self.calibrations.on_request = self.calibrations, self.stage.wake
        self.site = Site(f"minifilm demo: {source.name}")
        self.styles = frozenset(source.library.names)
        self.film_digests = {n: film_digest(source.library[n]) for n in source.library.names}
        self._loop = self._stopping = self._thread = None
        self._ready = threading.Event()
        self._error: Optional[BaseException] = None
        # every connection is read by the HTTP front first (http_front.py); the WebSocket's frames
        # then take from the page's budget (budget.py)
        self.address_budgets = AddressBudgets()
        self.front_connections = set()
        self.connection_class = with_http_front(self.modules[4], self, self.address_budgets)
        self.logger = logging.getLogger("minifilm.demo.websockets")
        self.logger.setLevel(logging.WARNING)      # not a line per page file or refused request

    @property
    def url(self) -> str:
        """A URL a browser on this machine can open (127.0.0.1 when bound to every interface)."""
        return f"http://{url_host(self.host)}:{self.port}/"

    @property
    def everywhere(self) -> bool:
        """Listening on every interface (0.0.0.0 or ::)."""
        return is_unspecified(self.host)

    # ---- HTTP ---------------------------------------------------------------------------------
    def _refusal(self, get_all, path: str, local: str):
        """(status, text) when a request with headers ``get_all(name)`` for ``path``, arrived at
        the address ``local``, is refused; None when it may be served."""
        hosts, origins = get_all("Host"), get_all("Origin")
        if len(hosts) != 1:
            return 400, f"a request needs exactly one Host header, got {len(hosts)}"
        if len(origins) > 1:
            return 400, f"a request may have one Origin header, got {len(origins)}"
        if not self.hosts.allows(hosts[0], local):
            return 403, (f"unexpected Host header {hosts[0][:60]!r}: open {self.url} "
                         "(or start the demo with --allow-host NAME)")
        if path == WEBSOCKET_PATH and origins and not self.hosts.allows_origin(origins[0], local):
            return 403, "a WebSocket of this demo may only be opened by its own page"
        return None

    def answer(self, request, local: str):
        """The HTTP front's answer to a GET or HEAD other than the WebSocket's (``http_front.py``):
        (status, headers, body) of the page's file, or of why not."""
        refused = self._refusal(request.get_all, request.path, local)
        if refused is not None:
            return plain(*refused)
        if request.path == WEBSOCKET_PATH:             # HEAD /ws: a WebSocket is opened by GET
            return plain(426, "the WebSocket is opened with GET and Upgrade: websocket")
        found = self.site.get(request.path)
        if found is None:
            return plain(404, "not found")
        body, kind = found
        return 200, self.site.headers(kind, len(body)), body

    def _http(self, connection, request):
        """process_request of ``websockets``, which the front gives only ``GET /ws``: None to open
        the WebSocket, or the refusal."""
        refused = self._refusal(request.headers.get_all, request.path.split("?", 1)[0], _local_address(connection))
        if refused is None:
            return None
        _, _, Response, Headers, _ = self.modules
        status, headers, body = plain(*refused)
        return Response(status, REASONS[status], Headers(headers + [("Connection", "close")]), body)

    # ---- one page -------------------------------------------------------------------------------
    def hello(self, character: Character) -> str:
        layout, state = self.source.layout, character.ctrl.state
        return encode({
            "type": "hello", "protocol": PROTOCOL_VERSION, "id": character.ident, "source": self.source.name,
            "fps": self.source.fps, "styles": self.source.library.names, "style": character.mix.target,
            "films": self.film_digests,
            "joints": list(layout.joint_names), "parents": [int(p) for p in layout.parents],
            "body": self._body_plan(state.out_pos[0]),
            "contactJoints": self.source.contact_joints(), "size": round(float(state.out_pos[0][:, 1].max()), 3),
            "settings": {"footLock": character.foot_lock, "fit": character.fit},
            "speeds": {"walk": self.settings.walk_speed, "run": self.settings.run_speed},
            "turnRate": self.settings.turn_rate_deg, "calibrate": self.calibrations.enabled,
            "limits": {"maxMessageBytes": MAX_MESSAGE_BYTES, "maxCharacters": self.stage.max_characters},
            "heldOut": held_out(self.source.library.names),
            "calibration": self.calibrations.progress(),
        })

    def _body_plan(self, positions) -> dict:
        """The mannequin's body plan (minifilm/viewer/body.py) of the source's layout, found once."""
        if getattr(self, "_body", None) is None:
            layout = self.source.layout
            self._body = body_plan_of_positions(positions, layout.parents, layout.joint_names)
        return self._body

    async def _connection(self, ws) -> None:
        ConnectionClosed = self.modules[1]
        loop = asyncio.get_running_loop()
        outbox = Outbox()
        history, joined = FrameHistory(self.source.layout.n_joints, self.source.fps), []

        def deliver(text: str, is_frame: bool) -> None:      # called by the frame loop's thread
            try:
                loop.call_soon_threadsafe(outbox.put, text, is_frame)
            except RuntimeError:      # the event loop has closed: the server is stopping
                pass

        try:
            character = self.stage.join(deliver)
        except StageFull as e:
            try:
                await ws.send(refused(str(e)))
                await ws.close(1013, "no free character")
            except ConnectionClosed:
                pass
            return
        joined.append(character)
        character.on_step = history.capture      # every step, for the page's record button (record.py)
        outbox.put(self.hello(character), False)
        # frames over this page's budget never get here (budget.py); it is told once a second
        ws.on_over_budget = lambda text: outbox.put(error(text), False)
        sender = asyncio.create_task(self._send(ws, outbox, character.sent))
        try:
            async for data in ws:
                try:
                    message = parse_message(data, self.styles)
                except ProtocolError as e:
                    outbox.put(error(str(e), e.seq), False)
                    continue
                if isinstance(message, PingMessage):
                    outbox.put(pong(message.t, message.seq), False)
                elif isinstance(message, RecordMessage):
                    self._record(loop, outbox, history, message)
                else:
                    character.submit(message)
        except ConnectionClosed:
            pass
        finally:
            self.stage.leave(character)
            sender.cancel()

    def _record(self, loop, outbox: Outbox, history: FrameHistory, message: RecordMessage) -> None:
        """Answer a record message off the event loop (record.py), one at a time per page."""
        if history.busy:
            outbox.put(error("record: the last recording is still being made", message.seq), False)
            return
        history.busy = True

        def send(text: str) -> None:          # from the executor's thread, as each answer is ready
            try:
                loop.call_soon_threadsafe(outbox.put, text, False)
            except RuntimeError:              # the event loop has closed: the server is stopping
                pass

        def done(_) -> None:
            history.busy = False
        loop.run_in_executor(None, answer_record, self.source, history, message, self.source.name,
                             send).add_done_callback(done)

    async def _send(self, ws, outbox: Outbox, sent=None) -> None:
        ConnectionClosed = self.modules[1]
        try:
            while True:
                for text in await outbox.take():
                    await ws.send(text)
                    if sent is not None and text.startswith('{"type":"frame"'):
                        sent.tick()     # the frame rate the page is told is what was sent
        except ConnectionClosed:
            pass

    # ---- running ------------------------------------------------------------------------------
    async def serve(self, on_ready: Optional[Callable[[str], None]] = None, stop_on_signals: bool = False) -> None:
        """Serve until :meth:`stop` (or cancellation); ``on_ready(url)`` once listening.
        ``stop_on_signals`` (main thread only): Ctrl-C and SIGTERM stop it the same way, so the
        pages are told."""
        serve = self.modules[0]
        self._loop, self._stopping = asyncio.get_running_loop(), asyncio.Event()
        if stop_on_signals:
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._loop.add_signal_handler(sig, self._stopping.set)
        try:
            async with serve(self._connection, self.host, self.port, process_request=self._http,
                             max_size=TRANSPORT_MAX_BYTES, compression=None, server_header=None,
                             close_timeout=CLOSE_TIMEOUT, create_connection=self.connection_class,
                             open_timeout=None,     # the front times out openings itself
                             logger=self.logger) as server:
                self.port = server.sockets[0].getsockname()[1]
                self.hosts.port = self.port
                self.stage.start()
                self.calibrations.begin()
                self._ready.set()
                if on_ready is not None:
                    on_ready(self.url)
                await self._stopping.wait()
                for connection in list(self.front_connections):   # idle ones kept for a next request
                    connection.close_http()
        finally:
            self.stage.stop()
            self.calibrations.close()

    def run(self, on_ready: Optional[Callable[[str], None]] = None) -> None:
        """Serve in this thread until Ctrl-C or SIGTERM."""
        try:
            asyncio.run(self.serve(on_ready, stop_on_signals=True))
        except KeyboardInterrupt:
            pass

    def start(self, timeout: float = 30.0) -> str:
        """Serve on a thread of its own; returns the URL once listening (raises what binding raised)."""
        def main():
            try:
                asyncio.run(self.serve())
            except BaseException as e:  # noqa: BLE001 - handed to the thread that called start()
                self._error = e
                self._ready.set()
        self._thread = threading.Thread(target=main, name="minifilm-demo-server", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise TimeoutError(f"the demo server did not start within {timeout} s")
        if self._error is not None:
            raise self._error
        return self.url

    def stop(self, timeout: float = 10.0) -> None:
        if self._loop is not None and self._stopping is not None:
            try:
                self._loop.call_soon_threadsafe(self._stopping.set)
            except RuntimeError:
                pass
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    def __enter__(self) -> "DemoServer":
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
