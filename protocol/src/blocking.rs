//! Blocking transport over `std::os::unix::net` (and `std::net` for `tcp:`),
//! used by the lockstep virtual platform.
//!
//! One [`Connection`] type serves both ends: the platform gets it from
//! [`Client::connect`] and calls [`Connection::request`] / [`Connection::send`];
//! the world gets it from [`Server::accept`] and calls
//! [`Connection::recv_request`] / [`Connection::send_reply`]. Every frame sent
//! or received is shown, as raw bytes, to an optional observer (the trace
//! writer) so tracing never re-serialises.

use std::io::{self, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::busy_poll::{BusyPoll, IdleWork};
use crate::endpoint::{bind_unix, tcp_bind_error, unlink_if_ours, Endpoint};
use crate::error::{ProtocolError, Result};
use crate::frame::{read_frame, write_frame, DEFAULT_MAX_FRAME};
use crate::image::{Image, ImageEncoding};
use crate::message::{decode_reply, decode_request, encode_reply, encode_request, Reply, Request};
use crate::trace::{Direction, FrameEvent, Observer};

/// A connected stream socket of either kind.
#[derive(Debug)]
pub enum Stream {
    Unix(UnixStream),
    Tcp(TcpStream),
}

impl Stream {
    /// Connects once.
    pub fn connect(ep: &Endpoint) -> io::Result<Stream> {
        Ok(match ep {
            Endpoint::Unix(p) => {
                let s = UnixStream::connect(p)?;
                crate::frame::enlarge_socket_buffers(std::os::fd::AsRawFd::as_raw_fd(&s));
                Stream::Unix(s)
            }
            Endpoint::Tcp(a) => {
                let s = TcpStream::connect(a.as_str())?;
                // Lockstep request/reply: Nagle would add a delay per frame.
                s.set_nodelay(true)?;
                Stream::Tcp(s)
            }
        })
    }

    /// Shuts both directions down (the peer then reads end of stream).
    pub fn shutdown(&self) -> io::Result<()> {
        match self {
            Stream::Unix(s) => s.shutdown(std::net::Shutdown::Both),
            Stream::Tcp(s) => s.shutdown(std::net::Shutdown::Both),
        }
    }

    fn raw_fd(&self) -> std::os::fd::RawFd {
        use std::os::fd::AsRawFd;
        match self {
            Stream::Unix(s) => s.as_raw_fd(),
            Stream::Tcp(s) => s.as_raw_fd(),
        }
    }
}

impl Read for Stream {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Stream::Unix(s) => s.read(buf),
            Stream::Tcp(s) => s.read(buf),
        }
    }
}

/// The stream as a connection reads it: polling for the peer's bytes for
/// the busy-poll budget before blocking ([`BusyPoll`]), doing the idle work
/// meanwhile.
struct Polled {
    stream: Stream,
    poll: BusyPoll,
    work: Vec<IdleWork>,
}

impl Read for Polled {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let fd = self.stream.raw_fd();
        match self.poll.recv_or_work(fd, buf, &mut self.work) {
            Some(r) => r,
            None => self.stream.read(buf),
        }
    }
}

impl Write for Stream {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Stream::Unix(s) => s.write(buf),
            Stream::Tcp(s) => s.write(buf),
        }
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Which end of the protocol a connection is (decides trace directions).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// The virtual platform: sends requests.
    Platform,
    /// The world: sends replies.
    World,
}

/// Connection options.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Largest frame body accepted or sent.
    pub max_frame: usize,
    /// How long a read polls for the peer's bytes before it blocks
    /// (default: off; the binaries poll for [`crate::busy_poll::DEFAULT_US`]).
    pub busy_poll: BusyPoll,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            max_frame: DEFAULT_MAX_FRAME,
            busy_poll: BusyPoll::OFF,
        }
    }
}

/// One end of a connection.
pub struct Connection {
    io: BufReader<Polled>,
    role: Role,
    max_frame: usize,
    rbuf: Vec<u8>,
    wbuf: Vec<u8>,
    /// Image encoding used by `send_reply` (world side); set by sending an
    /// `InitData` reply, i.e. by the `GET_INIT_DATA` negotiation.
    image_encoding: ImageEncoding,
    observer: Option<Observer>,
    /// Platform side: the world's shared-memory image file, once a reply
    /// has named it (`"image_encoding":"shm"`).
    shm: crate::shm::ShmReader,
    /// Platform side: the last deferred reply
    /// ([`Connection::request_deferred`]), decoded at the next receive.
    deferred: Option<Arc<Mutex<Slot>>>,
}

/// A deferred reply: the frame body, then, once decoded (by the
/// connection before it reads its next frame, or by the waiter), the
/// result. The body stays for the next deferred frame to reuse (a 380 KB
/// buffer, not allocated and faulted in per image).
#[derive(Debug)]
struct Slot {
    body: Vec<u8>,
    reply: Option<Result<Reply>>,
}

impl Slot {
    fn decode(&mut self) {
        if self.reply.is_none() {
            self.reply = Some(decode_reply(&self.body));
        }
    }
}

fn lock(slot: &Mutex<Slot>) -> std::sync::MutexGuard<'_, Slot> {
    // Decoding cannot panic short of a bug; the data stays consistent.
    slot.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A reply received whole but perhaps not yet decoded
/// ([`Connection::request_deferred`]).
#[derive(Debug)]
pub struct PendingReply {
    command: &'static str,
    state: Pending,
}

#[derive(Debug)]
enum Pending {
    /// What [`Connection::request`] gave (already checked).
    Ready(Result<Reply>),
    Deferred(Arc<Mutex<Slot>>),
}

impl PendingReply {
    /// The reply, with exactly the result [`Connection::request`] would
    /// have given for the same frame (the same errors, by the same code).
    pub fn wait(self) -> Result<Reply> {
        match self.state {
            Pending::Ready(r) => r,
            Pending::Deferred(slot) => {
                let mut s = lock(&slot);
                s.decode();
                let decoded = s.reply.take().expect("decoded above");
                check_reply(self.command, decoded?)
            }
        }
    }
}

/// `reply`, which must answer `command` (see [`Connection::request`]).
fn check_reply(command: &'static str, reply: Reply) -> Result<Reply> {
    match reply {
        Reply::Error { error } => Err(ProtocolError::Remote(error)),
        r if r.command() == command => Ok(r),
        r => Err(ProtocolError::UnexpectedReply {
            expected: command,
            got: r.command().to_owned(),
        }),
    }
}

impl std::fmt::Debug for Connection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Connection")
            .field("stream", &self.io.get_ref().stream)
            .field("role", &self.role)
            .field("image_encoding", &self.image_encoding)
            .finish_non_exhaustive()
    }
}

/// Read buffer: a small frame arrives with one `read`; large bodies bypass it.
const READ_BUF: usize = 64 * 1024;

impl Connection {
    /// Wraps a connected stream.
    pub fn new(stream: Stream, role: Role, opts: Options) -> Self {
        Connection {
            io: BufReader::with_capacity(
                READ_BUF,
                Polled {
                    stream,
                    poll: opts.busy_poll,
                    work: Vec::new(),
                },
            ),
            role,
            max_frame: opts.max_frame,
            rbuf: Vec::new(),
            wbuf: Vec::new(),
            image_encoding: ImageEncoding::Array,
            observer: None,
            shm: crate::shm::ShmReader::new(),
            deferred: None,
        }
    }

    /// Shows every frame, sent or received, to `observer` (e.g. a closure
    /// around a [`crate::trace::TraceWriter`]). An observer error aborts the
    /// operation with [`ProtocolError::Io`].
    pub fn set_observer(&mut self, observer: Observer) {
        self.observer = Some(observer);
    }

    pub fn role(&self) -> Role {
        self.role
    }

    /// Adds work to do while waiting for the peer's bytes ([`IdleWork`]);
    /// what was added first goes first.
    pub fn add_idle_work(&mut self, work: IdleWork) {
        self.io.get_mut().work.push(work);
    }

    /// The image encoding `send_reply` uses.
    pub fn image_encoding(&self) -> ImageEncoding {
        self.image_encoding
    }

    /// Overrides the image encoding `send_reply` uses (normally set by
    /// sending the `GET_INIT_DATA` reply).
    pub fn set_image_encoding(&mut self, e: ImageEncoding) {
        self.image_encoding = e;
    }

    pub fn stream(&self) -> &Stream {
        &self.io.get_ref().stream
    }

    fn out_dir(&self) -> Direction {
        match self.role {
            Role::Platform => Direction::ToWorld,
            Role::World => Direction::ToPlatform,
        }
    }

    // ------------------------------------------------------------ raw frames

    /// Sends one frame whose body `body` writes (header + body in one write).
    pub fn send_frame_with(
        &mut self,
        image: Option<&Image>,
        body: impl FnOnce(&mut Vec<u8>),
    ) -> Result<()> {
        self.wbuf.clear();
        write_frame(&mut self.wbuf, self.max_frame, body)?;
        self.io.get_mut().stream.write_all(&self.wbuf)?;
        let ev = FrameEvent {
            dir: self.out_dir(),
            bytes: &self.wbuf[4..],
            image,
            valid: true,
        };
        notify(&mut self.observer, &ev)
    }

    /// Sends a frame with this exact body (for replay tools and tests).
    pub fn send_raw(&mut self, body: &[u8]) -> Result<()> {
        self.send_frame_with(None, |o| o.extend_from_slice(body))
    }

    /// Sends frames with these exact bodies in one write (replay tools
    /// pipelining recorded requests).
    pub fn send_raw_batch(&mut self, bodies: &[&[u8]]) -> Result<()> {
        self.wbuf.clear();
        for b in bodies {
            write_frame(&mut self.wbuf, self.max_frame, |o| o.extend_from_slice(b))?;
        }
        self.io.get_mut().stream.write_all(&self.wbuf)?;
        let dir = self.out_dir();
        for b in bodies {
            let ev = FrameEvent {
                dir,
                bytes: b,
                image: None,
                valid: true,
            };
            notify(&mut self.observer, &ev)?;
        }
        Ok(())
    }

    /// Receives one frame body; `None` on a clean end of stream between
    /// frames. The slice is valid until the next receive.
    pub fn recv_raw(&mut self) -> Result<Option<&[u8]>> {
        if read_frame(&mut self.io, &mut self.rbuf, self.max_frame)? {
            Ok(Some(&self.rbuf))
        } else {
            Ok(None)
        }
    }

    // ------------------------------------------------------- platform side

    /// Sends a request without waiting (the only way for `SET_VELOCITY` and
    /// `ADVANCE_TIME`, which have no reply).
    ///
    /// If the world has already closed (it does so after answering a bad
    /// no-reply command with ERROR), the write fails; the ERROR frame it left
    /// behind is then reported as [`ProtocolError::Remote`] rather than a
    /// bare "broken pipe".
    pub fn send(&mut self, req: &Request) -> Result<()> {
        match self.send_frame_with(None, |o| encode_request(req, o)) {
            Err(ProtocolError::Io(e))
                if matches!(
                    e.kind(),
                    io::ErrorKind::BrokenPipe | io::ErrorKind::ConnectionReset
                ) =>
            {
                match self.recv_reply() {
                    Ok(Some(Reply::Error { error })) => Err(ProtocolError::Remote(error)),
                    _ => Err(ProtocolError::Io(e)),
                }
            }
            r => r,
        }
    }

    /// Sends a request and waits for its reply. A reply-less request is just
    /// sent and `Ok(None)` returned; an `ERROR` reply becomes
    /// [`ProtocolError::Remote`]; a reply to another command is
    /// [`ProtocolError::UnexpectedReply`].
    pub fn request(&mut self, req: &Request) -> Result<Option<Reply>> {
        self.send(req)?;
        if !req.expects_reply() {
            return Ok(None);
        }
        self.reply_to(req).map(Some)
    }

    /// The next reply, which must answer `req`.
    fn reply_to(&mut self, req: &Request) -> Result<Reply> {
        let reply = self
            .recv_reply()?
            .ok_or(ProtocolError::Closed(req.command()))?;
        check_reply(req.command(), reply)
    }

    /// [`Connection::request`] for a request with a reply, its reply
    /// decoded later: returns once the frame is read whole, and
    /// [`PendingReply::wait`] gives what `request` would have given. The
    /// frame is decoded by the next `request_deferred`, once its request is
    /// written (so while the world works on it: in the race the next
    /// `GET_IMAGE`, which the world renders), or by `wait` if that comes
    /// first: a camera image's ~380 KB of JSON are parsed while the
    /// platform would otherwise wait. (Other requests in between leave it
    /// undecoded: their answers are the world's quick ones.)
    ///
    /// The observer sees the frame when it is read, without the decoded
    /// image (`image: None`) and with `valid: true` (not yet known): use
    /// this only when no trace needs the image's hash. Replies in shared
    /// memory (`"image_encoding":"shm"` negotiated) are decoded at once, as
    /// the next image overwrites the file.
    pub fn request_deferred(&mut self, req: &Request) -> Result<PendingReply> {
        let command = req.command();
        if !req.expects_reply() || self.image_encoding == ImageEncoding::Shm {
            let state = Pending::Ready(match self.request(req) {
                Ok(Some(r)) => Ok(r),
                Ok(None) => Err(ProtocolError::Closed(command)),
                Err(e) => Err(e),
            });
            return Ok(PendingReply { command, state });
        }
        self.send(req)?;
        // Decodes the previous deferred frame if nobody did, and reuses
        // its buffer.
        self.settle_deferred();
        let mut body = match self.deferred.take() {
            Some(slot) => std::mem::take(&mut lock(&slot).body),
            None => Vec::new(),
        };
        if !read_frame(&mut self.io, &mut body, self.max_frame)? {
            return Err(ProtocolError::Closed(command));
        }
        let ev = FrameEvent {
            dir: Direction::ToPlatform,
            bytes: &body,
            image: None,
            valid: true,
        };
        notify(&mut self.observer, &ev)?;
        let slot = Arc::new(Mutex::new(Slot { body, reply: None }));
        self.deferred = Some(Arc::clone(&slot));
        Ok(PendingReply {
            command,
            state: Pending::Deferred(slot),
        })
    }

    /// Decodes the deferred frame, if any is still undecoded.
    fn settle_deferred(&mut self) {
        if let Some(slot) = &self.deferred {
            lock(slot).decode();
        }
    }

    /// Pipelining: sends `reqs` in one write, then reads the replies of the
    /// ones that have a reply, in order (a conforming world answers in
    /// order, DESIGN.md §2, so this needs no negotiation). One write and,
    /// usually, one read instead of one of each per request.
    ///
    /// The observer sees the frames in the order a one-at-a-time exchange
    /// would show them (each request, then its reply), so a trace is the
    /// same byte for byte. On failure, the error comes with the index in
    /// `reqs` of the request it concerns.
    pub fn pipeline(
        &mut self,
        reqs: &[Request],
    ) -> std::result::Result<Vec<Reply>, (usize, ProtocolError)> {
        self.wbuf.clear();
        let mut ends = Vec::with_capacity(reqs.len());
        for (i, req) in reqs.iter().enumerate() {
            write_frame(&mut self.wbuf, self.max_frame, |o| encode_request(req, o))
                .map_err(|e| (i, e))?;
            ends.push(self.wbuf.len());
        }
        if let Err(e) = self.io.get_mut().stream.write_all(&self.wbuf) {
            // As in `send`: a world that already closed left an ERROR frame.
            let first = reqs.iter().position(Request::expects_reply).unwrap_or(0);
            return Err((
                first,
                match self.recv_reply() {
                    Ok(Some(Reply::Error { error })) => ProtocolError::Remote(error),
                    _ => ProtocolError::Io(e),
                },
            ));
        }
        let wbuf = std::mem::take(&mut self.wbuf);
        let mut replies = Vec::new();
        let mut start = 0;
        let mut outcome = Ok(());
        for (i, (req, end)) in reqs.iter().zip(ends).enumerate() {
            let ev = FrameEvent {
                dir: self.out_dir(),
                bytes: &wbuf[start + 4..end],
                image: None,
                valid: true,
            };
            start = end;
            if let Err(e) = notify(&mut self.observer, &ev) {
                outcome = Err((i, e));
                break;
            }
            if req.expects_reply() {
                match self.reply_to(req) {
                    Ok(r) => replies.push(r),
                    Err(e) => {
                        outcome = Err((i, e));
                        break;
                    }
                }
            }
        }
        self.wbuf = wbuf;
        outcome.map(|()| replies)
    }

    /// Receives one reply; `None` on a clean close.
    pub fn recv_reply(&mut self) -> Result<Option<Reply>> {
        // A deferred frame stays undecoded here: the next deferred request
        // (in the race the next GET_IMAGE, the world's longest answer)
        // decodes it while the world works, or `wait` does.
        if !read_frame(&mut self.io, &mut self.rbuf, self.max_frame)? {
            return Ok(None);
        }
        let decoded = match decode_reply(&self.rbuf) {
            // The pixels of a frame in shared memory: read them now, so the
            // platform (and the trace's hash) sees an ordinary image.
            Ok(Reply::ShmImage(f)) => self.shm.read(&f).map(Reply::Image).map_err(Into::into),
            d => d,
        };
        // Platform side: remember the negotiated encoding (decides whether
        // `request_deferred` may defer).
        if let (Role::Platform, Ok(Reply::InitData { image_encoding, .. })) = (self.role, &decoded)
        {
            self.image_encoding = *image_encoding;
        }
        let image = match &decoded {
            Ok(Reply::Image(img)) => Some(img),
            _ => None,
        };
        let ev = FrameEvent {
            dir: Direction::ToPlatform,
            bytes: &self.rbuf,
            image,
            valid: decoded.is_ok(),
        };
        notify(&mut self.observer, &ev)?;
        decoded.map(Some)
    }

    // ---------------------------------------------------------- world side

    /// Receives one request; `None` on a clean close between frames.
    pub fn recv_request(&mut self) -> Result<Option<Request>> {
        if !read_frame(&mut self.io, &mut self.rbuf, self.max_frame)? {
            return Ok(None);
        }
        let decoded = decode_request(&self.rbuf);
        let ev = FrameEvent {
            dir: Direction::ToWorld,
            bytes: &self.rbuf,
            image: None,
            valid: decoded.is_ok(),
        };
        notify(&mut self.observer, &ev)?;
        decoded.map(Some)
    }

    /// Sends a reply; images use the negotiated encoding. Sending an
    /// `InitData` reply records its `image_encoding` for later images.
    pub fn send_reply(&mut self, reply: &Reply) -> Result<()> {
        if let Reply::InitData { image_encoding, .. } = reply {
            self.image_encoding = *image_encoding;
        }
        let enc = self.image_encoding;
        let image = match reply {
            Reply::Image(img) => Some(img),
            _ => None,
        };
        self.send_frame_with(image, |o| encode_reply(reply, enc, o))
    }
}

fn notify(observer: &mut Option<Observer>, ev: &FrameEvent<'_>) -> Result<()> {
    match observer {
        Some(obs) => Ok(obs(ev)?),
        None => Ok(()),
    }
}

/// Client side (the virtual platform).
pub struct Client;

impl Client {
    /// Connects once.
    pub fn connect(ep: &Endpoint) -> Result<Connection> {
        Self::connect_with(ep, Options::default())
    }

    pub fn connect_with(ep: &Endpoint, opts: Options) -> Result<Connection> {
        let s = Stream::connect(ep).map_err(|e| {
            ProtocolError::Io(io::Error::new(
                e.kind(),
                format!("cannot connect to {ep}: {e}"),
            ))
        })?;
        Ok(Connection::new(s, Role::Platform, opts))
    }

    /// Connects, retrying every 10 ms while the server is not there yet
    /// (path missing or connection refused), for at most `patience`. For
    /// launchers that start both processes at once; wall-clock time only
    /// decides when to give up, never a simulated result.
    pub fn connect_retry(ep: &Endpoint, opts: Options, patience: Duration) -> Result<Connection> {
        let deadline = Instant::now() + patience;
        loop {
            match Stream::connect(ep) {
                Ok(s) => return Ok(Connection::new(s, Role::Platform, opts)),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::NotFound | io::ErrorKind::ConnectionRefused
                    ) && Instant::now() < deadline =>
                {
                    std::thread::sleep(Duration::from_millis(10))
                }
                Err(e) => {
                    return Err(ProtocolError::Io(io::Error::new(
                        e.kind(),
                        format!("cannot connect to {ep}: {e}"),
                    )))
                }
            }
        }
    }
}

#[derive(Debug)]
enum ListenerKind {
    Unix {
        l: UnixListener,
        path: PathBuf,
        ino: u64,
    },
    Tcp(TcpListener),
}

/// Server side (the world): binds, then accepts one client at a time.
#[derive(Debug)]
pub struct Server {
    kind: ListenerKind,
    opts: Options,
}

impl Server {
    /// Binds `ep`. For `unix:` a stale socket file is removed first, the
    /// socket is created mode 0600, and a path held by a live server gives
    /// [`ProtocolError::AddrInUse`]. The socket file is removed on drop.
    pub fn bind(ep: &Endpoint) -> Result<Server> {
        Self::bind_with(ep, Options::default())
    }

    pub fn bind_with(ep: &Endpoint, opts: Options) -> Result<Server> {
        let kind = match ep {
            Endpoint::Unix(p) => {
                let (l, ino) = bind_unix(p, 1)?;
                ListenerKind::Unix {
                    l,
                    path: p.clone(),
                    ino,
                }
            }
            Endpoint::Tcp(a) => {
                ListenerKind::Tcp(TcpListener::bind(a.as_str()).map_err(|e| tcp_bind_error(a, e))?)
            }
        };
        Ok(Server { kind, opts })
    }

    /// The bound endpoint (with the real port for `tcp:HOST:0`).
    pub fn local_endpoint(&self) -> Result<Endpoint> {
        Ok(match &self.kind {
            ListenerKind::Unix { path, .. } => Endpoint::Unix(path.clone()),
            ListenerKind::Tcp(l) => Endpoint::Tcp(l.local_addr()?.to_string()),
        })
    }

    /// Waits for the next client. Serve it to the end before calling again:
    /// the listen backlog is 1, as in the thesis.
    pub fn accept(&self) -> Result<Connection> {
        let s = match &self.kind {
            ListenerKind::Unix { l, .. } => {
                let s = l.accept()?.0;
                crate::frame::enlarge_socket_buffers(std::os::fd::AsRawFd::as_raw_fd(&s));
                Stream::Unix(s)
            }
            ListenerKind::Tcp(l) => {
                let s = l.accept()?.0;
                s.set_nodelay(true)?;
                Stream::Tcp(s)
            }
        };
        Ok(Connection::new(s, Role::World, self.opts))
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let ListenerKind::Unix { path, ino, .. } = &self.kind {
            unlink_if_ours(path, *ino);
        }
    }
}
