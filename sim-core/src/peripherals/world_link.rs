//! The platform's end of the socket to the world (the thesis's
//! VirtualConnector as the sensors use it, §4.1.1): typed requests, typed
//! replies, and the traffic figures for `summary.json`.

use protocol::{Reply, Request};
use thiserror::Error;

use crate::units::Picos;

/// A failed exchange with the world.
#[derive(Debug, Error)]
pub enum LinkError {
    #[error("{0}")]
    Protocol(#[from] protocol::ProtocolError),
    #[error("the world answered {request} with an error: {message}")]
    Remote {
        request: &'static str,
        message: String,
    },
    #[error("the world answered {request} with {reply}")]
    Unexpected {
        request: &'static str,
        reply: &'static str,
    },
    #[error("the world closed the connection during {request}")]
    Closed { request: &'static str },
}

/// Counters of the traffic over the link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkStats {
    pub messages: u64,
    pub bytes_to_world: u64,
    pub bytes_to_platform: u64,
}

/// Something that answers the platform's requests: the world server over a
/// socket, or a world model in the same process.
pub trait WorldLink {
    /// Sends a request that has a reply and returns the reply. A reply with
    /// `"command":"ERROR"` is an error.
    fn call(&mut self, request: &Request, now: Picos) -> Result<Reply, LinkError>;
    /// Sends a request without reply (SET_VELOCITY, ADVANCE_TIME).
    fn send(&mut self, request: &Request, now: Picos) -> Result<(), LinkError>;
    fn stats(&self) -> LinkStats;
}
