"""Drone-to-drone detection (seed 004 §4.3.2.A): a "poor man's radar" on
the Crazyflies' peer-to-peer radio.

Used as a context manager, a :class:`Radar` sets the firmware's
``radar.enable`` parameter — the drone starts broadcasting its beacon, so
nobody can detect others without being detected ("purposely enforced for
safety reasons") — and logs ``radar.id`` and ``radar.rssi`` every 100 ms:
the last drone heard and the strength of its signal (the firmware keeps
the last beacon's sender, and clears it after 3 s of silence, §4.3.1).

- :meth:`Radar.detected`: the id of the drone heard, or None;
- :meth:`Radar.proximity`: ``"danger"`` above ``danger_dbm`` (−48 dBm, the
  seed's threshold found by trial and error, §5.3), ``"close"`` above
  ``close_dbm``, ``"far"`` otherwise, None when nobody is heard;
- :meth:`Radar.has_priority`: a drone has priority over those with a
  greater id (§4.3.2.A: "a drone has lower priority over another if its ID
  is greater").

Like every lab module, it never sends a set-point: what to do about a drone
nearby is the user's (§4.3.3's rules are guide 3's exercise 2).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: §5.3: "Proximity is considered dangerous if the RSSI value returned is
#: bigger than -48 dBm".
DANGER_DBM = -48.0
#: "Close": 6 dB below danger — about twice the distance under a free-space
#: (20 dB/decade) path loss; the seed leaves this threshold to the students.
CLOSE_DBM = -54.0


@dataclass(frozen=True)
class Echo:
    """One radar reading: the drone's own time (ms, the log's timestamp),
    the id heard (0: nobody) and its RSSI (dBm)."""

    t_ms: int
    id: int
    rssi: float


class Radar:
    """The radar of the Crazyflie ``cf`` (a cflib ``Crazyflie`` whose
    firmware has the radar: ``radar.*`` in its TOCs)."""

    def __init__(self, cf: Any, danger_dbm: float = DANGER_DBM, close_dbm: float = CLOSE_DBM,
                 period_ms: int = 100, window_ms: int = 1000):
        if close_dbm > danger_dbm:
            raise ValueError("close_dbm must not exceed danger_dbm")
        self.cf = cf
        self.danger_dbm = danger_dbm
        self.close_dbm = close_dbm
        self.period_ms = period_ms
        #: How long a drone heard counts (drone time): the firmware's log
        #: gives the drone heard *last*, so with several neighbours it
        #: alternates between them; the nearest one of this window is the
        #: one the radar reports (ours; the seed has two drones in view).
        self.window_ms = window_ms
        self.my_id: int | None = None
        self.echo = Echo(0, 0, 0.0)
        self._recent: dict[int, Echo] = {}
        self.history: list[Echo] = []
        self.listeners: list[Callable[[Echo], None]] = []
        self._lock = threading.Lock()
        self._conf = None

    def __enter__(self) -> Radar:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def start(self) -> None:
        from cflib.crazyflie.log import LogConfig

        toc = self.cf.param.toc.toc
        if "radar" not in toc:
            raise RuntimeError("this Crazyflie's firmware has no radar (no radar.* parameters)")
        self.my_id = int(self.cf.param.get_value("radar.myId"))
        # Broadcasting first: no detecting without being detected.
        self.cf.param.set_value("radar.enable", 1)
        conf = LogConfig(name="lab.radar", period_in_ms=self.period_ms)
        conf.add_variable("radar.id", "uint8_t")
        conf.add_variable("radar.rssi", "float")
        self.cf.log.add_config(conf)
        conf.data_received_cb.add_callback(self._on_data)
        conf.start()
        self._conf = conf

    def stop(self) -> None:
        if self._conf is not None:
            try:
                self._conf.stop()
                self._conf.delete()
                self.cf.param.set_value("radar.enable", 0)
            except Exception:  # the link may be gone already
                pass
            self._conf = None

    def _on_data(self, ts: int, data: dict[str, float], _conf: Any) -> None:
        e = Echo(int(ts), int(data["radar.id"]), float(data["radar.rssi"]))
        with self._lock:
            self.echo = e
            self.history.append(e)
            if e.id:
                self._recent[e.id] = e
        for fn in list(self.listeners):
            fn(e)

    # -- what the user asks ----------------------------------------------
    def _nearest(self) -> Echo | None:
        """The strongest echo among the drones heard within ``window_ms``
        of the latest reading (None: nobody)."""
        with self._lock:
            if not self.echo.id:
                return None
            now = self.echo.t_ms
            live = [e for e in self._recent.values() if now - e.t_ms <= self.window_ms]
            return max(live, key=lambda e: (e.rssi, -e.id), default=None)

    def detected(self) -> int | None:
        """The id of the nearest drone heard in the last ``window_ms`` (the
        strongest RSSI; None: nobody heard for 3 s, the firmware's timeout)."""
        e = self._nearest()
        return e.id if e else None

    def rssi(self) -> float | None:
        """The RSSI of that drone (dBm)."""
        e = self._nearest()
        return e.rssi if e else None

    def classify(self, rssi: float | None) -> str | None:
        if rssi is None:
            return None
        if rssi > self.danger_dbm:
            return "danger"
        if rssi > self.close_dbm:
            return "close"
        return "far"

    def proximity(self) -> str | None:
        """``"danger"``, ``"close"``, ``"far"`` or None (nobody heard)."""
        return self.classify(self.rssi())

    def has_priority(self, other: int | None = None) -> bool:
        """True when this drone has priority over ``other`` (default: the
        drone heard): the smaller id has priority."""
        other = self.detected() if other is None else other
        if other is None or self.my_id is None:
            return True
        return self.my_id < other
