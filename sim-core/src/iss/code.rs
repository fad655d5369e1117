//! The code cache: what the cores make of the bytes in RAM, kept apart
//! from the RAM itself (QEMU keeps its translation blocks apart from guest
//! memory in the same way; rv32emu keeps decode, emulate and JIT apart).
//!
//! - the decoded blocks (`block.rs`): [`Inst`]s, block after block, and
//!   per RAM region the index of the block starting at each halfword;
//! - the translated code of those blocks (`iss/jit`, x86-64 hosts), made
//!   on first use by a core running the translator.
//!
//! Whoever owns a [`Memory`] keeps one [`CodeCache`] beside it and hands
//! both to the cores ([`Cpu::run_until`](super::Cpu::run_until)); the
//! cluster's cores share the FC's, as they share its memory.
//!
//! # Coherence
//!
//! Memory marks the bytes every decoded instruction came from
//! (`Region::mark_code`). A write to a marked halfword (a store, a device
//! or the platform writing a buffer, [`Memory::write_bytes`]) drops the
//! marks and starts a new code epoch ([`Memory::invalidate_code`]); the
//! cache compares the epoch its blocks were decoded under with memory's
//! before every use (one comparison per block lookup) and empties itself,
//! translations included, when they differ. Self-modifying code is rare:
//! QEMU also drops whole translation caches for it. The core never stores
//! into decoded code from inside a block or a translation: such a store
//! leaves for the general path, after which the next block is looked up
//! again, so a block never runs stale instructions and `fence.i` is free.

use super::block::Inst;
use super::mem::Memory;

/// Where the blocks of one RAM region start.
#[derive(Debug, Default)]
pub(crate) struct Starts {
    /// Per halfword of the region: 1 + the index in [`CodeCache::insts`]
    /// of the first instruction of the block starting there; 0 means
    /// none. Empty until a block of the region is decoded, then allocated
    /// zeroed, so the OS only backs the pages that really hold code.
    pub(crate) at: Vec<u32>,
    /// Halfword indices `[lo, hi)` holding every non-zero entry, so that
    /// emptying the cache writes only there (writing a never-touched zero
    /// page would commit it).
    lo: usize,
    hi: usize,
}

impl Starts {
    /// Record that the block at halfword `h` starts at `insts[first]`.
    pub(crate) fn set(&mut self, h: usize, first: usize) {
        self.at[h] = first as u32 + 1;
        self.lo = self.lo.min(h);
        self.hi = self.hi.max(h + 1);
    }

    fn clear(&mut self) {
        if self.lo < self.hi {
            for slot in &mut self.at[self.lo..self.hi] {
                if *slot != 0 {
                    *slot = 0;
                }
            }
        }
        self.lo = usize::MAX;
        self.hi = 0;
    }
}

/// The decoded blocks of a [`CodeCache`], borrowed apart from its
/// translations (the translator reads them while it adds to those).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Blocks<'a> {
    pub insts: &'a [Inst],
    pub starts: &'a [Starts],
}

/// The decoded blocks and translated code of one [`Memory`] (see the
/// module documentation).
#[derive(Debug, Default)]
pub struct CodeCache {
    /// The memory's code epoch these blocks were decoded under (0: none
    /// yet; memory's are never 0).
    epoch: u64,
    /// The cached blocks' instructions, block after block (`block.rs`).
    pub(crate) insts: Vec<Inst>,
    /// Per RAM region, in memory's order: where its blocks start.
    pub(crate) starts: Vec<Starts>,
    /// Translated code of the cached blocks (`iss/jit`), made on first use
    /// by a core running the translator.
    #[cfg(target_arch = "x86_64")]
    pub(crate) jit: Option<Box<super::jit::JitCache>>,
}

impl CodeCache {
    pub fn new() -> CodeCache {
        CodeCache::default()
    }

    /// Empty the cache if `mem`'s code changed (or `mem` is not the
    /// memory it was filled from) since it was filled.
    #[inline(always)]
    pub(crate) fn sync(&mut self, mem: &Memory) {
        if self.epoch != mem.code_epoch {
            self.reset(mem);
        }
    }

    /// Drop every block and translation, and fit the tables to `mem`.
    #[cold]
    fn reset(&mut self, mem: &Memory) {
        self.starts.truncate(mem.regions.len());
        for (s, r) in self.starts.iter_mut().zip(&mem.regions) {
            if s.at.len() == r.size as usize / 2 {
                s.clear();
            } else {
                *s = Starts::default();
            }
        }
        self.insts.clear();
        #[cfg(target_arch = "x86_64")]
        if let Some(j) = &mut self.jit {
            j.flush();
        }
        self.epoch = mem.code_epoch;
    }

    /// Drop every block (the cache is full): memory forgets the code
    /// marks too, as it does when code is overwritten.
    pub(crate) fn flush(&mut self, mem: &mut Memory) {
        mem.invalidate_code();
        self.reset(mem);
    }

    /// The start table of region `idx`, allocated for `mem` if needed.
    pub(crate) fn starts_of(&mut self, mem: &Memory, idx: usize) -> &mut Starts {
        if self.starts.len() <= idx {
            self.starts
                .resize_with(mem.regions.len().max(idx + 1), Starts::default);
        }
        let s = &mut self.starts[idx];
        if s.at.is_empty() {
            s.at = vec![0; mem.regions[idx].size as usize / 2];
            s.lo = usize::MAX;
            s.hi = 0;
        }
        s
    }

    /// 1 + the index of the first instruction of the block starting at
    /// byte `off` of region `idx`; 0 if none is cached.
    #[inline(always)]
    pub(crate) fn start(&self, idx: usize, off: usize) -> u32 {
        self.starts
            .get(idx)
            .and_then(|s| s.at.get(off >> 1))
            .copied()
            .unwrap_or(0)
    }

    /// The block translator's counters, if a core used it on this cache.
    #[cfg(target_arch = "x86_64")]
    pub fn jit_stats(&self) -> Option<super::jit::JitStats> {
        self.jit.as_ref().map(|j| j.stats())
    }
}
