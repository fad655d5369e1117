//! Wire protocol shared by `sim-core` (the virtual platform) and
//! `world-server` (the physics world): DESIGN.md §2, byte-compatible with the
//! thesis's VirtualConnector (§4.1.1, Appendix B). Full description, with
//! example frames, in `docs/PROTOCOL.md`.
//!
//! - [`frame`]: 4-byte little-endian length + compact UTF-8 JSON body,
//!   maximum frame size ([`DEFAULT_MAX_FRAME`]) checked before allocating.
//! - [`Request`] / [`Reply`]: the eleven commands and their replies, plus
//!   `ERROR`; [`encode_request`], [`encode_reply`] (nlohmann `dump()`
//!   spelling: sorted keys, no spaces) and [`decode_request`],
//!   [`decode_reply`] (unknown keys ignored, errors typed as
//!   [`ProtocolError`]).
//! - [`Image`] with [`ImageEncoding::Array`] (the thesis's, default),
//!   [`ImageEncoding::Base64`] or [`ImageEncoding::Shm`] (negotiated in
//!   `GET_INIT_DATA`; [`shm`]: the pixels in a shared-memory file).
//! - [`blocking`]: std sockets, for the lockstep platform.
//! - [`busy_poll`]: waiting for the peer's frame by polling for a short
//!   budget before sleeping (both transports).
//! - [`tokio_transport`]: a `tokio_util` codec on `LengthDelimitedCodec`,
//!   for the world server.
//! - [`trace`]: JSON-lines traces, writer and reader.
//! - [`series`]: a run's series files (CSV, plain or zstd-compressed),
//!   writer and reader.
//! - [`Endpoint`]: `unix:PATH` (default) or `tcp:HOST:PORT`.
//! - [`TimestepMs`]: the basicTimeStep and its rules, checked alike by
//!   all three processes.
//!
//! The calls the two binaries make:
//!
//! | side | call |
//! |---|---|
//! | platform | `blocking::Client::connect(&Endpoint) -> Result<Connection>` (or `connect_retry`) |
//! | platform | `Connection::request(&Request) -> Result<Option<Reply>>` (`None` for the reply-less `SET_VELOCITY` / `ADVANCE_TIME`; an `ERROR` reply is `Err(ProtocolError::Remote)`) |
//! | platform | `Connection::send(&Request) -> Result<()>` |
//! | platform | `Connection::pipeline(&[Request]) -> Result<Vec<Reply>, (usize, ProtocolError)>` (one write, replies in order) |
//! | world | `tokio_transport::Listener::bind(&Endpoint).await`, `listener.accept().await -> Result<ServerFramed>`, then `StreamExt::next` for [`Request`]s and `SinkExt::send(&Reply)` |
//! | world (blocking) | `blocking::Server::bind(&Endpoint)`, `server.accept() -> Result<Connection>`, `recv_request() -> Result<Option<Request>>` (`None` = clean close), `send_reply(&Reply)` |
//! | both | `set_observer(Box<dyn FnMut(&FrameEvent) -> io::Result<()> + Send>)` on a `Connection` or a codec; `trace::TraceWriter::record(&FrameEvent, now)` inside it |
//!
//! The image encoding of the world's replies follows the `GET_INIT_DATA`
//! reply it sent (`Reply::InitData { image_encoding, .. }`); decoding detects
//! the encoding by itself.

pub mod airframe;
pub mod blocking;
pub mod busy_poll;
mod decode;
pub mod dump;
mod endpoint;
mod error;
pub mod frame;
pub mod heap;
mod image;
mod message;
pub mod radio;
pub mod sched;
pub mod series;
pub mod shm;
mod timestep;
pub mod tokio_transport;
pub mod trace;

pub use endpoint::Endpoint;
pub use error::{ProtocolError, Result};
pub use frame::DEFAULT_MAX_FRAME;
pub use image::{sha256_hex, Image, ImageEncoding};
pub use message::{
    command, decode_reply, decode_request, encode_reply, encode_request, Reply, Request, Sensors,
    State,
};
pub use radio::{Radio, RadioPacket, TxDone};
pub use timestep::{TimestepError, TimestepMs};
pub use trace::{Direction, FrameEvent, Observer};
