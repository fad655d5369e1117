//! The Crazyflie firmware's own flight stack: the cascaded PID controller
//! (`controller_pid.c`: position → velocity at 100 Hz, attitude → rate at
//! the attitude rate) with the default gains, integral limits and output
//! limits of the Crazyflie 2.x (`platform_defaults_cf2.h`), the legacy
//! power distribution (`power_distribution_quadrotor.c`) and a motor
//! model from the firmware's PWM to the world's propeller speed
//! (DESIGN.md §20). Selected by the run key `stabilizer.controller = pid`;
//! the thesis's controller ([`super::pid`]) stays the default.
//!
//! Conventions are the firmware's: angles in degrees, roll positive right
//! side down, pitch positive nose up, yaw counter-clockwise; the rate loop
//! sees pitch rate nose-up positive (`controller_pid.c` passes
//! `-gyro.y`). The world's InertialUnit has pitch nose-down positive, so
//! [`State::from_world`] negates it.
//!
//! What the firmware has that this does not: the D-term and attitude
//! low-pass filters (off, or acting on D terms whose default gain is 0, with
//! the defaults), the battery compensation of the motor ratios, and the
//! other controllers (Mellinger, INDI, Brescianini, Lee).

/// One PID axis as the firmware's `pid.c` computes it: P on the error, D
/// on the measurement (no derivative kick on a set-point step), I with an
/// integral limit, a feed-forward on the set-point, an output limit (0:
/// none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidAxis {
    pub kp: f64,
    pub ki: f64,
    pub kd: f64,
    pub kff: f64,
    pub i_limit: f64,
    pub out_limit: f64,
    integ: f64,
    prev_measured: f64,
}

impl PidAxis {
    pub const fn new(kp: f64, ki: f64, kd: f64, i_limit: f64) -> Self {
        PidAxis {
            kp,
            ki,
            kd,
            kff: 0.0,
            i_limit,
            out_limit: 0.0,
            integ: 0.0,
            prev_measured: 0.0,
        }
    }

    /// `pidUpdate`: `yaw` wraps the error and the measurement's step to
    /// ±180°.
    pub fn update(&mut self, desired: f64, measured: f64, dt: f64, yaw: bool) -> f64 {
        let wrap = |a: f64| {
            if !yaw {
                a
            } else if a > 180.0 {
                a - 360.0
            } else if a < -180.0 {
                a + 360.0
            } else {
                a
            }
        };
        let error = wrap(desired - measured);
        let mut out = self.kp * error;
        let deriv = wrap(-(measured - self.prev_measured)) / dt;
        if deriv.is_finite() {
            out += self.kd * deriv;
        }
        self.integ += error * dt;
        if self.i_limit != 0.0 {
            self.integ = self.integ.clamp(-self.i_limit, self.i_limit);
        }
        out += self.ki * self.integ + self.kff * desired;
        if self.out_limit != 0.0 {
            out = out.clamp(-self.out_limit, self.out_limit);
        }
        self.prev_measured = measured;
        out
    }

    /// `pidReset`: no integral, the derivative measured from `actual`.
    pub fn reset(&mut self, actual: f64) {
        self.integ = 0.0;
        self.prev_measured = actual;
    }
}

/// What one axis of a set-point asks (`setpoint_t`'s `stab_mode_t`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Axis {
    /// Not controlled here (x, y: the attitude set-point; z: its thrust).
    Disable,
    /// Hold this position (m) or yaw (°).
    Abs(f64),
    /// This velocity (m/s) or yaw rate (°/s).
    Velocity(f64),
}

/// A set-point as the commander hands it to the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setpoint {
    pub x: Axis,
    pub y: Axis,
    pub z: Axis,
    pub yaw: Axis,
    /// x and y velocities are in the body (yaw) frame (the hover set-point).
    pub velocity_body: bool,
    /// Roll and pitch (°) when x, y are [`Axis::Disable`].
    pub roll: f64,
    pub pitch: f64,
    /// The thrust (0..65535) when z is [`Axis::Disable`].
    pub thrust: f64,
}

impl Setpoint {
    /// The motors off (the stop set-point, or a thrust of 0).
    pub const STOP: Setpoint = Setpoint {
        x: Axis::Disable,
        y: Axis::Disable,
        z: Axis::Disable,
        yaw: Axis::Velocity(0.0),
        velocity_body: false,
        roll: 0.0,
        pitch: 0.0,
        thrust: 0.0,
    };

    /// The modes alone (`setpoint_mode_t`), compared to reset on a change.
    fn modes(&self) -> [u8; 5] {
        let m = |a: Axis| match a {
            Axis::Disable => 0,
            Axis::Abs(_) => 1,
            Axis::Velocity(_) => 2,
        };
        [
            m(self.x),
            m(self.y),
            m(self.z),
            m(self.yaw),
            self.velocity_body as u8,
        ]
    }
}

/// The state the controller reads, in the firmware's conventions.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct State {
    /// m, world frame.
    pub pos: [f64; 3],
    /// m/s, world frame.
    pub vel: [f64; 3],
    /// Roll, pitch (nose up), yaw (°).
    pub attitude: [f64; 3],
    /// Roll, pitch (nose up), yaw rates (°/s).
    pub rates: [f64; 3],
}

impl State {
    /// From the world's sensors (rad, rad/s; pitch nose down positive).
    pub fn from_world(
        pos: [f64; 3],
        vel: [f64; 3],
        [roll, pitch, yaw]: [f64; 3],
        [roll_rate, pitch_rate, yaw_rate]: [f64; 3],
    ) -> State {
        State {
            pos,
            vel,
            attitude: [roll.to_degrees(), -pitch.to_degrees(), yaw.to_degrees()],
            rates: [
                roll_rate.to_degrees(),
                -pitch_rate.to_degrees(),
                yaw_rate.to_degrees(),
            ],
        }
    }
}

/// The controller's output (`control_t`, legacy mode): thrust and the
/// rate loops' roll, pitch, yaw commands, all in PWM units.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Control {
    pub thrust: f64,
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
}

/// The position controller's limits and thrust feed-forward
/// (`position_controller_pid.c`, its `posCtlPid` parameters).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// PWM of a hover, roughly (`PID_VEL_THRUST_BASE`).
    pub thrust_base: f64,
    /// The least thrust while the height loop flies (`PID_VEL_THRUST_MIN`).
    pub thrust_min: f64,
    /// Largest roll, pitch the velocity loop asks (°).
    pub r_limit: f64,
    pub p_limit: f64,
    /// Largest velocities the position loop asks (m/s).
    pub x_vel_max: f64,
    pub y_vel_max: f64,
    pub z_vel_max: f64,
}

/// The largest world timestep (ms) the cascade is flown at: its attitude
/// and rate loops run once a step, and their gains are the firmware's for
/// 500 Hz (2 ms). A run key check refuses more before any process starts.
pub const MAX_TIMESTEP_MS: u64 = 4;

/// The cascade's rule on the world's timestep.
pub fn check_timestep(ms: u64) -> Result<(), String> {
    if ms > MAX_TIMESTEP_MS {
        return Err(format!(
            "stabilizer.controller = pid flies the firmware's 500 Hz attitude loops once a world step: \
             basicTimeStep {ms} ms is more than {MAX_TIMESTEP_MS} ms (use timestep_ms = 2)"
        ));
    }
    Ok(())
}

/// The position loop runs at `POSITION_RATE`, 100 Hz.
pub const POSITION_PERIOD_S: f64 = 0.01;
/// The velocity loop's thrust scale (PWM per m/s of output).
const THRUST_SCALE: f64 = 1000.0;
/// Headroom over the limits (`rpLimitOverhead`, `velMaxOverhead`).
const OVERHEAD: f64 = 1.10;

/// The cascade with its memory.
#[derive(Debug, Clone, PartialEq)]
pub struct Cascade {
    /// x, y, z position loops (m → m/s).
    pub pos: [PidAxis; 3],
    /// x, y, z velocity loops (m/s → °, and thrust / 1000).
    pub vel: [PidAxis; 3],
    /// Roll, pitch, yaw attitude loops (° → °/s).
    pub att: [PidAxis; 3],
    /// Roll, pitch, yaw rate loops (°/s → PWM).
    pub rate: [PidAxis; 3],
    pub limits: Limits,
    /// The attitude asked of the attitude loops (°).
    att_desired: [f64; 3],
    /// The thrust the velocity loop last asked (PWM).
    thrust: f64,
    /// Time since the position loop last ran (s; infinite before its
    /// first run, which is at the first tick as in the firmware).
    since_position: f64,
    modes: Option<[u8; 5]>,
}

impl Default for Cascade {
    fn default() -> Self {
        Cascade::new()
    }
}

impl Cascade {
    /// The Crazyflie 2.x's defaults (`platform_defaults_cf2.h`).
    pub fn new() -> Cascade {
        let p = PidAxis::new;
        Cascade {
            pos: [
                p(2.0, 0.0, 0.0, 0.0),
                p(2.0, 0.0, 0.0, 0.0),
                p(2.0, 0.5, 0.0, 0.0),
            ],
            vel: [
                p(25.0, 1.0, 0.0, 0.0),
                p(25.0, 1.0, 0.0, 0.0),
                p(25.0, 15.0, 0.0, 0.0),
            ],
            att: [
                p(6.0, 3.0, 0.0, 20.0),
                p(6.0, 3.0, 0.0, 20.0),
                p(6.0, 1.0, 0.35, 360.0),
            ],
            rate: [
                p(250.0, 500.0, 2.5, 33.3),
                p(250.0, 500.0, 2.5, 33.3),
                p(120.0, 16.7, 0.0, 166.7),
            ],
            limits: Limits {
                thrust_base: 36000.0,
                thrust_min: 20000.0,
                r_limit: 20.0,
                p_limit: 20.0,
                x_vel_max: 1.0,
                y_vel_max: 1.0,
                z_vel_max: 1.0,
            },
            att_desired: [0.0; 3],
            thrust: 0.0,
            since_position: f64::INFINITY,
            modes: None,
        }
    }

    /// The attitude the loops are asked to hold (roll, pitch nose up, yaw; °).
    pub fn attitude_desired(&self) -> [f64; 3] {
        self.att_desired
    }

    /// `controllerPidReinitialize`: every loop reset at the state, the
    /// attitude asked = the attitude held (the yaw asked is kept).
    fn reinitialize(&mut self, s: &State) {
        for i in 0..3 {
            self.pos[i].reset(s.pos[i]);
            self.vel[i].reset(0.0);
            self.att[i].reset(s.attitude[i]);
            self.rate[i].reset(0.0);
        }
        self.att_desired[0] = s.attitude[0];
        self.att_desired[1] = s.attitude[1];
    }

    /// One tick of `controllerPid` after `dt` seconds (the attitude loops
    /// every tick, the position loops when [`POSITION_PERIOD_S`] has
    /// passed).
    pub fn step(&mut self, sp: &Setpoint, s: &State, dt: f64) -> Control {
        let modes = sp.modes();
        if self.modes != Some(modes) {
            self.reinitialize(s);
            self.modes = Some(modes);
        }
        // The yaw asked: integrated from a rate, or absolute.
        match sp.yaw {
            Axis::Velocity(r) => self.att_desired[2] = cap_angle(self.att_desired[2] + r * dt),
            Axis::Abs(y) => self.att_desired[2] = cap_angle(y),
            Axis::Disable => {}
        }
        self.since_position += dt;
        if self.since_position >= POSITION_PERIOD_S - 1e-9 {
            let period = if self.since_position.is_finite() {
                self.since_position
            } else {
                POSITION_PERIOD_S
            };
            self.since_position = 0.0;
            self.position(sp, s, period);
        }
        let thrust = match sp.z {
            Axis::Disable => sp.thrust,
            _ => self.thrust,
        };
        if sp.x == Axis::Disable || sp.y == Axis::Disable {
            self.att_desired[0] = sp.roll;
            self.att_desired[1] = sp.pitch;
        }
        let mut rate_desired = [0.0; 3];
        for (i, r) in rate_desired.iter_mut().enumerate() {
            *r = self.att[i].update(self.att_desired[i], s.attitude[i], dt, i == 2);
        }
        let mut out = [0.0; 3];
        for (i, o) in out.iter_mut().enumerate() {
            *o = saturate_i16(self.rate[i].update(rate_desired[i], s.rates[i], dt, false));
        }
        if thrust == 0.0 {
            // Motors off: everything starts afresh, the yaw asked is the
            // yaw held.
            self.reinitialize(s);
            self.att_desired[2] = s.attitude[2];
            return Control::default();
        }
        Control {
            thrust,
            roll: out[0],
            pitch: out[1],
            yaw: out[2],
        }
    }

    /// `positionController` then `velocityController`: the attitude and
    /// thrust asked of the inner loops.
    fn position(&mut self, sp: &Setpoint, s: &State, dt: f64) {
        let l = self.limits;
        self.pos[0].out_limit = l.x_vel_max * OVERHEAD;
        self.pos[1].out_limit = l.y_vel_max * OVERHEAD;
        // The firmware keeps at least 0.5 m/s for the landing detectors.
        self.pos[2].out_limit = l.z_vel_max.max(0.5) * OVERHEAD;
        let (sy, cy) = s.attitude[2].to_radians().sin_cos();
        let body = |v: [f64; 2]| [v[0] * cy + v[1] * sy, -v[0] * sy + v[1] * cy];
        let sp_xy = body([abs_or(sp.x), abs_or(sp.y)]);
        let st_xy = body([s.pos[0], s.pos[1]]);
        let vel_xy = [velocity_or(sp.x), velocity_or(sp.y)];
        let global = body(vel_xy);
        let mut v = [0.0; 3];
        for i in 0..2 {
            let axis = if i == 0 { sp.x } else { sp.y };
            v[i] = match axis {
                Axis::Abs(_) => self.pos[i].update(sp_xy[i], st_xy[i], dt, false),
                _ if sp.velocity_body => vel_xy[i],
                _ => global[i],
            };
        }
        v[2] = match sp.z {
            Axis::Abs(z) => self.pos[2].update(z, s.pos[2], dt, false),
            a => velocity_or(a),
        };

        self.vel[0].out_limit = l.p_limit * OVERHEAD;
        self.vel[1].out_limit = l.r_limit * OVERHEAD;
        self.vel[2].out_limit = f64::from(u16::MAX) / 2.0 / THRUST_SCALE;
        let st_v = body([s.vel[0], s.vel[1]]);
        let pitch = -self.vel[0].update(v[0], st_v[0], dt, false);
        let roll = -self.vel[1].update(v[1], st_v[1], dt, false);
        self.att_desired[0] = roll.clamp(-l.r_limit, l.r_limit);
        self.att_desired[1] = pitch.clamp(-l.p_limit, l.p_limit);
        let raw = self.vel[2].update(v[2], s.vel[2], dt, false);
        self.thrust = (raw * THRUST_SCALE + l.thrust_base)
            .max(l.thrust_min)
            .clamp(0.0, f64::from(u16::MAX));
    }
}

fn abs_or(a: Axis) -> f64 {
    match a {
        Axis::Abs(v) => v,
        _ => 0.0,
    }
}

fn velocity_or(a: Axis) -> f64 {
    match a {
        Axis::Velocity(v) => v,
        _ => 0.0,
    }
}

/// An angle in (−180°, 180°] (`capAngle`).
fn cap_angle(a: f64) -> f64 {
    let mut r = a;
    while r > 180.0 {
        r -= 360.0;
    }
    while r < -180.0 {
        r += 360.0;
    }
    r
}

/// `saturateSignedInt16`.
fn saturate_i16(v: f64) -> f64 {
    v.clamp(f64::from(i16::MIN), f64::from(i16::MAX))
}

/// `powerDistributionLegacy` and `powerDistributionCap`: the four motors'
/// PWM (m1 front right, m2 back right, m3 back left, m4 front left; the
/// world's propellers in the same order). Roll and pitch are halved and
/// truncated to int16 as the firmware does; a motor above full scale
/// lowers all four by the excess; none goes below 0 (idle thrust 0).
pub fn power_distribution(c: &Control) -> [f64; 4] {
    let r = (c.roll / 2.0).trunc();
    let p = (c.pitch / 2.0).trunc();
    let m = [
        c.thrust - r + p + c.yaw,
        c.thrust - r - p - c.yaw,
        c.thrust + r - p + c.yaw,
        c.thrust + r + p - c.yaw,
    ];
    let full = f64::from(u16::MAX);
    let excess = m.iter().fold(0.0f64, |a, &v| a.max(v - full));
    m.map(|v| (v - excess).clamp(0.0, full))
}

/// Thrust of one Crazyflie 2 motor and propeller (N) at a PWM ratio
/// `r` = PWM / 65535: F = a·r² + b·r, Förster's identification
/// ("System Identification of the Crazyflie 2.0 Nano Quadrocopter", ETH
/// Zürich, 2015; the firmware's `PWM_TO_THRUST_a/b` constants).
pub fn crazyflie_thrust(pwm: f64) -> f64 {
    const A: f64 = 0.091492681;
    const B: f64 = 0.067673604;
    let r = (pwm / f64::from(u16::MAX)).clamp(0.0, 1.0);
    A * r * r + B * r
}

/// The Crazyflie 2.1's take-off weight (kg; Bitcraze's datasheet: 27 g).
pub const CRAZYFLIE_MASS_KG: f64 = 0.027;

/// The world's propeller speed (rad/s) for a motor's PWM: the world's
/// drone is the Webots PROTO, 50 g with thrust 4e-5·ω² per propeller
/// (DESIGN.md §5). Its motors are a Crazyflie's scaled by the mass ratio,
/// so a PWM lifts the same fraction of the weight as on the real drone:
/// hover is at the same PWM (36,500, near the firmware's `thrustBase`
/// 36,000) and the firmware's gains see the loop gain they were tuned for.
pub fn world_speed(pwm: f64) -> f64 {
    use protocol::airframe::{MASS_KG, THRUST_CONSTANT};
    let f = crazyflie_thrust(pwm) * MASS_KG / CRAZYFLIE_MASS_KG;
    (f / THRUST_CONSTANT).sqrt()
}

/// One of the cascade's parameters under the firmware's name
/// (`position_controller_pid.c`, `attitude_pid_controller.c`).
#[derive(Clone, Copy)]
pub struct Param {
    pub group: &'static str,
    pub name: &'static str,
    /// `PARAM_UINT16` (`thrustBase`, `thrustMin`), else `PARAM_FLOAT`.
    pub uint16: bool,
    /// Where the value lives.
    pub field: fn(&mut Cascade) -> &mut f64,
}

macro_rules! params {
    ($($group:literal $name:literal $($u16:ident)? => |$c:ident| $e:expr;)*) => {
        &[$(Param {
            group: $group,
            name: $name,
            uint16: params!(@u16 $($u16)?),
            field: |$c: &mut Cascade| -> &mut f64 { &mut $e },
        },)*]
    };
    (@u16) => { false };
    (@u16 u16) => { true };
}

/// Every parameter of the cascade, in the firmware's TOC order per group.
pub const PARAMS: &[Param] = params! {
    "velCtlPid" "vxKp" => |c| c.vel[0].kp;
    "velCtlPid" "vxKi" => |c| c.vel[0].ki;
    "velCtlPid" "vxKd" => |c| c.vel[0].kd;
    "velCtlPid" "vxKFF" => |c| c.vel[0].kff;
    "velCtlPid" "vyKp" => |c| c.vel[1].kp;
    "velCtlPid" "vyKi" => |c| c.vel[1].ki;
    "velCtlPid" "vyKd" => |c| c.vel[1].kd;
    "velCtlPid" "vyKFF" => |c| c.vel[1].kff;
    "velCtlPid" "vzKp" => |c| c.vel[2].kp;
    "velCtlPid" "vzKi" => |c| c.vel[2].ki;
    "velCtlPid" "vzKd" => |c| c.vel[2].kd;
    "velCtlPid" "vzKFF" => |c| c.vel[2].kff;
    "posCtlPid" "xKp" => |c| c.pos[0].kp;
    "posCtlPid" "xKi" => |c| c.pos[0].ki;
    "posCtlPid" "xKd" => |c| c.pos[0].kd;
    "posCtlPid" "xKff" => |c| c.pos[0].kff;
    "posCtlPid" "yKp" => |c| c.pos[1].kp;
    "posCtlPid" "yKi" => |c| c.pos[1].ki;
    "posCtlPid" "yKd" => |c| c.pos[1].kd;
    "posCtlPid" "yKff" => |c| c.pos[1].kff;
    "posCtlPid" "zKp" => |c| c.pos[2].kp;
    "posCtlPid" "zKi" => |c| c.pos[2].ki;
    "posCtlPid" "zKd" => |c| c.pos[2].kd;
    "posCtlPid" "zKff" => |c| c.pos[2].kff;
    "posCtlPid" "thrustBase" u16 => |c| c.limits.thrust_base;
    "posCtlPid" "thrustMin" u16 => |c| c.limits.thrust_min;
    "posCtlPid" "rLimit" => |c| c.limits.r_limit;
    "posCtlPid" "pLimit" => |c| c.limits.p_limit;
    "posCtlPid" "xVelMax" => |c| c.limits.x_vel_max;
    "posCtlPid" "yVelMax" => |c| c.limits.y_vel_max;
    "posCtlPid" "zVelMax" => |c| c.limits.z_vel_max;
    "pid_attitude" "roll_kp" => |c| c.att[0].kp;
    "pid_attitude" "roll_ki" => |c| c.att[0].ki;
    "pid_attitude" "roll_kd" => |c| c.att[0].kd;
    "pid_attitude" "roll_kff" => |c| c.att[0].kff;
    "pid_attitude" "pitch_kp" => |c| c.att[1].kp;
    "pid_attitude" "pitch_ki" => |c| c.att[1].ki;
    "pid_attitude" "pitch_kd" => |c| c.att[1].kd;
    "pid_attitude" "pitch_kff" => |c| c.att[1].kff;
    "pid_attitude" "yaw_kp" => |c| c.att[2].kp;
    "pid_attitude" "yaw_ki" => |c| c.att[2].ki;
    "pid_attitude" "yaw_kd" => |c| c.att[2].kd;
    "pid_attitude" "yaw_kff" => |c| c.att[2].kff;
    "pid_rate" "roll_kp" => |c| c.rate[0].kp;
    "pid_rate" "roll_ki" => |c| c.rate[0].ki;
    "pid_rate" "roll_kd" => |c| c.rate[0].kd;
    "pid_rate" "roll_kff" => |c| c.rate[0].kff;
    "pid_rate" "pitch_kp" => |c| c.rate[1].kp;
    "pid_rate" "pitch_ki" => |c| c.rate[1].ki;
    "pid_rate" "pitch_kd" => |c| c.rate[1].kd;
    "pid_rate" "pitch_kff" => |c| c.rate[1].kff;
    "pid_rate" "yaw_kp" => |c| c.rate[2].kp;
    "pid_rate" "yaw_ki" => |c| c.rate[2].ki;
    "pid_rate" "yaw_kd" => |c| c.rate[2].kd;
    "pid_rate" "yaw_kff" => |c| c.rate[2].kff;
};

#[cfg(test)]
mod tests {
    use super::*;

    use protocol::airframe::{MASS_KG as WORLD_MASS, THRUST_CONSTANT as K_F};

    fn hover() -> Setpoint {
        Setpoint {
            x: Axis::Velocity(0.0),
            y: Axis::Velocity(0.0),
            z: Axis::Abs(0.5),
            yaw: Axis::Velocity(0.0),
            velocity_body: true,
            roll: 0.0,
            pitch: 0.0,
            thrust: 0.0,
        }
    }

    #[test]
    fn pid_axis_is_pid_c() {
        // kp 2, ki 0.5, kd 1, dt 0.01: error 1 from a measurement of 0
        // that was 0.1 before: P 2, D 1·(−(0 − 0.1))/0.01 = 10, I 0.5·0.01.
        let mut a = PidAxis::new(2.0, 0.5, 1.0, 0.0);
        a.reset(0.1);
        let out = a.update(1.0, 0.0, 0.01, false);
        assert!((out - (2.0 + 10.0 + 0.005)).abs() < 1e-12, "{out}");
        // The integral limit and the output limit.
        let mut b = PidAxis::new(0.0, 1.0, 0.0, 0.02);
        for _ in 0..10 {
            b.update(1.0, 0.0, 0.01, false);
        }
        assert!((b.update(1.0, 0.0, 0.01, false) - 0.02).abs() < 1e-12);
        b.out_limit = 0.01;
        assert_eq!(b.update(1.0, 0.0, 0.01, false), 0.01);
        // The yaw error wraps: 170° asked, −170° held is −20°, not 340°.
        let mut y = PidAxis::new(1.0, 0.0, 0.0, 0.0);
        y.reset(-170.0);
        assert!((y.update(170.0, -170.0, 0.01, true) + 20.0).abs() < 1e-12);
    }

    #[test]
    fn hover_pwm_is_near_the_firmwares_thrust_base() {
        // The PWM at which four motors carry the scaled drone.
        let weight = WORLD_MASS * 9.81 / 4.0;
        let pwm = (0..=65535)
            .map(f64::from)
            .find(|&p| crazyflie_thrust(p) * WORLD_MASS / CRAZYFLIE_MASS_KG >= weight)
            .unwrap();
        assert!((36000.0..37000.0).contains(&pwm), "{pwm}");
        // …and at it the world's propellers turn at the PROTO's hover speed.
        let w = world_speed(pwm);
        let hover = (WORLD_MASS * 9.81 / (4.0 * K_F)).sqrt();
        assert!((w - hover).abs() < 0.01, "{w} vs {hover}");
        assert_eq!(world_speed(0.0), 0.0);
    }

    #[test]
    fn power_distribution_mixes_caps_and_floors() {
        let c = Control {
            thrust: 30000.0,
            roll: 1001.0,
            pitch: -400.0,
            yaw: 50.0,
        };
        // r = 500 (truncated), p = −200.
        assert_eq!(power_distribution(&c), [29350.0, 29650.0, 30750.0, 30250.0]);
        let high = Control {
            thrust: 65000.0,
            roll: 2000.0,
            ..Control::default()
        };
        // m3, m4 would be 66000: all four lowered by 465.
        assert_eq!(
            power_distribution(&high),
            [63535.0, 63535.0, 65535.0, 65535.0]
        );
        let low = Control {
            thrust: 100.0,
            roll: -1000.0,
            ..Control::default()
        };
        assert_eq!(power_distribution(&low), [600.0, 600.0, 0.0, 0.0]);
    }

    #[test]
    fn at_the_set_point_the_thrust_is_the_base_and_nothing_turns() {
        let mut c = Cascade::new();
        let s = State {
            pos: [0.0, 0.0, 0.5],
            ..State::default()
        };
        let out = c.step(&hover(), &s, 0.002);
        assert_eq!(
            out,
            Control {
                thrust: 36000.0,
                roll: 0.0,
                pitch: 0.0,
                yaw: 0.0
            }
        );
    }

    #[test]
    fn below_the_set_point_the_height_loop_adds_thrust_and_integrates() {
        // 0.1 m low: position loop 2·0.1 + 0.5·0.1·0.01 = 0.2005 m/s,
        // velocity loop 25·0.2005 + 15·0.2005·0.01 → ×1000 on 36000.
        let mut c = Cascade::new();
        let s = State {
            pos: [0.0, 0.0, 0.4],
            ..State::default()
        };
        let out = c.step(&hover(), &s, 0.002);
        let v = 2.0 * 0.1 + 0.5 * 0.1 * 0.01;
        let want = 36000.0 + 1000.0 * (25.0 * v + 15.0 * v * 0.01);
        assert!((out.thrust - want).abs() < 1e-6, "{} vs {want}", out.thrust);
        // The position loop waits 10 ms: the next tick keeps the thrust.
        assert_eq!(c.step(&hover(), &s, 0.002).thrust, out.thrust);
    }

    #[test]
    fn a_forward_velocity_demand_pitches_nose_down_within_the_limit() {
        let mut c = Cascade::new();
        let s = State {
            pos: [0.0, 0.0, 0.5],
            ..State::default()
        };
        let sp = Setpoint {
            x: Axis::Velocity(1.0),
            ..hover()
        };
        let out = c.step(&sp, &s, 0.002);
        // 25·1 + 1·0.01 = 25.01° asked, limited to 20° nose down; the
        // attitude loop asks a nose-down rate, the rate loop a nose-down
        // command: the front motors (m1, m4) slow down.
        assert_eq!(c.att_desired[1], -20.0);
        assert!(out.pitch < 0.0);
        let m = power_distribution(&out);
        assert!(m[0] < m[1] && m[3] < m[2], "{m:?}");
    }

    #[test]
    fn thrust_zero_turns_the_motors_off_and_resets() {
        let mut c = Cascade::new();
        let s = State {
            pos: [0.0, 0.0, 0.4],
            attitude: [0.0, 0.0, 30.0],
            ..State::default()
        };
        c.step(&hover(), &s, 0.002);
        assert_eq!(c.step(&Setpoint::STOP, &s, 0.002), Control::default());
        assert_eq!(c.att_desired[2], 30.0);
    }
}
