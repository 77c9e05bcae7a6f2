"""The ``--live [HOST:]PORT`` and ``--live-speed`` options of ``drive``, ``replay`` and ``race``: checked
before anything runs (one line naming the flag, exit 2), the Foxglove server started, the stream
paced against the wall clock."""

from __future__ import annotations

import contextlib
import socket
import sys
import time
from collections.abc import Callable

from mcl.cli.common import Parser, live_speed
from mcl.io.live import LiveServer, parse_live_address

__all__ = ["Pacer", "add_live_arguments", "check_live", "start_live_view", "stop_live_view"]


def add_live_arguments(parser: Parser, what: str) -> None:
    """Add ``--live`` and ``--live-speed`` to ``parser`` (``what``: "drive", "replay", "race")."""
    parser.add_argument(
        "--live",
        default=None,
        metavar="[HOST:]PORT",
        help=f"stream the {what} to Foxglove as it runs: a WebSocket server on PORT, bound to "
        "127.0.0.1 unless HOST is given (e.g. 8765 or 0.0.0.0:8765); in Foxglove, "
        "Open connection, ws://localhost:PORT (extra [live]; default: no live view)",
    )
    parser.add_argument(
        "--live-speed",
        type=live_speed,
        default=1.0,
        metavar="X",
        help="with --live: X times real time (0.01 to 1000), 0 as fast as it runs "
        "(default: %(default)s)",
    )


def check_live(parser: Parser, text: str | None, speed: float) -> tuple[str, int] | None:
    """``--live`` as (host, port), or None when absent; a bad value stops naming the flag."""
    if text is None:
        return None
    try:
        address = parse_live_address(text)
    except ValueError as exc:
        parser.fail("--live", str(exc))
    try:
        import foxglove  # noqa: F401
    except ImportError:
        parser.fail(
            "--live",
            "needs foxglove-sdk: pip install -e '.[live]' in a checkout, "
            "pip install 'racecar-sim[live]' from PyPI",
        )
    return address


def start_live_view(
    parser: Parser,
    address: tuple[str, int] | None,
    start: Callable[..., LiveServer] | None = None,
) -> LiveServer | None:
    """Start the server at ``address`` (from [check_live][mcl.cli.live_options.check_live])
    without waiting for it, and say where to connect once it listens; ``start(address text,
    wait=False)`` makes the server (default: the recording's topics,
    [start_live][mcl.io.bag_writer.start_live]). A port given and in use stops here, naming the
    flag; a server that fails later warns in one line and the drive goes on."""
    if address is None:
        return None
    if start is None:
        from mcl.io.bag_writer import start_live as start

    host, port = address
    if port:
        problem = _bind_problem(host, port)
        if problem:
            parser.fail("--live", f"cannot serve the live view on {host}:{port}: {problem}")
    try:
        server = start(f"[{host}]:{port}" if ":" in host else f"{host}:{port}", wait=False)
    except RuntimeError as exc:
        parser.fail("--live", str(exc))
    server.when_ready(
        lambda url: print(f"live view: in Foxglove, Open connection, {url}", file=sys.stderr,
                          flush=True),
        lambda why: print(f"warning: the live view did not start ({why}); the drive goes on "
                          "without it", file=sys.stderr, flush=True),
    )  # fmt: skip
    return server


def _bind_problem(host: str, port: int) -> str | None:
    """Why ``host:port`` cannot be bound now (e.g. in use), or None."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
        family, kind, proto, _, where = infos[0]
        with contextlib.closing(socket.socket(family, kind, proto)) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            probe.bind(where)
    except OSError as exc:
        return str(exc)
    return None


def stop_live_view(server: LiveServer | None) -> None:
    """Stop the server from [start_live_view][mcl.cli.live_options.start_live_view] and say in
    one line what it sent, dropped and refused ([LiveServer.summary][mcl.io.live.LiveServer.summary])."""
    if server is None:
        return
    server.close()
    print(server.summary(), file=sys.stderr, flush=True)


class Pacer:
    """Call with the simulated time (s) after each step: sleeps so that the stream runs at
    ``speed`` times real time (0: never sleeps)."""

    def __init__(self, speed: float) -> None:
        self.speed = float(speed)
        self._start: float | None = None

    def __call__(self, sim_time: float) -> None:
        if self.speed <= 0:
            return
        now = time.perf_counter()
        if self._start is None or sim_time == 0.0:
            self._start = now - sim_time / self.speed
        wait = self._start + sim_time / self.speed - now
        if wait > 0:
            time.sleep(wait)
