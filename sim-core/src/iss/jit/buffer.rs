//! The executable code buffer: one fixed anonymous mapping, readable,
//! writable and executable, so code never moves (blocks jump to each other
//! and to the stubs at absolute addresses) and a full buffer is simply
//! emptied with the rest of the cache.

use std::io;

/// Bytes reserved for translated code. The kernel backs only the pages
/// written; at ~60 host bytes per guest instruction this holds ~500 k
/// instructions, more than the block cache keeps before it flushes.
pub(crate) const CODE_BYTES: usize = 32 << 20;

pub(crate) struct CodeBuffer {
    ptr: *mut u8,
    len: usize,
    used: usize,
}

// SAFETY: the buffer is plain memory owned by this value; the core that has
// the `CodeCache` holding it is the only user at any time.
unsafe impl Send for CodeBuffer {}

impl std::fmt::Debug for CodeBuffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "CodeBuffer({} of {} bytes)", self.used, self.len)
    }
}

impl CodeBuffer {
    pub fn new(len: usize) -> io::Result<CodeBuffer> {
        // SAFETY: an anonymous private mapping; no file, no aliasing.
        let ptr = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE | libc::PROT_EXEC,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        if ptr == libc::MAP_FAILED {
            return Err(io::Error::last_os_error());
        }
        Ok(CodeBuffer {
            ptr: ptr as *mut u8,
            len,
            used: 0,
        })
    }

    /// Host address where the next code lands.
    pub fn next_addr(&self) -> usize {
        self.ptr as usize + self.used
    }

    /// Whether `n` more bytes fit.
    pub fn fits(&self, n: usize) -> bool {
        self.used + n <= self.len
    }

    /// Append code assembled for [`CodeBuffer::next_addr`]; its address.
    pub fn push(&mut self, code: &[u8]) -> usize {
        assert!(self.fits(code.len()), "code buffer overflow");
        let at = self.next_addr();
        // SAFETY: `[used, used + len)` is inside the mapping (checked).
        unsafe { std::ptr::copy_nonoverlapping(code.as_ptr(), at as *mut u8, code.len()) };
        self.used += code.len();
        at
    }

    /// Point the rel32 field at host address `site` (a jump's, inside
    /// this buffer's code) at `target`.
    pub fn patch_rel32(&mut self, site: usize, target: usize) {
        let start = self.ptr as usize;
        assert!(
            site >= start && site + 4 <= start + self.used,
            "patch outside the code"
        );
        let rel = i32::try_from(target as i64 - (site + 4) as i64).expect("jump within the buffer");
        // SAFETY: inside the written part of the mapping (checked); no
        // translated code runs while the cache is being changed.
        unsafe { std::ptr::copy_nonoverlapping(rel.to_le_bytes().as_ptr(), site as *mut u8, 4) };
    }

    /// Forget everything after the first `keep` bytes.
    pub fn truncate(&mut self, keep: usize) {
        self.used = keep.min(self.used);
    }

    pub fn used(&self) -> usize {
        self.used
    }
}

impl Drop for CodeBuffer {
    fn drop(&mut self) {
        // SAFETY: the mapping made in `new`, unmapped once.
        unsafe {
            libc::munmap(self.ptr as *mut libc::c_void, self.len);
        }
    }
}
