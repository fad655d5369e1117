//! SIGINT and SIGTERM: no child of cosim outlives it (DESIGN.md §19).
//!
//! Every child (world-server, sim-core, a `--world-cmd` shell and what it
//! starts, cargo) is started by [`prepare`] in a process group of its own,
//! so that one signal reaches a shell's children too and a terminal's
//! Ctrl-C reaches cosim alone, which then stops the children in an order
//! that keeps their outputs:
//!
//! 1. at once, the children that lead ([`Role::First`]: the worlds, cargo,
//!    a platform whose world runs elsewhere) get the signal; a platform
//!    that loses its world writes its outputs and exits by itself;
//! 2. after [`FOLLOWER_GRACE`], the platforms still running get it too;
//! 3. after [`KILL_GRACE`] more, whatever is left is killed (SIGKILL).
//!
//! The supervising loops see their children end, the report is written from
//! what exists, and cosim exits with 128 + the signal's number. A second
//! signal kills every child at once and exits without the report.
//!
//! If cosim itself is killed (SIGKILL, which cannot be caught), the kernel
//! kills its direct children ([`prepare`]'s `PR_SET_PDEATHSIG`, Linux).

use std::io;
use std::process::Command;
use std::sync::atomic::{AtomicI32, Ordering};
use std::sync::Mutex;
use std::time::Duration;

/// How long the platforms get to end by themselves after their world was
/// signalled (they write their outputs on the broken link).
pub const FOLLOWER_GRACE: Duration = Duration::from_secs(3);
/// Then how long everything gets before SIGKILL.
pub const KILL_GRACE: Duration = Duration::from_secs(3);

/// When a child is signalled, relative to the others.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Signalled at once (a world, cargo, a lone platform).
    First,
    /// A platform of a world started by cosim: signalled only if it is
    /// still running [`FOLLOWER_GRACE`] after its world was.
    Follower,
}

/// The first signal received (0: none).
static REQUESTED: AtomicI32 = AtomicI32::new(0);
/// The process groups of the running children.
static CHILDREN: Mutex<Vec<(i32, Role)>> = Mutex::new(Vec::new());

/// The first SIGINT or SIGTERM received, if any.
pub fn requested() -> Option<i32> {
    match REQUESTED.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// `SIGINT`, `SIGTERM`, or the number.
pub fn name(sig: i32) -> String {
    match sig {
        libc::SIGINT => "SIGINT".into(),
        libc::SIGTERM => "SIGTERM".into(),
        s => format!("signal {s}"),
    }
}

/// The one-line error of a run stopped by a signal.
pub fn interrupted(sig: i32) -> String {
    format!("interrupted by {}: every process stopped", name(sig))
}

/// Starts the thread that receives SIGINT and SIGTERM (tokio's signal
/// support, already built for the world server: no signal handler of our
/// own). The handlers are in place when this returns.
pub fn install() -> io::Result<()> {
    use tokio::signal::unix::{signal, SignalKind};
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let (mut int, mut term) = {
        let _guard = rt.enter();
        (
            signal(SignalKind::interrupt())?,
            signal(SignalKind::terminate())?,
        )
    };
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            rt.block_on(async move {
                loop {
                    let sig = tokio::select! {
                        _ = int.recv() => libc::SIGINT,
                        _ = term.recv() => libc::SIGTERM,
                    };
                    if REQUESTED
                        .compare_exchange(0, sig, Ordering::SeqCst, Ordering::SeqCst)
                        .is_ok()
                    {
                        eprintln!(
                            "cosim: {} received: stopping the processes and writing the report (again to stop at once)",
                            name(sig)
                        );
                        tokio::spawn(stop_children(sig));
                    } else {
                        send_all(libc::SIGKILL, None);
                        eprintln!("cosim: {} received again: every process killed", name(sig));
                        std::process::exit(128 + sig);
                    }
                }
            })
        })?;
    Ok(())
}

/// Steps 1-3 of the module's order.
async fn stop_children(sig: i32) {
    send_all(sig, Some(Role::First));
    tokio::time::sleep(FOLLOWER_GRACE).await;
    send_all(sig, Some(Role::Follower));
    tokio::time::sleep(KILL_GRACE).await;
    send_all(libc::SIGKILL, None);
}

fn children() -> std::sync::MutexGuard<'static, Vec<(i32, Role)>> {
    CHILDREN.lock().unwrap_or_else(|e| e.into_inner())
}

fn send_all(sig: i32, role: Option<Role>) {
    for &(group, r) in children().iter() {
        if role.is_none_or(|want| want == r) {
            send(group, sig);
        }
    }
}

/// Sends `sig` to the process group `group` (a child started by
/// [`prepare`] leads its own group, whose id is its pid).
pub(crate) fn send(group: i32, sig: i32) {
    // SAFETY: kill(2) with a negative pid signals a process group; it has
    // no memory effects in this process.
    unsafe {
        libc::kill(-group, sig);
    }
}

/// Registers a child started with [`prepare`]: it is signalled with the
/// others; a child registered after a signal arrived gets it at once.
pub(crate) fn track(pid: u32, role: Role) {
    let group = pid as i32;
    let mut list = children();
    list.push((group, role));
    // Under the lock: either the signal thread sees this child in the list,
    // or this sees the signal.
    if let Some(sig) = requested() {
        send(group, sig);
    }
}

/// The child `pid` was reaped: never signal its (reusable) id again.
pub(crate) fn untrack(pid: u32) {
    let group = pid as i32;
    children().retain(|&(g, _)| g != group);
}

/// Makes `cmd` start its child in a process group of its own and, on
/// Linux, be killed by the kernel if cosim dies first (cosim killed with
/// SIGKILL gets no chance to stop it). Register the child with [`track`].
pub(crate) fn prepare(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    cmd.process_group(0);
    #[cfg(target_os = "linux")]
    {
        let parent = std::process::id() as libc::pid_t;
        // SAFETY: the closure runs in the child between fork and exec and
        // makes only async-signal-safe system calls (prctl, getppid).
        unsafe {
            cmd.pre_exec(move || {
                // The death signal follows the thread that forked: cosim's
                // supervising threads outlive their children (they reap
                // them), so it fires only when cosim itself is gone.
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) == -1 {
                    return Err(io::Error::last_os_error());
                }
                // cosim died before the prctl: nobody would ever stop us.
                if libc::getppid() != parent {
                    return Err(io::Error::other("cosim exited while starting this process"));
                }
                Ok(())
            });
        }
    }
}

/// Starts `cmd` (with [`prepare`]) and waits for it, forwarding SIGINT and
/// SIGTERM to it like to any child: for the commands cosim only waits for
/// (`cosim world`'s world-server, cargo).
pub fn run_to_end(cmd: &mut Command, role: Role) -> io::Result<std::process::ExitStatus> {
    prepare(cmd);
    let mut child = cmd.spawn()?;
    track(child.id(), role);
    let status = child.wait();
    untrack(child.id());
    status
}
