//! The STM32's exchanges that move the drone's clock (DESIGN.md §3, thesis
//! §4.2.4): INIT_PID through the platform's world session, the rounded
//! device delays sent as ADVANCE_TIME, the motors' SET_VELOCITY steps, STOP
//! at the end of the landing, and PRINT_SIMUL_TIME's report.

use protocol::Request;

use super::pid::MotorCommands;
use super::{invalid, session_err, world_err, Stm32, INIT_PID};
use crate::peripherals::{DeviceCtx, DeviceError};
use crate::units::{Millis, Picos};

impl Stm32 {
    /// INIT_PID: opens the world session if no radio has (GET_INIT_DATA and
    /// the start-up alignment), takes over the drone's clock, and starts the
    /// PID from the world's start pose.
    pub(super) fn init_pid(
        &mut self,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        let opened_here = !ctx.session.is_open();
        let init = ctx
            .session
            .open(now, ctx.world, ctx.time)
            .map_err(session_err)?;
        let timestep_ms = init.timestep.0;
        let ts = crate::sync::check_timestep(timestep_ms, ctx.time.mode())
            .map_err(|e| invalid(e.to_string()))?;
        if self.cfg.controller == super::Controller::Pid {
            super::cascade::check_timestep(timestep_ms).map_err(invalid)?;
        }
        ctx.session.hand_clock_to_stm32();
        self.timestep = init.timestep;
        let f = &mut self.flight;
        f.pid.reset();
        // A radio may have opened the session (and its ticker moved the
        // clock) before: the PID then starts from the drone's clock now.
        f.past_time = if opened_here {
            init.time_s
        } else {
            ctx.session.world_clock_s(ctx.time)
        };
        f.past_x = init.x;
        f.past_y = init.y;
        f.height_desired = init.z;
        f.target = [init.x, init.y, init.z];
        self.motion.init(f.past_time, [init.x, init.y, init.z], ts);
        self.initialised = true;
        // Done when the start-up alignment is (at once if it is over).
        let done = now.max(ctx.session.ready_at());
        self.power.busy_reading(done);
        self.complete(done, INIT_PID);
        tracing::info!(
            target: "cosim::stm32",
            timestep_ms,
            x = init.x,
            y = init.y,
            z = init.z,
            "PID initialised"
        );
        Ok(())
    }

    /// Sends a pending iteration delay (an ITER_ADVANCE not followed by a
    /// PID step) to the world before another kind of operation starts.
    pub(super) fn flush_iteration(
        &mut self,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        let pending = ctx.time.take_iteration();
        if pending.0 > 0 {
            let steps = ctx.time.iteration_steps(pending);
            self.send_advance(steps, now, ctx)?;
        }
        Ok(())
    }

    pub(super) fn advance_world(
        &mut self,
        d: Millis,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        let steps = ctx.time.delay(d, now);
        self.send_advance(steps, now, ctx)
    }

    fn send_advance(
        &mut self,
        steps: u64,
        now: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        if steps > 0 {
            let time = steps * self.timestep.0;
            ctx.world
                .send(&Request::AdvanceTime { time }, now)
                .map_err(world_err)?;
        }
        Ok(())
    }

    pub(super) fn drive(
        commands: MotorCommands,
        now: Picos,
        iter: Millis,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<(), DeviceError> {
        crate::peripherals::motors::drive_from_ctx(ctx, commands, iter, now).map_err(world_err)
    }

    /// End of a landing: STOP and the motors' stop time; returns when the
    /// landing command completes.
    pub(super) fn stop_world(
        &mut self,
        at: Picos,
        ctx: &mut DeviceCtx<'_>,
    ) -> Result<Picos, DeviceError> {
        let end = ctx
            .session
            .stop(at, ctx.world, ctx.time)
            .map_err(session_err)?;
        ctx.motors.stopped();
        Ok(end)
    }

    pub(super) fn print_simul_time(&mut self, now: Picos, ctx: &mut DeviceCtx<'_>) {
        let r = ctx.time.report(now);
        let mut text = format!(
            "\n[STM32] Platform time: {:.3} ms\n[STM32] Sensors offset: {:.3} ms, core overshoot (sim_off_accum): {:.6} ms\n[STM32] Estimated world time: {:.3} ms\n",
            r.platform_time.0 as f64 / Picos::PER_MS as f64,
            r.sensors_offset_ms,
            r.sim_off_accum_ms,
            r.world_time_estimate_ms
        );
        if let Some(stop) = ctx.session.stop_report() {
            let real = stop.time_s * 1000.0;
            let err = (r.world_time_estimate_ms - real) / real * 100.0;
            text.push_str(&format!(
                "[STM32] Real world time (STOP): {real:.3} ms, error: {err:.4} %\n"
            ));
        }
        (ctx.console)(&text);
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Stm32, Stm32Config, CTRL, INIT_PID, STATUS};
    use crate::peripherals::world_session::ClockOwner;
    use crate::peripherals::{DeviceCtx, DevicePower, Motors, SoloWorld, WorldSession};
    use crate::sync::{SyncMode, TimeKeeper};
    use crate::units::{Millis, Picos};

    #[test]
    fn init_pid_after_a_radio_opened_the_session_takes_the_clock_without_a_second_claim() {
        let mut world = SoloWorld::new([1.0, 2.0, 0.015], Millis(4));
        let mut session = WorldSession::new(None, protocol::ImageEncoding::Array);
        let mut time = TimeKeeper::new(SyncMode::Thesis);
        let mut motors = Motors::default();
        // A radio claimed the world at 1 ms; its ticker ran 3 ticks.
        session
            .open(Picos::from_ms(1), &mut world, &mut time)
            .unwrap();
        session.start_ticker();
        let p0 = Picos::from_ms(2001);
        session
            .tick(p0 + Picos::from_ms(12), &mut world, &mut time)
            .unwrap();
        assert_eq!(world.clock(), Millis(2012));
        let mut stm32 = Stm32::new(Stm32Config::default(), DevicePower::new(Picos::ZERO));
        let now = p0 + Picos::from_ms(13);
        let mut sink = |_: &str| {};
        let mut ctx = DeviceCtx {
            world: &mut world,
            session: &mut session,
            time: &mut time,
            motors: &mut motors,
            battery_low: false,
            console: &mut sink,
        };
        stm32.write(CTRL, INIT_PID, now, &mut ctx).unwrap();
        // Done at once (the alignment is long over), the ticker has stopped,
        // and the PID starts from the drone's clock, not from 2.0 s.
        assert_eq!(stm32.read(STATUS, now), INIT_PID);
        assert_eq!(session.clock_owner(), ClockOwner::Stm32);
        assert_eq!(session.next_event(), None);
        assert_eq!(stm32.flight.past_time, 2.012);
        assert_eq!(stm32.flight.past_x, 1.0);
        assert_eq!(world.requests("GET_INIT_DATA").len(), 1);
    }

    #[test]
    fn init_pid_during_the_alignment_completes_when_it_ends() {
        let mut world = SoloWorld::new([0.0, 0.0, 0.015], Millis(32));
        let mut session = WorldSession::new(None, protocol::ImageEncoding::Array);
        let mut time = TimeKeeper::new(SyncMode::Thesis);
        let mut motors = Motors::default();
        session.open(Picos::ZERO, &mut world, &mut time).unwrap();
        session.start_ticker();
        let mut stm32 = Stm32::new(Stm32Config::default(), DevicePower::new(Picos::ZERO));
        let mut sink = |_: &str| {};
        let mut ctx = DeviceCtx {
            world: &mut world,
            session: &mut session,
            time: &mut time,
            motors: &mut motors,
            battery_low: false,
            console: &mut sink,
        };
        stm32
            .write(CTRL, INIT_PID, Picos::from_ms(500), &mut ctx)
            .unwrap();
        assert_eq!(stm32.read(STATUS, Picos::from_ms(1999)), 0);
        assert_eq!(stm32.read(STATUS, Picos::from_ms(2000)), INIT_PID);
        assert_eq!(stm32.flight.past_time, 2.0);
    }
}
