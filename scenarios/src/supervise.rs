//! The processes of a run, supervised: each one's output forwarded line by
//! line into `cosim.log` (and, selected, onto the terminal, above the
//! progress bars of several drones), its end polled, and its stop: killed
//! with its process group, never left behind (crate::signals).

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::signals::Role;

/// Why a run could not be carried out.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    #[error("{what} not found at {path} ({hint})")]
    MissingBinary {
        what: &'static str,
        path: PathBuf,
        hint: String,
    },
    #[error("cannot start {what} ({path}): {source}")]
    Spawn {
        what: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{0}")]
    Io(String),
    #[error("`cargo build` of sim-core and world-server failed ({0})")]
    Build(String),
}

pub(crate) fn io_err(what: impl std::fmt::Display, e: std::io::Error) -> LaunchError {
    LaunchError::Io(format!("{what}: {e}"))
}

/// Which of a stream's lines are echoed on the terminal (all of them go
/// to `cosim.log`).
#[derive(Debug, Clone, Copy)]
pub(crate) enum Echo {
    /// Every line (the processes' own messages, errors included).
    All,
    /// The first `n` lines, then one line saying where the rest is: a
    /// firmware's console is kept to a screenful.
    First(usize),
    /// At most one line per period: a sign of progress where no progress
    /// bar can be drawn (stderr is not a terminal).
    Every(Duration),
    /// None: a progress bar shows the last line.
    Never,
    /// Every line but those the function picks.
    Except(fn(&str) -> bool),
}

/// sim-core's closing one-line summary (`sim-core: completed | targets …`):
/// cosim's report, printed next, says the same in full, so on the terminal
/// it is left out (cosim.log keeps it).
fn sim_core_summary(line: &str) -> bool {
    line.starts_with("sim-core: completed |") || line.starts_with("sim-core: did not complete |")
}

/// The console lines of one drone echoed before the rest goes to the logs only.
pub(crate) const CONSOLE_ECHO_LINES: usize = 60;

/// Shared log file + optional echo, one line at a time so lines of the two
/// processes never interleave mid-line.
#[derive(Clone)]
pub(crate) struct LogSink {
    pub(crate) file: Arc<Mutex<File>>,
    pub(crate) echo: bool,
    /// Where echoed lines go while progress bars are drawn (above them).
    pub(crate) bars: Option<indicatif::MultiProgress>,
}

impl LogSink {
    /// A line into `cosim.log`, and on the terminal when echoing.
    pub(crate) fn line(&self, prefix: &str, line: &str) {
        self.record(prefix, line, true);
    }

    /// A line into `cosim.log`; on the terminal too if `echo` (and echoing).
    fn record(&self, prefix: &str, line: &str, echo: bool) {
        let text = format!("[{prefix}] {line}\n");
        if let Ok(mut f) = self.file.lock() {
            // A failing log write must not stop the run; the run's own
            // outputs are what matter.
            let _ = f.write_all(text.as_bytes());
        }
        if self.echo && echo {
            match &self.bars {
                Some(bars) if !bars.is_hidden() => bars.suspend(|| eprint!("{text}")),
                _ => eprint!("{text}"),
            }
        }
    }

    /// Forwards the lines of `stream` with `prefix`, echoing those `echo`
    /// selects; the last one is also shown on `bar` (the progress display
    /// of several processes). Blank lines (a firmware's `printf("\n...")`
    /// after a line that ended with one) carry nothing and are dropped;
    /// the drone's own `console.log` keeps every byte.
    fn forward(
        &self,
        prefix: String,
        stream: impl Read + Send + 'static,
        bar: Option<indicatif::ProgressBar>,
        echo: Echo,
    ) -> JoinHandle<()> {
        let sink = self.clone();
        std::thread::spawn(move || {
            let mut r = BufReader::new(stream);
            let mut buf = Vec::new();
            let mut echoed = 0usize;
            let mut last_echo: Option<Instant> = None;
            loop {
                buf.clear();
                match r.read_until(b'\n', &mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(_) => {
                        let text = String::from_utf8_lossy(&buf);
                        let text = text.trim_end_matches(['\n', '\r']);
                        if text.trim().is_empty() {
                            continue;
                        }
                        let show = match echo {
                            Echo::All => true,
                            Echo::First(n) => {
                                echoed += 1;
                                if echoed == n + 1 {
                                    sink.record(
                                        &prefix,
                                        "(more console lines: see console.log and cosim.log in the output directory)",
                                        true,
                                    );
                                }
                                echoed <= n
                            }
                            Echo::Every(period) => {
                                let due = last_echo.is_none_or(|t| t.elapsed() >= period);
                                if due {
                                    last_echo = Some(Instant::now());
                                }
                                due
                            }
                            Echo::Never => false,
                            Echo::Except(skip) => !skip(text),
                        };
                        sink.record(&prefix, text, show);
                        if let Some(bar) = &bar {
                            bar.set_message(text.trim().to_string());
                        }
                    }
                }
            }
        })
    }
}

/// A child process with its log forwarders. It leads a process group of its
/// own and is stopped with cosim (crate::signals); one dropped while still
/// running (an early return) is killed, never left behind.
pub(crate) struct Supervised {
    pub(crate) what: String,
    child: Child,
    status: Option<ExitStatus>,
    forwarders: Vec<JoinHandle<()>>,
}

impl Supervised {
    /// `kind` names the program in errors, `what` (its log prefix) the
    /// process; `bar` shows its last line. Its console (stdout) is echoed
    /// as `stdout`, its stderr always (but sim-core's summary line).
    pub(crate) fn spawn(
        kind: &'static str,
        what: String,
        mut cmd: Command,
        sink: &LogSink,
        bar: Option<indicatif::ProgressBar>,
        role: Role,
        stdout: Echo,
    ) -> Result<Self, LaunchError> {
        tracing::debug!(?cmd, "starting {what}");
        crate::signals::prepare(&mut cmd);
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|source| LaunchError::Spawn {
                what: kind,
                path: PathBuf::from(cmd.get_program()),
                source,
            })?;
        crate::signals::track(child.id(), role);
        let mut forwarders = Vec::new();
        if let Some(out) = child.stdout.take() {
            forwarders.push(sink.forward(what.clone(), out, bar.clone(), stdout));
        }
        if let Some(err) = child.stderr.take() {
            let echo = match kind {
                "sim-core" => Echo::Except(sim_core_summary),
                _ => Echo::All,
            };
            forwarders.push(sink.forward(what.clone(), err, bar, echo));
        }
        Ok(Supervised {
            what,
            child,
            status: None,
            forwarders,
        })
    }

    pub(crate) fn poll(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() {
            self.status = self.child.try_wait().ok().flatten();
            if self.status.is_some() {
                crate::signals::untrack(self.child.id());
            }
        }
        self.status
    }

    /// Kills the process and its group (a `--world-cmd` shell's children).
    pub(crate) fn kill(&mut self) {
        if self.poll().is_none() {
            crate::signals::send(self.child.id() as i32, libc::SIGKILL);
            let _ = self.child.kill();
            self.status = self.child.wait().ok();
            crate::signals::untrack(self.child.id());
        }
    }

    /// Waits up to `grace` for the process to end by itself, then kills it.
    pub(crate) fn finish_within(&mut self, grace: Duration) -> bool {
        let until = Instant::now() + grace;
        while Instant::now() < until {
            if self.poll().is_some() {
                return true;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        tracing::warn!("{} did not exit within {grace:?}; killing it", self.what);
        self.kill();
        false
    }

    pub(crate) fn join(mut self) -> Option<ExitStatus> {
        // Reaped, or killed now: the forwarders then see their pipes close.
        self.kill();
        for f in std::mem::take(&mut self.forwarders) {
            let _ = f.join();
        }
        self.status
    }
}

impl Drop for Supervised {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Waits (up to 30 s) for the world server to create its socket, so that
/// sim-core's connection does not depend on its retry patience; a world that
/// dies first, or never listens (it is then killed), is the error returned.
pub(crate) fn wait_for_socket(world: &mut Supervised, socket: &Path) -> Option<String> {
    let until = Instant::now() + Duration::from_secs(30);
    while !socket.exists() {
        if let Some(st) = world.poll() {
            return Some(format!(
                "world-server exited before listening ({})",
                describe(Some(st))
            ));
        }
        if Instant::now() > until {
            world.kill();
            return Some("world-server did not create its socket within 30 s".into());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    None
}

pub(crate) fn describe(status: Option<ExitStatus>) -> String {
    match status {
        Some(s) => match s.code() {
            Some(c) => format!("exit code {c}"),
            None => format!("{s}"),
        },
        None => "still running".into(),
    }
}
