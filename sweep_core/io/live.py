"""A run served live over Foxglove's WebSocket protocol (``sweep run --live``, and a
recording as it was recorded, ``sweep replay --live``), through the
foxglove-sdk package (imported only here, only when a live view starts; its server speaks the
``foxglove.sdk.v1`` subprotocol).

Every channel a run records is served too, with the same ROS 2 CDR bytes and ``ros2msg``
schemas (the recording's), so Foxglove decodes them as it decodes the recording and one layout
(``config/foxglove_layout.json``) serves both. Latched channels (``/walls``,
``/navigation_field``, ``/tf_static``) are sent again to a client that subscribes to them
(with the next state), since the server keeps no history. Messages are stamped with simulated
time. :meth:`LiveView.pace` holds the stepping thread so that simulated time runs at ``rate``
times real time (0: as fast as the run goes). A client that leaves is said in one line; the
run goes on.
"""
from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from sweep_core import checks
from sweep_core.errors import SceneError, SweepError, show
from sweep_core.io.cdr import SCHEMAS

DEFAULT_PORT = 8765
SUBPROTOCOL = "foxglove.sdk.v1"
#: slowest pace (x real time) of a live view: a simulated second then takes 1000 s (about 17
#: minutes); slower, a view barely moves (at 1e-300 a wait of 1e300 s was asked of the clock)
MIN_RATE = 1e-3


class LiveError(SweepError):
    """The live view cannot start (the port is in use, foxglove-sdk is missing)."""


def check_rate(value: object, field: str = "--live-rate") -> float:
    """A live view's pace: 0 (as fast as it goes) or a finite factor >= MIN_RATE."""
    rate = checks.number(value, field, nonnegative=True,
                         fix=f"set {field} to 0 (as fast as it goes) or at least {MIN_RATE:g}")
    if 0 < rate < MIN_RATE:
        raise SceneError(field, f"{show(rate)} x real time is below {MIN_RATE:g}, where a "
                         f"simulated second takes {1 / MIN_RATE:g} s of real time",
                         f"set {field} to at least {MIN_RATE:g}, or 0 for as fast as it goes")
    return rate


def _say(line: str) -> None:
    print(f"sweep: {line}", file=sys.stderr, flush=True)


class LiveView:
    """A Foxglove WebSocket server on ``host``:``port`` (0: a free port, see :attr:`port`)
    serving a run at ``rate`` times real time. Use as a context manager, or call :meth:`stop`.

    Raises:
        LiveError: one line naming the port and the fix, when the server cannot start.
    """

    def __init__(self, port: int = DEFAULT_PORT, rate: float = 1.0, host: str = "127.0.0.1",
                 say: Callable[[str], None] = _say) -> None:
        try:
            import foxglove
            from foxglove.websocket import ServerListener
        except ImportError as err:
            raise LiveError("--live needs the foxglove-sdk package (fix: pip install "
                            "foxglove-sdk)") from err
        self.rate, self._say = float(rate), say
        self._foxglove = foxglove
        self._context = foxglove.Context()
        self._channels: dict[str, Any] = {}
        self._latched: dict[str, tuple[int, bytes]] = {}
        self._resend: set[str] = set()
        self._subscribed: dict[int, set[int]] = {}
        self._lock = threading.Lock()
        self._clock: tuple[float, float] | None = None  # (simulated t, wall time) at the start
        view = self

        class Listener(ServerListener):
            def on_subscribe(self, client: Any, channel: Any) -> None:
                view._subscribe(client.id, channel.id, channel.topic)

            def on_unsubscribe(self, client: Any, channel: Any) -> None:
                view._unsubscribe(client.id, channel.id)

        try:
            self._server = foxglove.start_server(
                name="sweep", host=host, port=int(port), server_listener=Listener(),
                supported_encodings=["cdr"], context=self._context)
        except RuntimeError as err:
            reason = str(err).split(": ", 1)[-1]
            raise LiveError(f"--live {port}: cannot serve on {host}:{port} ({reason}) (fix: "
                            "another port, e.g. --live 8766, or 0 for any free port)") from None
        self.port = int(self._server.port)

    # -- the server's thread ---------------------------------------------------------------
    def _subscribe(self, client: int, channel: int, topic: str) -> None:
        with self._lock:
            self._subscribed.setdefault(client, set()).add(channel)
            if topic in self._latched:
                self._resend.add(topic)

    def _unsubscribe(self, client: int, channel: int) -> None:
        with self._lock:
            chans = self._subscribed.get(client)
            if chans is None:
                return
            chans.discard(channel)
            if chans:
                return
            del self._subscribed[client]
        self._say(f"live view: client {client} left (or unsubscribed from every channel); "
                  "the run goes on")

    # -- the stepping thread ---------------------------------------------------------------
    def add_channel(self, topic: str, msgtype: str, latched: bool = False) -> None:
        """Serve ``topic`` of a ROS 2 type of :data:`~sweep_core.io.cdr.SCHEMAS`."""
        schema = self._foxglove.Schema(name=msgtype, encoding="ros2msg",
                                       data=SCHEMAS[msgtype].encode())
        self._channels[topic] = self._foxglove.Channel(
            topic, schema=schema, message_encoding="cdr", context=self._context)
        if latched:
            self._latched[topic] = (0, b"")

    def write(self, topic: str, stamp_ns: int, data: bytes) -> None:
        """Send a message (CDR bytes) of a served topic to the subscribed clients."""
        if topic in self._latched:
            self._latched[topic] = (stamp_ns, data)
        self._channels[topic].log(data, log_time=stamp_ns)

    def pace(self, t: float) -> None:
        """After the state at simulated time t (s): the latched messages a new subscriber
        waits for, then a wait until t / rate s of real time have passed since the first."""
        if self._resend:
            with self._lock:
                topics, self._resend = self._resend, set()
            for topic in topics:
                stamp, data = self._latched[topic]
                if data:
                    self._channels[topic].log(data, log_time=stamp)
        if self.rate <= 0:
            return
        now = time.monotonic()
        if self._clock is None:
            self._clock = (t, now)
            return
        ahead = self._clock[1] + (t - self._clock[0]) / self.rate - now
        if ahead > 0:
            time.sleep(ahead)

    @property
    def clients(self) -> int:
        """Clients subscribed to at least one channel."""
        with self._lock:
            return len(self._subscribed)

    def stop(self) -> None:
        """Close the server (clients see the connection end)."""
        self._server.stop()

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


#: the channels a recording of sweep holds latched (sent again to a late subscriber)
LATCHED = ("/walls", "/tf_static", "/navigation_field")


def serve_recording(path: str | os.PathLike[str], view: LiveView) -> int:
    """Serves the recording ``path`` on ``view`` as it was recorded (``sweep replay --live``):
    every message of a type the project encodes (:data:`~sweep_core.io.cdr.SCHEMAS`; others
    are skipped), with its recorded bytes, in file order, paced on the recording's log clock
    at the view's rate. Returns the number of messages served."""
    from sweep_core.io.recording import read_recording

    served, first = 0, None
    channels: set[str] = set()
    for msg in read_recording(path):
        if msg.msgtype not in SCHEMAS:
            continue
        if msg.topic not in channels:
            view.add_channel(msg.topic, msg.msgtype, latched=msg.topic in LATCHED)
            channels.add(msg.topic)
        first = msg.log_time_ns if first is None else first
        view.pace((msg.log_time_ns - first) / 1e9)
        view.write(msg.topic, msg.log_time_ns, msg.data)
        served += 1
    return served
