//! The functional bus and the peripheral window (MESSY's `functional_bus`,
//! thesis §3.2.2 and §4.2.1): the devices' register memories laid out one
//! after another from the window's base, as MESSY does, so the thesis's
//! offsets hold (Appendix D): camera at +0 (control, status, image
//! +2…+102401), STM32 at +102402 (control, status, target X/Y/Z at
//! +102404/+102412/+102420).
//!
//! The radios (docs/SWARM.md §4.3) sit at fixed offsets after them, so a
//! later growth of the STM32's register file never moves them: the UWB radio
//! at +0x1A000, the P2P radio at +0x1A200. The bytes from the STM32's end
//! (+102428) to +0x1A000 are reserved for future STM32 registers, and those
//! between the two radios' register files are unused: any access to either
//! is an access fault, as past the window's end (so the thesis's
//! `bad_read` firmware still faults at +102428).
//!
//! [`Platform`] is what the ISS sees behind the window: it routes each byte
//! of an access to its device (little-endian, so a 32-bit store into the
//! target registers writes four consecutive bytes), answers the idle-skip
//! question from the devices' scheduled changes, and drives the core's
//! external interrupt line from the radios.

use protocol::{Reply, Request};

use crate::iss::{AccessSize, Mmio, MmioError};
use crate::peripherals::radio::{self, RadioDevice};
use crate::peripherals::world_session::SessionError;
use crate::peripherals::{
    camera, stm32, Camera, DeviceCtx, DeviceError, LinkError, Motors, Stm32, WorldLink,
    WorldSession,
};
use crate::sync::TimeKeeper;
use crate::units::Picos;

/// Base address of the peripheral window (DESIGN.md §4).
pub const PERIPHERAL_BASE: u32 = 0x2000_0000;
/// Offset of the STM32 in the window: right after the camera.
pub const STM32_OFFSET: u32 = camera::REGISTER_MEMORY;
/// End of the bytes reserved for the STM32's register file (0x19002 + 222
/// used today: the thesis's 26 and the extension, stm32/motion.rs).
pub const STM32_RESERVED_END: u32 = 0x1A000;
/// Offset of the UWB radio (DW1000).
pub const UWB_OFFSET: u32 = 0x1A000;
/// Offset of the P2P radio (nRF51).
pub const P2P_OFFSET: u32 = 0x1A200;
/// Size of the window.
pub const WINDOW_SIZE: u32 = P2P_OFFSET + radio::REGISTER_MEMORY;

/// Index of each radio in [`Platform::radios`].
pub const UWB: usize = 0;
pub const P2P: usize = 1;

/// Which device an offset belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Target {
    Camera(u32),
    Stm32(u32),
    Radio(usize, u32),
}

fn route(offset: u32) -> Option<Target> {
    let stm32_end = STM32_OFFSET + stm32::REGISTER_MEMORY;
    let in_radio = |base: u32| (base..base + radio::REGISTER_MEMORY).contains(&offset);
    if offset < STM32_OFFSET {
        Some(Target::Camera(offset))
    } else if offset < stm32_end {
        if !stm32::is_register(offset - STM32_OFFSET) {
            return None;
        }
        Some(Target::Stm32(offset - STM32_OFFSET))
    } else if in_radio(UWB_OFFSET) {
        Some(Target::Radio(UWB, offset - UWB_OFFSET))
    } else if in_radio(P2P_OFFSET) {
        Some(Target::Radio(P2P, offset - P2P_OFFSET))
    } else {
        None
    }
}

/// The devices, the world link and the time bookkeeping: everything behind
/// the peripheral window.
pub struct Platform<W: WorldLink> {
    pub camera: Camera,
    pub stm32: Stm32,
    /// The UWB ([`UWB`]) and P2P ([`P2P`]) radios.
    pub radios: [RadioDevice; 2],
    pub motors: Motors,
    pub world: W,
    /// GET_INIT_DATA once, who moves the drone's clock, STOP.
    pub session: WorldSession,
    pub time: TimeKeeper,
    /// Set by the power network when the battery is under its low threshold.
    pub battery_low: bool,
    /// What the devices print (the console log).
    pub console: Vec<String>,
    /// The first device failure, kept whole for the final report (the ISS
    /// only carries its message).
    pub failure: Option<DeviceError>,
    /// The level of the core's external interrupt line as the kernel last
    /// set it; a different [`Platform::irq_level`] asks the ISS to stop so
    /// the kernel can update it right after the access.
    pub irq_line: bool,
}

impl<W: WorldLink> Platform<W> {
    pub fn new(
        camera: Camera,
        stm32: Stm32,
        radios: [RadioDevice; 2],
        world: W,
        session: WorldSession,
        time: TimeKeeper,
    ) -> Self {
        Platform {
            camera,
            stm32,
            radios,
            motors: Motors::default(),
            world,
            session,
            time,
            battery_low: false,
            console: Vec::new(),
            failure: None,
            irq_line: false,
        }
    }

    /// Runs `f` on the devices with a [`DeviceCtx`] over the shared parts
    /// (world link, session, time keeper, motors, console). If the drone's
    /// clock moved meanwhile and a radio is on, the radios get what the
    /// world has for them (docs/SWARM.md §4.2).
    fn with_ctx<R>(
        &mut self,
        now: Picos,
        f: impl FnOnce(
            &mut Camera,
            &mut Stm32,
            &mut [RadioDevice; 2],
            &mut DeviceCtx<'_>,
        ) -> Result<R, DeviceError>,
    ) -> Result<R, DeviceError> {
        let clock_before = self.time.world_sent();
        let mut console = std::mem::take(&mut self.console);
        let mut sink = |s: &str| console.push(s.to_string());
        let mut ctx = DeviceCtx {
            world: &mut self.world,
            session: &mut self.session,
            time: &mut self.time,
            motors: &mut self.motors,
            battery_low: self.battery_low,
            console: &mut sink,
        };
        let result = f(
            &mut self.camera,
            &mut self.stm32,
            &mut self.radios,
            &mut ctx,
        );
        self.console = console;
        let result = result?;
        if self.time.world_sent() != clock_before {
            self.poll_radios(now)?;
        }
        Ok(result)
    }

    /// RADIO_RECV after an advance of the drone's clock, once a radio has
    /// been switched on: every reception and finished transmission up to the
    /// clock t_d, handed to its radio at the platform time it maps to.
    fn poll_radios(&mut self, now: Picos) -> Result<(), DeviceError> {
        if !self.radios.iter().any(RadioDevice::switched_on) || !self.session.is_live() {
            return Ok(());
        }
        let world_err = |error| DeviceError::World {
            device: "radio",
            error,
        };
        let reply = self
            .world
            .call(&Request::RadioRecv, now)
            .map_err(world_err)?;
        let Reply::RadioRecv { packets, tx_done } = reply else {
            return Err(world_err(LinkError::Unexpected {
                request: "RADIO_RECV",
                reply: reply.command(),
            }));
        };
        let t_d = self.session.world_clock(&self.time);
        let p_d = self.time.accounted_until();
        let index = |r: protocol::radio::Radio| match r {
            protocol::radio::Radio::Uwb => UWB,
            protocol::radio::Radio::P2p => P2P,
        };
        for p in packets {
            let ended = radio::platform_time_of(p.time_ps, t_d, p_d);
            self.radios[index(p.radio)].deliver_packet(now, ended, p)?;
        }
        for d in tx_done {
            let ended = radio::platform_time_of(d.time_ps, t_d, p_d);
            self.radios[index(d.radio)].deliver_tx_done(now, ended, d)?;
        }
        Ok(())
    }

    /// Runs the devices' own activity that is due at `now`: the STM32's
    /// loops, the ticker of a drone whose clock the platform moves
    /// (docs/SWARM.md §4.1), then the radios' deliveries.
    pub fn handle_events(&mut self, now: Picos) -> Result<(), DeviceError> {
        self.with_ctx(now, |_, stm32, _, ctx| stm32.handle_event(now, ctx))?;
        let clock_moved = self
            .session
            .tick(now, &mut self.world, &mut self.time)
            .map_err(|e| session_error("clock", e))?;
        if clock_moved {
            self.poll_radios(now)?;
        }
        for r in &mut self.radios {
            r.apply_due(now);
        }
        Ok(())
    }

    /// The earliest time a device acts on its own.
    pub fn next_event(&self) -> Option<Picos> {
        [
            self.stm32.next_event(),
            self.session.next_event(),
            self.radios[UWB].next_event(),
            self.radios[P2P].next_event(),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// The core's external interrupt: the OR of `STATUS & IRQ_MASK` of both
    /// radios.
    pub fn irq_level(&self) -> bool {
        self.radios.iter().any(RadioDevice::irq)
    }

    /// Settles the clocks at a cut-off that falls at platform time `now`,
    /// which may be inside a device delay (the battery's cut-off falls on a
    /// 1 ms sample): the iteration delays counted but not yet sent to the
    /// world (a camera capture, an ITER_ADVANCE before the PID step) are
    /// sent now, rounded as the PID step would have sent them, as the
    /// firmware's PRINT_SIMUL_TIME does before its end. Returns the
    /// platform time at which the two clocks then agree: the end of the
    /// delays counted, at least `now`.
    pub fn settle(&mut self, now: Picos) -> Result<Picos, DeviceError> {
        let pending = self.time.take_iteration();
        if pending.0 > 0 && self.session.is_live() {
            let steps = self.time.iteration_steps(pending);
            if steps > 0 {
                let time = steps * self.time.timestep().0;
                self.world
                    .send(&Request::AdvanceTime { time }, now)
                    .map_err(|error| DeviceError::World {
                        device: "platform",
                        error,
                    })?;
            }
        }
        Ok(now.max(self.time.accounted_until()))
    }

    /// The firmware has ended (docs/SWARM.md §4.1): if the world session is
    /// open and no STOP was sent, send it now so the world can go on without
    /// this drone. Returns the platform time at the end of the motors' stop
    /// (the world's STOP_TIME is spent by both sides, as at GO_DOWN).
    pub fn end_session(&mut self, now: Picos) -> Result<Option<Picos>, DeviceError> {
        // The last frame's pixels, decoded or refused, before the end.
        self.camera.join()?;
        if !self.session.is_live() {
            return Ok(None);
        }
        let end = self
            .session
            .stop(now, &mut self.world, &mut self.time)
            .map_err(|e| session_error("platform", e))?;
        self.motors.stopped();
        Ok(Some(end))
    }

    fn write_byte(&mut self, offset: u32, value: u8, now: Picos) -> Result<(), DeviceError> {
        let target = route(offset).expect("checked by the caller");
        self.with_ctx(now, |camera, stm32, radios, ctx| match target {
            Target::Camera(o) => camera.write(o, value, now, ctx),
            Target::Stm32(o) => stm32.write(o, value, now, ctx),
            Target::Radio(i, o) => radios[i].write(o, value, now, ctx),
        })
    }

    fn read_byte(&mut self, offset: u32, now: Picos) -> Result<u8, DeviceError> {
        Ok(match route(offset).expect("checked by the caller") {
            Target::Camera(o) => self.camera.read(o, now)?,
            Target::Stm32(o) => self.stm32.read(o, now),
            Target::Radio(i, o) => self.radios[i].read(o, now),
        })
    }

    /// The window offset of an access, if every byte of it is a register.
    fn check(&self, addr: u32, size: AccessSize) -> Result<u32, MmioError> {
        let offset = addr.wrapping_sub(PERIPHERAL_BASE);
        let end = offset as u64 + size.bytes() as u64;
        if end > WINDOW_SIZE as u64 || (0..size.bytes()).any(|i| route(offset + i).is_none()) {
            return Err(MmioError::AccessFault { addr });
        }
        Ok(offset)
    }

    fn fail(&mut self, addr: u32, e: DeviceError) -> MmioError {
        let message = e.to_string();
        self.failure.get_or_insert(e);
        MmioError::Device { addr, message }
    }
}

fn session_error(device: &'static str, e: SessionError) -> DeviceError {
    match e {
        SessionError::World(error) => DeviceError::World { device, error },
        SessionError::Invalid(message) => DeviceError::Invalid { device, message },
    }
}

impl<W: WorldLink> Mmio for Platform<W> {
    fn read(&mut self, addr: u32, size: AccessSize, now: Picos) -> Result<u32, MmioError> {
        // The image registers, whole accesses at once: the same bytes as the
        // byte-by-byte path below (reads have no side effects there but the
        // join of a pending frame), without routing each byte. A vision
        // firmware copies a frame as 25,600 word reads (docs/VISION.md).
        let offset = addr.wrapping_sub(PERIPHERAL_BASE);
        let n = size.bytes();
        if offset >= camera::IMAGE && offset + n <= camera::REGISTER_MEMORY {
            let at = (offset - camera::IMAGE) as usize;
            return match self.camera.image() {
                Ok(image) => Ok(image[at..at + n as usize]
                    .iter()
                    .rev()
                    .fold(0, |v, &b| (v << 8) | u32::from(b))),
                Err(e) => Err(self.fail(addr, e)),
            };
        }
        let offset = self.check(addr, size)?;
        let mut value = 0u32;
        for i in 0..size.bytes() {
            match self.read_byte(offset + i, now) {
                Ok(b) => value |= (b as u32) << (8 * i),
                Err(e) => return Err(self.fail(addr, e)),
            }
        }
        Ok(value)
    }

    fn plain_window(&mut self) -> Option<(u32, &[u8])> {
        // The camera's image registers: they change only at a capture or a
        // store into them, both writes (`Camera::write`). A frame that
        // cannot be joined (a bad image) is left to `read`, which reports it.
        let base = PERIPHERAL_BASE + camera::IMAGE;
        self.camera.image().ok().map(|image| (base, image))
    }

    fn write(
        &mut self,
        addr: u32,
        size: AccessSize,
        value: u32,
        now: Picos,
    ) -> Result<(), MmioError> {
        let offset = self.check(addr, size)?;
        for i in 0..size.bytes() {
            let byte = (value >> (8 * i)) as u8;
            if let Err(e) = self.write_byte(offset + i, byte, now) {
                return Err(self.fail(addr, e));
            }
        }
        Ok(())
    }

    fn stable_until(&self, addr: u32, size: AccessSize, now: Picos) -> Picos {
        let Ok(offset) = self.check(addr, size) else {
            return now;
        };
        let mut until = Picos::MAX;
        for i in 0..size.bytes() {
            let t = match route(offset + i) {
                Some(Target::Camera(o)) => self.camera.stable_until(o, now),
                Some(Target::Stm32(o)) => self.stm32.stable_until(o, now),
                Some(Target::Radio(r, o)) => self.radios[r].stable_until(o, now),
                None => now,
            };
            until = until.min(t);
        }
        until
    }

    fn next_event(&self) -> Option<Picos> {
        Platform::next_event(self)
    }

    fn take_stop_request(&mut self) -> bool {
        self.irq_level() != self.irq_line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_offsets_hold() {
        // Appendix D: STM32 control at +102402, status +102403, targets at
        // +102404, +102412, +102420.
        assert_eq!(STM32_OFFSET, 102_402);
        assert_eq!(route(102_403), Some(Target::Stm32(stm32::STATUS)));
        assert_eq!(route(102_404), Some(Target::Stm32(stm32::TARGET_X)));
        assert_eq!(route(102_412), Some(Target::Stm32(stm32::TARGET_Y)));
        assert_eq!(route(102_420), Some(Target::Stm32(stm32::TARGET_Z)));
        assert_eq!(route(102_428), None);
        assert_eq!(route(1), Some(Target::Camera(camera::STATUS)));
    }

    #[test]
    fn radios_sit_at_fixed_offsets_after_the_reserved_stm32_bytes() {
        // docs/SWARM.md §4.3: 0x2001A000 and 0x2001A200.
        assert_eq!(PERIPHERAL_BASE + UWB_OFFSET, 0x2001_A000);
        assert_eq!(PERIPHERAL_BASE + P2P_OFFSET, 0x2001_A200);
        assert_eq!(STM32_RESERVED_END, UWB_OFFSET);
        assert_eq!(route(0x1A000), Some(Target::Radio(UWB, radio::CTRL)));
        assert_eq!(route(0x1A001), Some(Target::Radio(UWB, radio::STATUS)));
        assert_eq!(route(0x1A13F), Some(Target::Radio(UWB, 0x13F)));
        assert_eq!(route(0x1A140), None);
        assert_eq!(route(0x1A1FF), None);
        assert_eq!(route(0x1A220), Some(Target::Radio(P2P, radio::EUI)));
        assert_eq!(route(WINDOW_SIZE - 1), Some(Target::Radio(P2P, 0x13F)));
        assert_eq!(route(WINDOW_SIZE), None);
        // Every byte reserved for the STM32 faults: the gap before its
        // extension (cosim_regs.h, 102428-102431) and everything after it.
        assert!((102_428..102_432).all(|o| route(o).is_none()));
        assert_eq!(route(102_432), Some(Target::Stm32(stm32::motion::EXT_CTRL)));
        // The extension's last register (the radar's, docs/LAB.md).
        let last = stm32::motion::EXT_END - 1;
        assert_eq!(last, 245);
        assert_eq!(route(102_647), Some(Target::Stm32(last)));
        assert!((102_648..0x1A000).all(|o| route(o).is_none()));
    }
}
