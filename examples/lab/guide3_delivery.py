#!/usr/bin/env python3
"""Laboratory guide 3 (seed 004 §4.3.3): three groups' drone delivery
applications share one room and its airway, each with its own ground
station (a thread here, its own cflib link), the Radar and the DDS.

    python examples/lab/guide3_delivery.py        # launches `cosim run lab-delivery --set pace=4`

Each group (the student's code, exercises 1-3):
1. opens the Radar (its drone beacons from then on, and hears the others);
2. before every command, the safety check of exercise 2: if a drone with
   priority is heard (a smaller id), in close proximity the cruising speed
   drops to 0.1 m/s; in dangerous proximity the drone lands (without
   disconnecting) and waits for clearance — nobody dangerous heard for
   ``CLEARANCE_S`` — then takes off and proceeds;
3. flies a delivery (exercise 3): a pick-up and a drop-off from
   ``DDS.assign_delivery``, travelling in the airway (``DDS.travel``),
   leaving it only within ``LEAVE_M`` of a location; a pick-up or drop-off
   is a descent to 0.2 m and a climb back; then home, and land.

The groups start ``STAGGER_S`` apart, as groups in a lab do. Writes to
--out: delivery.json (each group's deliveries with their stages' times,
landings for the radar, radar heard), radar-g*.csv (every radar reading:
the drone's time in ms, the id heard, its RSSI) and cosim's outputs.
"""

from __future__ import annotations

import csv
import json
import sys
import threading
import traceback

import labcommon
from labcommon import Clock, drone_clock, land, take_off

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie
from crazyflie_cosim.lab import DDS, HOME, Command, Radar, Status
from crazyflie_cosim.worldfile import WorldFile

HEIGHT = 0.4  # m, the airway's height
LEAVE_M = 0.9  # leave the airway within this of a location (§4.3.3 d)
AT_M = 0.1  # at a location
CLEARANCE_S = 2.0  # nobody dangerous heard for this long: clear to take off
STAGGER_S = 8.0  # the groups start this far apart (drone time)
SLOW = 0.1  # m/s in close proximity (§4.3.3 c)
#: The lab's stations in the room's frame (m): 0.5 m inside the airway,
#: which runs 0.5 m from the walls (lab-delivery.toml).
STATIONS = {"North": (3.0, 3.0), "West": (1.0, 2.6), "East": (5.0, 2.6)}


class Group(threading.Thread):
    def __init__(self, index: int, uri: str, home: tuple[float, float], pace: float, seed: int):
        super().__init__(name=f"g{index + 1}")
        self.index, self.uri, self.home, self.pace, self.seed = index, uri, home, pace, seed
        self.report: dict = {"group": self.name, "uri": uri}
        self.radar_log: list = []
        self.error: str | None = None

    def run(self):
        try:
            self.fly()
        except Exception:
            self.error = traceback.format_exc()

    def safe(self, cf, radar: Radar, clock: Clock, cmd: Command) -> Command:
        """Exercise 2: the radar check before a command is sent."""
        other = radar.detected()
        if other is None:
            return cmd
        proximity = radar.proximity()
        if radar.has_priority(other):
            # Ours, beyond the guide's rule: the drone with priority slows
            # down in dangerous proximity too, so that the other has the
            # time to land before it is reached (landing takes 2.5 s; at
            # full speed two drones heading for the same station met at
            # the airway's height).
            return cmd.scaled(SLOW) if proximity == "danger" else cmd
        if proximity == "close":
            return cmd.scaled(SLOW)
        if proximity != "danger":
            return cmd
        # Dangerous proximity to a drone with priority: land, wait, go on.
        t_land = clock.now
        self.report["landings"].append({"t_s": round(t_land, 1), "for": other, "rssi": radar.rssi()})
        land(cf, clock, cmd.z)
        clear_since = clock.now
        while clock.now - clear_since < CLEARANCE_S:
            cf.commander.send_stop_setpoint()  # keeps the link alive, motors off
            clock.tick()
            if radar.proximity() == "danger":
                clear_since = clock.now
        take_off(cf, clock, cmd.z)
        self.report["landings"][-1]["waited_s"] = round(clock.now - t_land, 1)
        return cmd.hovering()

    def fly(self):
        with SyncCrazyflie(self.uri, cf=Crazyflie(rw_cache=None)) as scf:
            cf = scf.cf
            locations = {n: (x - self.home[0], y - self.home[1]) for n, (x, y) in STATIONS.items()}
            # Exercise 1: the radar (beaconing from here on).
            with Radar(cf) as radar, DDS(cf, locations=locations, height=HEIGHT, seed=self.seed) as dds:
                clock = drone_clock(dds.telemetry, self.pace)
                self.report.update(id=radar.my_id, landings=[])
                for _ in clock.seconds(STAGGER_S * self.index):
                    cf.commander.send_stop_setpoint()
                    clock.tick()
                delivery = dds.assign_delivery()
                self.report["delivery"] = {"pickup": delivery.pickup, "dropoff": delivery.dropoff}
                print(f"{self.name} (id {radar.my_id}): deliver from {delivery.pickup} to {delivery.dropoff}",
                      flush=True)
                take_off(cf, clock, HEIGHT)
                delivery.advance(int(clock.now * 1000))
                while delivery.status is not Status.DONE:
                    if clock.now > 900.0:
                        raise TimeoutError(f"{self.name}: no delivery in 900 s")
                    target = delivery.destination
                    d = dds.distance_to_location(target)
                    if d < AT_M:
                        if target == HOME:
                            delivery.advance(int(clock.now * 1000))
                            break
                        # Pick-up or drop-off: down to 0.2 m and back up,
                        # never onto or into another drone (ours, beyond the
                        # guide: the stations are shared). A drone without
                        # priority lands where the radar finds it (exercise
                        # 2), possibly at this station; one with priority
                        # holds its height while another is in dangerous
                        # proximity (it may be under it, landed or landing,
                        # or above it).
                        held = HEIGHT
                        for z in (0.2, HEIGHT):
                            for _ in clock.seconds(2.0):
                                cmd = self.safe(cf, radar, clock, Command(0.0, 0.0, 0.0, z))
                                if radar.proximity() == "danger":
                                    cmd = Command(0.0, 0.0, 0.0, held)
                                held = cmd.z
                                cf.commander.send_hover_setpoint(*cmd)
                                clock.tick()
                        delivery.advance(int(clock.now * 1000))
                        print(f"{self.name}: {delivery.status.value} at {clock.now:.0f} s", flush=True)
                        continue
                    cmd = dds.velocity_to_location(target) if d < LEAVE_M else dds.travel()
                    cf.commander.send_hover_setpoint(*self.safe(cf, radar, clock, cmd))
                    clock.tick()
                land(cf, clock, HEIGHT)
                print(f"{self.name}: home at {clock.now:.0f} s", flush=True)
                self.report["stages"] = [(s.value, t) for s, t in delivery.log]
                self.report["done"] = delivery.status is Status.DONE
                # Stay on the ground, beaconing, until everyone is home.
                self.radar_log = radar.history
            self.report["radar_readings"] = len(self.radar_log)


def main() -> int:
    args = labcommon.parser(__doc__.splitlines()[1], "lab-delivery", drones=3).parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    world = WorldFile.load(labcommon.ROOT / "scenarios" / "worlds" / "lab-delivery.toml")
    homes = [(d.position[0], d.position[1]) for d in world.drones]
    cflib.crtp.init_drivers()
    with labcommon.simulator(args) as sim:
        groups = [Group(i, uri, homes[i], args.pace, seed=i) for i, uri in enumerate(labcommon.uris(args))]
        for g in groups:
            g.start()
        for g in groups:
            g.join()
    for g in groups:
        with open(args.out / f"radar-{g.name}.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["t_ms", "id", "rssi_dbm"])
            w.writerows((e.t_ms, e.id, f"{e.rssi:.2f}") for e in g.radar_log)
    result = {"groups": [g.report for g in groups], "cosim_out": str(sim.out) if sim else None}
    (args.out / "delivery.json").write_text(json.dumps(result, indent=1) + "\n")
    failed = [g for g in groups if g.error or not g.report.get("done")]
    for g in failed:
        print(f"{g.name} failed:\n{g.error}", file=sys.stderr)
    print(json.dumps([{k: g.report.get(k) for k in ("group", "id", "done", "landings")} for g in groups]))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
