//! The interface between the cores and the arbiter of a banked L1 memory
//! (DESIGN.md §12): the ISS times a core's L1 accesses through it
//! ([`MemTiming::l1_port`](super::MemTiming::l1_port)), the platform
//! implements it (the cluster's TCDM) and puts it
//! in [`Memory::l1_arbiter`](super::Memory::l1_arbiter).
//!
//! The contract is exact in cycles: an access by a port to an address at
//! a core cycle is granted at the first cycle from there on at which its
//! bank is free, and the difference is the access's stall. The block
//! translator grants inline (`iss/jit/emit/mem.rs`), without a call, in
//! the arbiter's own bookkeeping ([`BankArbiter::grant_window`]); its
//! shape is therefore part of the interface: one mask of [`BANKS`] bits
//! per cycle of a window of [`WINDOW`] cycles, at `cycle % WINDOW`, bit
//! `(addr >> 2) % BANKS` for a granted bank (word-interleaved banks).

use std::fmt;

/// Banks of the L1 (GAP8: 16, one 32-bit word per bank in turn).
pub const BANKS: usize = 16;
/// Cycles of the grant window ([`BankArbiter::grant_window`]).
pub const WINDOW: u64 = 4096;
const _: () = assert!(WINDOW.is_power_of_two() && BANKS <= 16);

/// Per-port counts of an arbiter (for `--stats` and the power model).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PortStats {
    pub accesses: u64,
    pub stall_cycles: u64,
}

/// The arbiter's bookkeeping as translated code uses it: [`WINDOW`]
/// grant masks (see the module docs) and one port's counts, to which the
/// core adds what translated code granted and stalled.
#[derive(Debug, Clone, Copy)]
pub struct GrantWindow {
    pub masks: *mut u16,
    pub port: *mut PortStats,
}

/// A banked L1's arbiter, shared by the cores of one [`Memory`](super::Memory).
pub trait BankArbiter: fmt::Debug + Send {
    /// An access by `port` to `addr` issued at core cycle `cycle`: the
    /// stall cycles until its bank grants it.
    fn access(&mut self, port: u8, addr: u32, cycle: u64) -> u64;

    /// `port`'s counts so far.
    fn port_stats(&self, port: u8) -> PortStats;

    /// For the translator's inline grant: the window's masks and `port`'s
    /// counts. Translated code does in the masks exactly what
    /// [`BankArbiter::access`] does; the pointers stay valid while the
    /// arbiter is not moved or dropped.
    fn grant_window(&mut self, port: u8) -> GrantWindow;

    /// No access will be issued below core cycle `floor` from now on (the
    /// platform's scheduler knows its slowest core): the window may reuse
    /// the cycles before it. Called between the cores' turns, never while
    /// one runs.
    fn retire(&mut self, floor: u64);
}
