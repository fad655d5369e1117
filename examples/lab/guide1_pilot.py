#!/usr/bin/env python3
"""Laboratory guide 1 (seed 004 §4.1.4): the assisted pilot — piloting by
keyboard with a KeyboardPilot, stopped by the Multi-ranger before it flies
into an obstacle.

    python examples/lab/guide1_pilot.py                # scripted keys, launches `cosim run cflib-lab --set pace=4`
    python examples/lab/guide1_pilot.py --keyboard --no-launch --pace 1   # your own keys (a terminal), against
                                                       # a running `cosim run cflib-lab` (or a real Crazyflie)

Keys: arrows or w/a/s/d move, q/e turn, r/f climb/descend, space stops,
l lands. The scripted flight (``SCRIPT``, in the drone's seconds: the
keys follow the drone's clock, so a loaded machine flies the same) flies
forward, left, turns left, backs up, turns back, then pushes forward into
the room's partition: the assistant stops it ``STOP_M`` short.

The KeyboardPilot never sends: this script sends its command after the
assistant (the student's exercise) has corrected it. Writes keys.json to
--out: each key's press and release in the drone's time (ms) and the
estimate there, and cosim's outputs.
"""

from __future__ import annotations

import json
import sys

import labcommon
from labcommon import drone_clock, land, take_off

import cflib.crtp
from cflib.crazyflie import Crazyflie
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie
from crazyflie_cosim.lab import Command, Hold, KeyboardPilot, ScriptedKeys, Telemetry, TerminalKeys

HEIGHT = 0.3
STOP_M = 0.3  # the assistant stops a move towards an obstacle closer than this
#: (start s, key, hold s) in the drone's time after the take-off.
SCRIPT = [(0.0, "up", 5.0), (6.0, "left", 4.0), (11.0, "q", 2.0), (14.0, "down", 3.0),
          (18.0, "e", 2.0), (21.0, "w", 20.0)]


def assisted(cmd: Command, m: dict) -> Command:
    """Exercise (§4.1.4): no velocity towards an obstacle within STOP_M."""
    def near(name):
        d = m.get(name)
        return d is not None and d < STOP_M

    vx, vy = cmd.vx, cmd.vy
    if (vx > 0 and near("front")) or (vx < 0 and near("back")):
        vx = 0.0
    if (vy > 0 and near("left")) or (vy < 0 and near("right")):
        vy = 0.0
    return cmd._replace(vx=vx, vy=vy)


def main() -> int:
    p = labcommon.parser(__doc__.splitlines()[1], "cflib-lab")
    p.add_argument("--keyboard", action="store_true", help="read your keys from this terminal")
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    cflib.crtp.init_drivers()
    events = []
    with labcommon.simulator(args):
        with SyncCrazyflie(labcommon.uris(args)[0], cf=Crazyflie(rw_cache=None)) as scf:
            cf = scf.cf
            with Telemetry(cf) as tel:
                tel.wait()
                clock = drone_clock(tel, args.pace)
                take_off(cf, clock, HEIGHT)
                # Scripted keys on the drone's own clock (the log's time), so
                # a slow machine flies the same script.
                keys = TerminalKeys() if args.keyboard else ScriptedKeys(
                    [Hold(t, k, d) for t, k, d in SCRIPT], clock=lambda: tel.t_ms / 1000.0)
                landing = []
                with KeyboardPilot(keys, speed=0.2, height=HEIGHT) as pilot:
                    pilot.on("l", lambda: landing.append(True))
                    pilot.on("esc", lambda: landing.append(True))
                    held = frozenset()
                    while not landing:
                        finished = keys.finished  # before reading the keys: the last release is seen
                        now_held = pilot.held
                        pose = tel.pose
                        for k in held ^ now_held:
                            events.append({"key": k, "event": "press" if k in now_held else "release",
                                           "t_ms": tel.t_ms, "x": pose.x, "y": pose.y, "yaw": pose.yaw})
                        held = now_held
                        if finished:
                            break
                        cf.commander.send_hover_setpoint(*assisted(pilot.command, tel.measurements))
                        clock.tick()
                    z = pilot.height
                land(cf, clock, z)
    (args.out / "keys.json").write_text(json.dumps(events, indent=1) + "\n")
    for e in events:
        print(f"{e['t_ms'] / 1000:7.2f} s  {e['event']:7s} {e['key']:5s}  x {e['x']:.2f} y {e['y']:.2f} "
              f"yaw {e['yaw']:.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
