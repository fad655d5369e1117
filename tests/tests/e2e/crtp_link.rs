//! The CRTP link against raw datagrams (DESIGN.md §17, docs/CFLIB.md): `cosim run
//! cflib-lab` serves udp://127.0.0.1:19890; malformed packets, unknown
//! ports, channels, set-point types, log and param ids get what the
//! firmware answers (an errno, or nothing), and the drone keeps answering
//! and ends its run cleanly when the client goes quiet.

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use e2e_tests::{output_text, CosimBins};

const PORT: u16 = 19890;

/// The console's packets (port 0, link bits): the firmware's printed lines,
/// pushed to a client once it has connected, answers to nothing.
const CONSOLE_HEADER: u8 = 0x0C;

/// Sends `bytes`, returns the answer if one comes within 300 ms (console
/// lines are not answers: skipped, and the first one kept in `console`).
fn ask_noting_console(s: &UdpSocket, bytes: &[u8], console: &mut Vec<u8>) -> Option<Vec<u8>> {
    s.send(bytes).unwrap();
    let mut buf = [0u8; 64];
    loop {
        match s.recv(&mut buf) {
            Ok(n) if buf[0] == CONSOLE_HEADER && n > 0 => console.extend_from_slice(&buf[1..n]),
            Ok(n) => return Some(buf[..n].to_vec()),
            Err(_) => return None,
        }
    }
}

fn ask(s: &UdpSocket, bytes: &[u8]) -> Option<Vec<u8>> {
    ask_noting_console(s, bytes, &mut Vec::new())
}

#[test]
fn bad_packets_get_the_firmwares_answers_and_never_crash_the_drone() {
    let bins = CosimBins::new();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let spec = format!("crtp=udp:127.0.0.1:{PORT}");
    let child = bins
        .command(&[
            "run",
            "cflib-lab",
            "--out",
            out,
            "--no-plots",
            "--quiet",
            "--set",
            &spec,
            "--set",
            "pace=1",
            "--set",
            "crtp_idle_s=1",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.connect(("127.0.0.1", PORT)).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(300)))
        .unwrap();
    // The null packet (cflib's scan probe) is answered once the STM32 serves.
    let until = Instant::now() + Duration::from_secs(60);
    loop {
        if ask(&s, &[0xFF]) == Some(vec![0xFF]) {
            break;
        }
        assert!(Instant::now() < until, "the link never answered");
    }
    // Malformed: an empty datagram, 31 data bytes. The first packet that is
    // not a scan's probe connects: the console's lines follow.
    let mut console = Vec::new();
    assert_eq!(ask_noting_console(&s, &[], &mut console), None);
    assert_eq!(
        String::from_utf8_lossy(&console),
        "[crtp] serving the CRTP link\n"
    );
    assert_eq!(ask(&s, &[0xF0; 32]), None);
    // An unknown port, an unknown set-point type, a short high-level take-off.
    assert_eq!(ask(&s, &[0xA0, 1, 2]), None);
    assert_eq!(ask(&s, &[0x70, 42, 1, 2]), None);
    // Memories (port 4): a short read, a read of a memory that is not
    // there (EIO), the details of an id past the last, a write (the decks'
    // EEPROMs are read-only here: EIO).
    assert_eq!(ask(&s, &[0x41, 0, 0]), None);
    assert_eq!(
        ask(&s, &[0x41, 9, 0, 0, 0, 0, 4]),
        Some(vec![0x4D, 9, 0, 0, 0, 0, 5])
    );
    assert_eq!(ask(&s, &[0x40, 2, 9]), Some(vec![0x4C, 2]));
    assert_eq!(
        ask(&s, &[0x42, 0, 0, 0, 0, 0, 1]),
        Some(vec![0x4E, 0, 0, 0, 0, 0, 5])
    );
    assert_eq!(ask(&s, &[0x80, 7, 0]), None);
    // Log: a TOC item beyond the table gets nothing; a block with an
    // unknown variable ENOENT (2), a start of a missing block too.
    assert_eq!(ask(&s, &[0x50, 2, 0x0F, 0x27]), None);
    assert_eq!(
        ask(&s, &[0x51, 6, 1, 7, 0xFF, 0x7F]),
        Some(vec![0x5D, 6, 1, 2])
    );
    assert_eq!(ask(&s, &[0x51, 3, 9, 10]), Some(vec![0x5D, 3, 9, 2]));
    // Param: reading id 999 → ENOENT; writing it → nothing.
    assert_eq!(
        ask(&s, &[0x21, 0xE7, 0x03]),
        Some(vec![0x2D, 0xE7, 0x03, 2])
    );
    assert_eq!(ask(&s, &[0x22, 0xE7, 0x03, 1]), None);
    // Still the drone: echo, and the platform's protocol version.
    assert_eq!(ask(&s, &[0xF0, 1, 2, 3]), Some(vec![0xFC, 1, 2, 3]));
    assert_eq!(ask(&s, &[0xD1, 0]), Some(vec![0xDD, 0, 10]));
    // Quiet for crtp_idle_s: the link closes, the drone STOPs, the run ends.
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", output_text(&o));
    let console = std::fs::read_to_string(dir.path().join("console.log")).unwrap();
    assert!(console.contains("(2 malformed, 2 ignored"), "{console}");
    assert!(
        console.contains("[crtp] link closed, drone stopped"),
        "{console}"
    );
}
