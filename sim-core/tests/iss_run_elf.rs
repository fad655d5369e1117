//! The `sim-core run-elf` command line (DESIGN.md §4, §12): riscv-tests
//! `tohost` exit codes, RISCOF signatures, semihosting output, the
//! instruction limit, `--stats`, and clear errors on bad input.

mod iss_util;

use std::process::{Command, Output};

use iss_util::firmware;

fn sim_core(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sim-core"))
        .arg("run-elf")
        .args(args)
        .output()
        .expect("run sim-core")
}

fn fw(name: &str) -> String {
    firmware(name).to_str().unwrap().to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A failed run: non-zero status, one clear error line, no panic.
fn assert_clean_error(o: &Output, needle: &str) {
    let err = stderr(o);
    assert_ne!(o.status.code(), Some(0), "{err}");
    assert!(o.status.code().is_some(), "killed by a signal: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("error") && err.contains(needle), "{err}");
}

#[test]
fn tohost_pass_and_fail() {
    assert_eq!(sim_core(&[&fw("rvtest_pass")]).status.code(), Some(0));
    // tohost = (3 << 1) | 1: test 3 failed.
    assert_eq!(sim_core(&[&fw("rvtest_fail")]).status.code(), Some(3));
    // An unexpected trap with a0 = 0 fails as test 1337 (it once passed);
    // the exit status keeps the low 8 bits: 1337 & 0xff = 57.
    assert_eq!(sim_core(&[&fw("rvtest_trap")]).status.code(), Some(57));
}

#[test]
fn signature_is_written_one_word_per_line() {
    let dir = tempfile::tempdir().unwrap();
    let sig = dir.path().join("sig.txt");
    let o = sim_core(&[&fw("rvtest_sig"), "--signature", sig.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // 0x12345678 & 0x0f0f0f0f, the low word of 0x12345678 * 0x0f0f0f0f,
    // 0x12345678 >> 4 (arithmetic), and the patched immediate (fence.i).
    assert_eq!(
        std::fs::read_to_string(&sig).unwrap(),
        "02040608\n3b2a1908\n01234567\n00000002\n"
    );
}

#[test]
fn semihosting_console_goes_to_stdout() {
    let o = sim_core(&[&fw("hello")]);
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(
        String::from_utf8_lossy(&o.stdout),
        "Hello from the RV32IMC ISS!\n"
    );
}

#[test]
fn instruction_limit_exits_124() {
    let o = sim_core(&[&fw("bench"), "--max-instructions", "1000"]);
    assert_eq!(o.status.code(), Some(124));
}

#[test]
fn stats_go_to_stderr() {
    let o = sim_core(&[&fw("hello"), "--stats"]);
    assert_eq!(o.status.code(), Some(0));
    let err = stderr(&o);
    for key in [
        "instructions:",
        "cycles:",
        "simulated time:",
        "wall time:",
        "MIPS:",
    ] {
        assert!(err.contains(key), "{err}");
    }
}

#[test]
fn explicit_ram_regions() {
    let ok = sim_core(&[&fw("rvtest_pass"), "--ram", "0x80000000:64K"]);
    assert_eq!(ok.status.code(), Some(0), "{}", stderr(&ok));
    let outside = sim_core(&[&fw("rvtest_pass"), "--ram", "0x90000000:0x1000"]);
    assert_clean_error(&outside, "outside every RAM region");
    let bad = sim_core(&[&fw("rvtest_pass"), "--ram", "nonsense"]);
    assert_ne!(bad.status.code(), Some(0));
}

#[test]
fn bad_elves_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(firmware("hello")).unwrap();

    let truncated = dir.path().join("truncated.elf");
    std::fs::write(&truncated, &bytes[..100]).unwrap();
    assert_clean_error(&sim_core(&[truncated.to_str().unwrap()]), "ELF");

    let garbage = dir.path().join("garbage.elf");
    std::fs::write(&garbage, b"this is not an ELF file at all").unwrap();
    assert_clean_error(&sim_core(&[garbage.to_str().unwrap()]), "ELF");

    // The test binary itself: a valid ELF for another architecture.
    let host = std::env::current_exe().unwrap();
    assert_clean_error(&sim_core(&[host.to_str().unwrap()]), "RISC-V");

    assert_clean_error(&sim_core(&["/nonexistent/x.elf"]), "reading");
}

#[test]
fn fetch_from_unmapped_memory_is_a_clear_error() {
    // rvtest_pass with its entry point (e_entry, offset 0x18) moved to an
    // address with no memory behind it and no trap handler installed yet.
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = std::fs::read(firmware("rvtest_pass")).unwrap();
    bytes[0x18..0x1c].copy_from_slice(&0x4000_0000u32.to_le_bytes());
    let p = dir.path().join("bad_entry.elf");
    std::fs::write(&p, bytes).unwrap();
    assert_clean_error(&sim_core(&[p.to_str().unwrap()]), "0x40000000");
}
