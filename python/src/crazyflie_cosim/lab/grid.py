"""Mapping (seed 004 §4.2.1.A): an occupancy grid of the 2D slice the
drone flies in, built from the Multi-ranger's four horizontal rangers and
the pose estimate, after "Probabilistic Robotics" chapter 9 (the seed's
reference [21]).

Each cell holds the log-odds of being occupied (0: unknown). For every
measurement the cells in the sensor's cone up to the measured distance are
more likely free, the cells at the distance more likely occupied; a
ranger that sees nothing within ``max_range`` frees its cone up to
``max_range``. The cone is ``fov_deg`` wide (the seed: the VL53L1x sees
20°, but a narrow cone like 5° maps best, §4.2.1.A and Table 6; 4° in
Figure 5.2): a cell is in it when the cone touches the cell's square.
Measurements taken while tilted so far that the obstacle would lie more
than ``max_slice_offset`` above or below the flight height are dropped (the
2D slice, §4.2.1.A). The grid grows when the drone nears its border.

Classification of the normalised probability (§4.2.1.A): occupied > 0.5,
unknown = 0.5, free < 0.5.

    with Grid(cf, cell_size=0.05, fov_deg=4.0) as grid:   # maps by itself
        ...
    grid.save_png("map.png", plan=TruePlan.from_world(...))
"""

from __future__ import annotations

import math
import threading
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from .telemetry import BEARINGS, Measurements, Pose, Telemetry

#: Log-odds added per observation: occupied p = 0.7, free p = 0.35
#: (the seed's reference implementation uses 0.65/0.35; a slightly
#: stronger hit keeps thin obstacles, §5.1), clamped at p ≈ 0.9933 so a
#: cell can change its mind.
L_OCC = math.log(0.7 / 0.3)
L_FREE = math.log(0.35 / 0.65)
L_MAX = 5.0
#: Margin added around the drone when the grid grows (m).
GROW_M = 1.0

UNKNOWN, FREE, OCCUPIED = 0, 1, 2


class Grid:
    """An occupancy grid in the estimate's frame (m). With ``cf`` (a cflib
    ``Crazyflie``) it updates itself from a :class:`Telemetry` while used
    as a context manager; without, feed it :meth:`update`."""

    def __init__(self, cf: Any = None, cell_size: float = 0.05, fov_deg: float = 4.0,
                 max_range: float = 3.0, max_slice_offset: float = 0.1,
                 bounds: tuple[float, float, float, float] | None = None):
        if cell_size <= 0.0 or not 0.0 < fov_deg < 90.0 or max_range <= 0.0:
            raise ValueError("Grid needs cell_size > 0, 0 < fov_deg < 90 and max_range > 0")
        self.cf = cf
        self.cell = cell_size
        self.fov = fov_deg
        self.max_range = max_range
        self.max_slice_offset = max_slice_offset
        self.logodds = np.zeros((0, 0))
        self.origin = (0.0, 0.0)
        self.pose: Pose | None = None
        self.updates = 0
        self.telemetry: Telemetry | None = None
        self._lock = threading.RLock()
        if bounds is not None:
            x0, y0, x1, y1 = bounds
            self._allocate(x0, y0, x1, y1)

    # -- context manager: the map updates itself ------------------------
    def __enter__(self) -> Grid:
        if self.cf is None:
            raise ValueError("Grid used as a context manager needs a Crazyflie")
        self.telemetry = Telemetry(self.cf, max_range=self.max_range)
        self.telemetry.listeners.append(self.update)
        self.telemetry.start()
        return self

    def __exit__(self, *exc) -> None:
        if self.telemetry is not None:
            self.telemetry.stop()

    @property
    def measurements(self) -> Measurements:
        """The latest Multi-ranger measurements (for an Autopilot's run)."""
        assert self.telemetry is not None, "the Grid is not logging (use it as a context manager)"
        return self.telemetry.measurements

    # -- geometry ---------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return self.logodds.shape  # (rows = y, columns = x)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, column) of the cell holding the point."""
        return (int(math.floor((y - self.origin[1]) / self.cell)),
                int(math.floor((x - self.origin[0]) / self.cell)))

    def centre_of(self, row: int, col: int) -> tuple[float, float]:
        return (self.origin[0] + (col + 0.5) * self.cell, self.origin[1] + (row + 0.5) * self.cell)

    def inside(self, row: int, col: int) -> bool:
        return 0 <= row < self.shape[0] and 0 <= col < self.shape[1]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1) of the whole grid."""
        return (self.origin[0], self.origin[0] + self.shape[1] * self.cell,
                self.origin[1], self.origin[1] + self.shape[0] * self.cell)

    def _allocate(self, x0: float, y0: float, x1: float, y1: float) -> None:
        c = self.cell
        gx0, gy0 = math.floor(x0 / c) * c, math.floor(y0 / c) * c
        cols = int(math.ceil((x1 - gx0) / c))
        rows = int(math.ceil((y1 - gy0) / c))
        if self.logodds.size == 0:
            self.logodds = np.zeros((rows, cols))
            self.origin = (gx0, gy0)
            return
        ox, oy = self.origin
        # Keep the old cells aligned: the new origin is a whole number of
        # cells from the old one.
        dc = int(round((ox - gx0) / c))
        dr = int(round((oy - gy0) / c))
        new = np.zeros((rows, cols))
        h, w = self.logodds.shape
        new[dr:dr + h, dc:dc + w] = self.logodds
        self.logodds = new
        self.origin = (ox - dc * c, oy - dr * c)

    def _ensure(self, x: float, y: float) -> None:
        r = self.max_range + self.cell
        if self.logodds.size:
            x0, x1, y0, y1 = self.extent
            if x - r >= x0 and x + r <= x1 and y - r >= y0 and y + r <= y1:
                return
            nx0, ny0 = min(x0, x - r - GROW_M), min(y0, y - r - GROW_M)
            nx1, ny1 = max(x1, x + r + GROW_M), max(y1, y + r + GROW_M)
        else:
            nx0, ny0, nx1, ny1 = x - r - GROW_M, y - r - GROW_M, x + r + GROW_M, y + r + GROW_M
        self._allocate(nx0, ny0, nx1, ny1)

    # -- the algorithm ------------------------------------------------------
    def update(self, pose: Pose, measurements: Measurements) -> None:
        """One inverse-sensor-model update from a pose and the four
        horizontal measurements (m, None = nothing within range)."""
        with self._lock:
            self.pose = pose
            self._ensure(pose.x, pose.y)
            tilt = math.radians(max(abs(pose.roll), abs(pose.pitch)))
            c = self.cell
            r0, c0 = self.cell_of(pose.x - self.max_range - c, pose.y - self.max_range - c)
            r1, c1 = self.cell_of(pose.x + self.max_range + c, pose.y + self.max_range + c)
            r0, c0 = max(r0, 0), max(c0, 0)
            r1, c1 = min(r1 + 1, self.shape[0]), min(c1 + 1, self.shape[1])
            # The two auxiliary matrices of §4.2.1.A: distance and bearing
            # (relative to the drone's heading) of every cell in reach.
            xs = self.origin[0] + (np.arange(c0, c1) + 0.5) * c - pose.x
            ys = self.origin[1] + (np.arange(r0, r1) + 0.5) * c - pose.y
            dx, dy = np.meshgrid(xs, ys)
            dist = np.hypot(dx, dy)
            bearing = np.degrees(np.arctan2(dy, dx)) - pose.yaw
            # The cone touches a cell when its edge is within half a cell.
            half = self.fov / 2.0 + np.degrees(np.arctan2(c / 2.0, np.maximum(dist, 1e-9)))
            window = self.logodds[r0:r1, c0:c1]
            for name, b in BEARINGS.items():
                d = measurements.get(name)
                if d is not None and d * math.tan(tilt) > self.max_slice_offset:
                    continue  # the obstacle is out of the map's slice
                rel = np.abs((bearing - b + 180.0) % 360.0 - 180.0)
                cone = rel <= half
                if d is None:
                    window[cone & (dist <= self.max_range)] += L_FREE
                else:
                    # The hit's cell: its centre within half a cell of d
                    # (one cell when d falls on a cell edge).
                    window[cone & (dist <= d - c / 2.0)] += L_FREE
                    window[cone & (dist - d > -c / 2.0) & (dist - d <= c / 2.0)] += L_OCC
            # The drone's own cell is free.
            window[dist <= c / 2.0] += L_FREE
            np.clip(window, -L_MAX, L_MAX, out=window)
            self.updates += 1

    def reset(self) -> None:
        """Forget the map (e.g. after a change of flight height)."""
        with self._lock:
            self.logodds[:] = 0.0

    # -- reading the map ---------------------------------------------------
    def probabilities(self) -> np.ndarray:
        """The normalised occupancy probabilities (0.5 = unknown)."""
        with self._lock:
            return 1.0 - 1.0 / (1.0 + np.exp(self.logodds))

    def classes(self) -> np.ndarray:
        """UNKNOWN, FREE or OCCUPIED per cell."""
        with self._lock:
            lo = self.logodds.copy()
        out = np.full(lo.shape, UNKNOWN, dtype=np.int8)
        out[lo < 0.0] = FREE
        out[lo > 0.0] = OCCUPIED
        return out

    def frontiers(self, min_region: int = 5) -> list[list[tuple[int, int]]]:
        """Regions of frontier cells (free cells next to an unknown one,
        Yamauchi's frontiers, the seed's Algorithm 2 steps 2-4), each at
        least ``min_region`` cells, 8-connected."""
        cls = self.classes()
        free = cls == FREE
        unknown = cls == UNKNOWN
        near_unknown = np.zeros_like(free)
        near_unknown[1:, :] |= unknown[:-1, :]
        near_unknown[:-1, :] |= unknown[1:, :]
        near_unknown[:, 1:] |= unknown[:, :-1]
        near_unknown[:, :-1] |= unknown[:, 1:]
        frontier = free & near_unknown
        seen = np.zeros_like(frontier)
        regions = []
        for r, c in zip(*np.nonzero(frontier)):
            if seen[r, c]:
                continue
            region, queue = [], deque([(r, c)])
            seen[r, c] = True
            while queue:
                cr, cc = queue.popleft()
                region.append((int(cr), int(cc)))
                for nr in (cr - 1, cr, cr + 1):
                    for nc in (cc - 1, cc, cc + 1):
                        if self.inside(nr, nc) and frontier[nr, nc] and not seen[nr, nc]:
                            seen[nr, nc] = True
                            queue.append((nr, nc))
            if len(region) >= min_region:
                regions.append(region)
        return regions

    # -- outputs -------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """The map as NumPy arrays (``logodds``, ``origin``, ``cell``)."""
        path = Path(path)
        with self._lock:
            np.savez_compressed(path, logodds=self.logodds, origin=np.array(self.origin), cell=self.cell,
                                fov=self.fov)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Grid:
        data = np.load(path)
        g = cls(cell_size=float(data["cell"]), fov_deg=float(data["fov"]))
        g.logodds = data["logodds"].copy()
        g.origin = (float(data["origin"][0]), float(data["origin"][1]))
        return g

    def image(self) -> np.ndarray:
        """Grey levels (rows from the south): white free, black occupied,
        grey unknown, as the seed's maps."""
        return 1.0 - self.probabilities()

    def save_png(self, path: str | Path, plan: Any = None, goals: list[tuple[float, float]] | None = None,
                 title: str | None = None) -> Path:
        """The map (and, given a :class:`~.plan.TruePlan`, the true plan
        beside it, same frame and scale) as a PNG, with the goals the
        Explorer generated numbered in order (the seed's Figure 5.2)."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        panels = 2 if plan is not None else 1
        x0, x1, y0, y1 = self.extent
        fig, axes = plt.subplots(panels, 1, figsize=(8, 3.0 * panels), squeeze=False)
        ax = axes[0][0]
        ax.imshow(self.image(), cmap="gray", vmin=0.0, vmax=1.0, origin="lower", extent=(x0, x1, y0, y1))
        ax.set_title(title or f"occupancy grid: {self.cell * 100:.0f} cm cells, FOV {self.fov:g}°")
        if goals:
            gx, gy = zip(*goals)
            ax.plot(gx, gy, "o-", color="tab:blue", markersize=4, linewidth=0.8)
            for i, (x, y) in enumerate(goals):
                ax.annotate(str(i), (x, y), color="tab:blue", fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
        # The view: what the map observed (and the plan judged), 0.3 m round.
        seen = self.logodds != 0.0
        if plan is not None:
            seen = seen | (plan.truth != 0)
        if seen.any():
            rows, cols = np.nonzero(seen)
            view = (x0 + cols.min() * self.cell - 0.3, x0 + (cols.max() + 1) * self.cell + 0.3,
                    y0 + rows.min() * self.cell - 0.3, y0 + (rows.max() + 1) * self.cell + 0.3)
        else:
            view = (x0, x1, y0, y1)
        if plan is not None:
            px0, px1, py0, py1 = plan.extent
            ax2 = axes[1][0]
            ax2.imshow(plan.image(), cmap="gray", vmin=0.0, vmax=1.0, origin="lower",
                       extent=(px0, px1, py0, py1))
            ax2.set_title(f"the world's true plan at z = {plan.height:.2f} m (grey: not judged)")
        for row in axes:
            row[0].set_xlim(view[0], view[1])
            row[0].set_ylim(view[2], view[3])
        for row in axes:
            row[0].set_xlabel("x (m)")
            row[0].set_ylabel("y (m)")
            row[0].set_aspect("equal")
        fig.tight_layout()
        path = Path(path)
        fig.savefig(path, dpi=120)
        plt.close(fig)
        return path
