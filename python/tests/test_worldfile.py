"""World files and gates as world-server reads them."""

import math
import sys

import numpy as np
from conftest import ROOT

from crazyflie_cosim.env import WorldEnv
from crazyflie_cosim.worldfile import DroneStart, Gate, WorldFile, tomllib


def test_gate_crossings_as_gates_rs_counts_them():
    # world-server/src/gates.rs's own cases: centre (1, 2, 1), travel +y.
    g = Gate((1.0, 2.0, 1.0), math.pi / 2, 0.8)
    assert g.crossed((1.0, 1.9, 1.0), (1.0, 2.1, 1.0))
    assert g.crossed((0.61, 1.5, 1.39), (0.61, 2.5, 1.39))
    assert not g.crossed((1.0, 2.1, 1.0), (1.0, 1.9, 1.0))  # backwards
    assert not g.crossed((1.41, 1.9, 1.0), (1.41, 2.1, 1.0))  # beside
    assert not g.crossed((1.0, 1.9, 1.41), (1.0, 2.1, 1.41))  # above
    assert not g.crossed((1.0, 1.0, 1.0), (1.0, 1.99, 1.0))  # short of the plane
    assert g.crossed((0.0, 1.0, 1.0), (2.0, 3.0, 1.0))  # diagonal, inside


def test_every_world_file_round_trips_and_moved_drones_land_in_the_copy():
    for path in sorted((ROOT / "scenarios" / "worlds").glob("*.toml")):
        wf = WorldFile.load(path)
        assert tomllib.loads(wf.dumps()) == wf.data, path.name
    course = WorldFile.load(ROOT / "scenarios" / "worlds" / "thesis-course.toml")
    assert len(course.gates) == 10 and [d.name for d in course.drones] == ["cf1"]
    moved = course.with_drones([DroneStart("cf1", (1.0, 2.0, 0.015), 0.5)])
    assert moved.data["start"] == {"position": [1.0, 2.0, 0.015], "yaw": 0.5}
    assert moved.data["gate"] == course.data["gate"]
    two = course.with_drones([DroneStart("a", (0.0, 0.0, 0.015), 0.0), DroneStart("b", (1.0, 0.0, 0.015), 0.0)])
    assert [d.name for d in WorldFile(tomllib.loads(two.dumps())).drones] == ["a", "b"]


def test_the_environment_counts_gates_as_the_world_does():
    # The scripted policy of examples/python/gym_rollout.py through the first
    # gates; the world's STOP reply counts them itself.
    sys.path.insert(0, str(ROOT / "examples" / "python"))
    from gym_rollout import policy

    env = WorldEnv(action="velocity", max_time_s=25.0)
    obs, _ = env.reset(seed=1)
    while True:
        obs, _, term, trunc, info = env.step(policy(env, obs))
        if term or trunc:
            break
    env.close()
    assert info["gates_passed"]["cf1"] >= 2 and info["collisions"]["cf1"] == 0
    assert env.world_gates_passed == info["gates_passed"]
    assert np.isfinite(obs).all()
