//! `cosim bench race`: what the thesis's race costs (docs/COSIM.md
//! "Performance"). One after the other, never in parallel:
//!
//! 1. **defaults (traces)**: `thesis-race` as `cosim run` runs it (the
//!    thesis's settings, array images, both traces);
//! 2. **defaults (no traces)**: the thesis's settings alone (the thesis
//!    traced nothing);
//! 3. **fast**: the same race with the fast options (images through shared
//!    memory, `image_encoding = "shm"`, and no traces);
//! 4. **world alone**, without then with traces: a `world-server` started
//!    as in run 2 (run 1), fed the requests of run 1's world trace by a
//!    trivial client (each request's bytes as recorded, the reply-less ones
//!    written together with the next request, every reply read whole and
//!    not decoded, waiting for it with the same busy polling as sim-core);
//! 5. unless `busy_poll_us` is already 0: run 2 and the world alone without
//!    traces again with busy polling off (`busy_poll_us = 0` on every side),
//!    to show what polling changes on this host.
//!
//! It prints each run's real-time factor (platform time over the platform's
//! wall time, from `summary.json`) and the overhead ratios: run 2's wall
//! time over the world alone without traces (the thesis's defaults on both
//! sides), run 1's over the world alone with traces. Pipelining needs no option (a conforming
//! world answers in order), so both co-simulated runs use it. A
//! measurement, not a test: the numbers depend on the machine and its load.

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use protocol::blocking::{Client, Options};
use protocol::trace::Direction;
use protocol::{decode_request, Endpoint};
use serde::Deserialize;
use serde_json::value::RawValue;

use crate::launch::{world_command, Binaries, LaunchOptions};
use crate::outcome::RunOutcome;
use crate::run::run_scenario;
use crate::scenario::{resolve_scenario, Scenario};
pub use crate::swarm::bench::BenchError;
use crate::world::World;

/// The scenario the benchmark runs.
pub const RACE: &str = "thesis-race";

/// The `--set` overrides of the fast run (besides traces off).
pub const FAST_SETS: [&str; 1] = ["image_encoding=shm"];

/// One co-simulated run of the benchmark.
#[derive(Debug, Clone)]
pub struct RaceRun {
    pub label: &'static str,
    pub completed: bool,
    pub platform_time_s: f64,
    /// The platform's wall time (summary.json).
    pub wall_s: f64,
    pub realtime_factor: f64,
    pub messages: u64,
    pub bytes_to_platform: u64,
    pub error: Option<String>,
}

/// The whole benchmark.
#[derive(Debug, Clone)]
pub struct RaceBench {
    /// The race as `cosim run` runs it (traces on).
    pub defaults: RaceRun,
    /// The thesis's defaults on their own (no traces, as the thesis ran).
    pub defaults_untraced: RaceRun,
    pub fast: RaceRun,
    /// Wall time of the world alone with traces (connection to the STOP
    /// reply), and without.
    pub world_alone_s: f64,
    pub world_alone_untraced_s: f64,
    pub world_alone_requests: usize,
    /// The busy-poll budget of the runs above (µs, every process).
    pub busy_poll_us: u64,
    /// Run 2 and the world alone without traces with busy polling off
    /// (measurement 5), when it was on above.
    pub unpolled: Option<Unpolled>,
}

/// The thesis's defaults without traces and without busy polling.
#[derive(Debug, Clone)]
pub struct Unpolled {
    pub defaults_untraced: RaceRun,
    pub world_alone_untraced_s: f64,
}

impl Unpolled {
    pub fn overhead(&self) -> f64 {
        self.defaults_untraced.wall_s / self.world_alone_untraced_s.max(1e-9)
    }
}

impl RaceBench {
    /// Co-sim wall over world-alone wall, the thesis's defaults on both
    /// sides (no traces).
    pub fn overhead(&self) -> f64 {
        self.defaults_untraced.wall_s / self.world_alone_untraced_s.max(1e-9)
    }

    /// The same with traces on both sides.
    pub fn overhead_traced(&self) -> f64 {
        self.defaults.wall_s / self.world_alone_s.max(1e-9)
    }

    /// The printed report.
    pub fn markdown(&self) -> String {
        let mut t = String::from(
            "| run | status | platform time (s) | wall (s) | real-time factor | messages | bytes to platform |\n|---|---|---|---|---|---|---|\n",
        );
        let unpolled = self.unpolled.as_ref().map(|u| &u.defaults_untraced);
        for r in [&self.defaults, &self.defaults_untraced, &self.fast]
            .into_iter()
            .chain(unpolled)
        {
            t += &format!(
                "| {} | {} | {:.3} | {:.3} | {:.1}x | {} | {} |\n",
                r.label,
                match &r.error {
                    None if r.completed => "ok".to_string(),
                    e => format!("FAILED {}", e.as_deref().unwrap_or("")),
                },
                r.platform_time_s,
                r.wall_s,
                r.realtime_factor,
                r.messages,
                r.bytes_to_platform,
            );
        }
        t += &format!(
            "\nbusy polling: {} µs (sim-core, world-server and the world-alone client)\n\
             world alone ({} requests): {:.3} s wall without traces, {:.3} s with\n\
             co-sim / world alone, thesis defaults (no traces): {:.2}\n\
             co-sim / world alone, with traces: {:.2}\n",
            self.busy_poll_us,
            self.world_alone_requests,
            self.world_alone_untraced_s,
            self.world_alone_s,
            self.overhead(),
            self.overhead_traced()
        );
        if let Some(u) = &self.unpolled {
            t += &format!(
                "without busy polling: world alone {:.3} s without traces; \
                 co-sim / world alone, thesis defaults (no traces): {:.2}\n",
                u.world_alone_untraced_s,
                u.overhead()
            );
        }
        t
    }
}

fn run_row(label: &'static str, o: &RunOutcome) -> RaceRun {
    let s = o.summary.as_ref();
    RaceRun {
        label,
        completed: o.ok(),
        platform_time_s: s.map_or(0.0, |s| s.platform_time_s),
        wall_s: s.map_or(0.0, |s| s.wall_time_s),
        realtime_factor: s.map_or(0.0, |s| s.realtime_factor),
        messages: s.map_or(0, |s| s.messages),
        bytes_to_platform: s.map_or(0, |s| s.bytes_to_platform),
        error: o.error(),
    }
}

/// Runs the measurements one after the other into `out/defaults`,
/// `out/defaults-untraced`, `out/fast`, `out/world-alone-untraced` and
/// `out/world-alone`; writes `out/bench.md`.
///
/// With `repeat` > 1 each measurement is made that many times in a row and
/// the fastest kept (the load of other programs only ever slows a run).
pub fn bench_race(
    bins: &Binaries,
    out: &Path,
    sets: &[String],
    repeat: usize,
    progress: impl FnMut(&str),
) -> Result<RaceBench, BenchError> {
    let repeat = repeat.max(1);
    let load = |extra: &[&str]| -> Result<(Scenario, World), BenchError> {
        let mut s = Scenario::load(&resolve_scenario(Some(RACE))?)?;
        for a in sets.iter().map(String::as_str).chain(extra.iter().copied()) {
            s.set(a)?;
        }
        let world = s.check_files()?;
        Ok((s, world))
    };
    let defaults = load(&[])?;
    let fast = load(&FAST_SETS)?;
    let io = |what: &str, p: &Path, e: std::io::Error| {
        BenchError::Output(format!("cannot {what} {}: {e}", p.display()))
    };
    std::fs::create_dir_all(out).map_err(|e| io("create", out, e))?;
    let with_traces = LaunchOptions {
        echo: false,
        ..LaunchOptions::default()
    };
    let no_traces = LaunchOptions {
        traces: false,
        ..with_traces.clone()
    };

    // Both closures report through `progress`, so it is shared, not captured.
    let progress = std::cell::RefCell::new(progress);
    let say = |m: &str| (progress.borrow_mut())(m);
    let co_sim =
        |label: &'static str, (sc, w): &(Scenario, World), dir: &str, o: &LaunchOptions| {
            let mut best: Option<RaceRun> = None;
            for k in 0..repeat {
                say(&format!("{label}, run {} ...", k + 1));
                let r = run_row(label, &run_scenario(sc, w, bins, &out.join(dir), o, false)?);
                say(&format!("{label}: {:.1}x real time", r.realtime_factor));
                let failed = !r.completed;
                if failed || best.as_ref().is_none_or(|b| r.wall_s < b.wall_s) {
                    best = Some(r);
                }
                if failed {
                    break;
                }
            }
            Ok::<_, BenchError>(best.expect("at least one run"))
        };
    let d = co_sim("defaults (traces)", &defaults, "defaults", &with_traces)?;
    let du = co_sim(
        "defaults (no traces)",
        &defaults,
        "defaults-untraced",
        &no_traces,
    )?;
    let f = co_sim("fast (shm, no traces)", &fast, "fast", &no_traces)?;

    // The requests of run 1, fed to the world alone without and with traces.
    let requests = load_requests(
        &out.join("defaults")
            .join(crate::outputs::files::WORLD_TRACE),
    )?;
    let alone =
        |(sc, w): &(Scenario, World), dir: &str, o: &LaunchOptions| -> Result<f64, BenchError> {
            let w_dir = out.join(dir);
            std::fs::create_dir_all(&w_dir).map_err(|e| io("create", &w_dir, e))?;
            let sock = w_dir.join("world.sock");
            let _ = std::fs::remove_file(&sock);
            let endpoint = Endpoint::Unix(sock);
            let mut best = f64::INFINITY;
            for _ in 0..repeat {
                let mut world = world_command(sc, w, bins, &endpoint, &w_dir, o)?
                    .stderr(std::process::Stdio::null())
                    .spawn()
                    .map_err(|e| BenchError::Output(format!("cannot start world-server: {e}")))?;
                let poll = protocol::busy_poll::BusyPoll::from_micros(sc.busy_poll_us);
                let wall = feed_world(&endpoint, &requests, poll);
                let status = world.wait();
                let wall = wall?;
                if !status.as_ref().is_ok_and(|s| s.success()) {
                    return Err(BenchError::Output(format!(
                        "the world-alone world-server failed ({status:?})"
                    )));
                }
                say(&format!("world alone ({dir}): {:.3} s", wall.as_secs_f64()));
                best = best.min(wall.as_secs_f64());
            }
            Ok(best)
        };
    let wu = alone(&defaults, "world-alone-untraced", &no_traces)?;
    let wt = alone(&defaults, "world-alone", &with_traces)?;
    let unpolled = if defaults.0.busy_poll_us > 0 {
        let off = load(&["busy_poll_us=0"])?;
        Some(Unpolled {
            defaults_untraced: co_sim(
                "defaults (no traces, no busy polling)",
                &off,
                "defaults-untraced-unpolled",
                &no_traces,
            )?,
            world_alone_untraced_s: alone(&off, "world-alone-untraced-unpolled", &no_traces)?,
        })
    } else {
        None
    };

    let bench = RaceBench {
        defaults: d,
        defaults_untraced: du,
        fast: f,
        world_alone_s: wt,
        world_alone_untraced_s: wu,
        world_alone_requests: requests.len(),
        busy_poll_us: defaults.0.busy_poll_us,
        unpolled,
    };
    std::fs::write(out.join("bench.md"), bench.markdown())
        .map_err(|e| io("write", &out.join("bench.md"), e))?;
    Ok(bench)
}

#[derive(Deserialize)]
struct RawRecord<'a> {
    dir: Direction,
    #[serde(borrow)]
    msg: &'a RawValue,
}

/// A recorded request: its frame body, and whether the world answers it.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedRequest {
    pub body: Vec<u8>,
    pub expects_reply: bool,
}

/// The requests of a world trace, in order (a trace's `msg` is the frame
/// body as it crossed the socket).
pub fn load_requests(trace: &Path) -> Result<Vec<RecordedRequest>, BenchError> {
    let bad = |m: String| BenchError::Output(format!("{}: {m}", trace.display()));
    // Either form (`world.trace` or `world.trace.zst`).
    let f = protocol::series::open(trace).map_err(|e| bad(e.to_string()))?;
    let mut out = Vec::new();
    for (i, line) in f.lines().enumerate() {
        let line = line.map_err(|e| bad(e.to_string()))?;
        let r: RawRecord<'_> =
            serde_json::from_str(&line).map_err(|e| bad(format!("line {}: {e}", i + 1)))?;
        if r.dir != Direction::ToWorld {
            continue;
        }
        let body = r.msg.get().as_bytes().to_vec();
        let req = decode_request(&body).map_err(|e| bad(format!("line {}: {e}", i + 1)))?;
        out.push(RecordedRequest {
            body,
            expects_reply: req.expects_reply(),
        });
    }
    if out.is_empty() {
        return Err(bad("no requests".into()));
    }
    Ok(out)
}

/// The trivial client: connects to `endpoint` and sends `requests` as a
/// platform without a controller would: the requests without reply and
/// the next one with a reply in one write, then that reply read whole (not
/// decoded). Returns the wall time from the connection to the last reply.
pub fn feed_world(
    endpoint: &Endpoint,
    requests: &[RecordedRequest],
    busy_poll: protocol::busy_poll::BusyPoll,
) -> Result<Duration, BenchError> {
    let err = |m: String| BenchError::Output(format!("world alone: {m}"));
    let opts = Options {
        busy_poll,
        ..Options::default()
    };
    let mut conn = Client::connect_retry(endpoint, opts, Duration::from_secs(30))
        .map_err(|e| err(e.to_string()))?;
    let started = Instant::now();
    let mut batch: Vec<&[u8]> = Vec::new();
    for r in requests {
        batch.push(&r.body);
        if !r.expects_reply {
            continue;
        }
        conn.send_raw_batch(&batch)
            .map_err(|e| err(e.to_string()))?;
        batch.clear();
        match conn.recv_raw() {
            Ok(Some(_)) => {}
            Ok(None) => return Err(err("the world closed before the last reply".into())),
            Err(e) => return Err(err(e.to_string())),
        }
    }
    if !batch.is_empty() {
        conn.send_raw_batch(&batch)
            .map_err(|e| err(e.to_string()))?;
    }
    Ok(started.elapsed())
}

/// Default output directory.
pub fn default_out() -> PathBuf {
    Path::new("out").join("bench-race")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_world_trace_gives_its_requests_verbatim_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let t = dir.path().join("world.trace");
        std::fs::write(
            &t,
            concat!(
                r#"{"seq":0,"dir":"to_world","len":27,"msg":{"command":"GET_INIT_DATA"},"world_ms":2000}"#,
                "\n",
                r#"{"seq":1,"dir":"to_platform","len":9,"msg":{"COORDINATE_X":-2.6,"command":"GET_INIT_DATA"},"world_ms":2000}"#,
                "\n",
                r#"{"seq":2,"dir":"to_world","len":60,"msg":{"command":"SET_VELOCITY","m1":1.5,"m2":1.0,"m3":1.0,"m4":1.0},"world_ms":2000}"#,
                "\n",
                r#"{"seq":3,"dir":"to_world","len":22,"msg":{"command":"GET_DATA_2"},"world_ms":2032}"#,
                "\n",
            ),
        )
        .unwrap();
        let r = load_requests(&t).unwrap();
        let bodies: Vec<&str> = r
            .iter()
            .map(|r| std::str::from_utf8(&r.body).unwrap())
            .collect();
        assert_eq!(
            bodies,
            [
                r#"{"command":"GET_INIT_DATA"}"#,
                r#"{"command":"SET_VELOCITY","m1":1.5,"m2":1.0,"m3":1.0,"m4":1.0}"#,
                r#"{"command":"GET_DATA_2"}"#,
            ]
        );
        let replies: Vec<bool> = r.iter().map(|r| r.expects_reply).collect();
        assert_eq!(replies, [true, false, true]);
        // A trace without requests is an error, not an empty benchmark.
        std::fs::write(&t, "").unwrap();
        assert!(load_requests(&t)
            .unwrap_err()
            .to_string()
            .contains("no requests"));
    }
}
