"""Autopilots (seed 004 §4.2.1.B): each has a ``run(measurements)`` that
takes the Multi-ranger's measurements and returns a
:class:`~.command.Command` ready to be forwarded to the Crazyflie — as the
:class:`~.pilot.KeyboardPilot` does, and never sent by the autopilot.

- :class:`Autopilot`: the abstract base (``abc``, as the seed's).
- :class:`Follower`: a wall follower keeping the obstacle on its left at
  a safe distance, slower the closer it is (the default airway of the
  :class:`~.dds.DDS`, §4.3.2.B).
- :class:`Explorer`: frontier-based exploration (Yamauchi; the seed's
  Algorithm 2) on a :class:`~.grid.Grid`: goal generation, the distance and
  yaw to the goal, and a shortest path to it over the map's free cells.
  Its ``run`` is left to the student (§4.2.1.B: "this class is intended for
  students to extend"); guide 2's example is one solution.

Autopilots that need the pose (the Follower's square turns, the Explorer)
read it from a :class:`~.telemetry.Telemetry` or a :class:`~.grid.Grid`.
"""

from __future__ import annotations

import heapq
import math
from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from .command import Command, world_to_body, wrap_deg
from .grid import FREE, OCCUPIED, Grid
from .telemetry import Measurements, Pose


def clamp(v: float, lo: float, hi: float) -> float:
    return max(lo, min(hi, v))


class Autopilot(ABC):
    """The base of every autopilot: ``run(measurements)`` -> Command."""

    def __init__(self, height: float = 0.3):
        self.height = height

    @abstractmethod
    def run(self, measurements: Measurements) -> Command | None:
        """The command for these measurements (None: nothing more to do)."""

    @staticmethod
    def all_measurements_valid(measurements: Measurements,
                               directions: tuple[str, ...] = ("front", "back", "left", "right")) -> bool:
        """True when every ranger in ``directions`` sees something within
        its range (§4.2.1.B: a measurement is None when too far or when
        the sensor is malfunctioning)."""
        return all(measurements.get(d) is not None for d in directions)


class Follower(Autopilot):
    """Follows the wall on its left at ``distance`` m, at up to ``speed``
    m/s, slower as the wall ahead comes near. It starts by sliding left to
    the nearest wall on that side (joining the airway). Turns are square (the
    heading is held at the take-off heading plus multiples of 90°, so the
    room's walls should meet at right angles): right when blocked ahead,
    left round an outer corner when the left wall ends.

    ``pose`` is anything with a ``pose`` attribute (a Telemetry or a Grid).
    """

    def __init__(self, pose: Any, distance: float = 0.5, speed: float = 0.3, height: float = 0.3,
                 turn_rate: float = 60.0):
        super().__init__(height)
        self.source = pose
        self.distance = distance
        self.speed = speed
        self.turn_rate = turn_rate
        self.heading: float | None = None  # the held heading (deg)
        self.turning = False
        self.lost_at: tuple[float, float] | None = None
        self.searching = False  # after a left turn, until the wall is back
        self.joined = False  # until a wall is first on the left: slide left to it

    def _pose(self) -> Pose | None:
        return getattr(self.source, "pose", None)

    def run(self, measurements: Measurements) -> Command | None:
        pose = self._pose()
        if pose is None:
            return Command(z=self.height)
        if self.heading is None:
            self.heading = pose.yaw
        err = wrap_deg(self.heading - pose.yaw)
        hold = clamp(3.0 * err, -self.turn_rate, self.turn_rate)
        if self.turning:
            if abs(err) > 3.0:
                return Command(0.0, 0.0, hold, self.height)
            self.turning = False
        front, left = measurements.get("front"), measurements.get("left")
        d = self.distance
        if not self.joined:
            if left is not None and left < 1.2 * d:
                self.joined = True
            else:
                return Command(0.0, self.speed, hold, self.height)
        if front is not None and front < d:
            # Blocked ahead: a square right turn (the wall stays on the left).
            self.heading = wrap_deg(self.heading - 90.0)
            self.turning, self.lost_at, self.searching = True, None, False
            return Command(0.0, 0.0, 0.0, self.height)
        ahead = self.speed if front is None else self.speed * clamp((front - d) / (2.0 * d), 0.25, 1.0)
        if left is None or left > 2.5 * d:
            if self.searching:
                return Command(ahead, 0.0, hold, self.height)
            # The left wall ended: pass the corner by the follow distance,
            # then turn left round it.
            if self.lost_at is None:
                self.lost_at = (pose.x, pose.y)
            if math.hypot(pose.x - self.lost_at[0], pose.y - self.lost_at[1]) < d:
                return Command(ahead, 0.0, hold, self.height)
            self.heading = wrap_deg(self.heading + 90.0)
            self.turning, self.lost_at, self.searching = True, None, True
            return Command(0.0, 0.0, 0.0, self.height)
        self.lost_at, self.searching = None, False
        vy = clamp(0.8 * (left - d), -0.15, 0.15)
        return Command(ahead, vy, hold, self.height)


class Explorer(Autopilot):
    """Frontier-based exploration on ``grid`` (seed 004 §4.2.1.B,
    Algorithm 2). Extend it and write :meth:`run`; the helpers:

    - :meth:`generate_goal`: the centroid of the frontier region nearest to
      the last known pose (None when the map has no frontier left);
    - :meth:`distance_to_goal`, :meth:`yaw_to_goal`;
    - :meth:`path_to` : a shortest path over free cells kept
      ``clearance`` m away from every occupied or unknown cell;
    - :meth:`velocity_towards`: the body-frame command flying towards a
      point at ``speed``.
    """

    def __init__(self, grid: Grid, height: float = 0.3, speed: float = 0.2, clearance: float = 0.25,
                 min_region: int = 5):
        super().__init__(height)
        self.grid = grid
        self.speed = speed
        self.clearance = clearance
        self.min_region = min_region
        self.goal: tuple[float, float] | None = None
        self.goals: list[tuple[float, float]] = []
        #: Goals given up (see :meth:`give_up`): frontiers near them are skipped.
        self.unreachable: list[tuple[float, float]] = []

    @property
    def pose(self) -> Pose | None:
        return self.grid.pose

    def generate_goal(self) -> tuple[float, float] | None:
        """Algorithm 2: frontier cells grouped into regions (small ones
        dropped), each region's centroid; the closest to the pose. Kept
        as :attr:`goal` and appended to :attr:`goals`."""
        pose = self.pose
        regions = self.grid.frontiers(self.min_region)
        if pose is None or not regions:
            self.goal = None
            return None
        centroids = []
        for region in regions:
            rows, cols = zip(*region)
            c = self.grid.centre_of(float(np.mean(rows)), float(np.mean(cols)))
            if all(math.hypot(c[0] - u[0], c[1] - u[1]) > 0.3 for u in self.unreachable):
                centroids.append(c)
        if not centroids:
            self.goal = None
            return None
        self.goal = min(centroids, key=lambda c: math.hypot(c[0] - pose.x, c[1] - pose.y))
        self.goals.append(self.goal)
        return self.goal

    def give_up(self) -> None:
        """Mark the current goal unreachable (e.g. a frontier seen through
        a gap in a wall): :meth:`generate_goal` skips frontiers within
        0.3 m of it from now on."""
        if self.goal is not None:
            self.unreachable.append(self.goal)
            self.goal = None

    def distance_to_goal(self) -> float | None:
        pose = self.pose
        if pose is None or self.goal is None:
            return None
        return math.hypot(self.goal[0] - pose.x, self.goal[1] - pose.y)

    def yaw_to_goal(self) -> float | None:
        """The yaw change (deg) that faces the goal."""
        pose = self.pose
        if pose is None or self.goal is None:
            return None
        return wrap_deg(math.degrees(math.atan2(self.goal[1] - pose.y, self.goal[0] - pose.x)) - pose.yaw)

    def traversable(self) -> np.ndarray:
        """Free cells at least ``clearance`` from any occupied cell and
        half of it from any unknown one."""
        cls = self.grid.classes()
        ok = cls == FREE
        blocked = _dilate(cls == OCCUPIED, int(math.ceil(self.clearance / self.grid.cell)))
        unknown = _dilate(cls == 0, int(math.ceil(0.5 * self.clearance / self.grid.cell)))
        return ok & ~blocked & ~unknown

    def path_to(self, goal: tuple[float, float]) -> list[tuple[float, float]] | None:
        """A* over :meth:`traversable` cells (8-connected) from the pose to
        the traversable cell nearest the goal; None when there is none.
        The drone's own cell counts as traversable (it is where it is)."""
        pose = self.pose
        if pose is None:
            return None
        ok = self.traversable()
        start = self.grid.cell_of(pose.x, pose.y)
        if not self.grid.inside(*start):
            return None
        ok[start] = True
        reach = _reachable(ok, start)
        cand = np.argwhere(reach)
        if cand.size == 0:
            return None
        g = self.grid.cell_of(*goal)
        target = tuple(int(v) for v in cand[np.argmin(np.hypot(cand[:, 0] - g[0], cand[:, 1] - g[1]))])
        cells = _astar(ok, start, target)
        if cells is None:
            return None
        return [self.grid.centre_of(r, c) for r, c in _simplify(cells)]

    def velocity_towards(self, point: tuple[float, float], speed: float | None = None,
                         face: bool = False) -> Command:
        """Fly towards ``point`` at ``speed`` (slowing down within 0.3 m);
        with ``face`` also turn towards it."""
        pose = self.pose
        assert pose is not None
        dx, dy = point[0] - pose.x, point[1] - pose.y
        dist = math.hypot(dx, dy)
        v = (speed or self.speed) * clamp(dist / 0.3, 0.0, 1.0)
        vx, vy = (dx / dist * v, dy / dist * v) if dist > 1e-6 else (0.0, 0.0)
        bx, by = world_to_body(vx, vy, pose.yaw)
        yaw_rate = 0.0
        if face and dist > 0.05:
            yaw_rate = clamp(2.0 * wrap_deg(math.degrees(math.atan2(dy, dx)) - pose.yaw), -60.0, 60.0)
        return Command(bx, by, yaw_rate, self.height)

    @abstractmethod
    def run(self, measurements: Measurements) -> Command | None: ...


def _dilate(mask: np.ndarray, n: int) -> np.ndarray:
    """``mask`` grown by ``n`` cells (a disc)."""
    out = mask.copy()
    if n <= 0 or not mask.any():
        return out
    rows, cols = mask.shape
    for dr in range(-n, n + 1):
        for dc in range(-n, n + 1):
            if dr * dr + dc * dc > n * n or (dr == 0 and dc == 0):
                continue
            src = mask[max(0, -dr):rows - max(0, dr), max(0, -dc):cols - max(0, dc)]
            out[max(0, dr):rows - max(0, -dr), max(0, dc):cols - max(0, -dc)] |= src
    return out


def _reachable(ok: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    seen = np.zeros_like(ok)
    seen[start] = True
    stack = [start]
    rows, cols = ok.shape
    while stack:
        r, c = stack.pop()
        for nr, nc in ((r + 1, c), (r - 1, c), (r, c + 1), (r, c - 1)):
            if 0 <= nr < rows and 0 <= nc < cols and ok[nr, nc] and not seen[nr, nc]:
                seen[nr, nc] = True
                stack.append((nr, nc))
    return seen


def _astar(ok: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]] | None:
    rows, cols = ok.shape
    h = lambda p: math.hypot(p[0] - goal[0], p[1] - goal[1])  # noqa: E731
    frontier = [(h(start), 0.0, start)]
    came: dict[tuple[int, int], tuple[int, int] | None] = {start: None}
    cost = {start: 0.0}
    while frontier:
        _, g, cur = heapq.heappop(frontier)
        if cur == goal:
            path = [cur]
            while came[path[-1]] is not None:
                path.append(came[path[-1]])  # type: ignore[arg-type]
            return path[::-1]
        if g > cost[cur]:
            continue
        r, c = cur
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                if dr == dc == 0:
                    continue
                n = (r + dr, c + dc)
                if not (0 <= n[0] < rows and 0 <= n[1] < cols) or not ok[n]:
                    continue
                if dr and dc and not (ok[r + dr, c] and ok[r, c + dc]):
                    continue  # no corner cutting
                ng = g + (1.4142135623730951 if dr and dc else 1.0)
                if ng < cost.get(n, math.inf):
                    cost[n] = ng
                    came[n] = cur
                    heapq.heappush(frontier, (ng + h(n), ng, n))
    return None


def _simplify(cells: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """The path's corners only (where its direction changes), and its end."""
    if len(cells) <= 2:
        return cells[1:] or cells
    out = []
    for a, b, c in zip(cells, cells[1:], cells[2:]):
        if (b[0] - a[0], b[1] - a[1]) != (c[0] - b[0], c[1] - b[1]):
            out.append(b)
    out.append(cells[-1])
    return out
