//! The `sim-core` platform mode's command line: bad input ends in a clear
//! one-line error and a non-zero exit.

use std::process::Command;

use e2e_tests::binary;

#[test]
fn missing_firmware_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(binary("sim-core", "sim-core"))
        .args(["--socket", dir.path().join("w.sock").to_str().unwrap()])
        .args(["--firmware", dir.path().join("nope.elf").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cannot read firmware"), "{err}");
    assert!(err.contains("nope.elf"), "{err}");
}

#[test]
fn a_corrupt_elf_is_a_clear_error_and_leaves_a_summary() {
    let dir = tempfile::tempdir().unwrap();
    let elf = dir.path().join("corrupt.elf");
    std::fs::write(&elf, b"\x7fELF this is not a RISC-V program").unwrap();
    // A listening socket so that the run gets as far as loading the ELF.
    let sock = dir.path().join("w.sock");
    let _listener = std::os::unix::net::UnixListener::bind(&sock).unwrap();
    let out_dir = dir.path().join("out");
    let out = Command::new(binary("sim-core", "sim-core"))
        .arg("--socket")
        .arg(&sock)
        .arg("--firmware")
        .arg(&elf)
        .arg("--out")
        .arg(&out_dir)
        .args(["--quiet", "--no-progress"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let last = err.lines().last().unwrap_or_default();
    assert!(last.contains("firmware"), "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["completed"], false);
    assert!(summary["error"].as_str().unwrap().contains("firmware"));
}

#[test]
fn unknown_run_config_key_is_a_clear_error() {
    let out = Command::new(binary("sim-core", "sim-core"))
        .args(["--socket", "/nonexistent/w.sock", "--firmware", "x.elf"])
        .args(["--set", "no_such_key=1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no_such_key"), "{err}");
}
