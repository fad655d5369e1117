#!/usr/bin/env python3
"""Three drones of one world driven from one script, one thread.

Starts a world-server with three drones 2 m apart, claims them, and flies
each with its own motor commands through the wire protocol (a take-off, then
a hover with the ported STM32 controller), while alpha sends a UWB frame
every 10 steps and every drone collects its receptions.  One thread sends
every drone's requests, then reads every reply (DESIGN.md §15).

    python examples/python/three_drones.py
"""

import sys
from pathlib import Path

from crazyflie_cosim import World, WorldServer
from crazyflie_cosim import protocol as p
from crazyflie_cosim.controller import VelocityController, euler
from crazyflie_cosim.server import WorldServerError

WORLD = Path(__file__).with_name("three-drones.toml")


def main():
    with (
        WorldServer(WORLD) as srv,
        World.connect(srv.endpoint, ["alpha", "bravo", "charlie"]) as w,
    ):
        print(
            "claimed",
            ", ".join(f"{d.name} at {d.init.x:+.2f}, {d.init.y:+.2f}" for d in w),
        )
        states = w.request({n: p.get_state() for n in w.names})
        ctl = {
            n: VelocityController(32, s.time_s, s.x, s.y, s.z)
            for n, s in states.items()
        }
        # Each drone climbs at its own speed to a different height.
        climb = {"alpha": 0.2, "bravo": 0.3, "charlie": 0.4}
        heard = {n: 0 for n in w.names}
        for step in range(250):  # 8 s
            reqs = {}
            for n, s in states.items():
                roll, pitch, yaw = euler(s.qw, s.qx, s.qy, s.qz)
                vz = climb[n] if step < 125 else 0.0
                m = ctl[n].step(time_s=s.time_s, x=s.x, y=s.y, z=s.z, roll=roll, pitch=pitch, yaw=yaw,
                                yaw_rate=s.omega_z, vx=0.0, vy=0.0, vz=vz, desired_yaw_rate=0.0)  # fmt: skip
                reqs[n] = [p.set_velocity(*(max(0.0, x) for x in m))]
            if step % 10 == 0:
                reqs["alpha"].append(p.radio_send("uwb", f"ping {step}".encode()))
            for n in w.names:
                reqs[n] += [p.get_state(), p.radio_recv()]
            replies = w.request(reqs)
            states = {n: r[0] for n, r in replies.items()}
            for n, r in replies.items():
                heard[n] += len(r[1].packets)
        for n, s in states.items():
            print(f"{n}: z {s.z:.2f} m at {s.time_s:.3f} s, heard {heard[n]} frames, "
                  f"distances {({k: round(v, 2) for k, v in (s.drone_distances or {}).items()})}")  # fmt: skip
        for n, r in w.stop().items():
            print(
                f"{n}: STOP at {r.time_s:.3f} s ({r.stop_time_ms} ms to stop the propellers)"
            )
        print("world-server exited with", srv.wait(10))


if __name__ == "__main__":
    try:
        main()
    except (WorldServerError, p.ProtocolError, OSError) as e:
        sys.exit(f"three_drones.py: {e}")
