"""The co-simulation wire protocol (docs/PROTOCOL.md), framing and messages.

A frame is a 4-byte little-endian length N followed by N bytes of compact
UTF-8 JSON (PROTOCOL.md §2).  Writers in this project spell JSON as
nlohmann's ``json::dump()`` does (§3: keys sorted by byte order, no spaces,
shortest round-trip doubles laid out in fixed notation for decimal exponents
-4 < e <= 15, NaN and infinities as ``null``); :func:`dumps` does the same so
that frames sent from Python diff cleanly against the Rust tools' traces.

Requests are plain dicts built by the functions below (one per command of
§4, checked as the Rust decoder checks them); replies are parsed into small
frozen dataclasses by :func:`parse_reply`.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import socket
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field
from decimal import Decimal
from typing import Any

#: Default maximum frame body (PROTOCOL.md §2: ours is 64 MiB).
MAX_FRAME = 64 << 20

#: Image encodings a platform may ask for in GET_INIT_DATA (§5).
IMAGE_ENCODINGS = ("array", "base64", "shm")

#: Radios of the channel (§12.3) and the payload sizes they carry.
RADIO_PAYLOAD = {"uwb": 127, "p2p": 60}

#: Commands with no reply (§4).
NO_REPLY = frozenset({"SET_VELOCITY", "ADVANCE_TIME", "RADIO_SEND"})

_HEADER = struct.Struct("<I")


class ProtocolError(Exception):
    """A frame or a message that breaks docs/PROTOCOL.md."""


class FrameTooLarge(ProtocolError):
    def __init__(self, length: int, maximum: int):
        super().__init__(f"frame of {length} bytes exceeds the maximum frame size ({maximum})")
        self.length = length
        self.maximum = maximum


class Truncated(ProtocolError):
    def __init__(self, expected: int, got: int):
        super().__init__(f"connection closed in the middle of a frame (expected {expected} bytes, got {got})")
        self.expected = expected
        self.got = got


class Closed(ProtocolError):
    """The peer closed the connection where a reply was expected."""

    def __init__(self, command: str):
        super().__init__(f"the world closed the connection before answering {command}")
        self.command = command


class RemoteError(ProtocolError):
    """An ``{"command":"ERROR"}`` reply; ``reason`` is the world's one-line text."""

    def __init__(self, reason: str):
        super().__init__(f"the world answered ERROR: {reason}")
        self.reason = reason


class UnexpectedReply(ProtocolError):
    def __init__(self, expected: str, got: str):
        super().__init__(f"expected a {expected} reply, got {got}")
        self.expected = expected
        self.got = got


# ---------------------------------------------------------------- JSON ----


def _float(x: float) -> str:
    """A double as nlohmann's dump() lays it out (PROTOCOL.md §3)."""
    if not math.isfinite(x):
        return "null"
    # Python's repr is the shortest round-trip spelling; Decimal splits it
    # into its digits and exponent exactly: value = 0.DIGITS * 10**n.
    _, dtuple, exp = Decimal(repr(abs(x))).as_tuple()
    digits = "".join(map(str, dtuple)).lstrip("0")
    sign = "-" if math.copysign(1.0, x) < 0 else ""
    if not digits:
        return sign + "0.0"
    stripped = digits.rstrip("0")
    exp += len(digits) - len(stripped)
    digits = stripped
    n = len(digits) + exp
    k = len(digits)
    if k <= n <= 15:
        return sign + digits + "0" * (n - k) + ".0"
    if 0 < n <= 15:
        return sign + digits[:n] + "." + digits[n:]
    if -4 < n <= 0:
        return sign + "0." + "0" * (-n) + digits
    e = n - 1
    body = digits[0] + ("." + digits[1:] if k > 1 else "")
    return f"{sign}{body}e{'+' if e >= 0 else '-'}{abs(e):02d}"


def _encode(v: Any, out: list[str]) -> None:
    if v is None:
        out.append("null")
    elif v is True:
        out.append("true")
    elif v is False:
        out.append("false")
    elif isinstance(v, int):
        out.append(str(int(v)))
    elif isinstance(v, float):
        out.append(_float(v))
    elif isinstance(v, str):
        out.append(json.dumps(v, ensure_ascii=False))
    elif isinstance(v, Mapping):
        out.append("{")
        for i, key in enumerate(sorted(v, key=lambda s: s.encode("utf-8"))):
            if not isinstance(key, str):
                raise TypeError(f"JSON object keys must be strings, not {key!r}")
            if i:
                out.append(",")
            out.append(json.dumps(key, ensure_ascii=False))
            out.append(":")
            _encode(v[key], out)
        out.append("}")
    elif isinstance(v, (list, tuple)):
        out.append("[")
        for i, item in enumerate(v):
            if i:
                out.append(",")
            _encode(item, out)
        out.append("]")
    elif hasattr(v, "__float__"):  # numpy scalars
        if hasattr(v, "__index__"):
            out.append(str(int(v)))
        else:
            out.append(_float(float(v)))
    else:
        raise TypeError(f"cannot encode {type(v).__name__} as JSON")


def dumps(msg: Mapping[str, Any]) -> str:
    """The compact JSON of a message, spelled as our Rust encoder spells it."""
    out: list[str] = []
    _encode(msg, out)
    return "".join(out)


def loads(body: bytes) -> dict[str, Any]:
    """A frame body as a message (any valid JSON spelling; an object with a
    string ``command``)."""
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ProtocolError(f"invalid UTF-8 at byte {e.start}") from None
    try:
        msg = json.loads(text)
    except json.JSONDecodeError as e:
        raise ProtocolError(f"invalid JSON at byte {e.pos}: {e.msg}") from None
    if not isinstance(msg, dict):
        raise ProtocolError("the message is not a JSON object")
    if not isinstance(msg.get("command"), str):
        raise ProtocolError('the message has no string "command"')
    return msg


# ------------------------------------------------------------- framing ----


def encode_frame(msg: Mapping[str, Any]) -> bytes:
    """Header and body of one message."""
    body = dumps(msg).encode("utf-8")
    return _HEADER.pack(len(body)) + body


def _recv_exactly(sock: socket.socket, n: int, started: bool) -> bytes | None:
    buf = bytearray(n)
    view = memoryview(buf)
    got = 0
    while got < n:
        k = sock.recv_into(view[got:], n - got)
        if k == 0:
            if got == 0 and not started:
                return None
            raise Truncated(n, got)
        got += k
    return bytes(buf)


def recv_frame(sock: socket.socket, max_frame: int = MAX_FRAME) -> bytes | None:
    """The body of the next frame, or ``None`` on a clean end of stream
    (between frames).  Loops on short reads; checks the length before
    allocating (PROTOCOL.md §2)."""
    header = _recv_exactly(sock, 4, started=False)
    if header is None:
        return None
    (n,) = _HEADER.unpack(header)
    if n > max_frame:
        raise FrameTooLarge(n, max_frame)
    return _recv_exactly(sock, n, started=True)


def send_frame(sock: socket.socket, msg: Mapping[str, Any]) -> None:
    sock.sendall(encode_frame(msg))


# ------------------------------------------------------------ requests ----


def _finite(name: str, v: float) -> float:
    v = float(v)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, not {v}")
    return v


def get_init_data(image_encoding: str | None = None, drone: str | None = None) -> dict:
    msg: dict[str, Any] = {"command": "GET_INIT_DATA"}
    if image_encoding is not None:
        if image_encoding not in IMAGE_ENCODINGS:
            raise ValueError(f"image_encoding must be one of {IMAGE_ENCODINGS}, not {image_encoding!r}")
        msg["image_encoding"] = image_encoding
    if drone is not None:
        msg["drone"] = str(drone)
    return msg


def get_sensors() -> dict:
    return {"command": "GET_SENSORS"}


def get_state() -> dict:
    return {"command": "GET_STATE"}


def get_image() -> dict:
    return {"command": "GET_IMAGE"}


def get_data_2() -> dict:
    return {"command": "GET_DATA_2"}


def get_data_3() -> dict:
    return {"command": "GET_DATA_3"}


def stop() -> dict:
    return {"command": "STOP"}


def set_velocity(m1: float, m2: float, m3: float, m4: float) -> dict:
    """Motor speed magnitudes (rad/s, >= 0; the world applies the spin signs)
    for exactly one basicTimeStep (§6.3)."""
    msg: dict[str, Any] = {"command": "SET_VELOCITY"}
    for name, v in (("m1", m1), ("m2", m2), ("m3", m3), ("m4", m4)):
        v = _finite(name, v)
        if v < 0:
            raise ValueError(f"{name} must be >= 0 rad/s (a magnitude), not {v}")
        msg[name] = v
    return msg


def advance_time(time_ms: int) -> dict:
    """Step ``time_ms`` (a multiple of TIMESTEP) holding the motor targets."""
    if isinstance(time_ms, bool) or int(time_ms) != time_ms or time_ms < 0:
        raise ValueError(f"ADVANCE_TIME needs a non-negative integer of ms, not {time_ms!r}")
    return {"command": "ADVANCE_TIME", "time": int(time_ms)}


def radio_send(radio: str, data: bytes, offset_ps: int = 0) -> dict:
    """A frame leaving at the drone's clock + ``offset_ps`` (§12.3)."""
    if radio not in RADIO_PAYLOAD:
        raise ValueError(f"radio must be one of {tuple(RADIO_PAYLOAD)}, not {radio!r}")
    if not 1 <= len(data) <= RADIO_PAYLOAD[radio]:
        raise ValueError(f"a {radio} payload has 1-{RADIO_PAYLOAD[radio]} bytes, not {len(data)}")
    if isinstance(offset_ps, bool) or int(offset_ps) != offset_ps or offset_ps < 0:
        raise ValueError(f"offset_ps must be a non-negative integer, not {offset_ps!r}")
    return {
        "command": "RADIO_SEND",
        "radio": radio,
        "data": base64.b64encode(bytes(data)).decode("ascii"),
        "offset_ps": int(offset_ps),
    }


def radio_recv() -> dict:
    return {"command": "RADIO_RECV"}


# ------------------------------------------------------------- replies ----


def _num(msg: Mapping[str, Any], key: str) -> float:
    if key not in msg:
        raise ProtocolError(f"bad {msg.get('command')} reply: missing field `{key}`")
    v = msg[key]
    if v is None:  # NaN and infinities travel as null (§3).
        return math.nan
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ProtocolError(f"bad {msg.get('command')} reply: `{key}` is not a number")
    return float(v)


def _int(msg: Mapping[str, Any], key: str) -> int:
    v = msg.get(key)
    if isinstance(v, bool) or not isinstance(v, int):
        raise ProtocolError(f"bad {msg.get('command')} reply: `{key}` is not an integer")
    return v


@dataclass(frozen=True)
class InitData:
    x: float
    y: float
    z: float
    time_s: float
    timestep_ms: int
    image_encoding: str
    drone: str | None = None


@dataclass(frozen=True)
class Sensors:
    time_s: float
    x: float
    y: float
    z: float
    altitude: float
    roll: float
    pitch: float
    yaw: float
    roll_rate: float
    pitch_rate: float
    yaw_rate: float
    range_front: float
    range_left: float
    range_back: float
    range_right: float
    extra: dict = field(default_factory=dict, compare=False)


@dataclass(frozen=True)
class State:
    time_s: float
    x: float
    y: float
    z: float
    qw: float
    qx: float
    qy: float
    qz: float
    vx: float
    vy: float
    vz: float
    omega_x: float
    omega_y: float
    omega_z: float
    w1: float
    w2: float
    w3: float
    w4: float
    collisions: int
    drone_distances: dict | None = None


@dataclass(frozen=True)
class Image:
    """A grey image: ``width * height`` bytes, row-major from the top left."""

    width: int
    height: int
    pixels: bytes


@dataclass(frozen=True)
class Data2:
    velocity: float
    velocity_x: float
    velocity_y: float


@dataclass(frozen=True)
class Data3:
    velocity: float
    velocity_z: float
    pitch: float


@dataclass(frozen=True)
class StopReply:
    time_s: float
    stop_time_ms: int
    gates_passed: int | None = None


@dataclass(frozen=True)
class Packet:
    radio: str
    data: bytes
    sender: str
    rssi: float
    time_ps: int
    rx_stamp: int | None = None


@dataclass(frozen=True)
class TxDone:
    radio: str
    time_ps: int
    tx_stamp: int | None = None


@dataclass(frozen=True)
class RadioRecv:
    packets: tuple[Packet, ...]
    tx_done: tuple[TxDone, ...]


_SENSOR_KEYS = (
    ("time_s", "TIME"), ("x", "COORDINATE_X"), ("y", "COORDINATE_Y"), ("z", "COORDINATE_Z"),
    ("altitude", "ALTITUDE"), ("roll", "ROLL"), ("pitch", "PITCH"), ("yaw", "YAW"),
    ("roll_rate", "ROLL_RATE"), ("pitch_rate", "PITCH_RATE"), ("yaw_rate", "YAW_RATE"),
    ("range_front", "RANGE_FRONT"), ("range_left", "RANGE_LEFT"),
    ("range_back", "RANGE_BACK"), ("range_right", "RANGE_RIGHT"),
)  # fmt: skip

_STATE_KEYS = (
    ("time_s", "TIME"), ("x", "COORDINATE_X"), ("y", "COORDINATE_Y"), ("z", "COORDINATE_Z"),
    ("qw", "QW"), ("qx", "QX"), ("qy", "QY"), ("qz", "QZ"),
    ("vx", "VELOCITY_X"), ("vy", "VELOCITY_Y"), ("vz", "VELOCITY_Z"),
    ("omega_x", "OMEGA_X"), ("omega_y", "OMEGA_Y"), ("omega_z", "OMEGA_Z"),
    ("w1", "W1"), ("w2", "W2"), ("w3", "W3"), ("w4", "W4"),
)  # fmt: skip


def decode_image(camera: Mapping[str, Any]) -> Image:
    """The pixels of a ``camera`` object in any of the three encodings (§5)."""
    if not isinstance(camera, Mapping):
        raise ProtocolError("bad GET_IMAGE reply: `camera` is not an object")
    w, h = _int(camera, "width"), _int(camera, "height")
    n = w * h
    enc = camera.get("encoding")
    data = camera.get("data")
    if enc == "shm":
        pixels = _read_shm(camera, w, h)
    elif isinstance(data, str):
        if enc not in (None, "base64"):
            raise ProtocolError(f"bad GET_IMAGE reply: string data with encoding {enc!r}")
        try:
            pixels = base64.b64decode(data, validate=True)
        except binascii.Error as e:
            raise ProtocolError(f"bad GET_IMAGE reply: invalid base64 ({e})") from None
    elif isinstance(data, list):
        if enc not in (None, "array"):
            raise ProtocolError(f"bad GET_IMAGE reply: array data with encoding {enc!r}")
        try:
            pixels = bytes(data)
        except (TypeError, ValueError):
            raise ProtocolError("bad GET_IMAGE reply: a pixel is not an integer 0-255") from None
    else:
        raise ProtocolError("bad GET_IMAGE reply: `data` is neither an array nor a string")
    if len(pixels) != n:
        raise ProtocolError(f"bad GET_IMAGE reply: {len(pixels)} pixels for {w}x{h}")
    return Image(w, h, pixels)


_SHM_HEADER = struct.Struct("<8sQIIQ")


def _read_shm(camera: Mapping[str, Any], w: int, h: int) -> Image:
    """A frame of the world's shared-memory file (PROTOCOL.md §5.1)."""
    path = camera.get("path")
    seq = _int(camera, "seq")
    try:
        with open(path, "rb") as f:
            head = f.read(_SHM_HEADER.size)
            if len(head) != _SHM_HEADER.size:
                raise ProtocolError(f"shared-memory image file {path} is shorter than its header")
            magic, fseq, fw, fh, n = _SHM_HEADER.unpack(head)
            if magic != b"CFSHMIMG" or (fseq, fw, fh, n) != (seq, w, h, w * h):
                raise ProtocolError(
                    f"shared-memory image file {path} holds frame {fseq} {fw}x{fh}, the reply names frame {seq} {w}x{h}"
                )
            return f.read(n)
    except OSError as e:
        raise ProtocolError(
            f"cannot open the world's shared-memory image file {path}: {e.strerror} "
            '(image_encoding "shm" needs the platform and the world on one host; '
            'use "array" or "base64" otherwise)'
        ) from None


def parse_reply(msg: Mapping[str, Any]):
    """A reply as its dataclass; ERROR replies raise :class:`RemoteError`."""
    cmd = msg.get("command")
    if cmd == "ERROR":
        raise RemoteError(str(msg.get("error", "(no reason given)")))
    if cmd == "GET_INIT_DATA":
        return InitData(
            _num(msg, "COORDINATE_X"), _num(msg, "COORDINATE_Y"), _num(msg, "COORDINATE_Z"),
            _num(msg, "TIME"), _int(msg, "TIMESTEP"),
            # A thesis-era world omits the key, which means "array" (§4).
            msg.get("image_encoding", "array"), msg.get("drone"),
        )  # fmt: skip
    if cmd == "GET_SENSORS":
        known = {k for _, k in _SENSOR_KEYS} | {"command"}
        extra = {k: v for k, v in msg.items() if k not in known}
        return Sensors(**{a: _num(msg, k) for a, k in _SENSOR_KEYS}, extra=extra)
    if cmd == "GET_STATE":
        return State(
            **{a: _num(msg, k) for a, k in _STATE_KEYS},
            collisions=_int(msg, "COLLISIONS"),
            drone_distances=msg.get("DRONE_DISTANCES"),
        )
    if cmd == "GET_IMAGE":
        return decode_image(msg.get("camera"))
    if cmd == "GET_DATA_2":
        return Data2(_num(msg, "VELOCITY"), _num(msg, "VELOCITY_X"), _num(msg, "VELOCITY_Y"))
    if cmd == "GET_DATA_3":
        return Data3(_num(msg, "VELOCITY"), _num(msg, "VELOCITY_Z"), _num(msg, "PITCH"))
    if cmd == "STOP":
        gp = msg.get("GATES_PASSED")
        return StopReply(_num(msg, "TIME"), _int(msg, "STOP_TIME"), gp if isinstance(gp, int) else None)
    if cmd == "RADIO_RECV":
        # A malformed packet is a ProtocolError like every other bad reply.
        try:
            return RadioRecv(
                tuple(
                    Packet(
                        p["radio"],
                        base64.b64decode(p["data"], validate=True),
                        p["from"],
                        float(p["rssi"]),
                        int(p["time_ps"]),
                        p.get("rx_stamp"),
                    )
                    for p in msg.get("packets", [])
                ),
                tuple(TxDone(t["radio"], int(t["time_ps"]), t.get("tx_stamp")) for t in msg.get("tx_done", [])),
            )
        except (KeyError, TypeError, ValueError, binascii.Error) as e:
            raise ProtocolError(f"bad RADIO_RECV reply: {e!r}") from None
    raise ProtocolError(f"unknown reply command {cmd!r}")


def expects_reply(msg: Mapping[str, Any]) -> bool:
    return msg["command"] not in NO_REPLY
