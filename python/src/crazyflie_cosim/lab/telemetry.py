"""The pose and the Multi-ranger's measurements, logged from the Crazyflie
(seed 004 §4.2.1.A: "the pose and the measurements were split into two
distinct log configurations, both being sent at 100 ms intervals").

Every lab module that needs them (:class:`~.grid.Grid`,
:class:`~.dds.DDS`) opens its own :class:`Telemetry` on the same
Crazyflie; the user reads :attr:`Telemetry.measurements` to feed an
:class:`~.autopilot.Autopilot`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: The Multi-ranger's directions, as :class:`Measurements` keys, and their
#: bearing in the body frame (degrees, counter-clockwise from the front).
BEARINGS = {"front": 0.0, "left": 90.0, "back": 180.0, "right": -90.0}
#: The VL53L1x's "nothing in range" (the firmware logs 32767 mm; cflib's
#: Multiranger reads it as None).
OUT_OF_RANGE_MM = 32767

Measurements = dict[str, float | None]


@dataclass(frozen=True)
class Pose:
    """The Crazyflie's estimate: metres and degrees (stateEstimate.*)."""

    x: float
    y: float
    z: float
    yaw: float
    roll: float = 0.0
    pitch: float = 0.0


def to_metres(mm: int, max_range: float) -> float | None:
    """A range in mm as the lab's measurement: None beyond ``max_range``
    (§4.2.1.B: "the special value None, in case the measurement is too far
    off the sensor maximum distance")."""
    if mm >= OUT_OF_RANGE_MM:
        return None
    m = mm / 1000.0
    return None if m > max_range else m


class Telemetry:
    """Two log blocks on ``cf`` (a cflib ``Crazyflie``) every ``period_ms``:
    the pose and the ranges. ``listeners`` are called as
    ``fn(pose, measurements)`` whenever new ranges arrive."""

    POSE_VARS = ("stateEstimate.x", "stateEstimate.y", "stateEstimate.z",
                 "stateEstimate.yaw", "stateEstimate.roll", "stateEstimate.pitch")
    RANGE_VARS = ("range.front", "range.back", "range.left", "range.right", "range.up", "range.zrange")

    def __init__(self, cf: Any, period_ms: int = 100, max_range: float = 3.0):
        self.cf = cf
        self.period_ms = period_ms
        self.max_range = max_range
        self.pose: Pose | None = None
        #: The drone's time (ms, the log's timestamp) of the last pose.
        self.t_ms: int | None = None
        self.measurements: Measurements = {k: None for k in ("front", "back", "left", "right", "up", "down")}
        self.listeners: list[Callable[[Pose, Measurements], None]] = []
        self._lock = threading.Lock()
        self._configs: list[Any] = []
        self._fresh = threading.Event()

    def __enter__(self) -> Telemetry:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def start(self) -> None:
        from cflib.crazyflie.log import LogConfig

        pose = LogConfig(name="lab.pose", period_in_ms=self.period_ms)
        for v in self.POSE_VARS:
            pose.add_variable(v, "float")
        ranges = LogConfig(name="lab.ranges", period_in_ms=self.period_ms)
        for v in self.RANGE_VARS:
            ranges.add_variable(v, "uint16_t")
        for conf, cb in ((pose, self._on_pose), (ranges, self._on_ranges)):
            self.cf.log.add_config(conf)
            conf.data_received_cb.add_callback(cb)
            conf.start()
            self._configs.append(conf)

    def stop(self) -> None:
        for conf in self._configs:
            try:
                conf.stop()
                conf.delete()
            except Exception:  # the link may be gone already
                pass
        self._configs.clear()

    def wait(self, timeout: float = 5.0) -> bool:
        """Wait until both the pose and the ranges have arrived once."""
        return self._fresh.wait(timeout)

    def _on_pose(self, ts: int, data: dict[str, float], _conf: Any) -> None:
        with self._lock:
            self.t_ms = ts
            self.pose = Pose(data["stateEstimate.x"], data["stateEstimate.y"], data["stateEstimate.z"],
                             data["stateEstimate.yaw"], data["stateEstimate.roll"], data["stateEstimate.pitch"])

    def _on_ranges(self, _ts: int, data: dict[str, int], _conf: Any) -> None:
        m = {
            "front": to_metres(data["range.front"], self.max_range),
            "back": to_metres(data["range.back"], self.max_range),
            "left": to_metres(data["range.left"], self.max_range),
            "right": to_metres(data["range.right"], self.max_range),
            "up": to_metres(data["range.up"], self.max_range),
            "down": to_metres(data["range.zrange"], self.max_range),
        }
        with self._lock:
            self.measurements = m
            pose = self.pose
        if pose is None:
            return
        self._fresh.set()
        for fn in list(self.listeners):
            fn(pose, m)
