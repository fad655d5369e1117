"""Manual piloting (seed 004 §4.1.2.A, the *Manpilot* module): the
:class:`KeyboardPilot` turns held keys into a :class:`~.command.Command`
and never sends it. The user sends it (or an assisted pilot's corrected
version of it) to the Crazyflie.

The default key map (velocities in m/s, yaw rate in °/s, height in m)::

    up / w      forward          down / s    back
    left / a    left             right / d   right
    q           turn left        e           turn right
    r           climb 0.1 m      f           descend 0.1 m
    space       stop (drop every held key)

More keys are bound with :meth:`KeyboardPilot.on` (a callback called at
each press of that key), e.g. ``pilot.on("l", land)``.

    with KeyboardPilot(TerminalKeys()) as pilot:
        while flying:
            cf.commander.send_hover_setpoint(*pilot.command)
            time.sleep(0.1)
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from .command import Command
from .keys import KeySource

#: Per held key: (vx, vy, yaw rate) contributions (body frame).
MOVES: dict[str, tuple[float, float, float]] = {
    "up": (1.0, 0.0, 0.0),
    "w": (1.0, 0.0, 0.0),
    "down": (-1.0, 0.0, 0.0),
    "s": (-1.0, 0.0, 0.0),
    "left": (0.0, 1.0, 0.0),
    "a": (0.0, 1.0, 0.0),
    "right": (0.0, -1.0, 0.0),
    "d": (0.0, -1.0, 0.0),
    "q": (0.0, 0.0, 1.0),
    "e": (0.0, 0.0, -1.0),
}
HEIGHT_STEP_M = 0.1


class KeyboardPilot:
    """Held keys -> the command of the moment (:attr:`command`).

    ``speed`` m/s per held direction key (the seed's experiments flew at
    0.2 m/s, §5.1), ``yaw_rate`` °/s, ``height`` the initial height (m),
    kept within ``[min_height, max_height]``.
    """

    def __init__(self, keys: KeySource, speed: float = 0.2, yaw_rate: float = 45.0,
                 height: float = 0.3, min_height: float = 0.2, max_height: float = 1.5):
        self.keys = keys
        self.speed = speed
        self.yaw_rate = yaw_rate
        self.min_height = min_height
        self.max_height = max_height
        self._height = height
        self._held: set[str] = set()
        self._callbacks: dict[str, list[Callable[[], None]]] = {}
        self._lock = threading.Lock()
        self._running = False

    # -- context manager: starts and stops the key listener --------------
    def __enter__(self) -> KeyboardPilot:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def start(self) -> None:
        if not self._running:
            self.keys.start(self._press, self._release)
            self._running = True

    def stop(self) -> None:
        if self._running:
            self.keys.stop()
            self._running = False
        with self._lock:
            self._held.clear()

    # -- the key map -----------------------------------------------------
    def on(self, key: str, callback: Callable[[], None]) -> None:
        """Call ``callback()`` at every press of ``key`` (added to the
        default map; a key may have several callbacks)."""
        self._callbacks.setdefault(key, []).append(callback)

    def _press(self, key: str) -> None:
        with self._lock:
            if key == "space":
                self._held.clear()
            elif key == "r":
                self._height = min(self.max_height, self._height + HEIGHT_STEP_M)
            elif key == "f":
                self._height = max(self.min_height, self._height - HEIGHT_STEP_M)
            elif key in MOVES:
                self._held.add(key)
        for cb in self._callbacks.get(key, ()):
            cb()

    def _release(self, key: str) -> None:
        with self._lock:
            self._held.discard(key)

    # -- what the user sends ---------------------------------------------
    @property
    def held(self) -> frozenset[str]:
        self.keys.poll()
        with self._lock:
            return frozenset(self._held)

    @property
    def height(self) -> float:
        return self._height

    @property
    def command(self) -> Command:
        """The command the held keys ask for (not sent: send it yourself)."""
        self.keys.poll()
        with self._lock:
            held = set(self._held)
            z = self._height
        fx = sum(MOVES[k][0] for k in held)
        fy = sum(MOVES[k][1] for k in held)
        fr = sum(MOVES[k][2] for k in held)
        clamp = lambda v: max(-1.0, min(1.0, v))  # noqa: E731 - w and up together are one forward
        return Command(clamp(fx) * self.speed, clamp(fy) * self.speed, clamp(fr) * self.yaw_rate, z)
