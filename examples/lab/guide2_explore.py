#!/usr/bin/env python3
"""Laboratory guide 2, exercises 1 and 3 (seed 004 §4.2.2): log the
battery, and explore the room autonomously with an Explorer, mapping it
with a Grid; the map is drawn beside the world's true plan.

    python examples/lab/guide2_explore.py            # launches `cosim run cflib-lab --set pace=4`

The student's part is :class:`RoomExplorer.run` — the Explorer's ``run``
is left to students in the seed (§4.2.1.B) — a solution following the
seed's exploration behaviour (§5.2): take off, scan, generate a frontier
goal, fly there (here on the map's shortest path, §4.2.2's "more
sophisticated solution"), scan again …; land when no frontier is left, or
when the battery is low (exercise 2's automatic landing).

Writes to --out: explore-map.npz (the grid), explore-map.png (the map, its
goals numbered, beside the true plan), explore.json (coverage, accuracy,
goals, time) and cosim's outputs in cosim/.
"""

from __future__ import annotations

import json
import math
import sys

import labcommon
from labcommon import drone_clock, land, take_off

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.log import LogConfig
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie
from crazyflie_cosim.lab import Command, Explorer, Grid, TruePlan
from crazyflie_cosim.lab.command import wrap_deg

HEIGHT = 0.3  # m: the seed's room is mapped at 0.3 m (seed004-room.toml)
LOW_BATTERY_V = 3.2  # exercise 2: land when the battery sags below this (a 1S LiPo's safe floor)


class RoomExplorer(Explorer):
    """Scan (turn a quarter and a bit: four rangers see all round), goal,
    path, fly the path, scan ... None when the map has no frontier left."""

    SCAN_DEG = 100.0
    SCAN_RATE = 30.0  # deg/s: 3° per 100 ms reading, under the 4° cone

    def __init__(self, grid: Grid, **kw):
        super().__init__(grid, **kw)
        self.state = "scan"
        self.turned = 0.0
        self.last_yaw: float | None = None
        self.path: list[tuple[float, float]] = []
        self.stuck_ticks = 0

    def run(self, measurements):
        pose = self.pose
        if pose is None:
            return Command(z=self.height)
        if self.state == "scan":
            if self.last_yaw is not None:
                self.turned += abs(wrap_deg(pose.yaw - self.last_yaw))
            self.last_yaw = pose.yaw
            if self.turned < self.SCAN_DEG:
                return Command(0.0, 0.0, self.SCAN_RATE, self.height)
            self.state, self.turned, self.last_yaw = "plan", 0.0, None
        if self.state == "plan":
            while True:
                goal = self.generate_goal()
                if goal is None:
                    return None  # the room is explored
                path = self.path_to(goal)
                end = path[-1] if path else None
                if end is None or math.hypot(end[0] - pose.x, end[1] - pose.y) < 0.15:
                    self.give_up()  # nowhere to go towards it (seen through a gap)
                    continue
                self.path, self.state, self.stuck_ticks = path, "go", 0
                break
        # "go": fly the path's corners; a wall too close ahead stops it.
        front = measurements.get("front")
        wp = self.path[0]
        if math.hypot(wp[0] - pose.x, wp[1] - pose.y) < 0.08:
            self.path.pop(0)
            if not self.path:
                self.state = "scan"
                return Command(z=self.height)
            wp = self.path[0]
        cmd = self.velocity_towards(wp)
        if front is not None and front < 0.2 and cmd.vx > 0.0:
            cmd = cmd._replace(vx=0.0)
        self.stuck_ticks += 1
        if self.stuck_ticks > 600:  # 60 s on one goal: give it up, scan
            self.give_up()
            self.state = "scan"
        return cmd


def main() -> int:
    args = labcommon.parser(__doc__.splitlines()[1], "cflib-lab").parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    cflib.crtp.init_drivers()
    battery = {"vbat": None, "level": None}
    with labcommon.simulator(args) as sim:
        with SyncCrazyflie(labcommon.uris(args)[0], cf=Crazyflie(rw_cache=None)) as scf:
            cf = scf.cf
            # Exercise 1: the battery, logged every 500 ms.
            conf = LogConfig(name="battery", period_in_ms=500)
            conf.add_variable("pm.vbat", "float")
            conf.add_variable("pm.batteryLevel", "uint8_t")
            conf.data_received_cb.add_callback(
                lambda ts, d, _: battery.update(vbat=d["pm.vbat"], level=d["pm.batteryLevel"]))
            cf.log.add_config(conf)
            conf.start()
            with Grid(cf, cell_size=0.05, fov_deg=4.0, max_range=3.0) as grid:
                grid.telemetry.wait()
                clock = drone_clock(grid.telemetry, args.pace)
                print(f"battery {battery['vbat']:.2f} V ({battery['level']} %)", flush=True)
                take_off(cf, clock, HEIGHT)
                explorer = RoomExplorer(grid, height=HEIGHT, speed=0.2)
                t_start = clock.now
                reason = "explored"
                while True:
                    if battery["vbat"] is not None and battery["vbat"] < LOW_BATTERY_V:
                        reason = "battery low"
                        break
                    if clock.now - t_start > 600.0:
                        reason = "time budget (600 s)"
                        break
                    cmd = explorer.run(grid.measurements)
                    if cmd is None:
                        break
                    cf.commander.send_hover_setpoint(*cmd)
                    clock.tick()
                t_explore = clock.now - t_start
                land(cf, clock, HEIGHT)
            conf.stop()
            print(f"battery {battery['vbat']:.2f} V ({battery['level']} %)", flush=True)
    grid.save(args.out / "explore-map.npz")
    world = labcommon.ROOT / "scenarios" / "worlds" / "seed004-room.toml"
    plan = TruePlan.from_world(world, grid, HEIGHT)
    score = plan.score(grid)
    grid.save_png(args.out / "explore-map.png", plan=plan, goals=explorer.goals,
                  title=f"explored in {t_explore:.0f} s: coverage {score['coverage_pct']:.1f} %, "
                        f"accuracy {score['accuracy_pct']:.1f} %")
    result = {"ended": reason, "exploration_s": round(t_explore, 1), "goals": len(explorer.goals),
              "given_up": len(explorer.unreachable), **{k: round(v, 2) for k, v in score.items()},
              "cosim_out": str(sim.out) if sim else None}
    (args.out / "explore.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
