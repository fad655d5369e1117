#!/usr/bin/env python3
"""Laboratory guide 2, exercise 2 (seed 004 §4.2.2): map the room with a
Grid while piloting with the KeyboardPilot, and land by yourself when the
battery runs low (exercise 1's battery log).

    python examples/lab/guide2_mapping.py        # scripted keys, launches `cosim run cflib-lab --set pace=4`
    python examples/lab/guide2_mapping.py --keyboard --no-launch --pace 1

The scripted flight goes round the open zone of seed 004's room (the
seed's first mapping experiment flew "around the room", §5.1). Writes
mapping-map.png (the map beside the world's true plan), mapping-map.npz and
mapping.json (coverage, accuracy) to --out.
"""

from __future__ import annotations

import json
import sys

import labcommon
from guide1_pilot import assisted
from labcommon import drone_clock, land, take_off

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.log import LogConfig
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie
from crazyflie_cosim.lab import Grid, Hold, KeyboardPilot, ScriptedKeys, TerminalKeys, TruePlan

HEIGHT = 0.3
LOW_BATTERY_V = 3.2
#: A round of the open zone from the take-off point (0.5, 0.5), in the
#: drone's seconds at 0.3 m/s: east 2.7 m, north 1.2 m, west 2.7 m, south.
SCRIPT = [(0.0, "up", 9.0), (9.5, "left", 4.0), (14.0, "down", 9.0), (23.5, "right", 4.0)]


def main() -> int:
    p = labcommon.parser(__doc__.splitlines()[1], "cflib-lab")
    p.add_argument("--keyboard", action="store_true", help="read your keys from this terminal")
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    cflib.crtp.init_drivers()
    vbat = []
    with labcommon.simulator(args):
        with SyncCrazyflie(labcommon.uris(args)[0], cf=Crazyflie(rw_cache=None)) as scf:
            cf = scf.cf
            conf = LogConfig(name="battery", period_in_ms=500)
            conf.add_variable("pm.vbat", "float")
            conf.data_received_cb.add_callback(lambda ts, d, _: vbat.append(d["pm.vbat"]))
            cf.log.add_config(conf)
            conf.start()
            with Grid(cf, cell_size=0.05, fov_deg=5.0) as grid:
                grid.telemetry.wait()
                clock = drone_clock(grid.telemetry, args.pace)
                take_off(cf, clock, HEIGHT)
                tel = grid.telemetry
                keys = TerminalKeys() if args.keyboard else ScriptedKeys(
                    [Hold(t, k, d) for t, k, d in SCRIPT], clock=lambda: tel.t_ms / 1000.0)
                landing = []
                with KeyboardPilot(keys, speed=0.3, height=HEIGHT) as pilot:
                    pilot.on("l", lambda: landing.append("key"))
                    while not landing and not keys.finished:
                        if vbat and vbat[-1] < LOW_BATTERY_V:
                            landing.append(f"battery {vbat[-1]:.2f} V")
                        cf.commander.send_hover_setpoint(*assisted(pilot.command, grid.measurements))
                        clock.tick()
                land(cf, clock, HEIGHT)
            conf.stop()
    plan = TruePlan.from_world(labcommon.ROOT / "scenarios" / "worlds" / "seed004-room.toml", grid, HEIGHT)
    score = plan.score(grid)
    grid.save(args.out / "mapping-map.npz")
    grid.save_png(args.out / "mapping-map.png", plan=plan,
                  title=f"mapped while piloting: coverage {score['coverage_pct']:.1f} %, "
                        f"accuracy {score['accuracy_pct']:.1f} %")
    result = {"landed_for": landing or ["end of script"], "vbat_first": vbat[0], "vbat_last": vbat[-1],
              "map_updates": grid.updates, **{k: round(v, 2) for k, v in score.items()}}
    (args.out / "mapping.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
