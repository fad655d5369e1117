"""The Python port of the STM32's velocity controller gives the Rust
controller's doubles, bit for bit, on the golden flights that
sim-core/tests/pid_golden.rs checks against the Rust code."""

import json
import math
from pathlib import Path

import pytest

from crazyflie_cosim.controller import PidController, VelocityController, euler, to_body

GOLDEN = json.loads((Path(__file__).parent / "data" / "pid_golden.json").read_text())


@pytest.mark.parametrize("flight", GOLDEN["flights"], ids=lambda f: f"seed{f['seed']}")
def test_the_port_replays_the_rust_controller_exactly(flight):
    x, y, z = flight["start"]
    c = VelocityController(32, flight["start_time_s"], x, y, z)
    for i, s in enumerate(flight["steps"]):
        vx, vy, vz, yaw_rate = s["command"]
        m = c.step(
            time_s=s["time_s"], x=s["x"], y=s["y"], z=s["z"], roll=s["roll"], pitch=s["pitch"],
            yaw=s["yaw"], yaw_rate=s["yaw_rate"], vx=vx, vy=vy, vz=vz, desired_yaw_rate=yaw_rate,
        )  # fmt: skip
        assert list(m) == s["motors"], f"step {i}"
        assert [c.pid.desired_roll, c.pid.desired_pitch] == [s["desired_roll"], s["desired_pitch"]], f"step {i}"


def test_hand_worked_values_of_pid_rs():
    # pid.rs's own unit tests, worked by hand from the C code.
    pid = PidController()
    kw = dict(roll=0.0, pitch=0.0, yaw_rate=0.0, vx=0.0, vy=0.0, desired_yaw_rate=0.0, desired_vx=0.0, desired_vy=0.0)
    assert pid.step(altitude=1.0, desired_altitude=1.0, dt=0.032, **kw) == (48.0,) * 4
    pid.reset()
    assert pid.step(altitude=0.0, desired_altitude=2.0, dt=0.5, **kw)[0] == 48.0 + 10.0 + 20.0 + 5.0
    assert pid.step(altitude=0.0, desired_altitude=2.0, dt=0.5, **kw)[0] == 48.0 + 10.0 + 10.0


def test_world_velocity_is_rotated_into_the_body_frame():
    vx, vy = to_body(0.0, 1.0, math.pi / 2)  # facing +y, moving +y: forward
    assert abs(vx - 1.0) < 1e-12 and abs(vy) < 1e-12


def test_euler_angles_of_a_yawed_quaternion():
    h = math.pi / 4
    roll, pitch, yaw = euler(math.cos(h), 0.0, 0.0, math.sin(h))
    assert abs(yaw - math.pi / 2) < 1e-15 and roll == 0.0 and pitch == 0.0
