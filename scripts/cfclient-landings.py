#!/usr/bin/env python3
"""cfclient's *Land* flown many times, deterministically (docs/CFLIB.md,
"cfclient's Land").

Writes N seeded sessions of what cfclient's command-based flight buttons
send (`FlightTab._flight_command`: take off 0.5 m above the current height
in 1 s, moves of 0.5 m in 1 s — forward, back, left, right, up, down — as
relative `go_to`s, then *Land*: `land(0, z / 0.5)`, 0.5 m/s), as CRTP
recordings (`crtp.jsonl`, the high-level commander's packets on port 8 and
cflib's UDP keep-alive echoes), replays each through `cosim run cflib-lab
--set crtp=replay:FILE` (unpaced, exact) and prints, per session, the
largest tilt in flight, the largest tilt after touchdown, how far it slid
from its last point above 0.1 m, the attitude at the end and whether the
drone ended upright.

    scripts/cfclient-landings.py [--sessions 20] [--seed 1] [--out /tmp/cfclient-landings]
    scripts/cfclient-landings.py --hover     # cfclient flown by an input device instead

With ``--hover`` the sessions are what cfclient sends when flown by an
input device in its Hover assisted mode (scripts/cfclient-keys.py): hover
set-points at its 100 Hz input rate, from 0.4 m, moves at 0.3 m/s, then
down at 0.3 m/s to its lowest hover height (0.2 m), and the zero
set-point (motors off) when the assisted button is released.

Needs the release binaries (cargo build --release). Standard library only.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import random
import shutil
import struct
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# CRTP headers (port << 4 | link bits 0x0C | channel), as cflib sends them.
HL = (8 << 4) | 0x0C  # the high-level commander, channel 0
ECHO = (15 << 4) | 0x0C  # link echo: cflib's UDP keep-alive
RPYT = (3 << 4) | 0x0C  # the commander: close_link's zero set-point
GENERIC = (7 << 4) | 0x0C  # generic set-points, channel 0
TYPE_HOVER = 5
TAKEOFF_2, LAND_2, GO_TO_2 = 7, 8, 12
PS = 10**12
STEP_PS = 32 * 10**9  # cflib-lab's 32 ms step
# cfclient's buttons: 0.5 m in 1 s (FlightTab: `self._flight_command`).
MOVE_M, MOVE_S, LAND_SPEED = 0.5, 1.0, 0.5
MOVES = {"forward": (MOVE_M, 0, 0), "back": (-MOVE_M, 0, 0), "left": (0, MOVE_M, 0),
         "right": (0, -MOVE_M, 0), "up": (0, 0, MOVE_M), "down": (0, 0, -MOVE_M)}
# The start (seed004-room's) and the open part of the room the moves keep
# to (its walls at x = 0 and y = 0, 2.5; the cluttered zone beyond x = 3).
START = (0.5, 0.5)


def inside(x: float, y: float, z: float) -> bool:
    return 0.4 <= x <= 2.6 and 0.4 <= y <= 2.1 and 0.3 <= z <= 1.6


# Upright: within this of level once settled (rad).
UPRIGHT = 0.05


def takeoff(z: float, duration: float) -> bytes:
    return struct.pack("<BBBff?f", HL, TAKEOFF_2, 0, z, 0.0, True, duration)


def land(z: float, duration: float) -> bytes:
    return struct.pack("<BBBff?f", HL, LAND_2, 0, z, 0.0, True, duration)


def go_to(dx: float, dy: float, dz: float, duration: float) -> bytes:
    return struct.pack("<BBBBBfffff", HL, GO_TO_2, 0, True, False, dx, dy, dz, 0.0, duration)


def session(rng: random.Random) -> tuple[list[tuple[int, bytes]], list[str]]:
    """One flight: (arrival time in ps, packet) and the buttons clicked."""
    t = rng.uniform(3.6, 5.0)
    z = 0.015  # the drone's height at rest (seed004-room's start)
    packets: list[tuple[float, bytes]] = [(t, takeoff(z + MOVE_M, MOVE_S))]
    z += MOVE_M
    clicks = ["take off"]
    t += rng.uniform(2.5, 4.0)
    x, y = START
    for _ in range(rng.randint(2, 5)):
        name = rng.choice([m for m, d in sorted(MOVES.items()) if inside(x + d[0], y + d[1], z + d[2])])
        dx, dy, dz = MOVES[name]
        packets.append((t, go_to(dx, dy, dz, MOVE_S)))
        x, y, z = x + dx, y + dy, z + dz
        clicks.append(name)
        t += rng.uniform(1.5, 3.5)
    packets.append((t, land(0.0, z / LAND_SPEED)))
    clicks.append(f"land from {z:.2f} m")
    # cflib's keep-alive while the user watches the landing (10 s: the
    # drone comes down at most 0.2 m/s here, docs/CFLIB.md), then its
    # close_link (a zero set-point) when they disconnect.
    end = t + 10.0
    k = packets[0][0] + 0.4
    while k < end:
        packets.append((k, bytes([ECHO, 0])))
        k += 0.4
    packets.append((end, bytes([RPYT]) + bytes(14)))
    packets.sort(key=lambda p: p[0])
    return [(round(s * 1000) * 10**9, b) for s, b in packets], clicks


def hover(vx: float, vy: float, z: float) -> bytes:
    return struct.pack("<BBffff", GENERIC, TYPE_HOVER, vx, vy, 0.0, z)


def hover_session(rng: random.Random) -> tuple[list[tuple[int, bytes]], list[str]]:
    """cfclient flown by an input device in Hover mode (cfclient's
    `JoystickReader`, INPUT_READ_PERIOD 10 ms): zero set-points, then the
    assisted button held: hover from 0.4 m, moves, the descent to 0.2 m and
    a second there, then released: zero set-points (motors off)."""
    speed, vz, period = 0.3, 0.3, 0.01
    t = rng.uniform(3.6, 5.0)
    z = 0.4
    segments: list[tuple[float, float, float, float]] = [(rng.uniform(3.0, 4.0), 0.0, 0.0, 0.0)]
    clicks = ["take off"]
    x, y = START
    for _ in range(rng.randint(2, 4)):
        hold = rng.uniform(0.5, 1.5)
        k = speed * hold / MOVE_M
        name = rng.choice([m for m, d in sorted(MOVES.items())
                           if m != "down" and inside(x + k * d[0], y + k * d[1], z + k * d[2])])
        dx, dy, dz = MOVES[name]
        x, y = x + k * dx, y + k * dy
        segments.append((hold, speed * (dx > 0) - speed * (dx < 0), speed * (dy > 0) - speed * (dy < 0),
                         vz * (dz > 0)))
        segments.append((rng.uniform(1.0, 2.5), 0.0, 0.0, 0.0))
        clicks.append(f"{name} {hold:.1f} s")
    packets: list[tuple[float, bytes]] = []
    for duration, vx, vy, up in segments:
        for _ in range(round(duration / period)):
            z = min(2.0, z + up * period)
            packets.append((t, hover(vx, vy, z)))
            t += period
    clicks.append(f"land from {z:.2f} m")
    while z > 0.2:
        z = max(0.2, z - vz * period)
        packets.append((t, hover(0.0, 0.0, z)))
        t += period
    for _ in range(100):
        packets.append((t, hover(0.0, 0.0, z)))
        t += period
    end = t + 3.0
    while t < end:
        packets.append((t, bytes([RPYT]) + bytes(14)))
        t += period
    return [(round(s * 1000) * 10**9, b) for s, b in packets], clicks


def tilt(r: dict[str, float]) -> float:
    return max(abs(r["roll"]), abs(r["pitch"]))


def replay(cosim: Path, rec: Path, out: Path) -> list[dict[str, float]]:
    p = subprocess.run([str(cosim), "run", "cflib-lab", "--out", str(out), "--no-plots", "--quiet",
                        "--no-build", "--set", f"crtp=replay:{rec}", "--set", "crtp_idle_s=2",
                        # the plain trajectory.csv, kept after the run
                        "--set", "output.compress=false"],
                       cwd=ROOT, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"cfclient-landings: cosim run failed:\n{p.stdout}{p.stderr}")
    with open(out / "trajectory.csv") as f:
        return [{k: float(v) for k, v in r.items() if k != "drone"} for r in csv.DictReader(f)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("/tmp/cfclient-landings"))
    ap.add_argument("--keep", action="store_true",
                    help="keep each run's outputs (about 40 MB a session); by default only "
                         "session.jsonl and trajectory.csv stay")
    ap.add_argument("--hover", action="store_true",
                    help="cfclient flown by an input device in Hover mode instead of its buttons")
    ap.add_argument("--cosim", type=Path, default=ROOT / "target" / "release" / "cosim")
    a = ap.parse_args()
    if a.sessions < 1:
        ap.error("--sessions must be at least 1")
    rng = random.Random(a.seed)
    upright = 0
    print("session  flight tilt  touchdown tilt  slide  end roll  end pitch  end z  upright  clicks")
    for i in range(a.sessions):
        packets, clicks = (hover_session if a.hover else session)(rng)
        d = a.out / f"s{i:02}"
        d.mkdir(parents=True, exist_ok=True)
        rec = d / "session.jsonl"
        rec.write_text("".join(json.dumps({"platform_ps": t, "crtp": b.hex()}) + "\n" for t, b in packets))
        rows = replay(a.cosim, rec, d / "run")
        if not a.keep:
            shutil.copy(d / "run" / "trajectory.csv", d / "trajectory.csv")
            shutil.rmtree(d / "run")
        high = max(j for j, r in enumerate(rows) if r["z"] > 0.1)
        end = rows[-1]
        ok = tilt(end) < UPRIGHT and end["z"] < 0.03
        upright += ok
        # How far the drone moved from its last point above 0.1 m (m).
        slide = math.hypot(end["x"] - rows[high]["x"], end["y"] - rows[high]["y"])
        print(f"{i:7}  {max(map(tilt, rows[:high + 1])):11.3f}  {max(map(tilt, rows[high + 1:])):14.3f}  {slide:5.3f}  "
              f"{end['roll']:8.3f}  {end['pitch']:9.3f}  {end['z']:5.3f}  {'yes' if ok else 'NO':7}  "
              f"{', '.join(clicks)}")
    print(f"upright after landing: {upright} of {a.sessions} (seed {a.seed})")
    return 0 if upright == a.sessions else 1


if __name__ == "__main__":
    sys.exit(main())
