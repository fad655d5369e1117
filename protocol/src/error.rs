//! The one error type of the crate: every way a frame or a message can be
//! wrong has its own variant, so callers (and the one-line messages the
//! binaries print) name the problem instead of "parse error".

use std::io;

/// Everything that can go wrong reading, decoding, encoding or sending a frame.
#[derive(Debug, thiserror::Error)]
pub enum ProtocolError {
    /// The 4-byte length prefix announces more than the configured maximum.
    /// Raised before any buffer of that size is allocated.
    #[error("frame of {len} bytes exceeds the maximum frame size of {max} bytes")]
    FrameTooLarge { len: u64, max: usize },

    /// The stream ended in the middle of a frame (header or body).
    #[error("connection closed in the middle of a frame: expected {expected} bytes, got {got}")]
    Truncated { expected: usize, got: usize },

    /// The frame body is not UTF-8.
    #[error("frame body is not valid UTF-8 (first bad byte at offset {offset})")]
    InvalidUtf8 { offset: usize },

    /// The frame body is UTF-8 but not one JSON value.
    #[error("frame body is not valid JSON: {detail} (at byte {offset})")]
    InvalidJson { detail: String, offset: usize },

    /// The frame body is JSON but not an object.
    #[error("message is not a JSON object")]
    NotAnObject,

    /// The object has no `"command"` key.
    #[error("message has no \"command\" key")]
    MissingCommand,

    /// `"command"` names no known message (of the expected direction).
    #[error("unknown command {0:?}")]
    UnknownCommand(String),

    /// A known message with a missing, mistyped or out-of-range field.
    #[error("bad {command} message: {detail}")]
    BadField { command: String, detail: String },

    /// The peer answered with `{"command":"ERROR","error":...}`.
    #[error("the world replied with an error: {0}")]
    Remote(String),

    /// A reply arrived whose command does not answer the request sent.
    #[error("expected a reply to {expected}, got {got}")]
    UnexpectedReply { expected: &'static str, got: String },

    /// The peer closed the connection cleanly where a reply was due.
    #[error("connection closed by the peer while waiting for a reply to {0}")]
    Closed(&'static str),

    /// An endpoint string that is neither `unix:PATH`, `tcp:HOST:PORT` nor a path.
    #[error("bad endpoint {0:?}: expected unix:PATH, tcp:HOST:PORT or a socket path")]
    BadEndpoint(String),

    /// The socket path is bound by a server that still accepts connections.
    #[error("socket {path} is in use by a live server")]
    AddrInUse { path: String },

    /// Any other I/O failure (connect, bind, read, write).
    #[error("I/O error: {0}")]
    Io(#[from] io::Error),

    /// A frame in shared memory (`"image_encoding":"shm"`) cannot be read.
    #[error(transparent)]
    Shm(#[from] crate::shm::ShmError),
}

impl ProtocolError {
    pub(crate) fn bad(command: &str, detail: impl Into<String>) -> Self {
        ProtocolError::BadField {
            command: command.to_owned(),
            detail: detail.into(),
        }
    }

    pub(crate) fn json(e: &serde_json::Error, base: usize, line_offsets: &[u8]) -> Self {
        // serde_json reports line/column; turn them back into a byte offset so
        // the message points at the spot in the frame (frames are one line when
        // compact, but a foreign peer may send pretty JSON).
        let mut offset = base;
        let mut line = 1;
        for (i, &b) in line_offsets.iter().enumerate() {
            if line == e.line() {
                offset = base + i + e.column().saturating_sub(1);
                break;
            }
            if b == b'\n' {
                line += 1;
            }
        }
        ProtocolError::InvalidJson {
            detail: strip_position(&e.to_string()),
            offset,
        }
    }
}

/// serde_json appends " at line L column C"; we report a byte offset instead.
fn strip_position(s: &str) -> String {
    match s.rfind(" at line ") {
        Some(i) => s[..i].to_owned(),
        None => s.to_owned(),
    }
}

/// Shorthand used throughout the crate.
pub type Result<T, E = ProtocolError> = std::result::Result<T, E>;
