"""The STM32's velocity controller, ported from the Rust platform.

A line-by-line port of ``sim-core/src/peripherals/stm32/pid.rs`` (the
Bitcraze Webots ``pid_velocity_fixed_height_controller``, thesis §4.2.2 and
Appendix C) and of the measurement in ``sim-core/src/peripherals/stm32/
flight.rs`` (``Stm32::measured``/``control``: body velocities from two GPS
fixes, the first iteration's dt = one timestep) with the height set-point
integrated from a vertical speed demand (``pid_iteration``'s
``height_desired += height_diff_desired * dt``) and a world-frame
horizontal demand rotated into the body frame by the yaw (``motion.rs``,
``steer``).  The arithmetic is the Rust code's, operation for operation, so
the port gives the same doubles: ``python/tests/test_controller.py`` replays
the golden flights that ``sim-core/tests/pid_golden.rs`` checks against the
Rust controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PidGains:
    """The Bitcraze Webots controller's gains (``crazyflie_controller.c``
    ``main``; DESIGN.md §4; ``pid.rs`` ``PidGains::default``)."""

    kp_att_y: float = 1.0
    kd_att_y: float = 0.5  # set in the Bitcraze main but unused (P-only yaw rate)
    kp_att_rp: float = 0.5
    kd_att_rp: float = 0.1
    kp_vel_xy: float = 2.0
    kd_vel_xy: float = 0.5
    kp_z: float = 10.0
    ki_z: float = 5.0
    kd_z: float = 5.0
    base_thrust: float = 48.0  # rad/s that roughly carry the drone


def _clamp1(x: float) -> float:
    return min(max(x, -1.0), 1.0)


def mix(roll: float, pitch: float, yaw: float, altitude: float) -> tuple[float, float, float, float]:
    """Motor mixing of the Bitcraze controller (X configuration), m1..m4
    magnitudes in rad/s (the world applies the spin signs)."""
    return (
        altitude - roll + pitch + yaw,
        altitude - roll - pitch - yaw,
        altitude + roll - pitch + yaw,
        altitude + roll + pitch - yaw,
    )


def to_body(x: float, y: float, yaw: float) -> tuple[float, float]:
    """A world-frame horizontal vector in the body (yaw) frame."""
    s, c = math.sin(yaw), math.cos(yaw)
    return (x * c + y * s, -x * s + y * c)


def body_velocity(dx: float, dy: float, dt: float, yaw: float) -> tuple[float, float]:
    """Body velocities from two GPS fixes ``dt`` apart (Appendix C lines 5-13)."""
    return to_body(dx / dt, dy / dt, yaw)


class PidController:
    """``pid.rs`` ``PidController``: the cascade with its memory."""

    def __init__(self, gains: PidGains | None = None):
        self.gains = gains or PidGains()
        self.reset()

    def reset(self) -> None:
        self.past_vx_error = 0.0
        self.past_vy_error = 0.0
        self.past_altitude_error = 0.0
        self.past_pitch_error = 0.0
        self.past_roll_error = 0.0
        self.altitude_integrator = 0.0
        #: The desired roll and pitch the velocity loop set at the last step.
        self.desired_roll = 0.0
        self.desired_pitch = 0.0

    def step(
        self,
        *,
        roll: float,
        pitch: float,
        yaw_rate: float,
        altitude: float,
        vx: float,
        vy: float,
        desired_yaw_rate: float,
        desired_altitude: float,
        desired_vx: float,
        desired_vy: float,
        dt: float,
    ) -> tuple[float, float, float, float]:
        """One step over ``dt`` s; body-frame velocities; returns m1..m4."""
        g = self.gains
        # horizontal_velocity
        vx_error = desired_vx - vx
        vx_derivative = (vx_error - self.past_vx_error) / dt
        vy_error = desired_vy - vy
        vy_derivative = (vy_error - self.past_vy_error) / dt
        desired_pitch = g.kp_vel_xy * _clamp1(vx_error) + g.kd_vel_xy * vx_derivative
        desired_roll = -g.kp_vel_xy * _clamp1(vy_error) - g.kd_vel_xy * vy_derivative
        self.past_vx_error = vx_error
        self.past_vy_error = vy_error
        # fixed_height: no integrator or output limit in the C version.
        error = desired_altitude - altitude
        derivative = (error - self.past_altitude_error) / dt
        self.altitude_integrator += error * dt
        self.past_altitude_error = error
        altitude_cmd = g.kp_z * _clamp1(error) + g.kd_z * derivative + g.ki_z * self.altitude_integrator + g.base_thrust
        # attitude
        pitch_error = desired_pitch - pitch
        pitch_derivative = (pitch_error - self.past_pitch_error) / dt
        roll_error = desired_roll - roll
        roll_derivative = (roll_error - self.past_roll_error) / dt
        yaw_rate_error = desired_yaw_rate - yaw_rate
        roll_cmd = g.kp_att_rp * _clamp1(roll_error) + g.kd_att_rp * roll_derivative
        pitch_cmd = -g.kp_att_rp * _clamp1(pitch_error) - g.kd_att_rp * pitch_derivative
        yaw_cmd = g.kp_att_y * _clamp1(yaw_rate_error)
        self.past_pitch_error = pitch_error
        self.past_roll_error = roll_error
        self.desired_roll, self.desired_pitch = desired_roll, desired_pitch
        return mix(roll_cmd, pitch_cmd, yaw_cmd, altitude_cmd)


class VelocityController:
    """A velocity set-point flown as the STM32 flies it (``flight.rs``).

    ``step`` takes one sensor read (world time, GPS position, InertialUnit
    roll/pitch/yaw, gyro yaw rate) and the demand: world-frame horizontal
    velocity ``vx, vy`` (m/s), vertical speed ``vz`` (m/s, integrated into
    the height set-point) and ``yaw_rate`` (rad/s); it returns the four motor
    speed magnitudes for SET_VELOCITY.
    """

    def __init__(self, timestep_ms: int, time_s: float, x: float, y: float, z: float, gains: PidGains | None = None):
        self.timestep_s = timestep_ms / 1000.0
        self.pid = PidController(gains)
        self.past_time = time_s
        self.past_x = x
        self.past_y = y
        self.height_desired = z

    def step(
        self,
        *,
        time_s: float,
        x: float,
        y: float,
        z: float,
        roll: float,
        pitch: float,
        yaw: float,
        yaw_rate: float,
        vx: float,
        vy: float,
        vz: float,
        desired_yaw_rate: float,
    ) -> tuple[float, float, float, float]:
        dt = time_s - self.past_time
        # flight.rs: the first iteration sees the time of GET_INIT_DATA, where
        # the C code would divide by zero; one timestep instead.
        if dt <= 0.0:
            dt = self.timestep_s
        mvx, mvy = body_velocity(x - self.past_x, y - self.past_y, dt, yaw)
        self.height_desired += vz * dt
        dvx, dvy = to_body(vx, vy, yaw)
        motors = self.pid.step(
            roll=roll,
            pitch=pitch,
            yaw_rate=yaw_rate,
            altitude=z,
            vx=mvx,
            vy=mvy,
            desired_yaw_rate=desired_yaw_rate,
            desired_altitude=self.height_desired,
            desired_vx=dvx,
            desired_vy=dvy,
            dt=dt,
        )
        if not all(math.isfinite(m) for m in motors):
            raise ValueError(f"the controller produced non-finite motor commands {motors}")
        self.past_time, self.past_x, self.past_y = time_s, x, y
        return motors


def euler(qw: float, qx: float, qy: float, qz: float) -> tuple[float, float, float]:
    """Roll, pitch, yaw of Webots's InertialUnit from the orientation
    (``world-server/src/sensors.rs``: Z-Y-X Euler angles, pitch clamped)."""
    roll = math.atan2(2.0 * (qw * qx + qy * qz), 1.0 - 2.0 * (qx * qx + qy * qy))
    pitch = math.asin(min(max(2.0 * (qw * qy - qz * qx), -1.0), 1.0))
    yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return roll, pitch, yaw
