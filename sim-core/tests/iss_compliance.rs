//! The upstream RISC-V compliance suites on the ISS, under both back ends
//! (DESIGN.md §14: the riscv-tests and the architecture tests give identical
//! signatures, cycle counts and traces under interp and jit).
//!
//! The ELFs in `tests/compliance/` are built from riscv-tests (the "p"
//! environment: rv32ui, rv32um, rv32uc, rv32mi) and riscv-arch-test 2.7.4
//! (RV32 I, M, C, Zifencei, privilege, with our model in
//! `compliance/model/`); `compliance/build.sh` rebuilds them from the
//! upstream sources and checks they are byte-identical. What is left out,
//! and why, is in `compliance/README.md`.
//!
//! Each program runs through `sim-core run-elf --no-cluster` (riscv-tests'
//! reset code spins unless mhartid is 0, the FC's id without the cluster)
//! under `interp` and `jit`: a riscv-test must pass (`tohost` = 1, exit
//! 0), an architecture test's signature must equal the suite's reference
//! signature, and the two back ends must agree on the signature, the exit
//! status, and the instruction and cycle counts.

use std::path::{Path, PathBuf};
use std::process::Command;

fn compliance_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/compliance")
}

fn elfs(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "elf"))
        .collect();
    v.sort();
    v
}

/// One run: exit status, the `--stats` lines that count (instructions,
/// cycles), and the signature (empty without `--signature`).
#[derive(Debug, PartialEq)]
struct Run {
    status: Option<i32>,
    counts: Vec<String>,
    signature: String,
}

fn run(elf: &Path, iss: &str, signature: bool) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let sig = dir.path().join("sig");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_sim-core"));
    cmd.args(["run-elf", "--no-cluster", "--stats", "--iss", iss])
        .args(["--max-instructions", "50000000"])
        .arg(elf);
    if signature {
        cmd.arg("--signature").arg(&sig);
    }
    let out = cmd.output().expect("run sim-core");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let counts = stderr
        .lines()
        .filter(|l| l.starts_with("instructions:") || l.starts_with("cycles:"))
        .map(str::to_owned)
        .collect::<Vec<_>>();
    assert_eq!(counts.len(), 2, "{}: {stderr}", elf.display());
    Run {
        status: out.status.code(),
        counts,
        signature: if signature {
            std::fs::read_to_string(&sig).unwrap_or_default()
        } else {
            String::new()
        },
    }
}

fn name(p: &Path) -> String {
    let parent = p.parent().unwrap().file_name().unwrap().to_string_lossy();
    format!("{parent}/{}", p.file_stem().unwrap().to_string_lossy())
}

#[test]
fn riscv_tests_pass_identically_under_both_back_ends() {
    let all = elfs(&compliance_dir().join("riscv-tests"));
    assert_eq!(all.len(), 66, "rv32ui 42 + rv32um 8 + rv32uc 1 + rv32mi 15");
    let mut failed = Vec::new();
    for elf in &all {
        let interp = run(elf, "interp", false);
        let jit = run(elf, "jit", false);
        if interp.status != Some(0) {
            failed.push(format!(
                "{}: exit {:?} (test {:?} failed)",
                name(elf),
                interp.status,
                interp.status
            ));
        }
        if interp != jit {
            failed.push(format!("{}: interp {interp:?} != jit {jit:?}", name(elf)));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

#[test]
fn architecture_tests_match_the_reference_signatures_under_both_back_ends() {
    let mut failed = Vec::new();
    let mut count = 0;
    for suite in ["I", "M", "C", "Zifencei", "privilege"] {
        for elf in elfs(&compliance_dir().join("arch-test").join(suite)) {
            count += 1;
            let reference = std::fs::read_to_string(elf.with_extension("reference_output"))
                .unwrap_or_else(|e| panic!("{}: {e}", name(&elf)));
            let interp = run(&elf, "interp", true);
            let jit = run(&elf, "jit", true);
            if interp.status != Some(0) {
                failed.push(format!("{}: exit {:?}", name(&elf), interp.status));
            }
            if interp.signature.trim_end() != reference.trim_end() {
                failed.push(format!(
                    "{}: the signature differs from the reference",
                    name(&elf)
                ));
            }
            if interp != jit {
                failed.push(format!("{}: interp {interp:?} != jit {jit:?}", name(&elf)));
            }
        }
    }
    // I 38 + M 8 + C 27 + Zifencei 1 + privilege 16 - 5 (README.md).
    assert_eq!(count, 85);
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}
