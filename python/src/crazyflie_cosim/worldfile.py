"""World files (TOML, docs/SWARM.md and world-server's ``world_file``) as far
as a client needs them: the drones' names and starts, the gates' openings,
and writing a modified copy (the environment's seeded start positions).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]


@dataclass(frozen=True)
class Gate:
    """A gate's opening as ``world-server/src/gates.rs`` sees it: passed when
    the drone's centre crosses its plane along ``normal`` (the world file's
    ``yaw``) inside the square ``inner`` opening."""

    centre: tuple[float, float, float]
    yaw: float
    inner: float

    @property
    def normal(self) -> tuple[float, float, float]:
        return (math.cos(self.yaw), math.sin(self.yaw), 0.0)

    @property
    def across(self) -> tuple[float, float, float]:
        return (-math.sin(self.yaw), math.cos(self.yaw), 0.0)

    def crossed(self, a: tuple[float, float, float], b: tuple[float, float, float]) -> bool:
        """Whether the segment ``a`` -> ``b`` crosses the opening in the
        direction of travel (``GateOpening::crossed``, same arithmetic)."""
        c, n = self.centre, self.normal
        s0 = sum((a[i] - c[i]) * n[i] for i in range(3))
        s1 = sum((b[i] - c[i]) * n[i] for i in range(3))
        if not (s0 < 0.0 and s1 >= 0.0):
            return False
        t = s0 / (s0 - s1)
        q = [a[i] + (b[i] - a[i]) * t - c[i] for i in range(3)]
        across = self.across
        half = self.inner / 2.0
        return abs(sum(q[i] * across[i] for i in range(3))) < half and abs(q[2]) < half


@dataclass(frozen=True)
class DroneStart:
    name: str
    position: tuple[float, float, float]
    yaw: float


class WorldFile:
    """A parsed world file; ``data`` is the TOML document as dicts."""

    def __init__(self, data: dict[str, Any], path: Path | None = None):
        self.data = data
        self.path = path

    @classmethod
    def load(cls, path: str | os.PathLike) -> WorldFile:
        path = Path(path)
        try:
            with open(path, "rb") as f:
                return cls(tomllib.load(f), path)
        except OSError as e:
            raise ValueError(f"cannot read world file {path}: {e.strerror}") from None
        except tomllib.TOMLDecodeError as e:
            raise ValueError(f"world file {path}: {e}") from None

    @property
    def drones(self) -> list[DroneStart]:
        """The drones in file order; a file without ``[[drone]]`` has one,
        ``cf1``, at ``[start]`` (DESIGN.md §7)."""
        tables = self.data.get("drone")
        if tables:
            # A carried drone starts at its path's first point (t, x, y, z).
            return [
                DroneStart(
                    t["name"],
                    tuple(t["position"] if "position" in t else t["carried"][0][1:4]),
                    float(t.get("yaw", 0.0)),
                )
                for t in tables
            ]
        start = self.data.get("start", {})
        return [DroneStart("cf1", tuple(start.get("position", (0.0, 0.0, 0.015))), float(start.get("yaw", 0.0)))]

    @property
    def multi(self) -> bool:
        return bool(self.data.get("drone"))

    @property
    def gates(self) -> list[Gate]:
        return [
            Gate(tuple(g["centre"]), float(g.get("yaw", 0.0)), float(g["inner"])) for g in self.data.get("gate", [])
        ]

    def with_drones(self, drones: list[DroneStart]) -> WorldFile:
        """A copy whose drones are ``drones``: ``[start]`` for one drone named
        ``cf1`` in a file without ``[[drone]]``, ``[[drone]]`` tables
        otherwise (other keys of existing tables, e.g. ``clock_ppm``, kept)."""
        data = {k: v for k, v in self.data.items()}
        if len(drones) == 1 and drones[0].name == "cf1" and not self.multi:
            data["start"] = dict(data.get("start", {}), position=list(drones[0].position), yaw=drones[0].yaw)
        else:
            old = {t["name"]: t for t in self.data.get("drone", [])}
            data["drone"] = [
                dict(old.get(d.name, {}), name=d.name, position=list(d.position), yaw=d.yaw) for d in drones
            ]
        return WorldFile(data, None)

    def dumps(self) -> str:
        return _dump_table(self.data, ())

    def write(self, path: str | os.PathLike) -> Path:
        path = Path(path)
        path.write_text(self.dumps())
        return path


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        # A TOML basic string: JSON's escapes are TOML's.
        import json

        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _key(k: str) -> str:
    return k if k and all(c.isalnum() or c in "-_" for c in k) else _value(k)


def _dump_table(table: dict[str, Any], prefix: tuple[str, ...]) -> str:
    lines: list[str] = []
    sub: list[str] = []
    for k, v in table.items():
        name = ".".join(_key(p) for p in (*prefix, k))
        if isinstance(v, dict):
            sub.append(f"\n[{name}]\n" + _dump_table(v, (*prefix, k)))
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for x in v:
                sub.append(f"\n[[{name}]]\n" + _dump_table(x, (*prefix, k)))
        else:
            lines.append(f"{_key(k)} = {_value(v)}\n")
    return "".join(lines) + "".join(sub)
