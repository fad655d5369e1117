//! Where packets come from and go: cflib's `udp://` link (one datagram, one
//! packet; answers to the last sender), or a recording replayed; the
//! recording of arrivals; the wall-clock pacing.
//!
//! Pacing is the only use of the wall clock in the simulator: with a live
//! link, the world step that starts at platform time `t` is not run before
//! `wall_start + (t − t_start)/pace` (cflib's scripts sleep in wall time);
//! packets that arrive while waiting belong to that step. Each arrival is
//! recorded with the step's platform time (ps) and its bytes, one JSON line
//! each (`crtp.jsonl`: `{"platform_ps":N,"crtp":"hex"}`); replaying the
//! file feeds the same packets to the same steps, unpaced, so the run is
//! exact and deterministic.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{self, BufRead, BufReader, BufWriter, Write};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::{Duration, Instant};

use crate::units::Picos;

/// What `--crtp` / the run key `crtp` names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CrtpSpec {
    /// `udp:HOST:PORT`
    Udp(String),
    /// `replay:FILE` (a `crtp.jsonl` of an earlier run)
    Replay(PathBuf),
}

impl FromStr for CrtpSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if let Some(a) = s.strip_prefix("udp:") {
            let (host, port) = a
                .rsplit_once(':')
                .ok_or("expected udp:HOST:PORT (e.g. udp:127.0.0.1:19850)")?;
            port.parse::<u16>()
                .map_err(|_| format!("{port:?} is not a UDP port number"))?;
            if host.is_empty() {
                return Err("expected udp:HOST:PORT: the host is empty".into());
            }
            Ok(CrtpSpec::Udp(a.to_string()))
        } else if let Some(p) = s.strip_prefix("replay:") {
            if p.is_empty() {
                return Err("expected replay:FILE".into());
            }
            Ok(CrtpSpec::Replay(PathBuf::from(p)))
        } else {
            Err("expected udp:HOST:PORT or replay:FILE".into())
        }
    }
}

impl std::fmt::Display for CrtpSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CrtpSpec::Udp(a) => write!(f, "udp:{a}"),
            CrtpSpec::Replay(p) => write!(f, "replay:{}", p.display()),
        }
    }
}

impl CrtpSpec {
    /// The same link moved `n` ports up (a swarm's drones at PORT, PORT+1 …).
    pub fn offset(&self, n: u16) -> Result<CrtpSpec, String> {
        match self {
            CrtpSpec::Udp(a) => {
                let (host, port) = a.rsplit_once(':').expect("parsed");
                let p: u16 = port.parse().expect("parsed");
                let p = p
                    .checked_add(n)
                    .ok_or_else(|| format!("port {p} + {n} is beyond 65535"))?;
                Ok(CrtpSpec::Udp(format!("{host}:{p}")))
            }
            CrtpSpec::Replay(_) => Err("a replay names one drone's recording".into()),
        }
    }
}

#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct Arrival {
    platform_ps: u64,
    crtp: String,
}

pub enum Source {
    Udp {
        socket: UdpSocket,
        peer: Option<SocketAddr>,
    },
    Replay {
        arrivals: VecDeque<(Picos, Vec<u8>)>,
    },
}

fn io_err(what: String) -> impl FnOnce(io::Error) -> io::Error {
    move |e| io::Error::new(e.kind(), format!("{what}: {e}"))
}

impl Source {
    pub fn open(spec: &CrtpSpec) -> io::Result<Source> {
        match spec {
            CrtpSpec::Udp(addr) => {
                let socket = UdpSocket::bind(addr.as_str())
                    .map_err(io_err(format!("cannot bind the CRTP link udp:{addr}")))?;
                Ok(Source::Udp { socket, peer: None })
            }
            CrtpSpec::Replay(path) => Ok(Source::Replay {
                arrivals: read_recording(path)?,
            }),
        }
    }

    pub fn is_live(&self) -> bool {
        matches!(self, Source::Udp { .. })
    }

    /// The packets of the step at `now`: a live link waits for them until
    /// `deadline` (wall clock) and then takes what is queued; a replay
    /// gives what was recorded for `now`.
    pub fn receive(&mut self, now: Picos, deadline: Option<Instant>) -> io::Result<Vec<Vec<u8>>> {
        let mut out = Vec::new();
        match self {
            Source::Udp { socket, peer } => {
                let mut buf = [0u8; 1500];
                // `send` leaves the socket blocking.
                socket.set_nonblocking(true)?;
                loop {
                    match socket.recv_from(&mut buf) {
                        // Answer a packet as soon as it came: the caller
                        // dispatches between calls.
                        Ok((n, from)) => {
                            *peer = Some(from);
                            out.push(buf[..n].to_vec());
                            break;
                        }
                        Err(e) if e.kind() == io::ErrorKind::WouldBlock => {}
                        // An ICMP "port unreachable" from a client that went
                        // away shows as a reset on some systems: not ours.
                        Err(e) if e.kind() == io::ErrorKind::ConnectionReset => continue,
                        Err(e) => return Err(e),
                    }
                    match deadline.and_then(|d| d.checked_duration_since(Instant::now())) {
                        Some(w) if !w.is_zero() => wait_readable(socket, w)?,
                        _ => break,
                    }
                }
            }
            Source::Replay { arrivals } => {
                while arrivals.front().is_some_and(|(t, _)| *t <= now) {
                    out.push(arrivals.pop_front().expect("front").1);
                }
            }
        }
        Ok(out)
    }

    pub fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        if let Source::Udp {
            socket,
            peer: Some(p),
        } = self
        {
            socket.set_nonblocking(false)?;
            match socket.send_to(bytes, *p) {
                Ok(_) => {}
                // A client that closed its socket: the datagram is lost, as
                // a radio packet to a dongle that is gone.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

/// Waits until `socket` has a datagram or `wait` has passed.
///
/// Not the socket's read timeout: SO_RCVTIMEO counts in the kernel's ticks
/// (4 ms at HZ = 250), which released the steps of a paced run up to
/// 12 ms late, 6.6 ms on average at pace 1 (docs/notes/2026-12-07-pacing.md);
/// `ppoll`'s timeout is a high-resolution timer.
#[cfg(target_os = "linux")]
fn wait_readable(socket: &UdpSocket, wait: Duration) -> io::Result<()> {
    use std::os::fd::AsRawFd;
    let mut fd = libc::pollfd {
        fd: socket.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    };
    let ts = libc::timespec {
        tv_sec: libc::time_t::try_from(wait.as_secs()).unwrap_or(libc::time_t::MAX),
        tv_nsec: wait.subsec_nanos().into(),
    };
    // SAFETY: one valid pollfd, a valid timespec, no signal mask.
    let r = unsafe { libc::ppoll(&mut fd, 1, &ts, std::ptr::null()) };
    if r < 0 {
        let e = io::Error::last_os_error();
        if e.kind() != io::ErrorKind::Interrupted {
            return Err(e);
        }
    }
    Ok(())
}

/// Elsewhere `poll`, in whole milliseconds (rounded up: never early).
#[cfg(not(target_os = "linux"))]
fn wait_readable(socket: &UdpSocket, wait: Duration) -> io::Result<()> {
    use std::os::fd::AsRawFd;
    let mut fd = libc::pollfd {
        fd: socket.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    };
    let ms = libc::c_int::try_from(wait.as_micros().div_ceil(1000)).unwrap_or(libc::c_int::MAX);
    // SAFETY: one valid pollfd.
    let r = unsafe { libc::poll(&mut fd, 1, ms) };
    if r < 0 {
        let e = io::Error::last_os_error();
        if e.kind() != io::ErrorKind::Interrupted {
            return Err(e);
        }
    }
    Ok(())
}

fn read_recording(path: &Path) -> io::Result<VecDeque<(Picos, Vec<u8>)>> {
    let f = File::open(path).map_err(io_err(format!(
        "cannot read the CRTP recording {}",
        path.display()
    )))?;
    let mut out = VecDeque::new();
    for (i, line) in BufReader::new(f).lines().enumerate() {
        let line = line?;
        if line.trim().is_empty() {
            continue;
        }
        let bad = |m: String| {
            io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{} line {}: {m}", path.display(), i + 1),
            )
        };
        let a: Arrival = serde_json::from_str(&line).map_err(|e| bad(e.to_string()))?;
        let bytes = hex::decode(&a.crtp).map_err(|e| bad(format!("crtp: {e}")))?;
        out.push_back((Picos(a.platform_ps), bytes));
    }
    Ok(out)
}

/// Writes the arrivals (`crtp.jsonl`).
pub struct Recorder {
    out: BufWriter<File>,
}

impl Recorder {
    pub fn create(path: &Path) -> io::Result<Recorder> {
        let f = File::create(path).map_err(io_err(format!("cannot create {}", path.display())))?;
        Ok(Recorder {
            out: BufWriter::new(f),
        })
    }

    pub fn record(&mut self, now: Picos, bytes: &[u8]) -> io::Result<()> {
        let a = Arrival {
            platform_ps: now.0,
            crtp: hex::encode(bytes),
        };
        serde_json::to_writer(&mut self.out, &a)?;
        self.out.write_all(b"\n")
    }

    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// Wall-clock pacing of a live link, and how well it held.
///
/// Each step's deadline is absolute, `origin_wall + (t − t_origin)/pace`,
/// never a sleep added to the last one: a step released late leaves the
/// next deadlines where they were, so the world catches up (its next steps
/// run at once) instead of drifting, and it never runs ahead of the wall
/// clock by more than the step it is in.
pub struct Pacer {
    pace: f64,
    origin: Option<(Instant, Picos)>,
    held: Held,
    /// `pacing.csv`: one row a paced step (see [`Pacer::with_log`]).
    log: Option<BufWriter<File>>,
}

/// What the paced steps showed so far.
#[derive(Debug, Clone, Copy, Default)]
struct Held {
    steps: u64,
    /// The last step's platform time and the wall time it ran at.
    last: Option<(Picos, Instant)>,
    lag_sum: Duration,
    /// Steps that ran more than [`MAX_LAG_MS`] after their deadline.
    late: u64,
    worst: Option<(Duration, Picos)>,
}

/// The achieved pace is at least this share of the requested one, or the
/// run is reported as not kept up.
pub const MIN_PACE_SHARE: f64 = 0.95;
/// A step released more than this after its deadline (ms, wall) is reported
/// as not kept up: cflib's MotionCommander and cfclient stream set-points
/// at 10 Hz, so a lag past 100 ms puts the world a whole set-point period
/// behind the script; and when the world catches up, lag × pace of
/// simulated time passes in a burst without new packets, which at pace ≤ 4
/// stays under the commander's 500 ms watchdog (`commander::WDT_STABILIZE`)
/// for a client streaming at 10 Hz.
pub const MAX_LAG_MS: f64 = 100.0;

/// The pacing's figures (`summary.json`'s `pacing`, DESIGN.md §20).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PacingSummary {
    /// The pace asked for (simulated seconds per wall second).
    pub pace: f64,
    /// Simulated time over wall time from the first paced step to the last.
    pub achieved_pace: f64,
    /// The largest wall time by which a step ran after its deadline (ms).
    pub worst_lag_ms: f64,
    /// The platform time of that step (s).
    pub worst_lag_at_s: f64,
    pub mean_lag_ms: f64,
    /// Steps that ran more than [`MAX_LAG_MS`] after their deadline.
    pub steps_late: u64,
    /// Paced steps, and the simulated and wall time they spanned (s).
    pub steps: u64,
    pub paced_s: f64,
    pub wall_s: f64,
    /// The achieved pace was at least [`MIN_PACE_SHARE`] of the asked one
    /// and no step lagged more than [`MAX_LAG_MS`].
    pub kept_up: bool,
}

impl PacingSummary {
    /// The one-line warning of a run whose simulator could not keep up.
    pub fn warning(&self) -> Option<String> {
        (!self.kept_up).then(|| {
            format!(
                "the simulator did not keep pace {}: achieved {:.3}x ({:.1} % of it, limit {:.0} %); {} of {} steps ran more than {:.0} ms late, the worst {:.0} ms at {:.1} s (a busy host or too high a pace)",
                self.pace,
                self.achieved_pace,
                100.0 * self.achieved_pace / self.pace,
                100.0 * MIN_PACE_SHARE,
                self.steps_late,
                self.steps,
                MAX_LAG_MS,
                self.worst_lag_ms,
                self.worst_lag_at_s,
            )
        })
    }
}

/// The header of `pacing.csv`: the step's platform time, the wall time it
/// ran at since the first paced step, its lag behind its deadline.
pub const PACING_CSV_HEADER: &str = "platform_s,wall_s,lag_ms";

impl Pacer {
    /// `pace` = simulated seconds per wall second (0: as fast as possible).
    pub fn new(pace: f64) -> Self {
        Pacer {
            pace,
            origin: None,
            held: Held::default(),
            log: None,
        }
    }

    /// The same, writing each paced step to `path` (`pacing.csv`; nothing
    /// is created when unpaced).
    pub fn with_log(pace: f64, path: &Path) -> io::Result<Self> {
        let mut p = Pacer::new(pace);
        if pace > 0.0 {
            let f =
                File::create(path).map_err(io_err(format!("cannot create {}", path.display())))?;
            let mut w = BufWriter::new(f);
            writeln!(w, "{PACING_CSV_HEADER}")?;
            p.log = Some(w);
        }
        Ok(p)
    }

    /// When the step at `now` may run (`None`: at once).
    pub fn deadline(&mut self, now: Picos) -> Option<Instant> {
        if self.pace <= 0.0 {
            return None;
        }
        let (w0, t0) = *self.origin.get_or_insert((Instant::now(), now));
        let sim = now.saturating_sub(t0).as_secs_f64();
        Some(w0 + Duration::from_secs_f64(sim / self.pace))
    }

    /// The step at `now`, due at `deadline`, runs at wall time `at`.
    pub fn ran(&mut self, now: Picos, deadline: Instant, at: Instant) -> io::Result<()> {
        let lag = at.saturating_duration_since(deadline);
        let h = &mut self.held;
        h.steps += 1;
        h.last = Some((now, at));
        h.lag_sum += lag;
        if lag.as_secs_f64() * 1e3 > MAX_LAG_MS {
            h.late += 1;
        }
        if h.worst.is_none_or(|(w, _)| lag > w) {
            h.worst = Some((lag, now));
        }
        if let (Some(w), Some((w0, _))) = (&mut self.log, self.origin) {
            writeln!(
                w,
                "{:.6},{:.6},{:.3}",
                now.as_secs_f64(),
                at.saturating_duration_since(w0).as_secs_f64(),
                lag.as_secs_f64() * 1e3
            )?;
        }
        Ok(())
    }

    pub fn flush(&mut self) -> io::Result<()> {
        match &mut self.log {
            Some(w) => w.flush(),
            None => Ok(()),
        }
    }

    /// The figures so far (`None`: unpaced, or fewer than two paced steps).
    pub fn summary(&self) -> Option<PacingSummary> {
        let (w0, t0) = self.origin?;
        let h = &self.held;
        let (t1, w1) = h.last?;
        let (worst, worst_at) = h.worst?;
        let paced_s = t1.saturating_sub(t0).as_secs_f64();
        let wall_s = w1.saturating_duration_since(w0).as_secs_f64();
        if h.steps < 2 || wall_s <= 0.0 {
            return None;
        }
        let achieved_pace = paced_s / wall_s;
        let worst_lag_ms = worst.as_secs_f64() * 1e3;
        Some(PacingSummary {
            pace: self.pace,
            achieved_pace,
            worst_lag_ms,
            worst_lag_at_s: worst_at.as_secs_f64(),
            mean_lag_ms: h.lag_sum.as_secs_f64() * 1e3 / h.steps as f64,
            steps_late: h.late,
            steps: h.steps,
            paced_s,
            wall_s,
            kept_up: achieved_pace >= MIN_PACE_SHARE * self.pace && worst_lag_ms <= MAX_LAG_MS,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_and_offset() {
        let s: CrtpSpec = "udp:127.0.0.1:19850".parse().unwrap();
        assert_eq!(s.offset(2).unwrap().to_string(), "udp:127.0.0.1:19852");
        assert!("udp:127.0.0.1".parse::<CrtpSpec>().is_err());
        assert!("udp::1".parse::<CrtpSpec>().is_err());
        assert!("tcp:x:1".parse::<CrtpSpec>().is_err());
        assert!("udp:h:65535"
            .parse::<CrtpSpec>()
            .unwrap()
            .offset(1)
            .is_err());
        assert_eq!(
            "replay:a/crtp.jsonl".parse::<CrtpSpec>().unwrap(),
            CrtpSpec::Replay("a/crtp.jsonl".into())
        );
    }

    #[test]
    fn the_pacing_figures_are_those_of_the_steps() {
        // Pace 2: steps 1 s of simulated time apart are due 0.5 s apart;
        // released 0, 50 and 150 ms late.
        let mut p = Pacer::new(2.0);
        let lags = [0, 50, 150].map(Duration::from_millis);
        for (i, lag) in lags.iter().enumerate() {
            let now = Picos::from_ms(1000 * (i as u64 + 3));
            let d = p.deadline(now).unwrap();
            p.ran(now, d, d + *lag).unwrap();
        }
        let s = p.summary().unwrap();
        assert_eq!(s.steps, 3);
        assert!((s.paced_s - 2.0).abs() < 1e-9);
        assert!((s.wall_s - 1.15).abs() < 1e-6, "{s:?}");
        assert!((s.achieved_pace - 2.0 / 1.15).abs() < 1e-5);
        assert!((s.worst_lag_ms - 150.0).abs() < 1e-6);
        assert!((s.worst_lag_at_s - 5.0).abs() < 1e-9);
        assert!((s.mean_lag_ms - 200.0 / 3.0).abs() < 1e-6);
        // 87 % of the pace and a lag past MAX_LAG_MS: not kept up.
        assert!(!s.kept_up);
        assert_eq!(s.steps_late, 1);
        let w = s.warning().unwrap();
        assert!(
            w.contains("1 of 3 steps ran more than 100 ms late, the worst 150 ms at 5.0 s"),
            "{w}"
        );
        // Unpaced: no deadlines, no figures.
        let mut u = Pacer::new(0.0);
        assert_eq!(u.deadline(Picos::from_ms(5)), None);
        assert_eq!(u.summary(), None);
    }

    #[test]
    fn a_recording_replays_at_its_steps() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("crtp.jsonl");
        let mut r = Recorder::create(&p).unwrap();
        r.record(Picos(5), &[0xFF]).unwrap();
        r.record(Picos(9), &[0x3C, 1]).unwrap();
        r.flush().unwrap();
        let mut s = Source::open(&CrtpSpec::Replay(p)).unwrap();
        assert!(s.receive(Picos(4), None).unwrap().is_empty());
        assert_eq!(s.receive(Picos(5), None).unwrap(), vec![vec![0xFF]]);
        assert_eq!(s.receive(Picos(10), None).unwrap(), vec![vec![0x3C, 1]]);
    }
}
