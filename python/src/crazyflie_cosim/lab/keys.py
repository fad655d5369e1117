"""Where a :class:`~.pilot.KeyboardPilot` gets its keys from.

The seed's pilot listened to the computer's keyboard (§4.1.2.A). Here the
source is a small interface so that a script can drive the same pilot:

- :class:`TerminalKeys` reads the terminal the example runs in (no extra
  library, works over ssh). A terminal reports presses only, so a press
  holds its key for ``hold_s``; the keyboard's auto-repeat renews it while
  the key is held down.
- :class:`ScriptedKeys` replays a list of key holds on a clock (the wall's,
  or the drone's): what the tests and the headless examples use.
"""

from __future__ import annotations

import os
import select
import sys
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable
from dataclasses import dataclass

Press = Callable[[str], None]


class KeySource(ABC):
    """Calls ``on_press(key)`` and ``on_release(key)`` from its own thread
    between :meth:`start` and :meth:`stop`."""

    @abstractmethod
    def start(self, on_press: Press, on_release: Press) -> None: ...

    @abstractmethod
    def stop(self) -> None: ...

    def poll(self) -> None:
        """Deliver what is due now (sources without a thread of their own)."""

    @property
    def finished(self) -> bool:
        """True when the source has nothing more to say (a script's end)."""
        return False


@dataclass(frozen=True)
class Hold:
    """Key ``key`` held from ``start_s`` for ``duration_s`` (wall seconds
    after the source starts)."""

    start_s: float
    key: str
    duration_s: float


class ScriptedKeys(KeySource):
    """Key holds replayed on a clock, e.g.
    ``ScriptedKeys([Hold(0.0, "up", 1.0), Hold(1.5, "left", 0.5)])``.

    No thread: the events that are due fire when the pilot is asked for its
    command (:meth:`poll`), so a script on the drone's clock flies the same
    however late the caller's loop runs (a hold shorter than the loop's
    period would press and release in one poll).
    """

    def __init__(self, holds: Iterable[Hold], clock: Callable[[], float] = time.monotonic):
        self.holds = sorted(holds, key=lambda h: h.start_s)
        events: list[tuple[float, int, str]] = []
        for h in self.holds:
            if h.duration_s <= 0.0 or h.start_s < 0.0:
                raise ValueError(f"a key hold needs start >= 0 and a positive duration: {h}")
            events.append((h.start_s, 1, h.key))
            events.append((h.start_s + h.duration_s, 0, h.key))
        # Releases before presses at the same instant: a key released and
        # pressed again stays held.
        self._events = sorted(events)
        self._next = 0
        self._clock = clock
        self._t0: float | None = None
        self._calls: tuple[Press, Press] | None = None
        self._lock = threading.Lock()

    def start(self, on_press: Press, on_release: Press) -> None:
        self._t0 = self._clock()
        self._calls = (on_press, on_release)

    def stop(self) -> None:
        self._calls = None

    def poll(self) -> None:
        if self._calls is None or self._t0 is None:
            return
        with self._lock:
            elapsed = self._clock() - self._t0
            while self._next < len(self._events) and self._events[self._next][0] <= elapsed:
                _, down, key = self._events[self._next]
                self._next += 1
                self._calls[0 if down else 1](key)

    @property
    def finished(self) -> bool:
        self.poll()
        return self._next >= len(self._events)


class TerminalKeys(KeySource):
    """The keys typed in this terminal (POSIX): letters as themselves, the
    arrow keys as ``up``, ``down``, ``left``, ``right``, the space bar as
    ``space``, Escape as ``esc``."""

    ARROWS = {"A": "up", "B": "down", "C": "right", "D": "left"}

    def __init__(self, hold_s: float = 0.35):
        self.hold_s = hold_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._saved = None

    def start(self, on_press: Press, on_release: Press) -> None:
        import termios
        import tty

        if not sys.stdin.isatty():
            raise RuntimeError("TerminalKeys needs an interactive terminal (use ScriptedKeys otherwise)")
        fd = sys.stdin.fileno()
        self._saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)
        held: dict[str, float] = {}

        def read():
            buf = b""
            while not self._stop.is_set():
                ready, _, _ = select.select([fd], [], [], 0.05)
                if ready:
                    buf += os.read(fd, 16)
                while buf:
                    key, buf = self._decode(buf)
                    if key is None:
                        break
                    if key not in held:
                        on_press(key)
                    held[key] = time.monotonic() + self.hold_s
                now = time.monotonic()
                for key in [k for k, until in held.items() if until <= now]:
                    del held[key]
                    on_release(key)

        self._thread = threading.Thread(target=read, name="TerminalKeys", daemon=True)
        self._thread.start()

    def _decode(self, buf: bytes) -> tuple[str | None, bytes]:
        if buf.startswith(b"\x1b["):
            if len(buf) < 3:
                return None, buf
            return self.ARROWS.get(chr(buf[2]), "esc"), buf[3:]
        if buf.startswith(b"\x1b"):
            return "esc", buf[1:]
        ch = chr(buf[0])
        return ("space" if ch == " " else ch.lower()), buf[1:]

    def stop(self) -> None:
        import termios

        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self._saved is not None:
            termios.tcsetattr(sys.stdin.fileno(), termios.TCSADRAIN, self._saved)
