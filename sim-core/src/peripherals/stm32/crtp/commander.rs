//! Ports 3 and 7, the low-level set-points (the firmware's
//! `crtp_commander_rpyt.c` and `crtp_commander_generic.c`, cflib's
//! `commander.py`), and the commander's watchdog (`commander.c`).
//!
//! | port.channel | type | layout (little-endian) | flown as |
//! |---|---|---|---|
//! | 3.0 | rpyt | roll°, pitch°, yaw rate°/s (f32), thrust u16 | thrust 0: motors off; else attitude + collective |
//! | 7.0 | 0 stop | — | motors off |
//! | 7.0 | 1 / 8 velocity world | vx, vy, vz m/s, yaw rate°/s | world velocity, height integrated from vz |
//! | 7.0 | 2 / 9 z distance | roll°, pitch°, yaw rate°/s, z m | attitude + height |
//! | 7.0 | 5 / 10 hover | vx, vy (body) m/s, yaw rate°/s, z m | body velocity + height |
//! | 7.0 | 7 position | x, y, z m, yaw° | position |
//! | 7.1 | 0 notify set-point stop | remain valid ms u32 | back to the high-level commander |
//!
//! Types 1, 2 and 5 are the legacy ones (cflib sends them to a firmware of
//! protocol version ≤ 8) whose yaw rate is clockwise-positive; 8, 9, 10 are
//! counter-clockwise-positive. cflib's `send_setpoint` negates the pitch
//! before sending (a positive user pitch flies forward), so a positive pitch
//! in the packet is nose-up.
//!
//! Watchdog (`commander.c`): a low-level set-point older than
//! `COMMANDER_WDT_TIMEOUT_STABILIZE` (500 ms) is replaced by a level hover
//! at its height; older than `COMMANDER_WDT_TIMEOUT_SHUTDOWN` (2000 ms), the
//! motors stop.

use super::packet::{f32_at, u16_at, u32_at};
use crate::units::Picos;

pub const WDT_STABILIZE: Picos = Picos::from_ms(500);
pub const WDT_SHUTDOWN: Picos = Picos::from_ms(2000);

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Setpoint {
    Stop,
    /// Attitude (rad, roll right-down, pitch nose-down positive = forward),
    /// yaw rate (rad/s, counter-clockwise), thrust (0..65535).
    Attitude {
        roll: f64,
        pitch: f64,
        yaw_rate: f64,
        thrust: f64,
    },
    ZDistance {
        roll: f64,
        pitch: f64,
        yaw_rate: f64,
        z: f64,
    },
    Hover {
        vx: f64,
        vy: f64,
        yaw_rate: f64,
        z: f64,
    },
    VelocityWorld {
        vx: f64,
        vy: f64,
        vz: f64,
        yaw_rate: f64,
    },
    Position {
        x: f64,
        y: f64,
        z: f64,
        /// rad
        yaw: f64,
    },
}

impl Setpoint {
    /// Port 3 (rpyt). `None`: too short.
    pub fn rpyt(d: &[u8]) -> Option<Setpoint> {
        let thrust = f64::from(u16_at(d, 12)?);
        if thrust == 0.0 {
            return Some(Setpoint::Stop);
        }
        Some(Setpoint::Attitude {
            roll: f32_at(d, 0)?.to_radians(),
            pitch: -f32_at(d, 4)?.to_radians(),
            yaw_rate: -f32_at(d, 8)?.to_radians(),
            thrust,
        })
    }

    /// Port 7 channel 0. `None`: unknown type or too short (ignored, as
    /// the firmware's `crtpCommanderGenericDecodeSetpoint` ignores it).
    pub fn generic(d: &[u8]) -> Option<Setpoint> {
        let f = |i: usize| f32_at(d, 1 + 4 * i);
        let ty = *d.first()?;
        let sp = match ty {
            0 => Setpoint::Stop,
            1 | 8 => Setpoint::VelocityWorld {
                vx: f(0)?,
                vy: f(1)?,
                vz: f(2)?,
                yaw_rate: yaw_rate(ty == 1, f(3)?),
            },
            2 | 9 => Setpoint::ZDistance {
                roll: f(0)?.to_radians(),
                pitch: -f(1)?.to_radians(),
                yaw_rate: yaw_rate(ty == 2, f(2)?),
                z: f(3)?,
            },
            5 | 10 => Setpoint::Hover {
                vx: f(0)?,
                vy: f(1)?,
                yaw_rate: yaw_rate(ty == 5, f(2)?),
                z: f(3)?,
            },
            7 => Setpoint::Position {
                x: f(0)?,
                y: f(1)?,
                z: f(2)?,
                yaw: f(3)?.to_radians(),
            },
            _ => return None,
        };
        let finite = match sp {
            Setpoint::Stop => true,
            Setpoint::Attitude { .. } => true,
            Setpoint::ZDistance {
                roll,
                pitch,
                yaw_rate,
                z,
            } => [roll, pitch, yaw_rate, z].iter().all(|v| v.is_finite()),
            Setpoint::Hover {
                vx,
                vy,
                yaw_rate,
                z,
            } => [vx, vy, yaw_rate, z].iter().all(|v| v.is_finite()),
            Setpoint::VelocityWorld {
                vx,
                vy,
                vz,
                yaw_rate,
            } => [vx, vy, vz, yaw_rate].iter().all(|v| v.is_finite()),
            Setpoint::Position { x, y, z, yaw } => [x, y, z, yaw].iter().all(|v| v.is_finite()),
        };
        finite.then_some(sp)
    }
}

fn yaw_rate(legacy: bool, deg_s: f64) -> f64 {
    let r = deg_s.to_radians();
    if legacy {
        -r
    } else {
        r
    }
}

/// Port 7 channel 1, type 0: notify set-point stop. The remaining validity
/// (ms) is read and not used: the high-level commander takes over at once.
pub fn is_notify_stop(d: &[u8]) -> bool {
    d.first() == Some(&0) && u32_at(d, 1).is_some()
}

/// The last low-level set-point and when it arrived.
#[derive(Debug, Clone, Copy, Default)]
pub struct Commander {
    pub last: Option<(Setpoint, Picos)>,
}

/// What the watchdog makes of the last set-point at `now`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Watched {
    /// No low-level set-point (or notify-stop): the high-level commander.
    None,
    Fresh(Setpoint),
    /// Older than 500 ms: level, hold the height it had.
    Stale(Setpoint),
    /// Older than 2 s: motors off.
    Shutdown,
}

impl Commander {
    pub fn set(&mut self, sp: Setpoint, now: Picos) {
        self.last = Some((sp, now));
    }

    pub fn release(&mut self) {
        self.last = None;
    }

    pub fn watched(&self, now: Picos) -> Watched {
        match self.last {
            None => Watched::None,
            Some((sp, t)) => {
                let age = now.saturating_sub(t);
                if age > WDT_SHUTDOWN {
                    Watched::Shutdown
                } else if age > WDT_STABILIZE {
                    Watched::Stale(sp)
                } else {
                    Watched::Fresh(sp)
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pack(ty: u8, v: [f32; 4]) -> Vec<u8> {
        let mut d = vec![ty];
        for x in v {
            d.extend(x.to_le_bytes());
        }
        d
    }

    #[test]
    fn generic_types_decode_with_their_yaw_conventions() {
        assert_eq!(
            Setpoint::generic(&pack(10, [0.5, 0.0, 90.0, 0.4])),
            Some(Setpoint::Hover {
                vx: 0.5,
                vy: 0.0,
                yaw_rate: 90f64.to_radians(),
                z: 0.4f32 as f64
            })
        );
        let Some(Setpoint::Hover { yaw_rate, .. }) =
            Setpoint::generic(&pack(5, [0.0, 0.0, 90.0, 0.4]))
        else {
            panic!()
        };
        assert_eq!(yaw_rate, -(90f64.to_radians()));
        assert_eq!(Setpoint::generic(&[0]), Some(Setpoint::Stop));
        assert_eq!(Setpoint::generic(&[42, 1, 2]), None);
        assert_eq!(
            Setpoint::generic(&pack(7, [1.0, 2.0, 3.0, 0.0])[..10]),
            None
        );
        assert_eq!(Setpoint::generic(&pack(7, [f32::NAN, 2.0, 3.0, 0.0])), None);
        let mut rpyt = [0u8; 14].to_vec();
        assert_eq!(Setpoint::rpyt(&rpyt), Some(Setpoint::Stop));
        rpyt.pop();
        assert_eq!(Setpoint::rpyt(&rpyt), None);
    }

    #[test]
    fn the_watchdog_levels_then_stops() {
        let mut c = Commander::default();
        let t0 = Picos::from_ms(3000);
        c.set(Setpoint::Stop, t0);
        assert_eq!(
            c.watched(t0 + Picos::from_ms(500)),
            Watched::Fresh(Setpoint::Stop)
        );
        assert_eq!(
            c.watched(t0 + Picos::from_ms(501)),
            Watched::Stale(Setpoint::Stop)
        );
        assert_eq!(c.watched(t0 + Picos::from_ms(2001)), Watched::Shutdown);
        c.release();
        assert_eq!(c.watched(t0), Watched::None);
    }
}
