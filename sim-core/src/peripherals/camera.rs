//! The AI deck's HM01B0 camera as the thesis models it (§4.2.1, Table 4.1):
//! a control register (write 1 = GET_IMAGE), a status register (1 = image
//! ready) and 102,400 image registers holding the 320×320 grey frame.
//!
//! A GET_IMAGE asks the world for a frame at once (a blocking exchange, as
//! the thesis's `get_camera_image`), copies it into the image registers and
//! shows status 1 after the capture time (16 ms: the sensor's 60 FPS limit,
//! §4.2.1). The capture starts a PID iteration: `iter_delay` = 16 ms
//! (§4.2.4 "Adapting the simulation to the use-case scenario").
//!
//! Over a socket without a trace the reply is decoded later
//! ([`super::WorldLink::call_deferred`]): by the link once the next
//! GET_IMAGE is sent (before its reply is read), so the ~380 KB of JSON
//! are parsed while the world renders the next frame instead of the world
//! waiting for the parse. The pixels enter the image registers when these
//! are read, at the next capture, or at the end of the session. A bad image
//! still ends the run with the same error, but there, after one more
//! exchange with the world (docs/COSIM.md "Performance").

use protocol::{Reply, Request};

use super::{DeferredReply, DeviceCtx, DeviceError, DevicePower, TimedReg};
use crate::units::{Millis, Picos};

pub const WIDTH: u32 = 320;
pub const HEIGHT: u32 = 320;
/// Register offsets within the camera (Table 4.1).
pub const CTRL: u32 = 0;
pub const STATUS: u32 = 1;
pub const IMAGE: u32 = 2;
/// Size of the camera's register memory: control, status and the image.
pub const REGISTER_MEMORY: u32 = IMAGE + WIDTH * HEIGHT;
/// Camera command.
pub const GET_IMAGE: u8 = 1;

pub struct Camera {
    control: u8,
    status: TimedReg,
    image: Vec<u8>,
    capture: Millis,
    pub power: DevicePower,
    /// Frames served so far.
    pub frames: u64,
    /// The last GET_IMAGE's reply, if not yet in the image registers.
    pending: Option<DeferredReply>,
}

impl Camera {
    pub fn new(capture: Millis, power: DevicePower) -> Self {
        Camera {
            control: 0,
            status: TimedReg::default(),
            image: vec![0; (WIDTH * HEIGHT) as usize],
            capture,
            power,
            frames: 0,
            pending: None,
        }
    }

    /// The last frame in the image registers.
    pub fn image(&mut self) -> Result<&[u8], DeviceError> {
        self.join()?;
        Ok(&self.image)
    }

    pub fn read(&mut self, offset: u32, now: Picos) -> Result<u8, DeviceError> {
        Ok(match offset {
            CTRL => self.control,
            STATUS => self.status.get(now),
            _ => {
                self.join()?;
                self.image[(offset - IMAGE) as usize]
            }
        })
    }

    /// Puts the last GET_IMAGE's pixels into the image registers, once
    /// decoded, or reports why they cannot be.
    pub fn join(&mut self) -> Result<(), DeviceError> {
        let Some(pending) = self.pending.take() else {
            return Ok(());
        };
        let world_err = |source| DeviceError::World {
            device: "camera",
            error: source,
        };
        let reply = pending.wait().map_err(world_err)?;
        let Reply::Image(frame) = reply else {
            return Err(world_err(super::LinkError::Unexpected {
                request: "GET_IMAGE",
                reply: reply.command(),
            }));
        };
        if frame.width != WIDTH || frame.height != HEIGHT || frame.data.len() != self.image.len() {
            return Err(DeviceError::Invalid {
                device: "camera",
                message: format!(
                    "the world sent a {}x{} image with {} bytes; the image registers hold {WIDTH}x{HEIGHT}",
                    frame.width,
                    frame.height,
                    frame.data.len()
                ),
            });
        }
        // The decoded frame becomes the image registers (no copy).
        self.image = frame.data;
        Ok(())
    }

    pub fn stable_until(&self, offset: u32, now: Picos) -> Picos {
        match offset {
            STATUS => self.status.stable_until(now),
            // Control and image registers change only when the core writes
            // them or a capture runs (which happens at a write).
            _ => Picos::MAX,
        }
    }

    pub fn write(
        &mut self,
        offset: u32,
        value: u8,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        self.power.written(now);
        match offset {
            CTRL => {
                self.control = value;
                match value {
                    0 => Ok(()),
                    GET_IMAGE => self.capture(now, ctx),
                    other => Err(DeviceError::UnknownCommand {
                        device: "camera",
                        value: other,
                    }),
                }
            }
            STATUS => {
                self.status.write(now, value);
                Ok(())
            }
            _ => {
                self.image[(offset - IMAGE) as usize] = value;
                Ok(())
            }
        }
    }

    fn capture(&mut self, now: Picos, ctx: &mut DeviceCtx<'_>) -> Result<(), DeviceError> {
        let world_err = |source| DeviceError::World {
            device: "camera",
            error: source,
        };
        // The request first: the link decodes the previous frame while the
        // world renders this one. Then the previous frame's errors, which
        // come before this one's.
        let reply = ctx.world.call_deferred(&Request::GetImage, now);
        self.join()?;
        let reply = reply.map_err(world_err)?;
        let decoded = reply.is_ready();
        self.pending = Some(reply);
        self.frames += 1;
        if decoded {
            // An in-process world or a traced link decoded at once: the
            // errors at the capture, as before.
            self.join()?;
        }
        let done = now + self.capture.to_picos();
        self.status.set_at(done, GET_IMAGE);
        self.power.busy_reading(done);
        ctx.time.begin_iteration(self.capture, now);
        tracing::debug!(target: "cosim::camera", frame = self.frames, "image captured");
        Ok(())
    }
}
