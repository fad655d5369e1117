//! Tokio transport, used by the world server: codecs on
//! `tokio_util::codec::LengthDelimitedCodec` configured for this framing
//! (4-byte little-endian length, no adjustment, maximum frame), typed into
//! [`Request`] / [`Reply`] streams, and a listener with the same UNIX-socket
//! rules as the blocking server (stale file removal, mode 0600, "in use by a
//! live server").
//!
//! ```no_run
//! # async fn world() -> protocol::Result<()> {
//! use futures::{SinkExt, StreamExt};
//! use protocol::{tokio_transport::Listener, Reply, Request};
//! let listener = Listener::bind(&"unix:/tmp/world.sock".parse()?).await?;
//! let mut conn = listener.accept().await?; // one client at a time
//! while let Some(req) = conn.next().await {
//!     match req? {
//!         Request::GetSensors => { /* conn.send(&Reply::Sensors(..)).await? */ }
//!         Request::Stop => break,
//!         _ => conn.send(&Reply::error("not implemented")).await?,
//!     }
//! }
//! # Ok(()) }
//! ```

use std::marker::PhantomData;
use std::path::PathBuf;

use bytes::{Buf, BufMut, BytesMut};
use tokio::net::{TcpListener, TcpStream, UnixListener, UnixStream};
use tokio_util::codec::{Decoder, Encoder, Framed, LengthDelimitedCodec};
use tokio_util::either::Either;

use crate::endpoint::{bind_unix, tcp_bind_error, unlink_if_ours, Endpoint};
use crate::error::{ProtocolError, Result};
use crate::frame::{write_frame, DEFAULT_MAX_FRAME, HEADER_LEN};
use crate::image::{Image, ImageEncoding};
use crate::message::{decode_reply, decode_request, encode_reply, encode_request, Reply, Request};
use crate::trace::{Direction, FrameEvent, Observer};

/// A connected socket of either kind.
pub type AsyncStream = Either<UnixStream, TcpStream>;

/// Raw frames: bodies in, bodies out.
#[derive(Debug)]
pub struct FrameCodec {
    inner: LengthDelimitedCodec,
    max_frame: usize,
    /// Body length announced by a header the inner codec has consumed but
    /// whose body is not complete (to report truncation precisely).
    pending: Option<usize>,
}

impl FrameCodec {
    pub fn new(max_frame: usize) -> Self {
        let inner = LengthDelimitedCodec::builder()
            .little_endian()
            .length_field_offset(0)
            .length_field_length(HEADER_LEN)
            .length_adjustment(0)
            .num_skip(HEADER_LEN)
            .max_frame_length(max_frame)
            .new_codec();
        FrameCodec {
            inner,
            max_frame,
            pending: None,
        }
    }
}

impl Default for FrameCodec {
    fn default() -> Self {
        Self::new(DEFAULT_MAX_FRAME)
    }
}

impl Decoder for FrameCodec {
    type Item = BytesMut;
    type Error = ProtocolError;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<BytesMut>> {
        if self.pending.is_none() && src.len() >= HEADER_LEN {
            // Check the limit ourselves first: LengthDelimitedCodec would
            // refuse too, but with an untyped io::Error and no length.
            let len = (&src[..HEADER_LEN]).get_u32_le() as usize;
            if len > self.max_frame {
                return Err(ProtocolError::FrameTooLarge {
                    len: len as u64,
                    max: self.max_frame,
                });
            }
            self.pending = Some(len);
        }
        let frame = self.inner.decode(src)?;
        if frame.is_some() {
            self.pending = None;
        }
        Ok(frame)
    }

    fn decode_eof(&mut self, src: &mut BytesMut) -> Result<Option<BytesMut>> {
        match self.decode(src)? {
            Some(f) => Ok(Some(f)),
            None if src.is_empty() && self.pending.is_none() => Ok(None),
            None => Err(ProtocolError::Truncated {
                expected: self.pending.unwrap_or(HEADER_LEN),
                got: src.len(),
            }),
        }
    }
}

impl Encoder<&[u8]> for FrameCodec {
    type Error = ProtocolError;

    /// Writes header and body straight into `dst` (LengthDelimitedCodec's
    /// own encoder wants an owned `Bytes`, which would cost a copy).
    fn encode(&mut self, body: &[u8], dst: &mut BytesMut) -> Result<()> {
        if body.len() > self.max_frame {
            return Err(ProtocolError::FrameTooLarge {
                len: body.len() as u64,
                max: self.max_frame,
            });
        }
        dst.reserve(HEADER_LEN + body.len());
        dst.put_u32_le(body.len() as u32);
        dst.extend_from_slice(body);
        Ok(())
    }
}

/// Which end a [`MessageCodec`] is.
pub trait Side {
    /// What this end receives.
    type In;
    /// What this end sends.
    type Out;
    /// Direction of the frames this end receives.
    const IN: Direction;
    fn decode(body: &[u8]) -> Result<Self::In>;
    /// Encodes `msg`; returns the image inside it, if any (for observers).
    fn encode<'a>(
        msg: &'a Self::Out,
        enc: &mut ImageEncoding,
        out: &mut Vec<u8>,
    ) -> Option<&'a Image>;
}

/// The world's end: receives requests, sends replies.
#[derive(Debug)]
pub enum WorldSide {}

/// The platform's end: sends requests, receives replies.
#[derive(Debug)]
pub enum PlatformSide {}

impl Side for WorldSide {
    type In = Request;
    type Out = Reply;
    const IN: Direction = Direction::ToWorld;
    fn decode(body: &[u8]) -> Result<Request> {
        decode_request(body)
    }
    fn encode<'a>(r: &'a Reply, enc: &mut ImageEncoding, out: &mut Vec<u8>) -> Option<&'a Image> {
        // The GET_INIT_DATA reply fixes the encoding of later images.
        if let Reply::InitData { image_encoding, .. } = r {
            *enc = *image_encoding;
        }
        encode_reply(r, *enc, out);
        match r {
            Reply::Image(img) => Some(img),
            _ => None,
        }
    }
}

impl Side for PlatformSide {
    type In = Reply;
    type Out = Request;
    const IN: Direction = Direction::ToPlatform;
    fn decode(body: &[u8]) -> Result<Reply> {
        decode_reply(body)
    }
    fn encode<'a>(r: &'a Request, _: &mut ImageEncoding, out: &mut Vec<u8>) -> Option<&'a Image> {
        encode_request(r, out);
        None
    }
}

/// Typed codec: frames ↔ messages of one [`Side`].
pub struct MessageCodec<S: Side> {
    frames: FrameCodec,
    image_encoding: ImageEncoding,
    scratch: Vec<u8>,
    observer: Option<Observer>,
    _side: PhantomData<S>,
}

/// The world server's codec.
pub type ServerCodec = MessageCodec<WorldSide>;
/// A platform's codec (tests, tools).
pub type ClientCodec = MessageCodec<PlatformSide>;

impl<S: Side> MessageCodec<S> {
    pub fn new(max_frame: usize) -> Self {
        MessageCodec {
            frames: FrameCodec::new(max_frame),
            image_encoding: ImageEncoding::Array,
            scratch: Vec::new(),
            observer: None,
            _side: PhantomData,
        }
    }

    /// Shows every frame, sent or received, to `observer` (e.g. a trace).
    pub fn set_observer(&mut self, observer: Observer) {
        self.observer = Some(observer);
    }

    /// Image encoding used for outgoing images (set by sending the
    /// `GET_INIT_DATA` reply; can be forced here).
    pub fn image_encoding(&self) -> ImageEncoding {
        self.image_encoding
    }

    pub fn set_image_encoding(&mut self, e: ImageEncoding) {
        self.image_encoding = e;
    }

    fn notify(&mut self, ev: FrameEvent<'_>) -> Result<()> {
        match self.observer.as_mut() {
            Some(obs) => Ok(obs(&ev)?),
            None => Ok(()),
        }
    }
}

impl<S: Side> Default for MessageCodec<S> {
    fn default() -> Self {
        Self::new(DEFAULT_MAX_FRAME)
    }
}

impl<S: Side> Decoder for MessageCodec<S> {
    type Item = S::In;
    type Error = ProtocolError;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<S::In>> {
        match self.frames.decode(src)? {
            Some(body) => self.finish_decode(&body).map(Some),
            None => Ok(None),
        }
    }

    fn decode_eof(&mut self, src: &mut BytesMut) -> Result<Option<S::In>> {
        match self.frames.decode_eof(src)? {
            Some(body) => self.finish_decode(&body).map(Some),
            None => Ok(None),
        }
    }
}

impl<S: Side> MessageCodec<S> {
    fn finish_decode(&mut self, body: &[u8]) -> Result<S::In> {
        let decoded = S::decode(body);
        // Images received are only the platform's concern, whose observer
        // is in the blocking transport; here no image is passed on.
        self.notify(FrameEvent {
            dir: S::IN,
            bytes: body,
            image: None,
            valid: decoded.is_ok(),
        })?;
        decoded
    }
}

impl<S: Side> Encoder<&S::Out> for MessageCodec<S> {
    type Error = ProtocolError;

    fn encode(&mut self, msg: &S::Out, dst: &mut BytesMut) -> Result<()> {
        let mut buf = std::mem::take(&mut self.scratch);
        buf.clear();
        let mut enc = self.image_encoding;
        let mut image = None;
        let r = write_frame(&mut buf, self.frames.max_frame, |o| {
            image = S::encode(msg, &mut enc, o);
        });
        self.image_encoding = enc;
        let r = r.and_then(|()| {
            dst.extend_from_slice(&buf);
            self.notify(FrameEvent {
                dir: S::IN.reverse(),
                bytes: &buf[HEADER_LEN..],
                image,
                valid: true,
            })
        });
        self.scratch = buf;
        r
    }
}

/// The world's end of a connection.
pub type ServerFramed = Framed<AsyncStream, ServerCodec>;
/// The platform's end of a connection.
pub type ClientFramed = Framed<AsyncStream, ClientCodec>;

#[derive(Debug)]
enum Kind {
    Unix {
        l: UnixListener,
        path: PathBuf,
        ino: u64,
    },
    Tcp(TcpListener),
}

/// Listens on an endpoint; accept one client at a time.
#[derive(Debug)]
pub struct Listener {
    kind: Kind,
    max_frame: usize,
}

impl Listener {
    /// Binds `ep` (UNIX: stale file removed, mode 0600, live server detected;
    /// the file is removed on drop). Must run inside a tokio runtime.
    pub async fn bind(ep: &Endpoint) -> Result<Listener> {
        Self::bind_with(ep, DEFAULT_MAX_FRAME).await
    }

    pub async fn bind_with(ep: &Endpoint, max_frame: usize) -> Result<Listener> {
        Self::bind_backlog(ep, max_frame, 1).await
    }

    /// As [`Listener::bind_with`], holding `backlog` connections not yet
    /// accepted (UNIX; TCP keeps tokio's 1024). The thesis's listen(fd, 1)
    /// is 1.
    pub async fn bind_backlog(ep: &Endpoint, max_frame: usize, backlog: u32) -> Result<Listener> {
        let kind = match ep {
            Endpoint::Unix(p) => {
                let (l, ino) = bind_unix(p, backlog)?;
                l.set_nonblocking(true)?;
                Kind::Unix {
                    l: UnixListener::from_std(l)?,
                    path: p.clone(),
                    ino,
                }
            }
            Endpoint::Tcp(a) => Kind::Tcp(
                TcpListener::bind(a.as_str())
                    .await
                    .map_err(|e| tcp_bind_error(a, e))?,
            ),
        };
        Ok(Listener { kind, max_frame })
    }

    /// The bound endpoint (with the real port for `tcp:HOST:0`).
    pub fn local_endpoint(&self) -> Result<Endpoint> {
        Ok(match &self.kind {
            Kind::Unix { path, .. } => Endpoint::Unix(path.clone()),
            Kind::Tcp(l) => Endpoint::Tcp(l.local_addr()?.to_string()),
        })
    }

    /// Waits for the next client and frames it.
    pub async fn accept(&self) -> Result<ServerFramed> {
        let s = match &self.kind {
            Kind::Unix { l, .. } => {
                let s = l.accept().await?.0;
                crate::frame::enlarge_socket_buffers(std::os::fd::AsRawFd::as_raw_fd(&s));
                Either::Left(s)
            }
            Kind::Tcp(l) => {
                let s = l.accept().await?.0;
                s.set_nodelay(true)?;
                Either::Right(s)
            }
        };
        Ok(Framed::new(s, ServerCodec::new(self.max_frame)))
    }
}

impl Drop for Listener {
    fn drop(&mut self) {
        if let Kind::Unix { path, ino, .. } = &self.kind {
            unlink_if_ours(path, *ino);
        }
    }
}

/// Connects to a world (tests and tools; the platform itself is blocking).
pub async fn connect(ep: &Endpoint) -> Result<ClientFramed> {
    let s = match ep {
        Endpoint::Unix(p) => {
            let s = UnixStream::connect(p).await?;
            crate::frame::enlarge_socket_buffers(std::os::fd::AsRawFd::as_raw_fd(&s));
            Either::Left(s)
        }
        Endpoint::Tcp(a) => {
            let s = TcpStream::connect(a.as_str()).await?;
            s.set_nodelay(true)?;
            Either::Right(s)
        }
    };
    Ok(Framed::new(s, ClientCodec::default()))
}
