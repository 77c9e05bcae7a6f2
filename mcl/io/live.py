"""Watch a drive or a replay live in Foxglove: a Foxglove WebSocket server (the ``foxglove-sdk``
package, extra ``[live]``) that streams the topics of the MCAP recording as they are made.

The messages are the recording's own (:class:`mcl.io.BagRecorder`): ROS 2 CDR bytes with their
``ros2msg`` schemas, on the same topics (``/scan``, ``/odom``, ``/tf``, ``/tf_static``,
``/ground_truth``, ``/pf/pose``, ``/pf/particles``, ``/map``), so a Foxglove layout made for a
recording works live too. ``/map`` and ``/tf_static`` are sent once and again to each client that
subscribes later. Nothing is serialized for a topic no client subscribes to.

Open Foxglove, "Open connection", ``ws://localhost:PORT``.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = ["DEFAULT_HOST", "LATCHED", "LiveServer", "parse_live_address"]

DEFAULT_HOST = "127.0.0.1"
"""The server binds to this address unless a host is given (only this machine can connect)."""
LATCHED = ("/map", "/tf_static")
"""Topics whose last message every new subscriber receives (they are published once)."""


def parse_live_address(text: str | int) -> tuple[str, int]:
    """``"[HOST:]PORT"`` as (host, port); the host defaults to :data:`DEFAULT_HOST`.

    Raises:
        ValueError: not ``PORT`` or ``HOST:PORT`` with a port in 0-65535 (0: any free port).
    """
    spec = str(text).strip()
    host, sep, port_text = spec.rpartition(":")
    if not sep:
        host = DEFAULT_HOST
    host = host.strip("[]")  # [::1]:8765
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"expected [HOST:]PORT, e.g. 8765 or 0.0.0.0:8765, got {spec!r}") from None
    if not 0 <= port <= 65535 or (sep and not host):
        raise ValueError(f"expected [HOST:]PORT with a port in 0-65535, got {spec!r}")
    return host, port


class LiveServer:
    """A Foxglove WebSocket server with one channel per recorded topic.

    Args:
        address: ``"[HOST:]PORT"`` (see :func:`parse_live_address`) or a port number.
        types: topic -> ROS 2 message type, e.g. ``{"/scan": "sensor_msgs/msg/LaserScan"}``.
        typestore: the rosbags typestore that serializes the messages (for the schemas).
        name: the server's name shown in Foxglove.

    Raises:
        ValueError: a bad address.
        RuntimeError: foxglove-sdk is not installed, or the port cannot be bound.
    """

    def __init__(
        self,
        address: str | int,
        types: dict[str, str],
        typestore: Typestore,
        name: str = "racecar-sim",
    ) -> None:
        self.host, port = parse_live_address(address)
        try:
            import foxglove
        except ImportError:
            raise RuntimeError(
                "the live view needs foxglove-sdk: pip install 'racecar-sim[live]'"
            ) from None
        self._context = foxglove.Context()
        self._channels = {}
        for topic, kind in types.items():
            msgdef, _ = typestore.generate_msgdef(kind, ros_version=2)
            schema = foxglove.Schema(name=kind, encoding="ros2msg", data=msgdef.encode())
            self._channels[topic] = foxglove.Channel(
                topic, schema=schema, message_encoding="cdr", context=self._context
            )
        self._latched: dict[str, tuple[bytes, int]] = {}
        self._lock = threading.Lock()
        listener = _resend_listener(foxglove.ServerListener, self)
        try:
            self._server = foxglove.start_server(
                name=name,
                host=self.host,
                port=port,
                context=self._context,
                server_listener=listener,
            )
        except Exception as exc:  # the SDK raises its own error type for a busy port
            raise RuntimeError(f"cannot serve the live view on {self.host}:{port}: {exc}") from None
        self.port = int(self._server.port)
        self.n_published = 0

    @property
    def url(self) -> str:
        """What to type into Foxglove's "Open connection"."""
        host = "localhost" if self.host in ("127.0.0.1", "0.0.0.0", "::", "::1") else self.host
        return f"ws://{host}:{self.port}"

    def wants(self, topic: str) -> bool:
        """Whether a message on ``topic`` would reach anyone (latched topics always count)."""
        channel = self._channels.get(topic)
        return channel is not None and (topic in LATCHED or channel.has_sinks())

    def publish(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Send one serialized message on ``topic`` (stamped ``log_time_ns``)."""
        if topic in LATCHED:
            with self._lock:
                self._latched[topic] = (data, log_time_ns)
        self._channels[topic].log(data, log_time=log_time_ns)
        self.n_published += 1

    def resend_latched(self, topics: Iterable[str]) -> None:
        """Send the last message of each latched topic of ``topics`` again (a client that has just
        subscribed gets the map and the static transforms)."""
        with self._lock:
            latched = {t: self._latched[t] for t in topics if t in self._latched}
        for topic, (data, ns) in latched.items():
            self._channels[topic].log(data, log_time=ns)

    def close(self) -> None:
        """Stop the server (clients are disconnected)."""
        if self._server is not None:
            self._server.stop()
            self._server = None

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _resend_listener(base: type, server: LiveServer):
    """A server listener (``foxglove.ServerListener``, whose other callbacks do nothing): a client
    that subscribes to a latched topic gets its last message."""

    class Resend(base):
        def on_subscribe(self, client, channel) -> None:
            if channel.topic in LATCHED:
                server.resend_latched([channel.topic])

    return Resend()
