"""The Drone Delivery Service (seed 004 §4.3.2.B): the common interface
every group's delivery application uses, in a room where the groups' drones
share one airway.

- :meth:`DDS.travel` returns the command that keeps the drone in the
  airway: the call is the airway autopilot's ``run`` (by default a
  :class:`~.autopilot.Follower` round the room's perimeter, the same for
  everyone, so all drones fly it in the same direction).
- Locations: named points relative to the take-off position, which is the
  special location ``"Home"`` (0, 0); :meth:`distance_to_location`,
  :meth:`yaw_to_location` and :meth:`velocity_to_location` need the pose,
  which a DDS logs by itself while used as a context manager.
- Deliveries: :meth:`assign_delivery` picks a pick-up and a drop-off
  location (from a seeded generator: the same seed, the same deliveries);
  :attr:`Delivery.status` follows the application through
  :meth:`Delivery.advance`.

It never sends a command: the application forwards what it returns.
"""

from __future__ import annotations

import enum
import math
import random
from dataclasses import dataclass, field
from typing import Any

from .autopilot import Autopilot, Follower, clamp
from .command import Command, world_to_body, wrap_deg
from .telemetry import Measurements, Pose, Telemetry

HOME = "Home"


class Status(enum.Enum):
    ASSIGNED = "assigned"
    TO_PICKUP = "to pick-up"
    TO_DROPOFF = "to drop-off"
    RETURNING = "returning home"
    DONE = "done"


#: The order a delivery goes through.
_NEXT = {
    Status.ASSIGNED: Status.TO_PICKUP,
    Status.TO_PICKUP: Status.TO_DROPOFF,
    Status.TO_DROPOFF: Status.RETURNING,
    Status.RETURNING: Status.DONE,
    Status.DONE: Status.DONE,
}


@dataclass
class Delivery:
    pickup: str
    dropoff: str
    status: Status = Status.ASSIGNED
    log: list[tuple[Status, int]] = field(default_factory=list)

    @property
    def destination(self) -> str | None:
        """Where the drone is heading now."""
        return {Status.ASSIGNED: self.pickup, Status.TO_PICKUP: self.pickup, Status.TO_DROPOFF: self.dropoff,
                Status.RETURNING: HOME}.get(self.status)

    def advance(self, stamp: int = 0) -> Status:
        """The next stage (started, picked up, dropped off, home);
        ``stamp`` (e.g. the drone's time in ms) is kept in :attr:`log`."""
        self.status = _NEXT[self.status]
        self.log.append((self.status, stamp))
        return self.status


class DDS:
    """The delivery service for the Crazyflie ``cf``.

    ``locations``: name -> (x, y) m relative to the take-off position;
    ``airway``: the autopilot that defines the airway (default: a Follower
    at ``airway_distance`` m from the walls at ``speed`` m/s);
    ``seed``: the deliveries' generator.
    """

    def __init__(self, cf: Any, locations: dict[str, tuple[float, float]] | None = None,
                 airway: Autopilot | None = None, airway_distance: float = 0.5, speed: float = 0.3,
                 height: float = 0.4, seed: int = 0):
        self.cf = cf
        self.locations: dict[str, tuple[float, float]] = {HOME: (0.0, 0.0)}
        for name, xy in (locations or {}).items():
            self.add_location(name, *xy)
        self.height = height
        self.speed = speed
        self.telemetry = Telemetry(cf) if cf is not None else None
        self.airway = airway or Follower(self, distance=airway_distance, speed=speed, height=height)
        self.rng = random.Random(seed)
        self.home: Pose | None = None
        self.delivery: Delivery | None = None
        self.deliveries: list[Delivery] = []

    def __enter__(self) -> DDS:
        if self.telemetry is None:
            raise ValueError("DDS used as a context manager needs a Crazyflie")
        self.telemetry.start()
        if not self.telemetry.wait(10.0):
            raise TimeoutError("no pose from the Crazyflie")
        self.home = self.telemetry.pose
        return self

    def __exit__(self, *exc) -> None:
        if self.telemetry is not None:
            self.telemetry.stop()

    # -- the pose, relative to Home ----------------------------------------
    @property
    def pose(self) -> Pose | None:
        """The estimate (the Crazyflie's frame)."""
        return self.telemetry.pose if self.telemetry else None

    @property
    def measurements(self) -> Measurements:
        assert self.telemetry is not None
        return self.telemetry.measurements

    def position(self) -> tuple[float, float]:
        """Where the drone is, relative to Home (m)."""
        p, h = self.pose, self.home
        assert p is not None and h is not None, "no pose yet (use the DDS as a context manager)"
        return (p.x - h.x, p.y - h.y)

    # -- locations -------------------------------------------------------------
    def add_location(self, name: str, x: float, y: float) -> None:
        if name == HOME:
            raise ValueError('"Home" is the take-off position')
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"location {name!r}: coordinates must be finite")
        self.locations[name] = (float(x), float(y))

    def remove_location(self, name: str) -> None:
        if name == HOME:
            raise ValueError('"Home" cannot be removed')
        del self.locations[name]

    def _loc(self, name: str) -> tuple[float, float]:
        try:
            return self.locations[name]
        except KeyError:
            raise KeyError(f"unknown location {name!r} (known: {', '.join(self.locations)})") from None

    def distance_to_location(self, name: str) -> float:
        lx, ly = self._loc(name)
        x, y = self.position()
        return math.hypot(lx - x, ly - y)

    def yaw_to_location(self, name: str) -> float:
        """The yaw change (deg) that faces the location."""
        lx, ly = self._loc(name)
        x, y = self.position()
        assert self.pose is not None
        return wrap_deg(math.degrees(math.atan2(ly - y, lx - x)) - self.pose.yaw)

    def velocity_to_location(self, name: str, speed: float | None = None) -> Command:
        """The command flying straight to the location (leaving the airway:
        only when close to it, §4.3.3 d), slowing down within 0.3 m."""
        lx, ly = self._loc(name)
        x, y = self.position()
        assert self.pose is not None
        dx, dy = lx - x, ly - y
        d = math.hypot(dx, dy)
        v = (speed or self.speed) * clamp(d / 0.3, 0.0, 1.0)
        vx, vy = (dx / d * v, dy / d * v) if d > 1e-6 else (0.0, 0.0)
        bx, by = world_to_body(vx, vy, self.pose.yaw)
        return Command(bx, by, 0.0, self.height)

    # -- deliveries --------------------------------------------------------------
    def assign_delivery(self) -> Delivery:
        """A pick-up and a different drop-off location (never Home)."""
        names = sorted(n for n in self.locations if n != HOME)
        if len(names) < 2:
            raise ValueError("a delivery needs at least two locations besides Home")
        pickup, dropoff = self.rng.sample(names, 2)
        self.delivery = Delivery(pickup, dropoff)
        self.deliveries.append(self.delivery)
        return self.delivery

    @property
    def status(self) -> Status | None:
        return self.delivery.status if self.delivery else None

    def travel(self, measurements: Measurements | None = None) -> Command | None:
        """The command that flies the airway (the airway autopilot's run)."""
        return self.airway.run(self.measurements if measurements is None else measurements)
