use std::f64::consts::FRAC_PI_2;

use protocol::Sensors;

use super::super::{is_register, Stm32, Stm32Config, CTRL, INIT_PID, RUN_SINGLE_STEP_PID};
use super::*;
use crate::peripherals::{DeviceCtx, DevicePower, Motors, SoloWorld, WorldSession};
use crate::sync::{SyncMode, TimeKeeper};
use crate::units::Millis;

/// Writes `bytes` at `offset` one by one, as the bus does.
fn write_bytes(stm32: &mut Stm32, offset: u32, bytes: &[u8], now: Picos, ctx: &mut DeviceCtx<'_>) {
    for (i, b) in bytes.iter().enumerate() {
        stm32.write(offset + i as u32, *b, now, ctx).unwrap();
    }
}

/// Writes an extension command to EXT_CTRL (a whole word: it fires at the
/// last byte).
fn command(stm32: &mut Stm32, code: u32, now: Picos, ctx: &mut DeviceCtx<'_>) {
    write_bytes(stm32, EXT_CTRL, &code.to_le_bytes(), now, ctx);
}

/// Writes a command argument (f64) at `offset`.
fn set_arg(stm32: &mut Stm32, offset: u32, value: f64, now: Picos, ctx: &mut DeviceCtx<'_>) {
    write_bytes(stm32, offset, &value.to_le_bytes(), now, ctx);
}

/// What a device context borrows besides the world and the console.
struct Rig {
    session: WorldSession,
    time: TimeKeeper,
    motors: Motors,
}

impl Rig {
    fn new() -> Self {
        Rig {
            session: WorldSession::new(None, protocol::ImageEncoding::Array),
            time: TimeKeeper::new(SyncMode::Thesis),
            motors: Motors::default(),
        }
    }

    fn ctx<'a>(
        &'a mut self,
        world: &'a mut dyn crate::peripherals::WorldLink,
        console: &'a mut dyn FnMut(&str),
    ) -> DeviceCtx<'a> {
        DeviceCtx {
            world,
            session: &mut self.session,
            time: &mut self.time,
            motors: &mut self.motors,
            battery_low: false,
            console,
        }
    }
}

fn stat(stm32: &Stm32, now: Picos) -> u32 {
    u32::from_le_bytes(std::array::from_fn(|i| {
        stm32.read(EXT_STAT + i as u32, now)
    }))
}

#[test]
fn commands_complete_with_their_code_and_bad_ones_with_ext_error() {
    let mut world = SoloWorld::new([-2.6, 0.0, 0.015], Millis(32));
    let mut printed = String::new();
    let mut sink = |s: &str| printed.push_str(s);
    let mut rig = Rig::new();
    let mut ctx = rig.ctx(&mut world, &mut sink);
    let mut stm32 = Stm32::new(Stm32Config::default(), DevicePower::new(Picos::ZERO));
    let t = Picos::from_ms(1);
    // Before INIT_PID: refused.
    command(&mut stm32, EXT_SET_HEADING, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_ERROR);

    stm32.write(CTRL, INIT_PID, t, &mut ctx).unwrap();
    let t = Picos::from_ms(2001);
    // The estimate starts at the world's start position.
    let est_x = f64::from_le_bytes(std::array::from_fn(|i| stm32.read(EST_X + i as u32, t)));
    assert_eq!(est_x, -2.6);

    // A command fires at its last byte only.
    write_bytes(&mut stm32, EXT_CTRL, &[99, 0, 0], t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_ERROR, "still the earlier refusal");
    set_arg(&mut stm32, CMD_YAW, 0.5, t, &mut ctx);
    command(&mut stm32, EXT_SET_HEADING, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_SET_HEADING);
    assert_eq!(stm32.motion.heading, Some(0.5));

    // Unknown command, non-finite and non-positive arguments: EXT_ERROR.
    command(&mut stm32, 99, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_ERROR);
    set_arg(&mut stm32, CMD_SPEED_LIMIT, f64::NAN, t, &mut ctx);
    command(&mut stm32, EXT_SET_SPEED_LIMIT, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_ERROR);
    set_arg(&mut stm32, CMD_SPEED_LIMIT, 0.0, t, &mut ctx);
    command(&mut stm32, EXT_SET_SPEED_LIMIT, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_ERROR);
    set_arg(&mut stm32, CMD_SPEED_LIMIT, 0.5, t, &mut ctx);
    command(&mut stm32, EXT_SET_SPEED_LIMIT, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_SET_SPEED_LIMIT);

    // Velocity set-point: clamped to the speed limit, direction kept.
    set_arg(&mut stm32, CMD_VX, 3.0, t, &mut ctx);
    set_arg(&mut stm32, CMD_VY, 4.0, t, &mut ctx);
    set_arg(&mut stm32, CMD_HEIGHT, 1.0, t, &mut ctx);
    set_arg(&mut stm32, CMD_YAW_RATE, 0.0, t, &mut ctx);
    command(&mut stm32, EXT_SET_VELOCITY, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_SET_VELOCITY);
    let Mode::Velocity(sp) = stm32.motion.mode else {
        panic!("velocity mode expected")
    };
    assert!(
        (sp.vx - 0.3).abs() < 1e-12 && (sp.vy - 0.4).abs() < 1e-12,
        "{sp:?}"
    );
    // A height below the ground is refused and keeps the set-point.
    set_arg(&mut stm32, CMD_HEIGHT, -1.0, t, &mut ctx);
    command(&mut stm32, EXT_SET_VELOCITY, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_ERROR);
    assert_eq!(stm32.motion.mode, Mode::Velocity(sp));
    // RUN_PID would never end in velocity mode: a device error.
    assert!(stm32
        .write(CTRL, super::super::RUN_PID, t, &mut ctx)
        .is_err());
    command(&mut stm32, EXT_POSITION_MODE, t, &mut ctx);
    assert_eq!(stat(&stm32, t), EXT_POSITION_MODE);
    assert_eq!(stm32.motion.mode, Mode::Position);
    assert_eq!(stm32.target(), [-2.6, 0.0, 0.015]);
    assert_eq!(printed.matches("refused").count(), 5, "{printed}");
}

#[test]
fn the_register_file_has_a_faulting_gap_before_the_extension() {
    assert!(is_register(25));
    assert!((26..30).all(|o| !is_register(o)));
    assert!(is_register(EXT_CTRL) && is_register(EXT_END - 1));
    assert!(!is_register(EXT_END));
    // The firmware's offsets (cosim_regs.h) minus the STM32's base 102402.
    assert_eq!((EXT_CTRL, EST_X, RANGE_FRONT, FLOW_VX), (30, 38, 94, 142));
    assert_eq!(
        (
            CMD_VX,
            CMD_SPEED_LIMIT,
            EST_PITCH,
            EST_TIME,
            P2P_ENABLE,
            EXT_END
        ),
        (158, 198, 214, 222, 230, 246)
    );
}

#[test]
fn the_radar_registers_carry_the_p2p_side_to_the_stm32_and_the_flag_back() {
    let mut world = SoloWorld::new([0.0, 0.0, 0.015], Millis(32));
    let mut sink = |_: &str| {};
    let mut rig = Rig::new();
    let mut ctx = rig.ctx(&mut world, &mut sink);
    let mut stm32 = Stm32::new(Stm32Config::default(), DevicePower::new(Picos::ZERO));
    let t = Picos::from_ms(1);
    let word =
        |s: &Stm32, o: u32| u32::from_le_bytes(std::array::from_fn(|i| s.read(o + i as u32, t)));
    // Nothing written: no radar, nobody heard, the flag down.
    assert_eq!(stm32.motion.p2p_self(), None);
    assert_eq!(stm32.motion.p2p_heard(), None);
    write_bytes(&mut stm32, P2P_SELF, &2u32.to_le_bytes(), t, &mut ctx);
    write_bytes(&mut stm32, P2P_ID, &3u32.to_le_bytes(), t, &mut ctx);
    write_bytes(&mut stm32, P2P_RSSI, &(-4550i32).to_le_bytes(), t, &mut ctx);
    assert_eq!(stm32.motion.p2p_self(), Some(2));
    assert_eq!(stm32.motion.p2p_heard(), Some((3, -45.5)));
    // P2P_ENABLE is the STM32's to write (a core write is ignored).
    write_bytes(&mut stm32, P2P_ENABLE, &1u32.to_le_bytes(), t, &mut ctx);
    assert_eq!(word(&stm32, P2P_ENABLE), 0);
    stm32.motion.set_p2p_enable(true);
    assert_eq!(word(&stm32, P2P_ENABLE), 1);
    write_bytes(&mut stm32, P2P_ID, &0u32.to_le_bytes(), t, &mut ctx);
    assert_eq!(stm32.motion.p2p_heard(), None);
}

fn est_time(stm32: &Stm32, now: Picos) -> f64 {
    f64::from_le_bytes(std::array::from_fn(|i| {
        stm32.read(EST_TIME + i as u32, now)
    }))
}

/// A [`SoloWorld`] that also answers GET_SENSORS (and GET_DATA_2/3): the
/// drone at rest on its start, at the world's clock.
struct Resting(SoloWorld);

impl crate::peripherals::WorldLink for Resting {
    fn call(
        &mut self,
        request: &protocol::Request,
        now: Picos,
    ) -> Result<protocol::Reply, crate::peripherals::LinkError> {
        // At rest: no speed for the motor power models.
        match request {
            protocol::Request::GetData2 => {
                return Ok(protocol::Reply::Data2 {
                    velocity: 0.0,
                    velocity_x: 0.0,
                    velocity_y: 0.0,
                })
            }
            protocol::Request::GetData3 => {
                return Ok(protocol::Reply::Data3 {
                    velocity: 0.0,
                    velocity_z: 0.0,
                    pitch: 0.0,
                })
            }
            _ => {}
        }
        if let protocol::Request::GetSensors = request {
            self.0.log.push(crate::peripherals::solo_world::Logged {
                clock: self.0.clock(),
                platform: now,
                request: request.clone(),
            });
            let [x, y, z] = self.0.start;
            return Ok(protocol::Reply::Sensors(Sensors {
                time_s: self.0.clock().0 as f64 / 1000.0,
                x,
                y,
                z,
                altitude: z,
                ..Sensors::default()
            }));
        }
        self.0.call(request, now)
    }
    fn send(
        &mut self,
        request: &protocol::Request,
        now: Picos,
    ) -> Result<(), crate::peripherals::LinkError> {
        self.0.send(request, now)
    }
    fn stats(&self) -> crate::peripherals::LinkStats {
        self.0.stats()
    }
}

#[test]
fn est_time_is_the_world_time_of_the_last_sensor_read() {
    let mut world = Resting(SoloWorld::new([0.0, 0.0, 0.015], Millis(4)));
    let mut sink = |_: &str| {};
    let mut rig = Rig::new();
    let mut ctx = rig.ctx(&mut world, &mut sink);
    let mut stm32 = Stm32::new(Stm32Config::default(), DevicePower::new(Picos::ZERO));
    let t = Picos::from_ms(1);
    assert_eq!(est_time(&stm32, t), 0.0, "no sensor read yet");
    stm32.write(CTRL, INIT_PID, t, &mut ctx).unwrap();
    // GET_INIT_DATA's time: the end of the world's 2000 ms warm-up.
    assert_eq!(est_time(&stm32, Picos::from_ms(2001)), 2.0);
    // Each step reads the sensors (at the world's clock then), then the
    // world advances one 4 ms timestep: EST_TIME is the read's time, one
    // step behind the world's clock when the step completes. The core's
    // time (`now`, 10 ms per step here) does not enter.
    let mut seen = Vec::new();
    for k in 1..=3u64 {
        let now = Picos::from_ms(2001 + 10 * k);
        stm32
            .write(CTRL, RUN_SINGLE_STEP_PID, now, &mut ctx)
            .unwrap();
        seen.push(est_time(&stm32, now + Picos::from_ms(8)));
        stm32
            .write(CTRL, 0, now + Picos::from_ms(8), &mut ctx)
            .unwrap();
    }
    let reads: Vec<f64> = world
        .0
        .log
        .iter()
        .filter(|l| matches!(l.request, protocol::Request::GetSensors))
        .map(|l| l.clock.0 as f64 / 1000.0)
        .collect();
    assert_eq!(seen, reads, "the world's clock at each GET_SENSORS");
    assert_eq!(seen, [2.0, 2.004, 2.008]);
    assert_eq!(world.0.clock(), Millis(2012));
}

#[test]
fn without_a_heading_the_race_controller_is_appendix_c_bit_for_bit() {
    let m = Motion::new(PositionSource::Gps, 2000.0, FlowFilterParams::default());
    for yaw in [FRAC_PI_2, 1.5, 0.0, -3.0] {
        assert_eq!(m.steer(0.25, -0.5, yaw), (0.25, -0.5, 0.0));
    }
}

#[test]
fn with_a_heading_the_world_demand_is_rotated_by_the_yaw() {
    let mut m = Motion::new(PositionSource::Gps, 2000.0, FlowFilterParams::default());
    // At yaw +π/2 with the heading held: Appendix C's mapping.
    m.heading = Some(FRAC_PI_2);
    let (vx, vy, r) = m.steer(0.25, -0.5, FRAC_PI_2);
    assert!((vx - 0.25).abs() < 1e-15 && (vy + 0.5).abs() < 1e-15 && r == 0.0);
    // Facing +x (yaw 0): a target ahead in +x (x error < 0 → Appendix C's
    // sideways −0.5) is straight ahead in the body frame.
    m.heading = Some(0.0);
    let (vx, vy, r) = m.steer(0.0, -0.5, 0.0);
    assert!((vx - 0.5).abs() < 1e-15 && vy.abs() < 1e-15 && r == 0.0);
    // Facing +y, heading 0: turn clockwise at the clamped rate.
    assert_eq!(m.steer(0.0, 0.0, FRAC_PI_2).2, -MAX_YAW_RATE);
    // A small error: proportional, across the ±π seam.
    m.heading = Some(3.1);
    let r = m.steer(0.0, 0.0, -3.1).2;
    let expected = K_HEADING * (2.0 * std::f64::consts::PI - 6.2);
    assert!((r + expected).abs() < 1e-12, "{r} vs {}", -expected);
}

#[test]
fn ranges_in_metres_negative_out_of_range_and_flow_dead_reckoning() {
    // σ = 0: the flow filter's gain is 1, the estimate is the raw flow
    // (estimator.rs has the filter's own closed-form tests).
    let raw = FlowFilterParams {
        flow_std: super::super::estimator::MetresPerSecond(0.0),
        ..FlowFilterParams::default()
    };
    let mut m = Motion::new(PositionSource::Flow, 2000.0, raw);
    m.init(
        2.0,
        [1.0, 2.0, 0.015],
        protocol::TimestepMs::new(32).unwrap(),
    );
    let mut s = Sensors {
        time_s: 2.5,
        x: 9.0,
        y: 9.0,
        z: 1.0,
        yaw: FRAC_PI_2,
        range_front: 1234.0,
        range_back: 2000.0,
        range_left: 0.0,
        range_right: f64::NAN,
        range_up: None,
        range_down: Some(500.0),
        flow_vx: Some(0.4),
        flow_vy: Some(0.0),
        ..Sensors::default()
    };
    m.update(&mut s).unwrap();
    // Facing +y, 0.4 m/s forward for 0.5 s: +0.2 m in world y.
    assert!(
        (s.x - 1.0).abs() < 1e-12 && (s.y - 2.2).abs() < 1e-12,
        "{s:?}"
    );
    assert_eq!(m.position()[..2], [s.x, s.y]);
    assert!((m.est[5] - 0.4).abs() < 1e-12, "world vy {}", m.est[5]);
    assert_eq!(m.est[7..13], [1.234, -1.0, 0.0, -1.0, -1.0, 0.5]);
    assert_eq!(m.est[13..15], [0.4, 0.0]);
    // Without flow in flow mode: a clear error.
    s.flow_vx = None;
    assert!(m.update(&mut s).unwrap_err().contains("FLOW_VX"));
    // GPS mode: positions as the world says.
    let mut g = Motion::new(PositionSource::Gps, 2000.0, FlowFilterParams::default());
    g.init(
        2.0,
        [1.0, 2.0, 0.015],
        protocol::TimestepMs::new(32).unwrap(),
    );
    let mut s2 = Sensors {
        time_s: 2.5,
        x: 1.5,
        y: 2.0,
        z: 0.015,
        ..Sensors::default()
    };
    g.update(&mut s2).unwrap();
    assert_eq!((s2.x, g.est[4], g.est[13]), (1.5, 1.0, 0.0));
}

#[test]
fn angles_wrap_into_minus_pi_to_pi() {
    use std::f64::consts::PI;
    assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
    assert!((wrap_angle(-3.0 * PI / 2.0) - PI / 2.0).abs() < 1e-12);
    assert_eq!(wrap_angle(0.5), 0.5);
}
