//! The lockstep's binaries ask the scheduler for short time slices.
//!
//! A paced flight at the firmware's 500 Hz (DESIGN.md §20) is a round trip
//! between sim-core and the world every 2 ms of world time: each process
//! wakes about a thousand times a second, does a few microseconds of work
//! and sleeps again. On a host whose cores are busy with other work, Linux's
//! EEVDF scheduler lets the running task finish its slice (3 ms by
//! default) before a woken one runs, so every wake-up could wait up to a
//! slice: with two CPU-bound processes on a 2-core host, a cflib flight at
//! pace 1 ran at 0.37-0.59 of the wall clock. A short requested slice
//! (`sched_setattr`'s `sched_runtime` for SCHED_OTHER, Linux 6.12+, no
//! privilege needed) gives the woken process an earlier deadline, so it
//! preempts at once: the same flight then kept 0.94 and more
//! (docs/notes/2026-12-07-flight-stack.md). Nothing else changes: the
//! process's policy and nice value are kept, and its fair share of CPU is
//! the same. Changes only how soon a run's steps run, never what they
//! compute. On an older kernel or another OS the request is ignored.

/// The slice asked for (ns): EEVDF's smallest, 0.1 ms.
pub const SLICE_NS: u64 = 100_000;

/// Asks for [`SLICE_NS`] for the calling thread (and the threads it
/// spawns after, which inherit it). Call at start-up, before spawning.
/// Returns whether the kernel took it.
pub fn request_short_slice() -> bool {
    #[cfg(target_os = "linux")]
    {
        // `struct sched_attr` (include/uapi/linux/sched/types.h), its
        // first version: the libc crate does not declare it.
        #[repr(C)]
        #[derive(Default)]
        struct SchedAttr {
            size: u32,
            policy: u32,
            flags: u64,
            nice: i32,
            priority: u32,
            runtime: u64,
            deadline: u64,
            period: u64,
        }
        let mut attr = SchedAttr::default();
        let size = std::mem::size_of::<SchedAttr>() as u32;
        // SAFETY: the kernel writes at most `size` bytes into `attr`, a
        // live, properly aligned `sched_attr` of that size.
        let got = unsafe {
            libc::syscall(
                libc::SYS_sched_getattr,
                0,
                &mut attr as *mut SchedAttr,
                size,
                0,
            )
        };
        // SCHED_OTHER only: a real-time or idle policy is someone's choice.
        if got != 0 || attr.policy != libc::SCHED_OTHER as u32 {
            return false;
        }
        attr.size = size;
        attr.runtime = SLICE_NS;
        // SAFETY: `attr` is a valid `sched_attr` of `size` bytes, read
        // from the kernel above with only the slice changed.
        let set =
            unsafe { libc::syscall(libc::SYS_sched_setattr, 0, &attr as *const SchedAttr, 0) };
        set == 0
    }
    #[cfg(not(target_os = "linux"))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_slice_is_kept_or_the_request_is_refused_cleanly() {
        // Either outcome is valid on some kernel; neither may panic, and a
        // taken request leaves the policy and nice value as they were.
        let before = unsafe { libc::getpriority(libc::PRIO_PROCESS, 0) };
        let _ = super::request_short_slice();
        assert_eq!(unsafe { libc::getpriority(libc::PRIO_PROCESS, 0) }, before);
    }
}
