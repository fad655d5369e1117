//! Framing: a 4-byte unsigned little-endian length N, then N bytes of body
//! (Appendix B: `length_buffer[i] = (json_length >> 8*i) & 0xFF`).
//!
//! Reading loops until N bytes arrived (short reads are normal on sockets);
//! a clean end of stream *between* frames is a close, an end of stream inside
//! a frame (header or body) is [`ProtocolError::Truncated`]. The length is
//! checked against a maximum before any buffer of that size is allocated.

use std::io::{self, Read};

use crate::error::{ProtocolError, Result};

/// Default maximum frame body: 64 MiB (a 320×320 array image is ~380 KB).
pub const DEFAULT_MAX_FRAME: usize = 64 << 20;

/// Length of the prefix.
pub const HEADER_LEN: usize = 4;

/// The length prefix for a body of `len` bytes.
pub fn header(len: usize) -> [u8; 4] {
    (len as u32).to_le_bytes()
}

/// The body length a header announces.
pub fn body_len(header: [u8; 4]) -> usize {
    u32::from_le_bytes(header) as usize
}

/// Appends a whole frame to `out`: reserves the 4-byte prefix, lets `body`
/// write the JSON, then fills the prefix in, so header and body leave in one
/// `write` (one syscall instead of the thesis's two).
pub fn write_frame(
    out: &mut Vec<u8>,
    max_frame: usize,
    body: impl FnOnce(&mut Vec<u8>),
) -> Result<()> {
    let start = out.len();
    out.extend_from_slice(&[0; HEADER_LEN]);
    body(out);
    let len = out.len() - start - HEADER_LEN;
    if len > max_frame || len > u32::MAX as usize {
        out.truncate(start);
        return Err(ProtocolError::FrameTooLarge {
            len: len as u64,
            max: max_frame.min(u32::MAX as usize),
        });
    }
    out[start..start + HEADER_LEN].copy_from_slice(&header(len));
    Ok(())
}

/// Reads one frame body into `buf` (replacing its contents). `Ok(false)` is a
/// clean end of stream before the first byte of a frame.
///
/// `r` should be buffered (the blocking transport reads through a
/// `BufReader`), so that a small frame costs one `read` syscall.
pub fn read_frame<R: Read + ?Sized>(
    r: &mut R,
    buf: &mut Vec<u8>,
    max_frame: usize,
) -> Result<bool> {
    let mut hdr = [0u8; HEADER_LEN];
    let got = read_full(r, &mut hdr)?;
    if got == 0 {
        return Ok(false);
    }
    if got < HEADER_LEN {
        return Err(ProtocolError::Truncated {
            expected: HEADER_LEN,
            got,
        });
    }
    let len = body_len(hdr);
    if len > max_frame {
        return Err(ProtocolError::FrameTooLarge {
            len: len as u64,
            max: max_frame,
        });
    }
    // Reuse the buffer: only growth is zero-filled.
    if buf.len() < len {
        buf.resize(len, 0);
    } else {
        buf.truncate(len);
    }
    let got = read_full(r, buf)?;
    if got < len {
        return Err(ProtocolError::Truncated { expected: len, got });
    }
    Ok(true)
}

/// Fills `buf` unless the stream ends first; returns how much was read.
fn read_full<R: Read + ?Sized>(r: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Socket buffer size asked for on both ends of a connection (bytes).
///
/// A camera frame in the thesis's array format is ~380 KB, more than a UNIX
/// socket's default send buffer (~208 KB on Linux): the sender would block
/// and be woken several times per frame. With buffers larger than a frame,
/// each frame is written in one go (measured: about 1 s less kernel time in
/// a 32 ms race). The kernel caps the value at `net.core.wmem_max`; a
/// refusal is harmless, so errors are ignored.
pub const SOCKET_BUFFER: usize = 4 << 20;

/// Asks for [`SOCKET_BUFFER`]-sized send and receive buffers on `fd`.
#[cfg(unix)]
pub fn enlarge_socket_buffers(fd: std::os::fd::RawFd) {
    let size = SOCKET_BUFFER as libc::c_int;
    for opt in [libc::SO_SNDBUF, libc::SO_RCVBUF] {
        // SAFETY: `fd` is an open socket owned by the caller for the whole
        // call, and the option value points at a live c_int of the size
        // given; setsockopt only reads it.
        unsafe {
            libc::setsockopt(
                fd,
                libc::SOL_SOCKET,
                opt,
                (&size as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            );
        }
    }
}
