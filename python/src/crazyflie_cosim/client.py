"""A client of world-server: one connection per drone (docs/PROTOCOL.md §1,
§12.1), several drones from one script.

:class:`Drone` is one connection: the typed requests of PROTOCOL.md §4 and
§12.3, plus ``send``/``receive`` for pipelining (§5.2: a conforming world
answers a connection's requests in order, so several may be sent before
their replies are read).  :class:`World` claims several drones of one world
and drives them from one thread: it sends every drone's request first and
then reads every reply, which DESIGN.md §15's lockstep answers in any order.
"""

from __future__ import annotations

import collections
import socket
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from . import protocol as p


@dataclass(frozen=True)
class Endpoint:
    """``unix:PATH`` (a bare path means that too) or ``tcp:HOST:PORT`` (§1)."""

    kind: str
    path: str = ""
    host: str = ""
    port: int = 0

    @classmethod
    def parse(cls, text: str | Endpoint) -> Endpoint:
        if isinstance(text, Endpoint):
            return text
        text = str(text)
        if text.startswith("tcp:"):
            host, sep, port = text[4:].rpartition(":")
            if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
                raise ValueError(f"bad endpoint {text!r}: expected tcp:HOST:PORT")
            return cls("tcp", host=host.strip("[]"), port=int(port))
        path = text.removeprefix("unix:")
        if not path:
            raise ValueError(f"bad endpoint {text!r}: empty socket path")
        return cls("unix", path=path)

    def connect(self, timeout: float | None = None) -> socket.socket:
        if self.kind == "tcp":
            sock = socket.create_connection((self.host, self.port), timeout=timeout)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        else:
            deadline = None if timeout is None else time.monotonic() + timeout
            while True:
                sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                sock.settimeout(timeout)
                try:
                    sock.connect(self.path)
                    break
                except BlockingIOError:
                    # A full listen backlog (a world-server older than
                    # DESIGN.md §15 listens with a backlog of 1): retry.
                    sock.close()
                    if deadline is not None and time.monotonic() > deadline:
                        raise TimeoutError(f"{self}: the server's listen backlog stayed full") from None
                    time.sleep(0.002)
                except ConnectionRefusedError:
                    # The socket file appears at bind(2), before listen(2):
                    # a client that sees the path in that window is refused
                    # (seen on a loaded CI machine). Retry as the Rust
                    # client does (protocol::blocking::Connection::connect_retry);
                    # a server that is really gone still fails at the deadline.
                    sock.close()
                    if deadline is None:
                        deadline = time.monotonic() + 10.0
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.005)
                except OSError:
                    sock.close()
                    raise
        sock.settimeout(None)
        return sock

    def __str__(self) -> str:
        return f"tcp:{self.host}:{self.port}" if self.kind == "tcp" else f"unix:{self.path}"


class Drone:
    """One drone of a world: one connection, requests answered in order.

    ``name`` is the drone's name in the world file (``None`` for a
    single-drone world, whose claim carries no name, §12.1).
    """

    def __init__(
        self,
        sock: socket.socket,
        name: str | None = None,
        max_frame: int = p.MAX_FRAME,
        reply_timeout: float | None = None,
    ):
        self._sock = sock
        # A reply that takes longer raises TimeoutError; the connection is
        # then unusable (the world may be half-way through a frame).
        sock.settimeout(reply_timeout)
        self.name = name
        self.max_frame = max_frame
        self._pending: collections.deque[str] = collections.deque()
        self.init: p.InitData | None = None
        #: The drone's clock (ms of world time), advanced as §12.2 says.
        self.clock_ms: int | None = None
        self.stopped = False

    @classmethod
    def connect(
        cls,
        endpoint: str | Endpoint,
        name: str | None = None,
        timeout: float | None = 10.0,
        reply_timeout: float | None = None,
    ) -> Drone:
        """Connect (waiting at most ``timeout`` s); ``reply_timeout``: the
        longest wait for a reply (``None``: no limit)."""
        return cls(Endpoint.parse(endpoint).connect(timeout), name, reply_timeout=reply_timeout)

    # -- the wire ----------------------------------------------------------

    def send(self, msg: Mapping[str, Any]) -> None:
        """Send a request without waiting; its reply (if it has one) is read
        by a later :meth:`receive`."""
        self.send_many((msg,))

    def send_many(self, msgs: Iterable[Mapping[str, Any]]) -> None:
        """Send several requests in one write (PROTOCOL.md §5.2: the world
        answers them in order), without waiting."""
        msgs = list(msgs)
        if self.stopped and msgs:
            raise p.ProtocolError(f"drone {self.label}: no request after STOP")
        self._sock.sendall(b"".join(p.encode_frame(m) for m in msgs))
        for msg in msgs:
            cmd = msg["command"]
            if self.clock_ms is not None and self.init is not None:
                if cmd == "SET_VELOCITY":
                    self.clock_ms += self.init.timestep_ms
                elif cmd == "ADVANCE_TIME":
                    self.clock_ms += msg["time"]
            if p.expects_reply(msg):
                self._pending.append(cmd)

    def receive(self):
        """The reply to the oldest request sent and not yet answered."""
        if not self._pending:
            raise p.ProtocolError(f"drone {self.label}: no request is waiting for a reply")
        expected = self._pending.popleft()
        body = p.recv_frame(self._sock, self.max_frame)
        if body is None:
            raise p.Closed(expected)
        msg = p.loads(body)
        got = msg["command"]
        if got != expected and got != "ERROR":
            raise p.UnexpectedReply(expected, got)
        reply = p.parse_reply(msg)
        if got == "GET_INIT_DATA":
            self.init = reply
            self.clock_ms = round(reply.time_s * 1000)
        elif got == "STOP":
            self.stopped = True
        return reply

    def request(self, msg: Mapping[str, Any]):
        """Send a request and wait for its reply (``None`` for the commands
        without one)."""
        self.send(msg)
        return self.receive() if p.expects_reply(msg) else None

    @property
    def pending(self) -> int:
        """Requests sent whose replies were not read yet."""
        return len(self._pending)

    @property
    def label(self) -> str:
        return self.name or "cf1"

    def fileno(self) -> int:
        return self._sock.fileno()

    def close(self) -> None:
        self._sock.close()

    # -- typed requests (PROTOCOL.md §4, §12.3) -----------------------------

    def claim(self, image_encoding: str | None = None) -> p.InitData:
        """GET_INIT_DATA, the connection's first request (claims the drone)."""
        return self.request(p.get_init_data(image_encoding, self.name))

    def sensors(self) -> p.Sensors:
        return self.request(p.get_sensors())

    def state(self) -> p.State:
        return self.request(p.get_state())

    def image(self) -> p.Image:
        return self.request(p.get_image())

    def data2(self) -> p.Data2:
        return self.request(p.get_data_2())

    def data3(self) -> p.Data3:
        return self.request(p.get_data_3())

    def set_velocity(self, m1: float, m2: float, m3: float, m4: float) -> None:
        """Motor speed magnitudes for one basicTimeStep."""
        self.send(p.set_velocity(m1, m2, m3, m4))

    def advance_time(self, time_ms: int) -> None:
        self.send(p.advance_time(time_ms))

    def radio_send(self, radio: str, data: bytes, offset_ps: int = 0) -> None:
        self.send(p.radio_send(radio, data, offset_ps))

    def radio_recv(self) -> p.RadioRecv:
        return self.request(p.radio_recv())

    def stop(self) -> p.StopReply:
        """STOP: the propellers to 0; the reply when they stand still."""
        return self.request(p.stop())

    def __repr__(self) -> str:
        return f"Drone({self.label!r}, clock_ms={self.clock_ms})"


class World:
    """Several drones of one world-server, driven from one thread.

    >>> with World.connect("unix:/tmp/w.sock", ["A", "B", "C"]) as w:
    ...     w.send({d: protocol.set_velocity(50, 50, 50, 50) for d in w.names})
    ...     states = w.request({d: protocol.get_state() for d in w.names})
    """

    def __init__(self, drones: Iterable[Drone]):
        self.drones: dict[str, Drone] = {d.label: d for d in drones}

    @classmethod
    def connect(
        cls,
        endpoint: str | Endpoint,
        drones: Iterable[str] | None = None,
        image_encoding: str | None = None,
        timeout: float | None = 10.0,
        reply_timeout: float | None = None,
    ) -> World:
        """Connect one socket per drone and claim them all (§12.1); the
        replies come after the common warm-up, at 2.000 s.  ``drones`` are
        names of the world file (``None``: a single-drone world);
        ``timeout`` bounds each connect, ``reply_timeout`` each reply
        (``None``: no limit; a timed-out connection is unusable)."""
        ep = Endpoint.parse(endpoint)
        names = [None] if drones is None else list(drones)
        if len(set(names)) != len(names):
            raise ValueError(f"a drone is named twice in {names}")
        conns: list[Drone] = []
        try:
            for name in names:
                conns.append(Drone.connect(ep, name, timeout, reply_timeout))
            world = cls(conns)
            # Every claim first: the world answers none before all are made.
            world.send({d.label: p.get_init_data(image_encoding, d.name) for d in conns})
            world.receive()
        except BaseException:
            for d in conns:
                d.close()
            raise
        return world

    @property
    def names(self) -> list[str]:
        return list(self.drones)

    def __getitem__(self, name: str) -> Drone:
        return self.drones[name]

    def __iter__(self):
        return iter(self.drones.values())

    def __len__(self) -> int:
        return len(self.drones)

    def send(self, requests: Mapping[str, Mapping[str, Any] | Iterable[Mapping[str, Any]]]) -> None:
        """Send each drone its request (or list of requests, in one write),
        in world-file order, without reading anything."""
        unknown = set(requests) - set(self.drones)
        if unknown:
            raise KeyError(f"no drone {sorted(unknown)} in this world ({self.names})")
        for name, drone in self.drones.items():
            if name in requests:
                reqs = requests[name]
                drone.send_many([reqs] if isinstance(reqs, Mapping) else reqs)

    def receive(self) -> dict[str, Any]:
        """Every pending reply of every drone: ``{name: reply}``, or
        ``{name: [replies]}`` for a drone with several pending."""
        out: dict[str, Any] = {}
        for name, drone in self.drones.items():
            if drone.pending == 1:
                out[name] = drone.receive()
            elif drone.pending > 1:
                out[name] = [drone.receive() for _ in range(drone.pending)]
        return out

    def request(self, requests: Mapping[str, Mapping[str, Any] | Iterable[Mapping[str, Any]]]) -> dict[str, Any]:
        """:meth:`send`, then :meth:`receive`."""
        self.send(requests)
        return self.receive()

    def stop(self) -> dict[str, p.StopReply]:
        """STOP every drone still flying and wait for every reply; the world
        exits 0 after the last one (§12.2)."""
        return self.request({d.label: p.stop() for d in self if not d.stopped})

    def close(self) -> None:
        for d in self:
            d.close()

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
