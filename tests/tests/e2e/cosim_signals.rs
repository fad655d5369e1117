//! `cosim` stopped by a signal (DESIGN.md §19): SIGTERM or SIGINT to a
//! running `cosim run` (one drone, several drones) or `cosim sweep` stops
//! every process it started within seconds, it exits with 128 + the signal
//! and writes its report from what exists; cosim killed with SIGKILL (which
//! it cannot catch) still leaves no process behind (the kernel's parent
//! death signal). Real processes: the processes left are found in /proc.

use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::CosimBins as Bins;

/// The processes whose command line names `dir` (sim-core's `--out`,
/// world-server's `--trajectory`): those a run into `dir` started.
fn processes_naming(dir: &Path) -> Vec<(u32, String)> {
    let needle = dir.to_string_lossy().into_owned();
    e2e_tests::processes()
        .into_iter()
        .map(|p| (p.pid, p.cmdline()))
        .filter(|(_, cmdline)| cmdline.contains(&needle))
        .collect()
}

/// The children of `parent`: their pids and programs.
fn children_of(parent: u32) -> Vec<(u32, String)> {
    e2e_tests::processes()
        .into_iter()
        .filter(|p| p.ppid == Some(parent))
        .map(|p| (p.pid, p.args.first().cloned().unwrap_or_default()))
        .collect()
}

fn wait_until(secs: u64, mut f: impl FnMut() -> bool) -> bool {
    let until = Instant::now() + Duration::from_secs(secs);
    while Instant::now() < until {
        if f() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    f()
}

/// Starts `cosim ARGS --out OUT` and waits until it runs `need` children
/// of each name (`world-server`, `sim-core`), plus one second of the run.
fn start(b: &Bins, args: &[&str], out: &Path, stderr: &Path, need: &[(&str, usize)]) -> Child {
    let mut all: Vec<&str> = args.to_vec();
    let out_text = out.to_str().unwrap();
    all.extend(["--out", out_text]);
    let child = b
        .command(&all)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(stderr).unwrap())
        .spawn()
        .expect("start cosim");
    let pid = child.id();
    let ready = wait_until(120, || {
        let names: Vec<String> = processes_naming(out).into_iter().map(|(_, c)| c).collect();
        need.iter().all(|(name, n)| {
            names
                .iter()
                .filter(|c| {
                    c.split_whitespace()
                        .next()
                        .is_some_and(|p| p.ends_with(name))
                })
                .count()
                >= *n
        })
    });
    assert!(
        ready,
        "cosim {args:?} did not start its processes: children {:?}, stderr:\n{}",
        children_of(pid),
        std::fs::read_to_string(stderr).unwrap_or_default()
    );
    std::thread::sleep(Duration::from_secs(1));
    child
}

fn signal(child: &Child, sig: i32) {
    // SAFETY: kill(2) on a child we started and have not reaped.
    let r = unsafe { libc::kill(child.id() as libc::pid_t, sig) };
    assert_eq!(r, 0, "kill {sig}");
}

/// Waits (at most `secs`) for cosim to exit; its exit code.
fn exit_code(child: &mut Child, secs: u64, stderr: &Path) -> Option<i32> {
    let mut status = None;
    wait_until(secs, || {
        status = child.try_wait().unwrap();
        status.is_some()
    });
    match status {
        Some(s) => s.code(),
        None => {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "cosim still running {secs} s after the signal; stderr:\n{}",
                std::fs::read_to_string(stderr).unwrap_or_default()
            );
        }
    }
}

/// No process naming `out` remains (a moment allowed for the kernel).
fn assert_none_left(out: &Path, what: &str) {
    let gone = wait_until(3, || processes_naming(out).is_empty());
    assert!(
        gone,
        "{what}: processes left behind: {:#?}",
        processes_naming(out)
    );
}

fn stop_run(b: &Bins, args: &[&str], need: &[(&str, usize)], sig: i32) -> (PathBuf, String) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().canonicalize().unwrap().join("run");
    let stderr = tmp.path().join("stderr.txt");
    let mut cosim = start(b, args, &out, &stderr, need);
    let t0 = Instant::now();
    signal(&cosim, sig);
    let code = exit_code(&mut cosim, 30, &stderr);
    let took = t0.elapsed();
    let err = std::fs::read_to_string(&stderr).unwrap();
    assert_eq!(code, Some(128 + sig), "{args:?}: exit code; stderr:\n{err}");
    assert_none_left(&out, &format!("{args:?} after signal {sig}"));
    // The processes are stopped in order within a few seconds (the world
    // at once, the platforms after 3 s, SIGKILL after 6 s).
    assert!(took < Duration::from_secs(15), "{args:?}: took {took:?}");
    let report = std::fs::read_to_string(out.join("report.txt"))
        .unwrap_or_else(|e| panic!("{args:?}: no report.txt ({e}); stderr:\n{err}"));
    let name = if sig == libc::SIGTERM {
        "SIGTERM"
    } else {
        "SIGINT"
    };
    assert!(
        report.contains(&format!("interrupted by {name}")),
        "{args:?}: report:\n{report}"
    );
    // The launcher's own log was flushed: it holds the processes' lines.
    let log = std::fs::read_to_string(out.join("cosim.log")).unwrap();
    assert!(!log.is_empty(), "{args:?}: empty cosim.log");
    // The temporary directory goes after the check.
    drop(tmp);
    (out, err)
}

#[test]
fn sigterm_and_sigint_stop_a_run_and_leave_no_process() {
    let b = Bins::new();
    // The thesis race on debug binaries runs for minutes: stopped mid-run.
    let one = [("world-server", 1), ("sim-core", 1)];
    for sig in [libc::SIGTERM, libc::SIGINT] {
        let (_, err) = stop_run(&b, &["run", "thesis-race", "--no-plots"], &one, sig);
        assert!(err.contains("received"), "{err}");
    }
    // Several drones: the world and one sim-core per platform.
    let swarm = [("world-server", 1), ("sim-core", 2)];
    stop_run(
        &b,
        &["run", "swarm-hover-2", "--no-plots"],
        &swarm,
        libc::SIGTERM,
    );
}

#[test]
fn sigterm_stops_a_sweep_and_its_runs() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().canonicalize().unwrap().join("sweep");
    let stderr = tmp.path().join("stderr.txt");
    // Two runs at a time out of four: each has its world and its platform.
    let mut cosim = start(
        &b,
        &[
            "sweep",
            "thesis-race",
            "--param",
            "timestep_ms=16,32",
            "--param",
            "battery=lipol250,ufx250",
            "--jobs",
            "2",
        ],
        &out,
        &stderr,
        &[("world-server", 2), ("sim-core", 2)],
    );
    signal(&cosim, libc::SIGTERM);
    let code = exit_code(&mut cosim, 30, &stderr);
    assert_eq!(
        code,
        Some(128 + libc::SIGTERM),
        "{}",
        std::fs::read_to_string(&stderr).unwrap()
    );
    assert_none_left(&out, "the sweep");
    // No run was started after the signal: at most the two running ones
    // have a directory.
    let runs = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with("run-"))
        .count();
    assert!(runs <= 2, "{runs} run directories");
}

#[test]
fn cosim_killed_outright_takes_its_children_along() {
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().canonicalize().unwrap().join("run");
    let stderr = tmp.path().join("stderr.txt");
    let mut cosim = start(
        &b,
        &["run", "thesis-race", "--no-plots"],
        &out,
        &stderr,
        &[("world-server", 1), ("sim-core", 1)],
    );
    signal(&cosim, libc::SIGKILL);
    let status = cosim.wait().unwrap();
    assert_eq!(
        std::os::unix::process::ExitStatusExt::signal(&status),
        Some(libc::SIGKILL)
    );
    assert_none_left(&out, "cosim killed with SIGKILL");
}
