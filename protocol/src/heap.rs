//! The lockstep's binaries keep the heap they freed.
//!
//! Every camera frame crosses a platform as a few 100 KB buffers (the
//! shared-memory read, the trace's copy for hashing, the camera's
//! registers), allocated and freed thousands of times a race. glibc hands
//! a freed block at the top of the heap back to the kernel once the free
//! space passes `M_TRIM_THRESHOLD` (128 KiB by default), so the next frame's
//! buffer page-faulted its 25 pages in again, zeroed by the kernel: page
//! faults, `brk` and their accounting were ~3 % of a translated nn-race's
//! platform samples and 0.2 s of system time (docs/COSIM.md
//! "Performance"). Keeping up to 256 MiB free instead, and serving large
//! blocks from the heap rather than from fresh `mmap`s, removes that churn;
//! memory stays at the run's peak, which is what a simulation uses anyway.
//! Changes only how fast a run goes, never what it computes.

/// Applies the settings above (glibc only; elsewhere nothing to do).
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        const KEEP: libc::c_int = 256 << 20;
        // SAFETY: `mallopt` only sets allocator parameters; called at start-up,
        // before the binaries spawn any thread.
        unsafe {
            libc::mallopt(libc::M_TRIM_THRESHOLD, KEEP);
            libc::mallopt(libc::M_MMAP_THRESHOLD, KEEP);
        }
    }
}
