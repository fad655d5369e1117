#!/usr/bin/env python3
"""Steps per second of crazyflie_cosim/World-v0: one drone hovering through
the ported controller (velocity mode), without and with the camera image in
each image encoding, and three drones (one thread) without images.

    python examples/python/bench_env.py [--steps N]
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from crazyflie_cosim.env import WorldEnv
from crazyflie_cosim.server import WorldServerError

THREE = Path(__file__).with_name("three-drones.toml")


def bench(steps, **kw):
    env = WorldEnv(action="velocity", max_time_s=1e9, **kw)
    env.reset(seed=0)
    hover = np.zeros(4)
    act = hover if len(env.names) == 1 else {n: hover for n in env.names}
    t0 = time.perf_counter()
    for _ in range(steps):
        env.step(act)
    wall = time.perf_counter() - t0
    env.close()
    return steps / wall, steps * 0.032 / wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--no-three", action="store_true", help="skip the three-drone case")
    args = ap.parse_args()
    cases = [("1 drone, state only", {})]
    cases += [
        (f"1 drone + image ({e})", {"image": True, "image_encoding": e})
        for e in ("shm", "base64", "array")
    ]
    if not args.no_three:
        cases.append(("3 drones, state only", {"world": str(THREE)}))
    for name, kw in cases:
        rate, rt = bench(args.steps, **kw)
        print(f"{name:28s} {rate:8.0f} steps/s  {rt:6.1f}x real time (32 ms steps)")


if __name__ == "__main__":
    try:
        main()
    except (WorldServerError, RuntimeError, OSError, ValueError) as e:
        sys.exit(f"bench_env.py: {e}")
