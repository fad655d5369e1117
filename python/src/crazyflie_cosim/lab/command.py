"""The command every pilot of the lab API hands back: a hover set-point
ready to be sent, never sent by the API itself (seed 004 §4.1.2.A: "It is
still their responsibility to send the actual command").

A :class:`Command` unpacks into cflib's hover set-point::

    cf.commander.send_hover_setpoint(*command)

body-frame velocities in m/s along x (forward) and y (left), the yaw rate
in degrees/s (positive turns left, as cflib's), and the height in m
(§4.2.1.B: "velocities (in m/s), along the x and y axis, and yaw rate (in
degrees/s)").
"""

from __future__ import annotations

import math
from typing import NamedTuple


class Command(NamedTuple):
    vx: float = 0.0
    vy: float = 0.0
    yaw_rate: float = 0.0
    z: float = 0.3

    @property
    def speed(self) -> float:
        return math.hypot(self.vx, self.vy)

    def scaled(self, limit: float) -> Command:
        """The same command with its horizontal speed capped at ``limit``
        m/s (the Radar rule "reduce the cruising velocity to 0.1 m/s",
        §4.3.3)."""
        s = self.speed
        if s <= limit or s == 0.0:
            return self
        k = limit / s
        return self._replace(vx=self.vx * k, vy=self.vy * k)

    def hovering(self) -> Command:
        """Stay where you are at the same height."""
        return Command(0.0, 0.0, 0.0, self.z)


def world_to_body(vx: float, vy: float, yaw_deg: float) -> tuple[float, float]:
    """A world-frame velocity in the body frame of a drone at ``yaw_deg``."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return c * vx + s * vy, -s * vx + c * vy


def wrap_deg(a: float) -> float:
    """An angle in (-180, 180] degrees."""
    a = math.fmod(a + 180.0, 360.0)
    if a <= 0.0:
        a += 360.0
    return a - 180.0
