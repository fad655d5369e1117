//! The functional bus and the peripheral window (MESSY's `functional_bus`,
//! thesis §3.2.2 and §4.2.1): the devices' register memories laid out one
//! after another from the window's base, as MESSY does, so the thesis's
//! offsets hold (Appendix D): camera at +0 (control, status, image
//! +2…+102401), STM32 at +102402 (control, status, target X/Y/Z at
//! +102404/+102412/+102420).
//!
//! [`Platform`] is what the ISS sees behind the window: it routes each byte
//! of an access to its device (little-endian, so a 32-bit store into the
//! target registers writes four consecutive bytes) and answers the
//! idle-skip question from the devices' scheduled status changes.

use crate::iss::{AccessSize, Mmio, MmioError};
use crate::peripherals::{camera, stm32, Camera, DeviceCtx, DeviceError, Motors, Stm32, WorldLink};
use crate::sync::TimeKeeper;
use crate::units::Picos;

/// Base address of the peripheral window (DESIGN.md §4).
pub const PERIPHERAL_BASE: u32 = 0x2000_0000;
/// Offset of the STM32 in the window: right after the camera.
pub const STM32_OFFSET: u32 = camera::REGISTER_MEMORY;
/// Size of the window.
pub const WINDOW_SIZE: u32 = STM32_OFFSET + stm32::REGISTER_MEMORY;

/// Which device an offset belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Target {
    Camera(u32),
    Stm32(u32),
}

fn route(offset: u32) -> Option<Target> {
    if offset < STM32_OFFSET {
        Some(Target::Camera(offset))
    } else if offset < WINDOW_SIZE {
        Some(Target::Stm32(offset - STM32_OFFSET))
    } else {
        None
    }
}

/// The devices, the world link and the time bookkeeping: everything behind
/// the peripheral window.
pub struct Platform<W: WorldLink> {
    pub camera: Camera,
    pub stm32: Stm32,
    pub motors: Motors,
    pub world: W,
    pub time: TimeKeeper,
    /// Set by the power network when the battery is under its low threshold.
    pub battery_low: bool,
    /// What the devices print (the console log).
    pub console: Vec<String>,
    /// The first device failure, kept whole for the final report (the ISS
    /// only carries its message).
    pub failure: Option<DeviceError>,
}

impl<W: WorldLink> Platform<W> {
    pub fn new(camera: Camera, stm32: Stm32, world: W, time: TimeKeeper) -> Self {
        Platform {
            camera,
            stm32,
            motors: Motors::default(),
            world,
            time,
            battery_low: false,
            console: Vec::new(),
            failure: None,
        }
    }

    /// Runs `f` on the devices with a [`DeviceCtx`] over the shared parts
    /// (world link, time keeper, motors, console).
    fn with_ctx<R>(
        &mut self,
        f: impl FnOnce(&mut Camera, &mut Stm32, &mut DeviceCtx<'_>) -> R,
    ) -> R {
        let mut console = std::mem::take(&mut self.console);
        let mut sink = |s: &str| console.push(s.to_string());
        let mut ctx = DeviceCtx {
            world: &mut self.world,
            time: &mut self.time,
            motors: &mut self.motors,
            battery_low: self.battery_low,
            console: &mut sink,
        };
        let result = f(&mut self.camera, &mut self.stm32, &mut ctx);
        self.console = console;
        result
    }

    /// Runs the devices' own activity that is due at `now`.
    pub fn handle_events(&mut self, now: Picos) -> Result<(), DeviceError> {
        self.with_ctx(|_, stm32, ctx| stm32.handle_event(now, ctx))
    }

    /// The earliest time a device acts on its own.
    pub fn next_event(&self) -> Option<Picos> {
        self.stm32.next_event()
    }

    fn write_byte(&mut self, offset: u32, value: u8, now: Picos) -> Result<(), DeviceError> {
        self.with_ctx(|camera, stm32, ctx| match route(offset) {
            Some(Target::Camera(o)) => camera.write(o, value, now, ctx),
            Some(Target::Stm32(o)) => stm32.write(o, value, now, ctx),
            None => unreachable!("checked by the caller"),
        })
    }

    fn read_byte(&self, offset: u32, now: Picos) -> u8 {
        match route(offset) {
            Some(Target::Camera(o)) => self.camera.read(o, now),
            Some(Target::Stm32(o)) => self.stm32.read(o, now),
            None => unreachable!("checked by the caller"),
        }
    }

    fn check(&self, addr: u32, size: AccessSize) -> Result<u32, MmioError> {
        let offset = addr.wrapping_sub(PERIPHERAL_BASE);
        let end = offset as u64 + size.bytes() as u64;
        if end > WINDOW_SIZE as u64 {
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

impl<W: WorldLink> Mmio for Platform<W> {
    fn read(&mut self, addr: u32, size: AccessSize, now: Picos) -> Result<u32, MmioError> {
        let offset = self.check(addr, size)?;
        let mut value = 0u32;
        for i in 0..size.bytes() {
            value |= (self.read_byte(offset + i, now) as u32) << (8 * i);
        }
        Ok(value)
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
                None => now,
            };
            until = until.min(t);
        }
        until
    }

    fn next_event(&self) -> Option<Picos> {
        Platform::next_event(self)
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
}
