"""Fly Bitcraze's cfclient with the keyboard (DESIGN.md §17, docs/CFLIB.md,
"cfclient flown with the keyboard").

cfclient reads joysticks and gamepads (its Linux and SDL readers) and, as
an input *interface*, a ZMQ socket: `cfclient/utils/input/inputinterfaces/
zmqpull.py` binds a PULL socket at ``tcp://127.0.0.1:1212`` (1024 + 188)
when its configuration has ``"enable_zmq_input": true``, lists it as the
input device ``ZMQ@tcp://127.0.0.1:1212``, and merges every JSON message's
``"ctrl"`` dictionary into its input data (roll, pitch, yaw, thrust and the
buttons, ``assistedControl`` among them), which its `JoystickReader` reads
every 10 ms and flies as from a gamepad: its flight modes, its assisted
modes, its trims and limits, the same set-points to the Crazyflie.

This module turns held keys into those messages. cfclient's input
interfaces are not scaled (`InputInterface`: ``limit_rp``, ``limit_thrust``
and ``limit_yaw`` off), so the values are what `JoystickReader.read_input`
uses directly. The pilot flies cfclient's **Hover** assisted mode, the one
it selects with a Flow deck (`FlightTab._populate_assisted_mode_dropdown`):
with ``assistedControl`` held,

- ``pitch`` is the forward velocity and ``-roll`` the leftward one (m/s,
  body frame: cfclient sends ``send_hover_setpoint(pitch, -roll, -yaw,
  height)``), ``-yaw`` the yaw rate (°/s);
- ``thrust`` is a vertical speed, 32767 ± 32767 for ±1 m/s, which cfclient
  integrates into its target height (from 0.4 m when the button is
  pressed, kept within 0.2 m and the deck's ceiling, 2 m for the Flow deck
  v2);
- releasing the button leaves the assisted mode: cfclient flies the
  manual mode, in which ``thrust`` is a percentage: 0 stops the motors.

Keys (seed 004's KeyboardPilot layout, :data:`crazyflie_cosim.lab.pilot.MOVES`):

    t             take off (cfclient's Hover mode: up to 0.4 m)
    up / w        forward           down / s     back
    left / a      left              right / d    right
    q / e         turn left / right
    r / f         climb / descend (while held)
    space         stop moving
    l             land: descend to cfclient's lowest hover height, then motors off
    esc / x       motors off and quit

:class:`CfclientKeys` does no I/O: :meth:`CfclientKeys.message` gives the
message of the moment; :func:`push` sends them at a steady rate over ZMQ
(pyzmq, which cfclient itself depends on). The script
``scripts/cfclient-keys.py`` is the command line.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from .lab.keys import KeySource
from .lab.pilot import MOVES

#: cfclient's ZMQ input (`zmqpull.py`: ``ZMQ_PULL_PORT = 1024 + 188``).
ZMQ_INPUT = "tcp://127.0.0.1:1212"
#: The input device's name in cfclient's *Input device* menu (and its
#: configuration's ``input_device``).
ZMQ_DEVICE = "ZMQ@" + ZMQ_INPUT
#: cfclient's Hover mode (`utils/input/__init__.py`): the target height
#: when the assisted button is pressed, and its floor.
HOVER_START_M = 0.4
HOVER_FLOOR_M = 0.2
#: `JoystickReader`: ``vz = (thrust - 32767) / 32767`` (m/s).
THRUST_MID = 32767


@dataclass(frozen=True)
class Speeds:
    """How fast the keys fly: horizontal (m/s), yaw (°/s), climb (m/s),
    and the descent of a landing (m/s)."""

    horizontal: float = 0.3
    yaw: float = 45.0
    climb: float = 0.3
    land: float = 0.3


class CfclientKeys:
    """Held keys → cfclient's ZMQ input messages.

    ``clock`` is the clock the landing is timed on (wall seconds: cfclient
    integrates the vertical speed on its own 10 ms timer).
    """

    def __init__(self, keys: KeySource, speeds: Speeds = Speeds(),
                 clock: Callable[[], float] = time.monotonic):
        self.keys = keys
        self.speeds = speeds
        self._clock = clock
        self._lock = threading.Lock()
        self._held: set[str] = set()
        self.flying = False
        self.quit = False
        # Landing: when the descent ends and the motors stop (clock time).
        self._land_until: float | None = None
        # cfclient's target height as it integrates our vertical speed.
        self._target = HOVER_START_M
        self._last: float | None = None

    # -- keys ---------------------------------------------------------------
    def start(self) -> None:
        self.keys.start(self._press, self._release)

    def stop(self) -> None:
        self.keys.stop()

    def __enter__(self) -> CfclientKeys:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _press(self, key: str) -> None:
        with self._lock:
            if key in ("esc", "x"):
                self.quit = True
                self.flying = False
                self._land_until = None
            elif key == "t" and not self.flying:
                self.flying = True
                self._target = HOVER_START_M
                self._land_until = None
            elif key == "l" and self.flying and self._land_until is None:
                # Down to cfclient's floor at the landing speed, then as long
                # again as the drone needs to follow (its height loop lags),
                # at least a second: then the motors stop.
                self._held.clear()
                descent = max(0.0, self._target - HOVER_FLOOR_M) / self.speeds.land
                self._land_until = self._clock() + descent + max(1.0, descent)
            elif key == "space":
                self._held.clear()
            elif key in MOVES or key in ("r", "f"):
                self._held.add(key)

    def _release(self, key: str) -> None:
        with self._lock:
            self._held.discard(key)

    # -- what is pushed -------------------------------------------------------
    @property
    def landing(self) -> bool:
        return self._land_until is not None

    @property
    def target_height(self) -> float:
        """cfclient's target height as this pilot estimates it (m)."""
        return self._target

    def ctrl(self) -> dict[str, float | bool]:
        """The input of the moment (cfclient's `ZMQReader.data` keys)."""
        self.keys.poll()
        now = self._clock()
        with self._lock:
            dt = 0.0 if self._last is None else now - self._last
            self._last = now
            if self._land_until is not None and now >= self._land_until:
                self.flying = False
                self._land_until = None
            if not self.flying:
                # Manual mode, thrust 0 %: cfclient sends the zero set-point.
                return {"roll": 0.0, "pitch": 0.0, "yaw": 0.0, "thrust": 0.0,
                        "assistedControl": False}
            held = set(self._held)
            s = self.speeds
            fx = _unit(sum(MOVES[k][0] for k in held if k in MOVES))
            fy = _unit(sum(MOVES[k][1] for k in held if k in MOVES))
            fr = _unit(sum(MOVES[k][2] for k in held if k in MOVES))
            if self._land_until is not None:
                vz = -s.land
            else:
                vz = s.climb * ((("r" in held) - ("f" in held)))
            self._target = min(2.0, max(HOVER_FLOOR_M, self._target + vz * dt))
            return {
                "roll": -fy * s.horizontal,
                "pitch": fx * s.horizontal,
                "yaw": -fr * s.yaw,
                "thrust": THRUST_MID + vz * THRUST_MID,
                "assistedControl": True,
            }

    def message(self) -> dict:
        """One message for cfclient's PULL socket."""
        return {"version": 1, "client_name": "crazyflie-cosim cfclient-keys", "ctrl": self.ctrl()}


def _unit(v: float) -> float:
    return max(-1.0, min(1.0, v))


def push(pilot: CfclientKeys, address: str = ZMQ_INPUT, rate_hz: float = 50.0,
         until: Callable[[], bool] | None = None,
         on_message: Callable[[dict], None] | None = None) -> None:
    """Sends ``pilot``'s messages to cfclient's ZMQ input at ``rate_hz``
    until the pilot quits (or ``until()`` is true); the last message has
    the motors off."""
    import zmq  # cfclient's own dependency (pyzmq)

    ctx = zmq.Context()
    sock = ctx.socket(zmq.PUSH)
    # A message cfclient has not taken when we quit is dropped, not waited for.
    sock.setsockopt(zmq.LINGER, 500)
    sock.setsockopt(zmq.SNDHWM, 10)
    sock.connect(address)
    period = 1.0 / rate_hz
    try:
        nxt = time.monotonic()
        while not pilot.quit and not (until is not None and until()):
            msg = pilot.message()
            _send(sock, msg)
            if on_message is not None:
                on_message(msg)
            nxt += period
            time.sleep(max(0.0, nxt - time.monotonic()))
    finally:
        # Also on Ctrl-C: cfclient keeps flying the last input it got.
        pilot.flying = False
        _send(sock, pilot.message())
        sock.close()
        ctx.term()


def _send(sock, msg: dict) -> None:
    import zmq

    try:
        sock.send_string(json.dumps(msg), flags=zmq.NOBLOCK)
    except zmq.Again:
        # cfclient is not there (yet) or not reading: the next message
        # says the same, newer.
        pass
