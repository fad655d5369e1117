//! Port 0, console (the firmware's `console.c`, cflib's `console.py`): the
//! firmware's printed text, sent to the client on channel 0 in packets of
//! at most 30 bytes. The firmware fills a packet and sends it at a newline
//! or when it is full; here every complete line of `console.log` is sent
//! that way once the client has spoken (cflib's `Console.receivedChar`
//! gets each packet's text). Two differences, both for the client's sake:
//! what was printed before the client's first packet (the firmware's start
//! lines) is kept and sent then, where the firmware would have dropped it
//! with no link up; and a packet is never cut inside a UTF-8 character
//! (cflib decodes each packet on its own and would fail on half of one).

use std::sync::{Arc, Mutex};

use super::packet::MAX_DATA;

/// The console's text not yet sent, shared with the kernel's console
/// (`kernel::Console::tap`), which appends everything it prints.
pub type ConsoleTap = Arc<Mutex<Vec<u8>>>;

/// At most this much unsent text is kept (the oldest is dropped), so a run
/// whose client never connects does not grow it without bound.
pub const MAX_PENDING: usize = 4096;

/// Appends `bytes` to the tap, keeping at most [`MAX_PENDING`] bytes.
pub fn append(tap: &ConsoleTap, bytes: &[u8]) {
    let mut t = tap.lock().expect("console tap lock");
    t.extend_from_slice(bytes);
    if t.len() > MAX_PENDING {
        let cut = t.len() - MAX_PENDING;
        t.drain(..cut);
    }
}

/// The packets' data for the complete lines of the tap (taken from it;
/// a partial line stays for later).
pub fn take_packets(tap: &ConsoleTap) -> Vec<Vec<u8>> {
    let mut t = tap.lock().expect("console tap lock");
    let Some(end) = t.iter().rposition(|&b| b == b'\n') else {
        return Vec::new();
    };
    let lines: Vec<u8> = t.drain(..=end).collect();
    let mut out = Vec::new();
    for line in lines.split_inclusive(|&b| b == b'\n') {
        let mut rest = line;
        while !rest.is_empty() {
            let mut n = rest.len().min(MAX_DATA);
            // Back off to a character boundary (a UTF-8 continuation byte
            // is 0b10xx_xxxx); a 30-byte run of continuation bytes is not
            // UTF-8 anyway and is cut where it is.
            while n < rest.len() && n > 0 && rest[n] & 0xC0 == 0x80 {
                n -= 1;
            }
            if n == 0 {
                n = rest.len().min(MAX_DATA);
            }
            out.push(rest[..n].to_vec());
            rest = &rest[n..];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_sent_whole_in_packets_of_30_bytes() {
        let tap = ConsoleTap::default();
        append(&tap, b"[crtp] serving the CRTP link\nhalf a li");
        assert_eq!(
            take_packets(&tap),
            vec![b"[crtp] serving the CRTP link\n".to_vec()]
        );
        assert!(take_packets(&tap).is_empty());
        let long = format!("ne {}\n", "é".repeat(20));
        append(&tap, long.as_bytes());
        let p = take_packets(&tap);
        assert!(p.iter().all(|d| d.len() <= MAX_DATA));
        // Each packet decodes on its own, and together they are the line.
        let text: String = p
            .iter()
            .map(|d| std::str::from_utf8(d).expect("whole characters"))
            .collect();
        assert_eq!(text, format!("half a li{long}"));
    }

    #[test]
    fn pending_text_is_bounded() {
        let tap = ConsoleTap::default();
        append(&tap, &vec![b'x'; MAX_PENDING + 10]);
        assert_eq!(tap.lock().unwrap().len(), MAX_PENDING);
    }
}
