//! RISC-V semihosting (the ARM semihosting calls, reached through the
//! `slli x0,x0,0x1f; ebreak; srai x0,x0,7` sequence), as far as picolibc's
//! `--oslib=semihost` and our firmware need it.
//!
//! The host side is deliberately closed: no host file is ever opened. The
//! console is a sink chosen by the platform; times are simulated, never the
//! wall clock (determinism).

use std::io::Write;

use crate::units::Picos;

use super::mem::Memory;

pub const SYS_OPEN: u32 = 0x01;
pub const SYS_CLOSE: u32 = 0x02;
pub const SYS_WRITEC: u32 = 0x03;
pub const SYS_WRITE0: u32 = 0x04;
pub const SYS_WRITE: u32 = 0x05;
pub const SYS_READ: u32 = 0x06;
pub const SYS_READC: u32 = 0x07;
pub const SYS_ISERROR: u32 = 0x08;
pub const SYS_ISTTY: u32 = 0x09;
pub const SYS_SEEK: u32 = 0x0a;
pub const SYS_FLEN: u32 = 0x0c;
pub const SYS_CLOCK: u32 = 0x10;
pub const SYS_TIME: u32 = 0x11;
pub const SYS_ERRNO: u32 = 0x13;
pub const SYS_GET_CMDLINE: u32 = 0x15;
pub const SYS_HEAPINFO: u32 = 0x16;
pub const SYS_EXIT: u32 = 0x18;
pub const SYS_EXIT_EXTENDED: u32 = 0x20;
pub const SYS_ELAPSED: u32 = 0x30;
pub const SYS_TICKFREQ: u32 = 0x31;

/// `ADP_Stopped_ApplicationExit`: the reason code of a normal exit.
pub const ADP_STOPPED_APPLICATION_EXIT: u32 = 0x20026;

/// The 32-bit words around the `ebreak` that make it a semihosting call.
pub const SEMIHOST_PRE: u32 = 0x01f0_1013; // slli x0, x0, 0x1f
pub const SEMIHOST_POST: u32 = 0x4070_5013; // srai x0, x0, 7

/// Contents of the ":semihosting-features" pseudo-file: magic "SHFB" and a
/// feature byte with SH_EXT_EXIT_EXTENDED (bit 0) and SH_EXT_STDOUT_STDERR
/// (bit 1), so picolibc reports exit codes through SYS_EXIT_EXTENDED.
const FEATURES: [u8; 5] = [b'S', b'H', b'F', b'B', 0x03];

const ENOENT: u32 = 2;
const EBADF: u32 = 9;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum HostFile {
    Stdin,
    Stdout,
    Features { pos: u32 },
}

/// What a semihosting call asks of the core.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Return this value in a0 and continue.
    Return(u32),
    /// Stop the program with this exit code.
    Exit(i32),
}

/// The host side of semihosting.
pub struct Semihost {
    console: Box<dyn Write + Send>,
    files: Vec<Option<HostFile>>,
    errno: u32,
}

impl std::fmt::Debug for Semihost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Semihost")
            .field("files", &self.files)
            .field("errno", &self.errno)
            .finish_non_exhaustive()
    }
}

/// Simulated time and clock, for the time-related calls.
#[derive(Debug, Clone, Copy)]
pub struct Clock {
    pub now: Picos,
    pub cycles: u64,
    pub hz: u64,
}

const MINUS_ONE: u32 = u32::MAX;

impl Semihost {
    pub fn new(console: Box<dyn Write + Send>) -> Semihost {
        Semihost {
            console,
            files: Vec::new(),
            errno: 0,
        }
    }

    pub fn set_console(&mut self, console: Box<dyn Write + Send>) {
        self.console = console;
    }

    pub fn flush(&mut self) -> std::io::Result<()> {
        self.console.flush()
    }

    fn open(&mut self, f: HostFile) -> u32 {
        // Handles start at 1: picolibc treats 0 as a valid handle but some
        // runtimes do not, so avoid it.
        self.files.push(Some(f));
        self.files.len() as u32
    }

    fn file(&mut self, handle: u32) -> Option<&mut HostFile> {
        self.files
            .get_mut((handle as usize).checked_sub(1)?)
            .and_then(|f| f.as_mut())
    }

    fn fail(&mut self, errno: u32) -> Outcome {
        self.errno = errno;
        Outcome::Return(MINUS_ONE)
    }

    /// Perform call `op` with parameter `arg` (a1). Guest memory that cannot
    /// be read makes the call fail with -1, never the simulator. Console
    /// write errors are returned to the caller.
    pub fn call(
        &mut self,
        op: u32,
        arg: u32,
        mem: &mut Memory,
        clock: Clock,
    ) -> std::io::Result<Outcome> {
        let word = |i: u32| mem.read_u32(arg.wrapping_add(4 * i));
        let out = match op {
            SYS_WRITEC => match mem.read_u32(arg & !3) {
                Some(w) => {
                    let b = (w >> (8 * (arg & 3))) as u8;
                    self.console.write_all(&[b])?;
                    Outcome::Return(0)
                }
                None => self.fail(EBADF),
            },
            SYS_WRITE0 => {
                let mut s = Vec::new();
                let mut a = arg;
                let mut b = [0u8; 1];
                while mem.read_bytes(a, &mut b).is_ok() && b[0] != 0 && s.len() < 1 << 20 {
                    s.push(b[0]);
                    a = a.wrapping_add(1);
                }
                self.console.write_all(&s)?;
                Outcome::Return(0)
            }
            SYS_OPEN => {
                let (Some(name), Some(mode), Some(len)) = (word(0), word(1), word(2)) else {
                    return Ok(self.fail(EBADF));
                };
                let mut buf = vec![0u8; len.min(4096) as usize];
                if mem.read_bytes(name, &mut buf).is_err() {
                    return Ok(self.fail(ENOENT));
                }
                match (&buf[..], mode) {
                    (b":tt", 0..=3) => Outcome::Return(self.open(HostFile::Stdin)),
                    (b":tt", _) => Outcome::Return(self.open(HostFile::Stdout)),
                    (b":semihosting-features", 0..=3) => {
                        Outcome::Return(self.open(HostFile::Features { pos: 0 }))
                    }
                    _ => self.fail(ENOENT),
                }
            }
            SYS_CLOSE => match word(0) {
                Some(h) if self.file(h).is_some() => {
                    self.files[h as usize - 1] = None;
                    Outcome::Return(0)
                }
                _ => self.fail(EBADF),
            },
            SYS_WRITE => {
                let (Some(h), Some(ptr), Some(len)) = (word(0), word(1), word(2)) else {
                    return Ok(self.fail(EBADF));
                };
                match self.file(h).copied() {
                    Some(HostFile::Stdout) => {
                        let mut buf = vec![0u8; len.min(1 << 20) as usize];
                        if mem.read_bytes(ptr, &mut buf).is_err() {
                            return Ok(Outcome::Return(len));
                        }
                        self.console.write_all(&buf)?;
                        // Returns the number of bytes NOT written.
                        Outcome::Return(len - buf.len() as u32)
                    }
                    Some(_) => Outcome::Return(len),
                    None => self.fail(EBADF),
                }
            }
            SYS_READ => {
                let (Some(h), Some(ptr), Some(len)) = (word(0), word(1), word(2)) else {
                    return Ok(self.fail(EBADF));
                };
                match self.file(h) {
                    // No input: end of file, "len bytes not read".
                    Some(HostFile::Stdin) | Some(HostFile::Stdout) => Outcome::Return(len),
                    Some(HostFile::Features { pos }) => {
                        let start = (*pos as usize).min(FEATURES.len());
                        let n = (len as usize).min(FEATURES.len() - start);
                        *pos += n as u32;
                        if mem.write_bytes(ptr, &FEATURES[start..start + n]).is_err() {
                            return Ok(self.fail(EBADF));
                        }
                        Outcome::Return(len - n as u32)
                    }
                    None => self.fail(EBADF),
                }
            }
            SYS_READC => Outcome::Return(MINUS_ONE),
            SYS_ISERROR => Outcome::Return(word(0).is_some_and(|s| (s as i32) < 0) as u32),
            SYS_ISTTY => match word(0).and_then(|h| self.file(h).copied()) {
                Some(HostFile::Stdin | HostFile::Stdout) => Outcome::Return(1),
                Some(_) => Outcome::Return(0),
                None => self.fail(EBADF),
            },
            SYS_SEEK => {
                let (Some(h), Some(to)) = (word(0), word(1)) else {
                    return Ok(self.fail(EBADF));
                };
                match self.file(h) {
                    Some(HostFile::Features { pos }) => {
                        *pos = to;
                        Outcome::Return(0)
                    }
                    Some(_) => Outcome::Return(0),
                    None => self.fail(EBADF),
                }
            }
            SYS_FLEN => match word(0).and_then(|h| self.file(h).copied()) {
                Some(HostFile::Features { .. }) => Outcome::Return(FEATURES.len() as u32),
                Some(_) => Outcome::Return(0),
                None => self.fail(EBADF),
            },
            // Centiseconds and seconds of *simulated* time since reset.
            SYS_CLOCK => Outcome::Return((clock.now.0 / (Picos::PER_MS * 10)) as u32),
            SYS_TIME => Outcome::Return((clock.now.0 / Picos::PER_S) as u32),
            SYS_ERRNO => Outcome::Return(self.errno),
            SYS_GET_CMDLINE => {
                // An empty command line.
                match word(0) {
                    Some(buf) if mem.write_bytes(buf, &[0]).is_ok() => {
                        let _ = mem.write_bytes(arg.wrapping_add(4), &0u32.to_le_bytes());
                        Outcome::Return(0)
                    }
                    _ => self.fail(EBADF),
                }
            }
            SYS_HEAPINFO => {
                // Zeros: "use the linker symbols" (picolibc does anyway).
                if let Some(block) = word(0) {
                    let _ = mem.write_bytes(block, &[0u8; 16]);
                }
                Outcome::Return(0)
            }
            SYS_ELAPSED => {
                let bytes = clock.cycles.to_le_bytes();
                if mem.write_bytes(arg, &bytes).is_err() {
                    return Ok(self.fail(EBADF));
                }
                Outcome::Return(0)
            }
            SYS_TICKFREQ => Outcome::Return(clock.hz as u32),
            // On RV32 the reason code is passed directly in a1; like QEMU,
            // a normal-exit reason gives status 0 and anything else 1.
            SYS_EXIT => Outcome::Exit(if arg == ADP_STOPPED_APPLICATION_EXIT {
                0
            } else {
                1
            }),
            SYS_EXIT_EXTENDED => match (word(0), word(1)) {
                (Some(ADP_STOPPED_APPLICATION_EXIT), Some(code)) => Outcome::Exit(code as i32),
                _ => Outcome::Exit(1),
            },
            other => {
                tracing::warn!(op = other, "unsupported semihosting call, returning -1");
                self.fail(EBADF)
            }
        };
        Ok(out)
    }
}
