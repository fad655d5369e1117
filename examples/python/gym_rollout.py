#!/usr/bin/env python3
"""A Gymnasium rollout of crazyflie_cosim/World-v0 on the thesis course.

The policy is a hand-written one, not a trained agent: in velocity mode it
climbs to the next gate's height and flies at 0.5 m/s towards a point 0.6 m
before the gate, then through it along the gate's normal (the environment's
velocity actions go through the STM32's controller, ported from sim-core).
It prints each episode's return, the gates passed and how fast the world ran.

    python examples/python/gym_rollout.py [--episodes N] [--seed S]
"""

import argparse
import math
import sys
import time

import crazyflie_cosim  # noqa: F401  (registers crazyflie_cosim/World-v0)
import gymnasium as gym
import numpy as np
from crazyflie_cosim.env import velocity_action
from crazyflie_cosim.server import WorldServerError


def policy(env, obs):
    """Velocity demand towards the next gate's approach point, then through."""
    status = env.status[env.names[0]]
    x, y, z = obs[0:3]
    if status.next_gate >= len(env.gates):
        return velocity_action(0.0, 0.0, -0.3)  # every gate passed: descend
    g = env.gates[status.next_gate]
    nx, ny, _ = g.normal
    cx, cy, cz = g.centre
    # Signed distance before the gate's plane (negative: not yet through).
    s = (x - cx) * nx + (y - cy) * ny
    lateral = -(x - cx) * ny + (y - cy) * nx
    if s < -0.75 or abs(lateral) > 0.2:
        tx, ty = cx - 0.6 * nx, cy - 0.6 * ny  # the approach point
    else:
        tx, ty = cx + 0.5 * nx, cy + 0.5 * ny  # through the opening
    dx, dy = tx - x, ty - y
    d = math.hypot(dx, dy)
    speed = min(0.5, d)
    v = (dx / d * speed, dy / d * speed) if d > 1e-9 else (0.0, 0.0)
    vz = float(np.clip(cz - z, -0.3, 0.3))
    return velocity_action(v[0], v[1], vz)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--max-time",
        type=float,
        default=120.0,
        help="time limit of an episode (s of world time)",
    )
    args = ap.parse_args()
    env = gym.make(
        "crazyflie_cosim/World-v0", action="velocity", max_time_s=args.max_time
    )
    for ep in range(args.episodes):
        obs, info = env.reset(seed=args.seed + ep)
        ret, steps, t0 = 0.0, 0, time.perf_counter()
        while True:
            obs, r, terminated, truncated, info = env.step(policy(env.unwrapped, obs))
            ret += r
            steps += 1
            if terminated or truncated:
                break
        wall = time.perf_counter() - t0
        sim = steps * 0.032
        print(
            f"episode {ep} (seed {args.seed + ep}): return {ret:.2f}, gates passed "
            f"{info['gates_passed']['cf1']}/{len(env.unwrapped.gates)}, collisions {info['collisions']['cf1']}, "
            f"{'terminated' if terminated else 'truncated'} after {sim:.2f} s of flight; "
            f"{steps} steps in {wall:.2f} s wall = {steps / wall:.0f} steps/s, {sim / wall:.1f}x real time"
        )
    env.close()


if __name__ == "__main__":
    try:
        main()
    except (WorldServerError, RuntimeError, OSError, ValueError) as e:
        sys.exit(f"gym_rollout.py: {e}")
