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
