"""Steer a character live in the browser: the paper's real-time stylised controller (Sec. 4.4).

    minifilm demo --params ../shared/data/released-lpn      # the authors' released network
    minifilm demo --run runs/train_small                    # a run folder written by minifilm train
    minifilm demo --params DIR --port 0                     # any free port (the URL is printed)
    minifilm demo --params DIR --record demo.gif            # no server: a scripted session as a GIF
    minifilm demo --params DIR --styles PACK                # with styles taught by finetune --params

Prints the URL of a page on this machine (127.0.0.1; --host opts in to another interface). On
every interface the server answers only requests that name it (this machine's names and
addresses, localhost, and each --allow-host NAME): a web page elsewhere cannot reach it through a
DNS name of its own. On
the page: W A S D or the arrows move, Q / E turn, Shift runs, nothing held stops; a gamepad's left
stick moves, right stick turns, right trigger runs; pick a style, or blend three in the triangle;
toggle foot locking and the skeleton fit. Each open page gets its own character (up to
--max-characters); closing the page frees it. Ctrl-C stops the server.

The page is served within a few seconds. The speed calibration (per style) of the released
network comes with the package; a trained run's, or a new style's, is measured in the background,
printed here as it goes, and kept in the user's cache folder ($XDG_CACHE_HOME/minifilm, or
~/.cache/minifilm; MINIFILM_CACHE overrides it) for the next start (--recalibrate measures every
style again).

Needs the websockets package: pip install 'minifilm[demo]'.
"""
from __future__ import annotations

import sys

from minifilm.cli.args import add_network_source, gif_path, in_range
from minifilm.demo.calibration_cache import SHIPPED, CalibrationCache
from minifilm.demo.character import DemoSettings
from minifilm.demo.record import record_gif
from minifilm.demo.hosts import check_name, is_loopback
from minifilm.demo.server import DemoServer, check_bind_host
from minifilm.demo.source import DemoSource
from minifilm.errors import InputError
from minifilm.files import check_writable

HELP = "steer a character live in the browser (released network or a trained run)"


def add_arguments(ap) -> None:
    add_network_source(ap)
    ap.add_argument("--host", default="127.0.0.1",
                    help="interface to listen on (default 127.0.0.1, this machine only; another opens the demo "
                         "to whoever can reach that interface)")
    ap.add_argument("--allow-host", action="append", default=[], metavar="NAME",
                    help="another name this server may be reached by (e.g. a DNS name of this machine used by "
                         "other machines with --host 0.0.0.0); repeatable")
    ap.add_argument("--port", type=in_range(0, 65535, int), default=8765, help="port (0: any free port)")
    ap.add_argument("--max-characters", type=in_range(1, 16, int), default=4,
                    help="pages served at once, one character each (1-16)")
    ap.add_argument("--style", help="the style every character starts in (default Neutral, or the first)")
    ap.add_argument("--walk-speed", type=in_range(0.1, 5.0), default=1.3, help="walking speed, m/s")
    ap.add_argument("--run-speed", type=in_range(0.1, 8.0), default=2.8, help="running speed (Shift), m/s")
    ap.add_argument("--turn-rate", type=in_range(10.0, 720.0), default=120.0, help="turning speed (Q/E), deg/s")
    ap.add_argument("--foot-lock", action="store_true", help="start with foot locking on")
    ap.add_argument("--no-fit", action="store_true", help="start with the skeleton fit off")
    ap.add_argument("--no-calibrate", action="store_true",
                    help="command the raw speed (the network then walks slower or faster than asked)")
    ap.add_argument("--recalibrate", action="store_true",
                    help="measure every style's speed calibration again (the package's and the cache's are not read; "
                         "the new ones replace the cache's)")
    ap.add_argument("--record", type=gif_path, help="write a scripted session as an animated GIF instead of serving")
    ap.add_argument("--record-seconds", type=in_range(1.0, 60.0), default=5.0, help="length of --record, seconds")


def run(args) -> int:
    host = check_bind_host(args.host)           # before loading anything: a clear error at once
    if args.run_speed < args.walk_speed:
        raise ValueError(f"--run-speed {args.run_speed:g} is slower than --walk-speed {args.walk_speed:g}: "
                         "Shift runs, so the running speed must be at least the walking speed")
    allow = [check_name(n) for n in args.allow_host]
    if args.record is not None:
        check_writable(args.record, "--record")
    if args.recalibrate and args.no_calibrate:
        raise InputError("--recalibrate measures the speed calibrations that --no-calibrate turns off: "
                         "give one of them")
    if args.styles is not None and args.params is None:
        raise InputError("--styles (a style pack) is for --params; a run folder keeps its styles itself")
    source = DemoSource.released(args.params, calibrate=not args.no_calibrate, pack=args.styles) \
        if args.params is not None else DemoSource.run_folder(args.run, calibrate=not args.no_calibrate)
    settings = DemoSettings(style=args.style or source.default_style(), walk_speed=args.walk_speed,
                            run_speed=args.run_speed, turn_rate_deg=args.turn_rate, foot_lock=args.foot_lock,
                            fit=not args.no_fit)
    if args.record is not None:
        path = record_gif(source, settings, args.record, seconds=args.record_seconds)
        print(f"recorded {args.record_seconds:g} s of {settings.style} -> {path}")
        return 0
    cache = CalibrationCache(source, shipped=None if args.recalibrate else SHIPPED,
                             ignore_cached=args.recalibrate) if source.calibrate else None
    try:
        server = DemoServer(source, settings, host=host, port=args.port, max_characters=args.max_characters,
                            allow_hosts=allow, calibration_cache=cache)
    except ImportError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if not is_loopback(host):
        print(f"warning: listening on {host}: anyone who can reach it can open the demo", file=sys.stderr)

    def ready(url: str) -> None:
        print(f"minifilm demo: {source.name}, {len(source.library)} styles at {source.fps:g} fps, "
              f"up to {args.max_characters} pages\n  open {url}   (Ctrl-C stops)", flush=True)
        if server.everywhere:
            names = ", ".join(sorted(n for n in server.hosts.names if n not in ("localhost", host.strip("[]"))))
            print(f"  from another machine: http://<this machine's name or address>:{server.port}/ "
                  f"(names allowed: {names or 'none'}; add more with --allow-host NAME)", flush=True)

    try:
        server.run(ready)
    except OSError as e:          # the port is taken, the address is not this machine's, ...
        raise ValueError(f"cannot listen on {host}:{args.port}: {e.strerror or e}") from None
    return 0
