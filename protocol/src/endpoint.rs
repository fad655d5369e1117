//! Endpoints `unix:PATH` (the default, as the thesis) and `tcp:HOST:PORT`,
//! and the UNIX-socket server setup both transports share.

use std::fmt;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::{FileTypeExt, MetadataExt, PermissionsExt};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::error::{ProtocolError, Result};

/// Where the world listens.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Endpoint {
    /// A UNIX stream socket at this path.
    Unix(PathBuf),
    /// `HOST:PORT` for TCP (kept as text: resolved at connect/bind time).
    Tcp(String),
}

impl FromStr for Endpoint {
    type Err = ProtocolError;
    /// `unix:PATH`, `tcp:HOST:PORT`, or a bare path (= unix).
    fn from_str(s: &str) -> Result<Self> {
        if let Some(p) = s.strip_prefix("unix:") {
            if p.is_empty() {
                return Err(ProtocolError::BadEndpoint(s.into()));
            }
            Ok(Endpoint::Unix(p.into()))
        } else if let Some(a) = s.strip_prefix("tcp:") {
            match a.rsplit_once(':') {
                Some((host, port)) if !host.is_empty() && port.parse::<u16>().is_ok() => {
                    Ok(Endpoint::Tcp(a.into()))
                }
                _ => Err(ProtocolError::BadEndpoint(s.into())),
            }
        } else if s.is_empty() || s.contains("://") {
            Err(ProtocolError::BadEndpoint(s.into()))
        } else {
            Ok(Endpoint::Unix(s.into()))
        }
    }
}

impl fmt::Display for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Endpoint::Unix(p) => write!(f, "unix:{}", p.display()),
            Endpoint::Tcp(a) => write!(f, "tcp:{a}"),
        }
    }
}

/// Binds a UNIX listener at `path` the way the thesis's controller does
/// (Listing 4.7: unlink, bind, listen(1)) with four safety additions:
/// - an existing socket file is removed only if nobody accepts on it (a
///   stale file left by a crashed server); if a live server answers, the
///   error says so instead of stealing its path;
/// - a path that exists but is not a socket is never removed;
/// - the socket is made mode 0600 *between* `bind` and `listen`, so no other
///   user can connect even for an instant (std's `UnixListener::bind` listens
///   immediately, hence the raw calls);
/// - `path` appears only once the socket listens: it is bound under a
///   private name beside `path` and published with `link(2)` (which, unlike
///   `rename(2)`, never replaces a file that appeared meanwhile). A client
///   that waits for the file and connects is never refused in the window
///   between `bind` and `listen` (a loaded CI machine hit it). When the
///   private name would not fit a socket address, `path` is bound directly.
///
/// `backlog`: the connections the kernel holds before they are accepted
/// (the thesis: 1; a world of N drones: N, so that a client may connect all
/// its drones without blocking, DESIGN.md §15).
pub(crate) fn bind_unix(path: &Path, backlog: u32) -> Result<(UnixListener, u64)> {
    remove_stale(path)?;
    let private = private_bind_path(path);
    if let Some(private) = &private {
        // Our pid is in the name: a socket file there was left by a
        // crashed process that had the same pid.
        if std::fs::symlink_metadata(private).is_ok_and(|m| m.file_type().is_socket()) {
            let _ = std::fs::remove_file(private);
        }
    }
    let bound = private.as_deref().unwrap_or(path);
    let fd = bind_listen(bound, path, backlog)?;
    if let Some(private) = &private {
        let published = std::fs::hard_link(private, path);
        let _ = std::fs::remove_file(private);
        if let Err(e) = published {
            let taken = e.kind() == io::ErrorKind::AlreadyExists;
            return Err(path_error(path, e, taken, "cannot publish socket"));
        }
    }
    let ino = std::fs::symlink_metadata(path)?.ino();
    Ok((UnixListener::from(fd), ino))
}

/// The error for a socket path that could not be taken: "in use" when
/// another socket holds it (`taken`), else `what` and the OS error.
fn path_error(path: &Path, e: io::Error, taken: bool, what: &str) -> ProtocolError {
    if taken {
        ProtocolError::AddrInUse {
            path: path.display().to_string(),
        }
    } else {
        ProtocolError::Io(io::Error::new(
            e.kind(),
            format!("{what} {}: {e}", path.display()),
        ))
    }
}

/// `DIR/.NAME.PID.bind` beside `path`, if it fits `sockaddr_un`.
fn private_bind_path(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?.to_string_lossy().into_owned();
    let private = path.with_file_name(format!(".{name}.{}.bind", std::process::id()));
    // SAFETY: only the size of a zeroed sockaddr_un's path field is read.
    let room = unsafe { std::mem::zeroed::<libc::sockaddr_un>() }
        .sun_path
        .len();
    (private.as_os_str().len() < room).then_some(private)
}

/// socket, bind at `bound`, chmod 0600, listen. Errors name `path`, the
/// address the caller asked for.
fn bind_listen(bound: &Path, path: &Path, backlog: u32) -> Result<OwnedFd> {
    let bytes = bound.as_os_str().as_bytes();
    // SAFETY: plain socket syscalls on a zeroed sockaddr_un whose path we
    // bound-check below; the fd is owned by `OwnedFd` from creation on, so it
    // is closed on every error path.
    unsafe {
        let mut addr: libc::sockaddr_un = std::mem::zeroed();
        if bytes.len() >= addr.sun_path.len() {
            return Err(ProtocolError::Io(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "socket path {} is longer than the {} bytes a UNIX socket address holds",
                    path.display(),
                    addr.sun_path.len() - 1
                ),
            )));
        }
        addr.sun_family = libc::AF_UNIX as libc::sa_family_t;
        for (d, s) in addr.sun_path.iter_mut().zip(bytes) {
            *d = *s as libc::c_char;
        }
        let fd = libc::socket(libc::AF_UNIX, libc::SOCK_STREAM | libc::SOCK_CLOEXEC, 0);
        if fd < 0 {
            return Err(io::Error::last_os_error().into());
        }
        let fd = OwnedFd::from_raw_fd(fd);
        let len = std::mem::size_of::<libc::sockaddr_un>() as libc::socklen_t;
        if libc::bind(
            fd.as_raw_fd(),
            &addr as *const _ as *const libc::sockaddr,
            len,
        ) != 0
        {
            let e = io::Error::last_os_error();
            let taken = e.kind() == io::ErrorKind::AddrInUse;
            return Err(path_error(path, e, taken, "cannot bind"));
        }
        if let Err(e) = std::fs::set_permissions(bound, std::fs::Permissions::from_mode(0o600)) {
            let _ = std::fs::remove_file(bound);
            return Err(e.into());
        }
        let backlog = libc::c_int::try_from(backlog.max(1)).unwrap_or(libc::c_int::MAX);
        if libc::listen(fd.as_raw_fd(), backlog) != 0 {
            let e = io::Error::last_os_error();
            let _ = std::fs::remove_file(bound);
            return Err(e.into());
        }
        Ok(fd)
    }
}

fn remove_stale(path: &Path) -> Result<()> {
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e.into()),
    };
    if !meta.file_type().is_socket() {
        return Err(ProtocolError::Io(io::Error::new(
            io::ErrorKind::AlreadyExists,
            format!(
                "{} exists and is not a socket; refusing to remove it",
                path.display()
            ),
        )));
    }
    match UnixStream::connect(path) {
        Ok(_) => Err(ProtocolError::AddrInUse {
            path: path.display().to_string(),
        }),
        Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => {
            tracing::info!(path = %path.display(), "removing stale socket file");
            std::fs::remove_file(path)?;
            Ok(())
        }
        Err(e) => Err(ProtocolError::Io(io::Error::new(
            e.kind(),
            format!("cannot probe existing socket {}: {e}", path.display()),
        ))),
    }
}

/// The error for a failed TCP bind, naming the endpoint.
pub(crate) fn tcp_bind_error(addr: &str, e: io::Error) -> ProtocolError {
    ProtocolError::Io(io::Error::new(
        e.kind(),
        format!("cannot bind tcp:{addr}: {e}"),
    ))
}

/// Removes the socket file a server bound, unless something else replaced it
/// since (compared by inode).
pub(crate) fn unlink_if_ours(path: &Path, ino: u64) {
    if let Ok(m) = std::fs::symlink_metadata(path) {
        if m.ino() == ino {
            let _ = std::fs::remove_file(path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_print() {
        let e: Endpoint = "unix:/tmp/w.sock".parse().unwrap();
        assert_eq!(e, Endpoint::Unix("/tmp/w.sock".into()));
        assert_eq!(e.to_string(), "unix:/tmp/w.sock");
        assert_eq!(
            "w.sock".parse::<Endpoint>().unwrap(),
            Endpoint::Unix("w.sock".into())
        );
        let t: Endpoint = "tcp:127.0.0.1:4000".parse().unwrap();
        assert_eq!(t, Endpoint::Tcp("127.0.0.1:4000".into()));
        assert_eq!(t.to_string(), "tcp:127.0.0.1:4000");
        assert_eq!(
            "tcp:[::1]:4000".parse::<Endpoint>().unwrap(),
            Endpoint::Tcp("[::1]:4000".into())
        );
        for bad in [
            "",
            "unix:",
            "tcp:",
            "tcp:host",
            "tcp::80",
            "tcp:h:99999",
            "http://x",
        ] {
            assert!(
                matches!(bad.parse::<Endpoint>(), Err(ProtocolError::BadEndpoint(_))),
                "{bad:?}"
            );
        }
    }

    /// A client that connects the moment the path exists is never refused:
    /// the path appears only once the socket listens (against the old
    /// bind-chmod-listen sequence this client was refused within the first
    /// 30 rounds in two runs of three on a 2-core host).
    #[test]
    fn the_path_appears_only_once_the_socket_listens() {
        use std::sync::atomic::{AtomicBool, Ordering};
        use std::sync::Arc;
        let dir = tempfile::tempdir().unwrap();
        for round in 0..300 {
            let path = dir.path().join(format!("w{round}.sock"));
            let stop = Arc::new(AtomicBool::new(false));
            let client = {
                let (path, stop) = (path.clone(), stop.clone());
                std::thread::spawn(move || loop {
                    match UnixStream::connect(&path) {
                        Ok(_) => return Ok(()),
                        Err(e) if e.kind() == io::ErrorKind::NotFound => {
                            if stop.load(Ordering::Relaxed) {
                                return Ok(());
                            }
                        }
                        Err(e) => return Err(e),
                    }
                })
            };
            let (listener, ino) = bind_unix(&path, 1).unwrap();
            stop.store(true, Ordering::Relaxed);
            let seen = client.join().unwrap();
            assert!(seen.is_ok(), "round {round}: {seen:?}");
            assert_eq!(std::fs::symlink_metadata(&path).unwrap().ino(), ino);
            // No private name left behind.
            let names: Vec<_> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name())
                .collect();
            assert_eq!(names.len(), 1, "{names:?}");
            drop(listener);
            unlink_if_ours(&path, ino);
        }
    }
}
