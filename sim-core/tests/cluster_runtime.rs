//! The PMSIS runtime (sim-core/firmware/src/pmsis/, DESIGN.md §12) on the
//! cluster, through `sim-core run-elf` as a user runs it: the first cluster
//! program, the runtime's self-test, the matmul benchmark's checks, and
//! `make app` building a user's own program.

mod iss_util;

use std::path::Path;
use std::process::{Command, Output};

use iss_util::firmware;

fn run_elf(elf: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sim-core"))
        .arg("run-elf")
        .arg(elf)
        .args(extra)
        .output()
        .expect("run sim-core")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Each core prints its ids under the team's mutex, the FC its own
/// (cluster id 32, gap_sdk's ARCHI_FC_CID); the same every run.
#[test]
fn cluster_hello_prints_each_core_once() {
    let o = run_elf(&firmware("cluster_hello"), &[]);
    let out = stdout(&o);
    assert_eq!(o.status.code(), Some(0), "{out}{}", stderr(&o));
    assert!(
        out.starts_with("[fc: cluster 32, core 0] opening the cluster\n"),
        "{out}"
    );
    for core in 0..8 {
        let line = format!("[cluster 0, core {core}] hello, team of 8\n");
        assert_eq!(out.matches(&line).count(), 1, "{line:?} in {out}");
    }
    assert!(out.ends_with("[fc] done\n"), "{out}");
    assert_eq!(out.lines().count(), 10, "{out}");
    let again = run_elf(&firmware("cluster_hello"), &[]);
    assert_eq!(stdout(&again), out, "same ELF, same output");
}

/// The self-test on the default 8 cores and on clusters of 1 and 3 (the
/// runtime sizes its forks, stacks and teams from `NB_CORES`).
#[test]
fn runtime_selftest_passes() {
    for (cores, checks) in [("8", 54), ("1", 48), ("3", 50)] {
        let o = run_elf(&firmware("cluster_selftest"), &["--cluster-cores", cores]);
        let out = stdout(&o);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{cores} cores: {out}{}",
            stderr(&o)
        );
        assert_eq!(
            out,
            format!("cluster_selftest: {checks} checks, 0 failures: PASS\n"),
            "{cores} cores"
        );
    }
}

/// The benchmark's own checks: every run's checksum equals the FC's plain
/// C reference, 8 cores reach the 8 MAC/cycle aimed at, and more cores are
/// faster. Cycles are simulated, so this cannot flake with the host's load.
#[test]
fn matmul_is_exact_and_reaches_8_mac_per_cycle() {
    let o = run_elf(&firmware("cluster_matmul"), &[]);
    let out = stdout(&o);
    assert_eq!(o.status.code(), Some(0), "{out}{}", stderr(&o));
    assert!(out.contains("differ: PASS"), "{out}");
    let rows: Vec<(u32, u64, f64)> = out
        .lines()
        .skip_while(|l| !l.starts_with("cores "))
        .skip(1)
        .take_while(|l| !l.starts_with("reference"))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        rows.iter().map(|r| r.0).collect::<Vec<_>>(),
        [1, 2, 4, 8],
        "{out}"
    );
    for w in rows.windows(2) {
        assert!(w[1].1 < w[0].1, "more cores, fewer cycles: {out}");
    }
    assert!(rows[3].2 >= 8.0, "8 cores: {} MAC/cycle\n{out}", rows[3].2);
}

/// `make -C sim-core/firmware app SRC=… OUT=…` on a program outside the
/// tree (clang-19 and the RISC-V gcc, both installed by .ci/run), then run.
#[test]
fn make_app_builds_a_users_program() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("sum.c");
    std::fs::write(
        &src,
        r#"#include <pmsis.h>
#include <stdio.h>

static volatile int total;

static void add_id(void *arg)
{
    (void)arg;
    pi_cl_team_critical_enter();
    total += (int)pi_core_id() + 1;
    pi_cl_team_critical_exit();
}

static void entry(void *arg)
{
    (void)arg;
    pi_cl_team_fork(4, add_id, NULL);
}

int main(void)
{
    struct pi_device cl;
    struct pi_cluster_conf conf;
    struct pi_cluster_task task;
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cl, &conf);
    if (pi_cluster_open(&cl))
        return 1;
    pi_cluster_send_task_to_cl(&cl, pi_cluster_task(&task, entry, NULL));
    pi_cluster_close(&cl);
    printf("sum of ids+1 over 4 cores: %d\n", total);
    return 0;
}
"#,
    )
    .unwrap();
    let elf = dir.path().join("sum.elf");
    let fw_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("firmware");
    let make = Command::new("make")
        .arg("-C")
        .arg(&fw_dir)
        .arg("app")
        .arg(format!("SRC={}", src.display()))
        .arg(format!("OUT={}", elf.display()))
        .output()
        .expect("run make (install make, clang-19 and gcc-riscv64-unknown-elf: .ci/run)");
    assert!(make.status.success(), "make app: {}", stderr(&make));
    let o = run_elf(&elf, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stdout(&o), "sum of ids+1 over 4 cores: 10\n");

    // A missing source: a one-line usage error, non-zero status.
    let bad = Command::new("make")
        .arg("-C")
        .arg(&fw_dir)
        .arg("app")
        .arg(format!("SRC={}", dir.path().join("none.c").display()))
        .arg(format!("OUT={}", elf.display()))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(
        stderr(&bad).contains("app: no such file"),
        "{}",
        stderr(&bad)
    );
}
