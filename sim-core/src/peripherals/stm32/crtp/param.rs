//! Port 2, parameters (the firmware's `param.c`, cflib's `param.py`):
//! channel 0 the TOC ([`super::toc`]), channel 1 read `[id u16]` →
//! `[id u16, 0, value]` (an unknown id → `[id u16, ENOENT]`), channel 2
//! write `[id u16, value]` → `[id u16, value]` (the value the parameter
//! holds afterwards; an unknown id or a read-only parameter gets no answer,
//! as from the firmware). Channel 3 (misc: set by name, persistent storage,
//! extended types, defaults) is not served.
//!
//! Type bytes as `param.h`: bit 3 unsigned, bits 0..1 the size (0 = 1 byte,
//! 2 = 4 bytes), 0x06 float, bit 6 read-only.

use super::localization::DEFAULT_EXT_POS_STD;
use super::packet::u16_at;
use super::toc::{self, TocEntry};
use crate::peripherals::stm32::cascade::{self, Cascade};
use crate::peripherals::stm32::pid::PidGains;

pub const CHAN_TOC: u8 = 0;
pub const CHAN_READ: u8 = 1;
pub const CHAN_WRITE: u8 = 2;

pub const PARAM_UINT8: u8 = 0x08;
pub const PARAM_UINT16: u8 = 0x09;
pub const PARAM_UINT32: u8 = 0x0A;
pub const PARAM_FLOAT: u8 = 0x06;
pub const PARAM_RONLY: u8 = 0x40;
const ENOENT: u8 = 2;

/// The firmware's `stabilizer.controller` value of the PID controller
/// (`controller.h`: ControllerTypePID = 1): the firmware's cascade, or
/// the thesis's PID when the run flies that one (the run key
/// `stabilizer.controller` chooses; the parameter cannot switch).
pub const CONTROLLER_PID: f64 = 1.0;

/// The decks the world gives this drone.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Decks {
    pub flow2: bool,
    pub multiranger: bool,
    pub ai: bool,
}

/// Parameters the STM32 acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Known {
    FlowDeck,
    MultirangerDeck,
    AiDeck,
    /// A deck the firmware has a driver for but this drone does not carry
    /// (the firmware registers one `deck.bc…` per driver; cfclient's flight
    /// tab reads `bcFlow`, `bcZRanger`, `bcZRanger2`, `bcLighthouse4`,
    /// `bcLoco`, `bcDWM1000` for its assist modes and command-based flight,
    /// its LED-ring tab `bcLedRing`, and fails on a missing one).
    AbsentDeck,
    /// `locSrv.extPosStdDev` (m): the standard deviation external positions
    /// are fused with.
    ExtPosStdDev,
    EnHighLevel,
    ResetEstimation,
    Controller,
    /// A gain of the Bitcraze controller (DESIGN.md §4), by the firmware's
    /// name for the same loop.
    Gain(Gain),
    /// A parameter of the firmware's cascade ([`cascade::PARAMS`] index).
    Cascade(usize),
    /// Seed 004's radar (§4.3.1): the flag that makes the drone broadcast
    /// its P2P beacon, and the drone's own id (its radio's).
    RadarEnable,
    RadarId,
    /// `firmware.revision0/1` and `firmware.modified` (the firmware's
    /// `version.c`: its git revision and whether the tree was clean).
    /// cfclient's About box formats them before it lists the decks.
    Firmware,
}

/// The gains of [`PidGains`] served as parameters. The Webots controller
/// has one gain for roll and pitch and one for both horizontal velocities:
/// `pid_attitude.roll_kp` and `pitch_kp` are the same gain (writing one
/// writes both), as are `vxKp` and `vyKp`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gain {
    AttRpKp,
    AttRpKd,
    AttYKp,
    VelKp,
    VelKd,
    ZKp,
    ZKi,
    ZKd,
}

impl Gain {
    fn of(self, g: &PidGains) -> f64 {
        match self {
            Gain::AttRpKp => g.kp_att_rp,
            Gain::AttRpKd => g.kd_att_rp,
            Gain::AttYKp => g.kp_att_y,
            Gain::VelKp => g.kp_vel_xy,
            Gain::VelKd => g.kd_vel_xy,
            Gain::ZKp => g.kp_z,
            Gain::ZKi => g.ki_z,
            Gain::ZKd => g.kd_z,
        }
    }

    fn set(self, g: &mut PidGains, v: f64) {
        *match self {
            Gain::AttRpKp => &mut g.kp_att_rp,
            Gain::AttRpKd => &mut g.kd_att_rp,
            Gain::AttYKp => &mut g.kp_att_y,
            Gain::VelKp => &mut g.kp_vel_xy,
            Gain::VelKd => &mut g.kd_vel_xy,
            Gain::ZKp => &mut g.kp_z,
            Gain::ZKi => &mut g.ki_z,
            Gain::ZKd => &mut g.kd_z,
        } = v;
    }
}

/// (group, name, gain) of the gain parameters.
const GAINS: [(&str, &str, Gain); 12] = [
    ("pid_attitude", "roll_kp", Gain::AttRpKp),
    ("pid_attitude", "roll_kd", Gain::AttRpKd),
    ("pid_attitude", "pitch_kp", Gain::AttRpKp),
    ("pid_attitude", "pitch_kd", Gain::AttRpKd),
    ("pid_attitude", "yaw_kp", Gain::AttYKp),
    ("velCtlPid", "vxKp", Gain::VelKp),
    ("velCtlPid", "vxKd", Gain::VelKd),
    ("velCtlPid", "vyKp", Gain::VelKp),
    ("velCtlPid", "vyKd", Gain::VelKd),
    ("posCtlPid", "zKp", Gain::ZKp),
    ("posCtlPid", "zKi", Gain::ZKi),
    ("posCtlPid", "zKd", Gain::ZKd),
];

struct Param {
    entry: TocEntry,
    known: Known,
    value: f64,
}

pub struct Params {
    params: Vec<Param>,
    entries: Vec<TocEntry>,
    /// Writes of `kalman.resetEstimation` = 1 (counted: see `set`).
    pub resets: u64,
}

impl Params {
    /// `radar`: the drone's radio id when its firmware runs the radar
    /// (adds `radar.enable` and the read-only `radar.myId`). With
    /// `cascade` (the run flies the firmware's cascade) the gain
    /// parameters are the cascade's, all of them; without, the thesis's
    /// controller's gains under the firmware's names for the same loops.
    pub fn new(
        decks: Decks,
        gains: &PidGains,
        cascade: Option<&Cascade>,
        radar: Option<u8>,
    ) -> Self {
        let b = |v: bool| if v { 1.0 } else { 0.0 };
        let p = |ty: u8, group: &'static str, name: &'static str, known: Known, value: f64| Param {
            entry: TocEntry { ty, group, name },
            known,
            value,
        };
        let ro = PARAM_UINT8 | PARAM_RONLY;
        let mut params = vec![
            p(ro, "deck", "bcFlow2", Known::FlowDeck, b(decks.flow2)),
            p(
                ro,
                "deck",
                "bcMultiranger",
                Known::MultirangerDeck,
                b(decks.multiranger),
            ),
            p(ro, "deck", "bcAI", Known::AiDeck, b(decks.ai)),
            p(
                PARAM_UINT8,
                "commander",
                "enHighLevel",
                Known::EnHighLevel,
                1.0,
            ),
            p(
                PARAM_UINT8,
                "kalman",
                "resetEstimation",
                Known::ResetEstimation,
                0.0,
            ),
            p(
                PARAM_UINT8,
                "stabilizer",
                "controller",
                Known::Controller,
                CONTROLLER_PID,
            ),
        ];
        match cascade {
            Some(c) => {
                let mut c = c.clone();
                for (i, q) in cascade::PARAMS.iter().enumerate() {
                    let ty = if q.uint16 { PARAM_UINT16 } else { PARAM_FLOAT };
                    params.push(p(
                        ty,
                        q.group,
                        q.name,
                        Known::Cascade(i),
                        *(q.field)(&mut c),
                    ));
                }
            }
            None => {
                for (group, name, g) in GAINS {
                    params.push(p(PARAM_FLOAT, group, name, Known::Gain(g), g.of(gains)));
                }
            }
        }
        if let Some(id) = radar {
            params.push(p(PARAM_UINT8, "radar", "enable", Known::RadarEnable, 0.0));
            params.push(p(ro, "radar", "myId", Known::RadarId, f64::from(id)));
        }
        for name in [
            "bcFlow",
            "bcZRanger",
            "bcZRanger2",
            "bcLighthouse4",
            "bcLoco",
            "bcDWM1000",
            "bcLedRing",
        ] {
            params.push(p(ro, "deck", name, Known::AbsentDeck, 0.0));
        }
        // No Bitcraze build is running, so there is no revision to name:
        // 0 and 0, and "modified" (cfclient shows "00 (MODIFIED)").
        let fw = |ty: u8, name: &'static str, v: f64| {
            p(ty | PARAM_RONLY, "firmware", name, Known::Firmware, v)
        };
        params.push(fw(PARAM_UINT32, "revision0", 0.0));
        params.push(fw(PARAM_UINT16, "revision1", 0.0));
        params.push(fw(PARAM_UINT8, "modified", 1.0));
        params.push(p(
            PARAM_FLOAT,
            "locSrv",
            "extPosStdDev",
            Known::ExtPosStdDev,
            DEFAULT_EXT_POS_STD,
        ));
        let entries = params.iter().map(|p| p.entry.clone()).collect();
        Params {
            params,
            entries,
            resets: 0,
        }
    }

    pub fn entries(&self) -> &[TocEntry] {
        &self.entries
    }

    pub fn toc(&self, request: &[u8]) -> Option<Vec<u8>> {
        toc::answer(&self.entries, request, &[])
    }

    pub fn get(&self, k: Known) -> f64 {
        self.params
            .iter()
            .find(|p| p.known == k)
            .map_or(0.0, |p| p.value)
    }

    /// The controller's gains as the parameters hold them.
    pub fn apply_gains(&self, g: &mut PidGains) {
        for p in &self.params {
            if let Known::Gain(k) = p.known {
                k.set(g, p.value);
            }
        }
    }

    /// The cascade's parameters as they hold them.
    pub fn apply_cascade(&self, c: &mut Cascade) {
        for p in &self.params {
            if let Known::Cascade(i) = p.known {
                *(cascade::PARAMS[i].field)(c) = p.value;
            }
        }
    }

    fn encode(p: &Param) -> Vec<u8> {
        if p.entry.ty & 0x0F == PARAM_FLOAT {
            (p.value as f32).to_le_bytes().to_vec()
        } else {
            // An integer of 1, 2, 4 or 8 bytes (`param.h`: bits 0..1).
            let n = 1usize << (p.entry.ty & 0x03);
            (p.value as i64).to_le_bytes()[..n].to_vec()
        }
    }

    pub fn read(&self, d: &[u8]) -> Option<Vec<u8>> {
        let id = u16_at(d, 0)?;
        let mut out = id.to_le_bytes().to_vec();
        match self.params.get(id as usize) {
            Some(p) => {
                out.push(0);
                out.extend(Self::encode(p));
            }
            None => out.push(ENOENT),
        }
        Some(out)
    }

    /// A write: the answer and the parameter written.
    pub fn write(&mut self, d: &[u8]) -> Option<(Vec<u8>, Known)> {
        let id = u16_at(d, 0)?;
        let p = self.params.get_mut(id as usize)?;
        if p.entry.ty & PARAM_RONLY != 0 {
            return None;
        }
        let raw = &d[2..];
        let v = if p.entry.ty & 0x0F == PARAM_FLOAT {
            super::packet::f32_at(raw, 0)?
        } else {
            // An unsigned integer of the type's width (`param.h`: bits 0..1).
            let n = 1usize << (p.entry.ty & 0x03);
            let bytes = raw.get(..n.min(8))?;
            let mut le = [0u8; 8];
            le[..bytes.len()].copy_from_slice(bytes);
            u64::from_le_bytes(le) as f64
        };
        p.value = match p.known {
            // One controller is flown (the Bitcraze PID of DESIGN.md §4):
            // the parameter keeps saying so, and the answer shows it.
            Known::Controller => CONTROLLER_PID,
            // A gain must be a finite number (the PID would fly NaN).
            Known::Gain(_) | Known::Cascade(_) if !v.is_finite() => p.value,
            // A standard deviation is finite and not negative (the update
            // would not be a Kalman update).
            Known::ExtPosStdDev if !(v.is_finite() && v >= 0.0) => p.value,
            _ => v,
        };
        let (known, value) = (p.known, p.value);
        if known == Known::ResetEstimation && value != 0.0 {
            self.resets += 1;
        }
        let mut out = id.to_le_bytes().to_vec();
        out.extend(Self::encode(p));
        // A shared gain: every name of it holds the new value.
        if let Known::Gain(_) = known {
            for q in self.params.iter_mut().filter(|q| q.known == known) {
                q.value = value;
            }
        }
        Some((out, known))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_writes_and_refusals_follow_param_c() {
        let mut p = Params::new(
            Decks {
                flow2: true,
                multiranger: true,
                ai: false,
            },
            &PidGains::default(),
            None,
            None,
        );
        let flow = toc::find(p.entries(), "deck.bcFlow2").unwrap();
        let ai = toc::find(p.entries(), "deck.bcAI").unwrap();
        let hl = toc::find(p.entries(), "commander.enHighLevel").unwrap();
        let ctl = toc::find(p.entries(), "stabilizer.controller").unwrap();
        assert_eq!(p.read(&flow.to_le_bytes()), Some(vec![flow as u8, 0, 0, 1]));
        assert_eq!(p.read(&ai.to_le_bytes()), Some(vec![ai as u8, 0, 0, 0]));
        assert_eq!(p.read(&[200, 0]), Some(vec![200, 0, ENOENT]));
        assert_eq!(p.read(&[1]), None);
        // Read-only and unknown: no answer.
        assert_eq!(p.write(&[flow as u8, 0, 0]), None);
        assert_eq!(p.write(&[200, 0, 1]), None);
        let (ans, k) = p.write(&[hl as u8, 0, 0]).unwrap();
        assert_eq!((ans, k), (vec![hl as u8, 0, 0], Known::EnHighLevel));
        assert_eq!(p.get(Known::EnHighLevel), 0.0);
        let (ans, _) = p.write(&[ctl as u8, 0, 2]).unwrap();
        assert_eq!(ans, vec![ctl as u8, 0, 1]);
        // pitch_kd is the Webots controller's roll/pitch kd (0.1), shared.
        let pkd = toc::find(p.entries(), "pid_attitude.pitch_kd").unwrap();
        let rkd = toc::find(p.entries(), "pid_attitude.roll_kd").unwrap();
        assert_eq!(
            p.read(&pkd.to_le_bytes()).unwrap()[3..],
            0.1f32.to_le_bytes()
        );
        let mut w = pkd.to_le_bytes().to_vec();
        w.extend(0.2f32.to_le_bytes());
        p.write(&w).unwrap();
        assert_eq!(
            p.read(&rkd.to_le_bytes()).unwrap()[3..],
            0.2f32.to_le_bytes()
        );
        let mut g = PidGains::default();
        p.apply_gains(&mut g);
        assert_eq!(g.kd_att_rp, 0.2f32 as f64);
        assert!(toc::find(p.entries(), "radar.enable").is_none());
    }

    #[test]
    fn the_radar_adds_its_flag_and_its_id() {
        let mut p = Params::new(Decks::default(), &PidGains::default(), None, Some(3));
        let en = toc::find(p.entries(), "radar.enable").unwrap();
        let me = toc::find(p.entries(), "radar.myId").unwrap();
        assert_eq!(p.read(&me.to_le_bytes()), Some(vec![me as u8, 0, 0, 3]));
        assert_eq!(p.write(&[me as u8, 0, 5]), None); // read-only
        assert_eq!(p.get(Known::RadarEnable), 0.0);
        let (ans, k) = p.write(&[en as u8, 0, 1]).unwrap();
        assert_eq!((ans, k), (vec![en as u8, 0, 1], Known::RadarEnable));
        assert_eq!(p.get(Known::RadarEnable), 1.0);
    }

    #[test]
    fn cfclients_decks_read_zero_and_the_extpos_std_dev_refuses_negatives() {
        let mut p = Params::new(Decks::default(), &PidGains::default(), None, None);
        // cfclient's decks: present as 0; the extpos σ: 0.01 m, a negative
        // write keeps it.
        let zr = toc::find(p.entries(), "deck.bcZRanger2").unwrap();
        assert_eq!(p.read(&zr.to_le_bytes()), Some(vec![zr as u8, 0, 0, 0]));
        let sd = toc::find(p.entries(), "locSrv.extPosStdDev").unwrap();
        let mut w = sd.to_le_bytes().to_vec();
        w.extend((-1.0f32).to_le_bytes());
        assert_eq!(p.write(&w).unwrap().0[2..], 0.01f32.to_le_bytes());
        w.truncate(2);
        w.extend(0.05f32.to_le_bytes());
        p.write(&w).unwrap();
        assert_eq!(p.get(Known::ExtPosStdDev), 0.05f32 as f64);
    }

    #[test]
    fn the_firmware_revision_reads_in_its_types_width_and_is_read_only() {
        let mut p = Params::new(Decks::default(), &PidGains::default(), None, None);
        // The value after `[id u16, 0]`: 4, 2 and 1 bytes (`version.c`'s
        // uint32, uint16, uint8).
        for (name, value) in [
            ("firmware.revision0", vec![0, 0, 0, 0]),
            ("firmware.revision1", vec![0, 0]),
            ("firmware.modified", vec![1]),
        ] {
            let id = toc::find(p.entries(), name).unwrap();
            let answer = p.read(&id.to_le_bytes()).unwrap();
            assert_eq!(answer[3..], value, "{name}");
            let mut w = id.to_le_bytes().to_vec();
            w.extend([7, 7, 7, 7]);
            assert_eq!(p.write(&w), None, "{name} is read-only");
        }
    }

    #[test]
    fn the_cascades_parameters_have_the_firmwares_names_and_defaults() {
        let c = Cascade::new();
        let mut p = Params::new(Decks::default(), &PidGains::default(), Some(&c), None);
        let read = |p: &Params, name: &str| {
            let id = toc::find(p.entries(), name).unwrap_or_else(|| panic!("{name}"));
            p.read(&id.to_le_bytes()).unwrap()[3..].to_vec()
        };
        // platform_defaults_cf2.h
        for (name, v) in [
            ("posCtlPid.xKp", 2.0f32),
            ("posCtlPid.zKp", 2.0),
            ("posCtlPid.zKi", 0.5),
            ("velCtlPid.vxKp", 25.0),
            ("velCtlPid.vzKi", 15.0),
            ("pid_attitude.roll_kp", 6.0),
            ("pid_attitude.yaw_kd", 0.35),
            ("pid_rate.roll_kp", 250.0),
            ("pid_rate.roll_ki", 500.0),
            ("pid_rate.yaw_kp", 120.0),
        ] {
            assert_eq!(read(&p, name), v.to_le_bytes(), "{name}");
        }
        assert_eq!(read(&p, "posCtlPid.thrustBase"), 36000u16.to_le_bytes());
        // A 16-bit write, and the cascade takes it.
        let id = toc::find(p.entries(), "posCtlPid.thrustBase").unwrap();
        let mut w = id.to_le_bytes().to_vec();
        w.extend(38000u16.to_le_bytes());
        assert_eq!(p.write(&w).unwrap().0[2..], 38000u16.to_le_bytes());
        let mut c2 = Cascade::new();
        p.apply_cascade(&mut c2);
        assert_eq!(c2.limits.thrust_base, 38000.0);
        // The thesis's gains are not served beside them.
        assert!(toc::find(p.entries(), "posCtlPid.thrustBase").is_some());
        assert_eq!(
            p.entries()
                .iter()
                .filter(|e| e.group == "posCtlPid" && e.name == "zKp")
                .count(),
            1
        );
    }
}
