//! A sweep across machines (DESIGN.md §11), end to end with real processes:
//! `cosim sweep --plan` lists the runs in the one-machine order; the same
//! 4-run sweep of the short hop (the four batteries) is run once on one
//! machine and once as 2 shards through GNU parallel
//! (`scripts/sweep-parallel.sh`), and the merged table and SOC plot equal
//! the one-machine sweep's but for the wall-clock columns. Then the merge
//! refuses, with one line naming the run, a missing run, a duplicate run,
//! a run of other settings and a corrupt summary. The script's ssh path
//! (parallel --sshlogin) runs with a stand-in for ssh.
//!
//! GNU parallel is required (CI installs it in .ci/run): without it the test
//! fails and says how to install it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use e2e_tests::{output_text as text, repo_root, CosimBins as Bins};

const PARAM: &str = "battery=lipol250,ufx250,cyclone300,lipol350";

fn require_gnu_parallel() {
    let ok = Command::new("parallel")
        .arg("--version")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).starts_with("GNU parallel"));
    assert!(
        ok,
        "GNU parallel is needed by this test and by scripts/sweep-parallel.sh: \
         install it with `apt-get install -y parallel` (.ci/run does); \
         moreutils' `parallel` is another program"
    );
}

/// `sweep.csv` as header + rows.
fn csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header = r.headers().unwrap().iter().map(String::from).collect();
    let rows = r
        .records()
        .map(|rec| rec.unwrap().iter().map(String::from).collect())
        .collect();
    (header, rows)
}

/// The table with the wall-clock columns left out and `dir` reduced to the
/// run directory's name (the rest of it is the sweep's output directory).
fn comparable(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let (h, rows) = csv(path);
    let skip: Vec<usize> = h
        .iter()
        .enumerate()
        .filter(|(_, c)| scenarios::sweep::WALL_CLOCK_COLUMNS.contains(&c.as_str()))
        .map(|(i, _)| i)
        .collect();
    assert_eq!(skip.len(), 2, "{h:?}");
    let dir = h.iter().position(|c| c == "dir").unwrap();
    let keep = |row: &[String]| -> Vec<String> {
        row.iter()
            .enumerate()
            .filter(|(i, _)| !skip.contains(i))
            .map(|(i, c)| {
                if i == dir {
                    Path::new(c)
                        .file_name()
                        .unwrap()
                        .to_string_lossy()
                        .into_owned()
                } else {
                    c.clone()
                }
            })
            .collect()
    };
    (keep(&h), rows.iter().map(|r| keep(r)).collect())
}

/// `sweep.md` with the wall-clock cells left out.
fn comparable_md(path: &Path) -> Vec<String> {
    let md = std::fs::read_to_string(path).unwrap();
    let lines: Vec<&str> = md.lines().collect();
    let cells = |l: &str| l.split(" | ").map(String::from).collect::<Vec<_>>();
    let header = cells(lines[0]);
    let skip: Vec<usize> = header
        .iter()
        .enumerate()
        .filter(|(_, c)| scenarios::sweep::WALL_CLOCK_COLUMNS.contains(&c.as_str()))
        .map(|(i, _)| i)
        .collect();
    assert_eq!(skip.len(), 2, "{header:?}");
    lines
        .iter()
        .map(|l| {
            if l.starts_with("|---") {
                return l.to_string();
            }
            cells(l)
                .into_iter()
                .enumerate()
                .filter(|(i, _)| !skip.contains(i))
                .map(|(_, c)| c)
                .collect::<Vec<_>>()
                .join(" | ")
        })
        .collect()
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}

fn run_dir(sweep: &Path, prefix: &str) -> PathBuf {
    std::fs::read_dir(sweep)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix))
        .unwrap_or_else(|| panic!("no {prefix}* in {}", sweep.display()))
}

fn assert_refused(o: &Output, needle: &str) {
    assert_eq!(o.status.code(), Some(2), "{}", text(o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("merge refused") && err.contains(needle),
        "expected a refusal with {needle:?}:\n{}",
        text(o)
    );
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
}

#[test]
fn shards_through_gnu_parallel_merge_into_the_one_machine_table() {
    require_gnu_parallel();
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();

    // The plan: the one-machine order, one line per run.
    let o = b.cosim(&["sweep", "short-hop", "--param", PARAM, "--plan"]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        String::from_utf8_lossy(&o.stdout),
        "1 battery=lipol250\n2 battery=ufx250\n3 battery=cyclone300\n4 battery=lipol350\n"
    );
    let o = b.cosim(&[
        "sweep",
        "short-hop",
        "--param",
        PARAM,
        "--plan",
        "--shard",
        "2/2",
    ]);
    assert_eq!(
        String::from_utf8_lossy(&o.stdout),
        "2 battery=ufx250\n4 battery=lipol350\n",
        "{}",
        text(&o)
    );

    // One machine.
    let full = tmp.path().join("full");
    let o = b.cosim(&[
        "sweep",
        "short-hop",
        "--param",
        PARAM,
        "--no-trace",
        "--jobs",
        "2",
        "--out",
        &s(&full),
    ]);
    assert!(o.status.success(), "{}", text(&o));

    // Two shards through GNU parallel, then the merge (the script's).
    let sharded = tmp.path().join("sharded");
    let o = Command::new(repo_root().join("scripts/sweep-parallel.sh"))
        .args([
            "short-hop",
            "-j",
            "2",
            "--shards",
            "2",
            "--out",
            &s(&sharded),
        ])
        .args(["--", "--param", PARAM, "--no-trace"])
        .env("COSIM", &b.cosim)
        // Under `cargo test`, cosim would `cargo build` sim-core and
        // world-server itself (it does under `cargo run`): they are built.
        .env_remove("CARGO")
        .current_dir(repo_root())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let joblog = std::fs::read_to_string(sharded.join("parallel.joblog")).unwrap();
    assert_eq!(joblog.lines().count(), 3, "two shard jobs:\n{joblog}");
    for (n, shard) in [(1, "1/2"), (2, "2/2"), (3, "1/2"), (4, "2/2")] {
        let rec: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(
                run_dir(&sharded, &format!("run-00{n}_")).join("sweep-run.json"),
            )
            .unwrap(),
        )
        .unwrap();
        assert_eq!(rec["shard"], shard, "run {n}: {rec}");
        assert_eq!(rec["run"], n);
    }

    let (fh, frows) = comparable(&full.join("sweep.csv"));
    let (mh, mrows) = comparable(&sharded.join("sweep.csv"));
    assert_eq!(fh, mh);
    assert_eq!(frows.len(), 4);
    assert_eq!(
        frows, mrows,
        "merged table differs from the one-machine table"
    );
    let status = fh.iter().position(|c| c == "status").unwrap();
    assert!(frows.iter().all(|r| r[status] == "ok"), "{frows:?}");
    assert_eq!(
        comparable_md(&full.join("sweep.md")),
        comparable_md(&sharded.join("sweep.md"))
    );
    // The SOC overlay is drawn from the same files with the same labels.
    assert_eq!(
        std::fs::read(full.join("sweep_soc.png")).unwrap(),
        std::fs::read(sharded.join("sweep_soc.png")).unwrap(),
        "sweep_soc.png differs"
    );

    // Merging the shard output elsewhere gives the same table, and the runs
    // are there too (linked), so the plots and the table's dirs resolve.
    let elsewhere = tmp.path().join("elsewhere");
    let o = b.cosim(&["sweep", "--merge", &s(&sharded), "--out", &s(&elsewhere)]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(comparable(&elsewhere.join("sweep.csv")).1, frows);
    assert!(e2e_tests::series_file(&run_dir(&elsewhere, "run-003_").join("power.csv")).is_file());

    // Refusals, each one line naming what is wrong, nothing written.
    let missing = tmp.path().join("missing");
    copy_dir(&sharded, &missing);
    std::fs::remove_dir_all(run_dir(&missing, "run-003_")).unwrap();
    let out = tmp.path().join("m1");
    assert_refused(
        &b.cosim(&["sweep", "--merge", &s(&missing), "--out", &s(&out)]),
        "missing run(s) 3 (battery=cyclone300) of 4",
    );
    assert!(!out.join("sweep.csv").exists());

    assert_refused(
        &b.cosim(&[
            "sweep",
            "--merge",
            &s(&full),
            &s(&sharded),
            "--out",
            &s(&tmp.path().join("m2")),
        ]),
        "run 1 (battery=lipol250) is in both",
    );

    let corrupt = tmp.path().join("corrupt");
    copy_dir(&sharded, &corrupt);
    let summary = run_dir(&corrupt, "run-002_").join("summary.json");
    let edited = std::fs::read_to_string(&summary).unwrap().replacen(
        "\"targets_reached\": 1",
        "\"targets_reached\": 0",
        1,
    );
    std::fs::write(&summary, edited).unwrap();
    assert_refused(
        &b.cosim(&[
            "sweep",
            "--merge",
            &s(&corrupt),
            "--out",
            &s(&tmp.path().join("m3")),
        ]),
        "run-002_battery=ufx250/summary.json is corrupt",
    );

    // Shard 1/4 of the same sweep with another tolerance: other settings.
    let other = tmp.path().join("other");
    let o = b.cosim(&[
        "sweep",
        "short-hop",
        "--param",
        PARAM,
        "--set",
        "tolerance=0.2",
        "--no-trace",
        "--shard",
        "1/4",
        "--out",
        &s(&other),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(!other.join("sweep.csv").exists(), "a shard writes no table");
    std::fs::remove_dir_all(run_dir(&missing, "run-001_")).unwrap();
    assert_refused(
        &b.cosim(&[
            "sweep",
            "--merge",
            &s(&other),
            &s(&missing),
            "--out",
            &s(&tmp.path().join("m4")),
        ]),
        "different settings or input files",
    );
}

/// The same script over "ssh hosts": GNU parallel's remote path (the job
/// shipped through ssh as a quoted command line, run in the remote's shell)
/// with a stand-in for ssh that runs it here — what a host sharing this
/// filesystem would do. Each host runs one shard; the merge sees both.
#[test]
fn shards_on_ssh_hosts_through_gnu_parallel() {
    require_gnu_parallel();
    let b = Bins::new();
    let tmp = tempfile::tempdir().unwrap();
    let ssh = tmp.path().join("ssh");
    std::fs::write(
        &ssh,
        "#!/bin/sh\n\
         # ssh HOST [--] COMMAND...: options and host dropped, the command\n\
         # run by the shell as sshd does. sshd also sets SHELL (the login\n\
         # shell), which parallel's remote wrapper execs the job with: a\n\
         # test run without SHELL in its environment (CI) must still have it.\n\
         export SHELL=\"${SHELL:-/bin/sh}\"\n\
         while [ $# -gt 0 ]; do case \"$1\" in -o|-p|-l|-S|-i) shift 2;; -*) shift;; *) shift; break;; esac; done\n\
         [ \"$1\" = \"--\" ] && shift\n\
         exec sh -c \"$*\"\n",
    )
    .unwrap();
    std::fs::set_permissions(&ssh, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let out = tmp.path().join("over ssh");
    let o = Command::new(repo_root().join("scripts/sweep-parallel.sh"))
        .args(["short-hop", "--sshlogin", "1/hostA,1/hostB"])
        .args(["--out", out.to_str().unwrap()])
        .args(["--", "--param", "battery=lipol250,ufx250", "--no-trace"])
        .env("COSIM", &b.cosim)
        // Under `cargo test`, cosim would `cargo build` sim-core and
        // world-server itself (it does under `cargo run`): they are built.
        .env_remove("CARGO")
        .env("PARALLEL_SSH", &ssh)
        .current_dir(repo_root())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let joblog = std::fs::read_to_string(out.join("parallel.joblog")).unwrap();
    let mut hosts: Vec<&str> = joblog
        .lines()
        .skip(1)
        .map(|l| l.split('\t').nth(1).unwrap())
        .collect();
    hosts.sort();
    assert_eq!(hosts, ["hostA", "hostB"], "{joblog}");
    let (h, rows) = csv(&out.join("sweep.csv"));
    let status = h.iter().position(|c| c == "status").unwrap();
    assert_eq!(rows.len(), 2);
    assert!(rows.iter().all(|r| r[status] == "ok"), "{rows:?}");
}
