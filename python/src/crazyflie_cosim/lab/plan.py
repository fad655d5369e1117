"""The world's true floor plan at the flight height, laid on a
:class:`~.grid.Grid`'s cells, and the map's score against it — the same
definitions as the simulator's own (scenarios/src/mapping/truth.rs,
DESIGN.md §9, docs/EXPLORE.md):

- a cell is *truly free* if its square touches no obstacle footprint and it
  is connected to the take-off cell through such cells (a flood fill: what
  lies outside the room is never counted);
- *truly occupied* if its centre lies inside a footprint;
- otherwise not judged.

Coverage: the share of truly free cells the map has observed (log-odds not
0). Accuracy: of the observed cells whose truth is clear-cut, the share
whose class matches. The obstacles are the world file's ``[[box]]``es whose
height span contains the flight height (the world's gates are not read).
"""

from __future__ import annotations

import math
import os
from collections import deque
from dataclasses import dataclass

import numpy as np

from ..worldfile import WorldFile
from .grid import FREE, OCCUPIED, Grid

NOT_JUDGED, TRUE_FREE, TRUE_OCCUPIED = 0, 1, 2


@dataclass(frozen=True)
class Footprint:
    """An obstacle's oriented rectangle in the slice (m, rad)."""

    centre: tuple[float, float]
    half: tuple[float, float]
    yaw: float

    def _axes(self):
        s, c = math.sin(self.yaw), math.cos(self.yaw)
        return ((c, s), (-s, c))

    def contains(self, x: float, y: float) -> bool:
        d = (x - self.centre[0], y - self.centre[1])
        return all(abs(d[0] * a[0] + d[1] * a[1]) <= h for a, h in zip(self._axes(), self.half))

    def overlaps_square(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """Separating axes, open interiors (truth.rs's Footprint::overlaps_square)."""
        sc = ((x0 + x1) / 2.0, (y0 + y1) / 2.0)
        sh = ((x1 - x0) / 2.0, (y1 - y0) / 2.0)
        ax = self._axes()
        d = (self.centre[0] - sc[0], self.centre[1] - sc[1])
        for n in ((1.0, 0.0), (0.0, 1.0), ax[0], ax[1]):
            dist = abs(d[0] * n[0] + d[1] * n[1])
            r_sq = sh[0] * abs(n[0]) + sh[1] * abs(n[1])
            r_box = (self.half[0] * abs(ax[0][0] * n[0] + ax[0][1] * n[1])
                     + self.half[1] * abs(ax[1][0] * n[0] + ax[1][1] * n[1]))
            if dist >= r_sq + r_box - 1e-9:
                return False
        return True


def footprints(world: WorldFile, height: float) -> list[Footprint]:
    out = []
    for b in world.data.get("box", []):
        cz, sz = float(b["centre"][2]), float(b["size"][2])
        if abs(cz - height) < sz / 2.0:
            out.append(Footprint((float(b["centre"][0]), float(b["centre"][1])),
                                 (float(b["size"][0]) / 2.0, float(b["size"][1]) / 2.0), float(b.get("yaw", 0.0))))
    return out


class TruePlan:
    """The truth of every cell of ``grid`` (same shape and frame)."""

    def __init__(self, grid: Grid, obstacles: list[Footprint], start: tuple[float, float], height: float):
        self.height = height
        self.cell = grid.cell
        self.origin = grid.origin
        rows, cols = grid.shape
        c = grid.cell
        touches = np.zeros((rows, cols), dtype=bool)
        centre_in = np.zeros((rows, cols), dtype=bool)
        for o in obstacles:
            # Only the cells near the footprint need the exact tests.
            reach = math.hypot(*o.half) + c
            r0, c0 = grid.cell_of(o.centre[0] - reach, o.centre[1] - reach)
            r1, c1 = grid.cell_of(o.centre[0] + reach, o.centre[1] + reach)
            for r in range(max(r0, 0), min(r1 + 1, rows)):
                for k in range(max(c0, 0), min(c1 + 1, cols)):
                    x0, y0 = grid.origin[0] + k * c, grid.origin[1] + r * c
                    if o.overlaps_square(x0, y0, x0 + c, y0 + c):
                        touches[r, k] = True
                    if o.contains(x0 + c / 2.0, y0 + c / 2.0):
                        centre_in[r, k] = True
        sr, sc = grid.cell_of(*start)
        if not grid.inside(sr, sc):
            raise ValueError(f"the take-off point {start} is outside the map's grid")
        if touches[sr, sc]:
            raise ValueError(f"the take-off point {start} is inside an obstacle at z = {height} m")
        free = np.zeros((rows, cols), dtype=bool)
        free[sr, sc] = True
        queue = deque([(sr, sc)])
        while queue:
            r, k = queue.popleft()
            for nr, nk in ((r + 1, k), (r - 1, k), (r, k + 1), (r, k - 1)):
                if 0 <= nr < rows and 0 <= nk < cols and not free[nr, nk] and not touches[nr, nk]:
                    free[nr, nk] = True
                    queue.append((nr, nk))
        self.truth = np.full((rows, cols), NOT_JUDGED, dtype=np.int8)
        self.truth[free] = TRUE_FREE
        self.truth[centre_in] = TRUE_OCCUPIED
        self.extent = grid.extent

    @classmethod
    def from_world(cls, path: str | os.PathLike, grid: Grid, height: float,
                   start: tuple[float, float] | None = None) -> TruePlan:
        """The plan of world file ``path`` on ``grid``; ``start`` defaults
        to the world's (first) drone's start."""
        world = WorldFile.load(path)
        if start is None:
            d = world.drones[0]
            start = (d.position[0], d.position[1])
        return cls(grid, footprints(world, height), start, height)

    def image(self) -> np.ndarray:
        img = np.full(self.truth.shape, 0.5)
        img[self.truth == TRUE_FREE] = 1.0
        img[self.truth == TRUE_OCCUPIED] = 0.0
        return img

    def score(self, grid: Grid) -> dict[str, float]:
        """Coverage, accuracy and free coverage (%) of ``grid`` (the grid
        this plan was laid on)."""
        cls = grid.classes()
        if cls.shape != self.truth.shape:
            raise ValueError("the plan was laid on another grid")
        observed = cls != 0
        free = self.truth == TRUE_FREE
        judged = self.truth != NOT_JUDGED
        right = ((cls == FREE) & free) | ((cls == OCCUPIED) & (self.truth == TRUE_OCCUPIED))
        n_free = int(free.sum())
        n_judged = int((observed & judged).sum())
        return {
            "cells": int(cls.size),
            "true_free_cells": n_free,
            "coverage_pct": 100.0 * int((observed & free).sum()) / max(n_free, 1),
            "accuracy_pct": 100.0 * int((right & observed & judged).sum()) / max(n_judged, 1),
            "free_coverage_pct": 100.0 * int(((cls == FREE) & free).sum()) / max(n_free, 1),
        }
