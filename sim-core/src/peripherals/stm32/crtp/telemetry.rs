//! What the log variables read: the STM32's state estimate, its ranges, the
//! attitude, the motor commands of the last iteration, and the power
//! network's last sample (the kernel hands it over every millisecond). The
//! names and types are the firmware's (`LOG_GROUP_START(stateEstimate)` in
//! `estimator.c`, `range` in `range.c`, `pm` in `pm_stm32f4.c`, `stabilizer`
//! in `stabilizer.c`, `motor` in `motors.c`); `power` and `gap8` are this
//! platform's own, `radar` seed 004's modified firmware's (§4.3.1: the last
//! drone heard and its RSSI; the seed does not name them).

use super::toc::TocEntry;
use crate::peripherals::motors::MAX_SPEED;

/// The firmware's log types (`log.h`: LOG_UINT8 = 1 … LOG_FLOAT = 7, LOG_FP16 = 8).
pub const LOG_UINT8: u8 = 1;
pub const LOG_UINT16: u8 = 2;
pub const LOG_UINT32: u8 = 3;
pub const LOG_INT8: u8 = 4;
pub const LOG_INT16: u8 = 5;
pub const LOG_INT32: u8 = 6;
pub const LOG_FLOAT: u8 = 7;
pub const LOG_FP16: u8 = 8;

/// A range sensor with nothing in range reads this (mm): cflib's
/// `Multiranger` takes 8000 mm and more as "nothing" (`multiranger.py`).
pub const RANGE_NONE_MM: f64 = 32767.0;

/// The firmware's PWM full scale (`motors.h`: 16-bit ratios); our motor
/// commands are speeds up to the world's [`MAX_SPEED`] rad/s, mapped
/// linearly onto it.
pub const PWM_FULL: f64 = 65535.0;

/// The power network's last sample, as the log shows it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PowerTelemetry {
    pub vbat: f64,
    pub soc: f64,
    pub low_battery: bool,
    pub i_battery: f64,
    pub p_motor: f64,
    pub i_vcc: f64,
    /// The cluster's power (W) on a platform with one.
    pub p_cluster: Option<f64>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Telemetry {
    pub pos: [f64; 3],
    pub vel: [f64; 3],
    /// rad
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
    /// front, back, left, right, up, down (m; negative = nothing in range)
    pub ranges: [f64; 6],
    /// The last iteration's motor commands (rad/s).
    pub motors: [f64; 4],
    /// The attitude the controller asked for (rad) and its collective (rad/s).
    pub sp_roll: f64,
    pub sp_pitch: f64,
    pub sp_yaw: f64,
    pub collective: f64,
    /// The firmware's cascade flies: its thrust and the four motors' PWM
    /// (the log shows them rather than speeds mapped onto PWM).
    pub pwm: Option<(f64, [f64; 4])>,
    pub power: PowerTelemetry,
    /// The radar's last drone heard (0: none for 3 s) and its RSSI (dBm).
    pub radar_id: f64,
    pub radar_rssi: f64,
    /// The dead-reckoned position's error variance per axis (m², flow mode).
    pub position_variance: Option<f64>,
    /// The world's position of the drone (its GPS), whatever the estimate.
    pub world: [f64; 3],
}

fn mm(m: f64) -> f64 {
    if m >= 0.0 {
        m * 1000.0
    } else {
        RANGE_NONE_MM
    }
}

fn pwm(speed: f64) -> f64 {
    (speed / MAX_SPEED * PWM_FULL).clamp(0.0, PWM_FULL)
}

/// Motor `i`'s PWM: the cascade's, or the speed mapped onto PWM.
fn motor_pwm(t: &Telemetry, i: usize) -> f64 {
    t.pwm.map_or(pwm(t.motors[i]), |p| p.1[i])
}

/// The firmware's `pm.state` (`pm.h`: 0 battery, 3 low power).
fn pm_state(p: &PowerTelemetry) -> f64 {
    if p.low_battery {
        3.0
    } else {
        0.0
    }
}

pub struct LogVar {
    pub entry: TocEntry,
    pub get: fn(&Telemetry) -> f64,
}

macro_rules! var {
    ($ty:expr, $g:literal, $n:literal, $f:expr) => {
        LogVar {
            entry: TocEntry {
                ty: $ty,
                group: $g,
                name: $n,
            },
            get: $f,
        }
    };
}

/// The firmware's `supervisor.info` bits (`supervisor.h`, as cfclient's
/// flight tab reads them): can be armed, is armed, auto-arm (the Crazyflie
/// 2.1 arms itself), can fly, is flying, is tumbled.
const SUPERVISOR_CAN_ARM: u16 = 1 << 0;
const SUPERVISOR_ARMED: u16 = 1 << 1;
const SUPERVISOR_AUTO_ARM: u16 = 1 << 2;
const SUPERVISOR_CAN_FLY: u16 = 1 << 3;
const SUPERVISOR_FLYING: u16 = 1 << 4;
const SUPERVISOR_TUMBLED: u16 = 1 << 5;

/// `supervisor.info`: always armed and able to fly (auto-arming, no
/// supervisor lock modelled); flying while the motors turn; tumbled when
/// the body's z axis is more than 60° from the vertical (the firmware's
/// `supervisorIsTumbled`: the accelerometer's z below 0.5 g).
fn supervisor_info(t: &Telemetry) -> f64 {
    let mut bits = SUPERVISOR_CAN_ARM | SUPERVISOR_ARMED | SUPERVISOR_AUTO_ARM | SUPERVISOR_CAN_FLY;
    if t.collective > 0.0 {
        bits |= SUPERVISOR_FLYING;
    }
    if t.roll.cos() * t.pitch.cos() < 0.5 {
        bits |= SUPERVISOR_TUMBLED;
    }
    f64::from(bits)
}

/// The optional groups of a drone's log TOC.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LogGroups {
    /// `gap8.*`: a platform with a cluster (the AI deck's GAP8).
    pub cluster: bool,
    /// `radar.*`: a drone whose firmware runs seed 004's radar.
    pub radar: bool,
    /// `kalman.varPX`, `varPY`: the estimate is the flow filter's (which
    /// keeps a position variance for external positions).
    pub variance: bool,
}

/// The log TOC, with the optional `groups`. Angles in degrees as the
/// firmware logs them.
pub fn log_toc(groups: LogGroups) -> Vec<LogVar> {
    let mut v = vec![
        var!(LOG_FLOAT, "stateEstimate", "x", |t| t.pos[0]),
        var!(LOG_FLOAT, "stateEstimate", "y", |t| t.pos[1]),
        var!(LOG_FLOAT, "stateEstimate", "z", |t| t.pos[2]),
        var!(LOG_FLOAT, "stateEstimate", "vx", |t| t.vel[0]),
        var!(LOG_FLOAT, "stateEstimate", "vy", |t| t.vel[1]),
        var!(LOG_FLOAT, "stateEstimate", "vz", |t| t.vel[2]),
        var!(LOG_FLOAT, "stateEstimate", "roll", |t| t.roll.to_degrees()),
        var!(LOG_FLOAT, "stateEstimate", "pitch", |t| t
            .pitch
            .to_degrees()),
        var!(LOG_FLOAT, "stateEstimate", "yaw", |t| t.yaw.to_degrees()),
        var!(LOG_UINT16, "range", "front", |t| mm(t.ranges[0])),
        var!(LOG_UINT16, "range", "back", |t| mm(t.ranges[1])),
        var!(LOG_UINT16, "range", "left", |t| mm(t.ranges[2])),
        var!(LOG_UINT16, "range", "right", |t| mm(t.ranges[3])),
        var!(LOG_UINT16, "range", "up", |t| mm(t.ranges[4])),
        var!(LOG_UINT16, "range", "zrange", |t| mm(t.ranges[5])),
        var!(LOG_FLOAT, "pm", "vbat", |t| t.power.vbat),
        var!(LOG_UINT8, "pm", "batteryLevel", |t| (t.power.soc * 100.0)
            .round()
            .clamp(0.0, 100.0)),
        var!(LOG_INT8, "pm", "state", |t| pm_state(&t.power)),
        var!(LOG_FLOAT, "stabilizer", "roll", |t| t.sp_roll.to_degrees()),
        var!(LOG_FLOAT, "stabilizer", "pitch", |t| t
            .sp_pitch
            .to_degrees()),
        var!(LOG_FLOAT, "stabilizer", "yaw", |t| t.sp_yaw.to_degrees()),
        var!(LOG_FLOAT, "stabilizer", "thrust", |t| t
            .pwm
            .map_or(pwm(t.collective), |p| p.0)),
        var!(LOG_UINT32, "motor", "m1", |t| motor_pwm(t, 0)),
        var!(LOG_UINT32, "motor", "m2", |t| motor_pwm(t, 1)),
        var!(LOG_UINT32, "motor", "m3", |t| motor_pwm(t, 2)),
        var!(LOG_UINT32, "motor", "m4", |t| motor_pwm(t, 3)),
        var!(LOG_FLOAT, "power", "vbat", |t| t.power.vbat),
        var!(LOG_FLOAT, "power", "soc", |t| t.power.soc),
        var!(LOG_FLOAT, "power", "iBattery", |t| t.power.i_battery),
        var!(LOG_FLOAT, "power", "iVcc", |t| t.power.i_vcc),
        var!(LOG_FLOAT, "power", "pMotor", |t| t.power.p_motor),
        // cfclient's flight tab logs these to enable its flight controls.
        var!(LOG_UINT8, "sys", "canfly", |_| 1.0),
        var!(LOG_UINT16, "supervisor", "info", supervisor_info),
        // This platform's own: the world's position of the drone (its GPS),
        // what a motion-capture system measures, for a client that stands
        // in for one (send it back with `send_extpos`; docs/CFLIB.md).
        var!(LOG_FLOAT, "world", "x", |t| t.world[0]),
        var!(LOG_FLOAT, "world", "y", |t| t.world[1]),
        var!(LOG_FLOAT, "world", "z", |t| t.world[2]),
    ];
    if groups.variance {
        v.push(var!(LOG_FLOAT, "kalman", "varPX", |t| t
            .position_variance
            .unwrap_or(0.0)));
        v.push(var!(LOG_FLOAT, "kalman", "varPY", |t| t
            .position_variance
            .unwrap_or(0.0)));
    }
    if groups.cluster {
        v.push(var!(LOG_FLOAT, "gap8", "pCluster", |t| t
            .power
            .p_cluster
            .unwrap_or(0.0)));
    }
    if groups.radar {
        v.push(var!(LOG_UINT8, "radar", "id", |t| t.radar_id));
        v.push(var!(LOG_FLOAT, "radar", "rssi", |t| t.radar_rssi));
    }
    v
}

/// Size in bytes of a log type (`None`: not a log type).
pub fn type_size(ty: u8) -> Option<usize> {
    match ty {
        LOG_UINT8 | LOG_INT8 => Some(1),
        LOG_UINT16 | LOG_INT16 | LOG_FP16 => Some(2),
        LOG_UINT32 | LOG_INT32 | LOG_FLOAT => Some(4),
        _ => None,
    }
}

/// `v` in log type `ty`, little-endian; integers as C converts a float
/// (toward zero; saturated here where C's conversion is undefined).
pub fn encode(ty: u8, v: f64, out: &mut Vec<u8>) {
    match ty {
        LOG_UINT8 => out.push(v as u8),
        LOG_INT8 => out.push(v as i8 as u8),
        LOG_UINT16 => out.extend((v as u16).to_le_bytes()),
        LOG_INT16 => out.extend((v as i16).to_le_bytes()),
        LOG_UINT32 => out.extend((v as u32).to_le_bytes()),
        LOG_INT32 => out.extend((v as i32).to_le_bytes()),
        LOG_FLOAT => out.extend((v as f32).to_le_bytes()),
        LOG_FP16 => out.extend(half::f16::from_f64(v).to_le_bytes()),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn get(toc: &[LogVar], name: &str, t: &Telemetry) -> Option<f64> {
        toc.iter()
            .find(|v| format!("{}.{}", v.entry.group, v.entry.name) == name)
            .map(|v| (v.get)(t))
    }

    #[test]
    fn cfclients_variables_and_the_variance_are_logged() {
        let mut t = Telemetry {
            position_variance: Some(2.5e-4),
            world: [1.0, 2.0, 0.5],
            ..Telemetry::default()
        };
        let toc = log_toc(LogGroups {
            variance: true,
            ..LogGroups::default()
        });
        assert_eq!(get(&toc, "sys.canfly", &t), Some(1.0));
        // On the ground: can arm, armed, auto-arm, can fly.
        assert_eq!(get(&toc, "supervisor.info", &t), Some(15.0));
        t.collective = 5000.0;
        assert_eq!(get(&toc, "supervisor.info", &t), Some(31.0));
        t.roll = 1.2;
        assert_eq!(get(&toc, "supervisor.info", &t), Some(63.0));
        assert_eq!(get(&toc, "kalman.varPY", &t), Some(2.5e-4));
        assert_eq!(get(&toc, "world.y", &t), Some(2.0));
        // The variance only with the flow filter.
        assert_eq!(
            get(&log_toc(LogGroups::default()), "kalman.varPX", &t),
            None
        );
    }
}
