//! The server: sockets around a [`Session`] (DESIGN.md §2, §7).
//!
//! 1. **Claims.** Connections are accepted on the one endpoint until every
//!    drone of the world file is claimed. The first frame of a connection
//!    claims a drone: with several drones it must be GET_INIT_DATA with
//!    `"drone": NAME`; an unknown or already claimed name (or anything else)
//!    gets ERROR and that connection is closed, and the world keeps waiting.
//!    With one drone the first connection claims it whatever it sends first
//!    (a thesis-era platform names no drone), unless it names another one.
//!    Claims that do not arrive within `--connect-timeout` end the run,
//!    naming the drones never claimed.
//! 2. **Warm-up**, once, for all drones; then every connection's frames
//!    are read as they come (one stream per connection, polled together on
//!    the single-threaded runtime) and pushed into the session, which
//!    processes them in the lockstep's canonical order. The world's trace is
//!    written in that order (the frames' bytes as received and sent, with
//!    `"drone"` when there are several), so two runs give the same trace
//!    whatever the platforms' speeds.
//! 3. **End.** After the last STOP reply: exit 0. A failure (a bad request,
//!    a platform gone before its STOP): ERROR to the drone at fault (if it is
//!    still connected) and `drone NAME: …` to every other platform, then the
//!    world keeps reading (and discarding) until the platforms have closed
//!    or [`DRAIN`] has passed, so that a platform's next request meets the
//!    ERROR frame rather than a broken pipe; outputs are flushed and the run
//!    fails.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::pin::Pin;
use std::time::Duration;

use futures::stream::{self, FuturesUnordered, SelectAll};
use futures::{FutureExt, Stream, StreamExt};
use protocol::busy_poll::BusyPoll;
use protocol::frame::{write_frame, DEFAULT_MAX_FRAME, HEADER_LEN};
use protocol::shm::{ShmError, ShmFrame, ShmWriter};
use protocol::tokio_transport::{FrameCodec, Listener};
use protocol::trace::{TraceClock, TraceQueue, TraceWriter};
use protocol::{
    decode_request, encode_reply, Direction, Endpoint, FrameEvent, ImageEncoding, Reply, Request,
};
use tokio::io::AsyncWriteExt;
use tokio::net::{tcp, unix};
use tokio_util::codec::FramedRead;
use tokio_util::either::Either;

use crate::physics::StepConfig;
use crate::session::{Input, Outputs, Progress, Session, SessionError, SessionOutputs};
use crate::time::Millis;
use crate::world_file::WorldDesc;

/// After a failure, how long the world keeps reading from platforms that
/// have not closed yet (wall time), so they read the ERROR frame.
pub const DRAIN: Duration = Duration::from_secs(5);

/// Everything the command line configures.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    pub endpoint: Endpoint,
    pub world: WorldDesc,
    pub step: StepConfig,
    pub trace: Option<PathBuf>,
    pub trace_images: bool,
    pub frames_dir: Option<PathBuf>,
    pub trajectory: Option<PathBuf>,
    /// `--radio-log`: one CSV row per (frame, receiver).
    pub radio_log: Option<PathBuf>,
    /// `--mcap`: the world's half of a run's run.mcap (docs/FOXGLOVE.md).
    pub mcap: Option<PathBuf>,
    /// `--mcap-image-every`: every Nth camera frame into the MCAP (0: none).
    pub mcap_image_every: u64,
    /// How long to wait for every drone to be claimed (wall time).
    pub connect_timeout: Duration,
    /// How long the world polls for the next request before it sleeps
    /// (`--busy-poll-us`, protocol's `busy_poll`).
    pub busy_poll: BusyPoll,
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error(transparent)]
    Protocol(#[from] protocol::ProtocolError),
    #[error(transparent)]
    Session(#[from] SessionError),
    #[error(
        "no platform claimed {} within {secs} s (--connect-timeout)",
        describe_unclaimed(names)
    )]
    Unclaimed { names: Vec<String>, secs: f64 },
    #[error("cannot write {path}: {source}")]
    Output {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

fn describe_unclaimed(names: &[String]) -> String {
    let quoted: Vec<String> = names.iter().map(|n| format!("{n:?}")).collect();
    match quoted.len() {
        1 => format!("drone {}", quoted[0]),
        _ => format!("drones {}", quoted.join(", ")),
    }
}

type ReadHalf = Either<unix::OwnedReadHalf, tcp::OwnedReadHalf>;
type WriteHalf = Either<unix::OwnedWriteHalf, tcp::OwnedWriteHalf>;
type Frames = FramedRead<ReadHalf, FrameCodec>;
/// What the world waits for while it serves.
enum Event {
    /// An input of drone `.0`'s connection; its stream ends with `Closed`.
    Input(usize, Input),
    /// A connection after every drone was claimed: refused at once
    /// (DESIGN.md §15).
    Late(protocol::Result<protocol::tokio_transport::ServerFramed>),
}

/// One connection's inputs, or the listener's late connections.
type Inputs = Pin<Box<dyn Stream<Item = Event>>>;

/// What a connection made after every drone was claimed is told.
pub const EVERY_DRONE_CLAIMED: &str = "every drone is claimed";

/// Binds, waits for the claims, warms up, serves until the last STOP.
/// Returns Ok only after every drone's STOP was answered.
pub async fn serve(cfg: ServerConfig) -> Result<(), ServerError> {
    let mut session = Session::new(
        &cfg.world,
        cfg.step,
        SessionOutputs {
            trajectory: cfg.trajectory.as_deref(),
            frames_dir: cfg.frames_dir.as_deref(),
            radio_log: cfg.radio_log.as_deref(),
            mcap: cfg.mcap.as_deref(),
            mcap_image_every: cfg.mcap_image_every,
        },
    )?;
    let mut trace = match &cfg.trace {
        // Its lines (and the hashes of the images) are written while the
        // world waits for the platforms (run_loop).
        Some(path) => Some(TraceQueue::new(
            TraceWriter::create(path, TraceClock::WorldMs, cfg.trace_images).map_err(|source| {
                ServerError::Output {
                    path: path.clone(),
                    source,
                }
            })?,
        )),
        None => None,
    };
    let result = serve_session(&cfg, &mut session, trace.as_mut()).await;
    // Flush outputs on every path; the first error wins.
    let flushed = session.flush().map_err(ServerError::from);
    let traced = match trace.as_mut() {
        Some(t) => t.finish().map_err(|source| ServerError::Output {
            path: cfg.trace.clone().unwrap_or_default(),
            source,
        }),
        None => Ok(()),
    };
    result.and(flushed).and(traced)
}

async fn serve_session(
    cfg: &ServerConfig,
    session: &mut Session,
    trace: Option<&mut TraceQueue>,
) -> Result<(), ServerError> {
    // The backlog holds every drone's connection, so that one client may
    // connect all of them without blocking (DESIGN.md §15).
    let backlog = u32::try_from(cfg.world.drones.len()).unwrap_or(u32::MAX);
    let listener = Listener::bind_backlog(&cfg.endpoint, DEFAULT_MAX_FRAME, backlog).await?;
    tracing::info!(
        endpoint = %listener.local_endpoint()?,
        world = %cfg.world.name,
        drones = session.names().len(),
        "listening"
    );
    let claimed = claim_all(&listener, &cfg.world, cfg.connect_timeout).await?;
    session.warm_up()?;
    tracing::info!(
        time_ms = session.world().time().0,
        "every drone claimed, warm-up done, serving"
    );
    let n = claimed.len();
    let mut wire = Wire {
        trace,
        trace_path: cfg.trace.clone().unwrap_or_default(),
        names: session.names().to_vec(),
        multi: session.is_multi(),
        encodings: vec![ImageEncoding::Array; n],
        outbox: Vec::new(),
        spare: vec![Vec::new(); n],
        early: vec![VecDeque::new(); n],
        shm: (0..n).map(|_| None).collect(),
    };
    let mut writers: Vec<Option<WriteHalf>> = Vec::with_capacity(n);
    let mut inputs: SelectAll<Inputs> = SelectAll::new();
    for (d, c) in claimed.into_iter().enumerate() {
        session.push(d, c.first)?;
        writers.push(Some(c.write));
        inputs.push(tagged(d, c.read));
    }
    inputs.push(Box::pin(stream::unfold(listener, |l| async move {
        let conn = l.accept().await;
        Some((Event::Late(conn), l))
    })));
    let mut open = vec![true; n];
    let outcome = run_loop(
        session,
        &mut wire,
        &mut writers,
        &mut inputs,
        &mut open,
        cfg.busy_poll,
    )
    .await;
    match outcome {
        Ok(()) => Ok(()),
        Err(e) => {
            // Replies already traced go out first, then the ERRORs.
            let _ = send_outbox(&mut wire, &mut writers).await;
            let now = session.world().time();
            let connected: Vec<usize> = (0..n).filter(|&d| writers[d].is_some()).collect();
            for d in connected {
                let message = match e.drone() {
                    Some(culprit) if culprit == d => e.message(),
                    _ => e.to_string(),
                };
                // Best effort: the platform may be gone.
                let _ = wire.reply(d, Reply::error(message), now);
            }
            let _ = send_outbox(&mut wire, &mut writers).await;
            for w in writers.iter_mut().filter_map(Option::take) {
                let mut w = w;
                let _ = w.shutdown().await;
            }
            drain(&mut inputs, &mut open).await;
            Err(e.into())
        }
    }
}

/// Feeds the session until it finishes.
async fn run_loop(
    session: &mut Session,
    wire: &mut Wire<'_>,
    writers: &mut [Option<WriteHalf>],
    inputs: &mut SelectAll<Inputs>,
    open: &mut [bool],
    busy_poll: BusyPoll,
) -> Result<(), SessionError> {
    loop {
        let progress = session.run(wire)?;
        send_outbox(wire, writers)
            .await
            .map_err(|(d, e)| SessionError::Drone {
                drone: d,
                name: wire.names[d].clone(),
                message: format!("cannot send the reply: {e}"),
            })?;
        if progress == Progress::Finished {
            return Ok(());
        }
        let trace = &mut wire.trace;
        let work = || trace.as_deref_mut().is_some_and(|t| t.work());
        match busy_poll.next_or_work(inputs, work).await {
            Some(event) => accept_event(session, writers, open, event).await?,
            None => unreachable!("the listener's stream never ends"),
        }
        // A pipelining platform sends an iteration's requests together
        // (docs/PROTOCOL.md "Pipelining"): take every frame already read,
        // so that their replies leave in one write and wake the platform
        // once. Frames buffered by the codec come without a system call.
        while let Some(Some(event)) = inputs.next().now_or_never() {
            accept_event(session, writers, open, event).await?;
        }
    }
}

/// One input of a drone into the session, or a late connection refused.
async fn accept_event(
    session: &mut Session,
    writers: &mut [Option<WriteHalf>],
    open: &mut [bool],
    event: Event,
) -> Result<(), SessionError> {
    let (d, input) = match event {
        Event::Input(d, input) => (d, input),
        Event::Late(conn) => {
            refuse_late(conn).await;
            return Ok(());
        }
    };
    match input {
        // Gone: nothing more can be written to it either.
        Input::Closed => {
            open[d] = false;
            writers[d] = None;
        }
        Input::Broken(_) => open[d] = false,
        Input::Frame { .. } => {}
    }
    session.push(d, input)
}

/// Writes the replies in order, the consecutive replies to one drone in
/// one write; a STOP reply closes its connection.
async fn send_outbox(
    wire: &mut Wire<'_>,
    writers: &mut [Option<WriteHalf>],
) -> Result<(), (usize, std::io::Error)> {
    let mut first_error = None;
    let mut frames = std::mem::take(&mut wire.outbox).into_iter().peekable();
    while let Some((d, mut frame, mut close)) = frames.next() {
        // Replies to the same drone that follow are appended (a reply after
        // STOP cannot exist: STOP is a connection's last request).
        while !close {
            match frames.next_if(|(next, _, _)| *next == d) {
                Some((_, more, c)) => {
                    frame.extend_from_slice(&more);
                    close = c;
                }
                None => break,
            }
        }
        if let Some(w) = writers[d].as_mut() {
            let r = match w.write_all(&frame).await {
                Ok(()) if close => w.shutdown().await,
                r => r,
            };
            if close {
                writers[d] = None;
            }
            if let Err(e) = r {
                writers[d] = None;
                first_error.get_or_insert((d, e));
            }
        }
        wire.spare[d] = frame;
    }
    match first_error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// Reads and drops what the platforms still send, until they have all
/// closed or [`DRAIN`] has passed.
async fn drain(inputs: &mut SelectAll<Inputs>, open: &mut [bool]) {
    let until = tokio::time::Instant::now() + DRAIN;
    while open.iter().any(|&o| o) {
        match tokio::time::timeout_at(until, inputs.next()).await {
            Ok(Some(Event::Input(d, Input::Closed | Input::Broken(_)))) => open[d] = false,
            Ok(Some(Event::Late(conn))) => refuse_late(conn).await,
            Ok(Some(Event::Input(..))) => {}
            Ok(None) | Err(_) => return,
        }
    }
}

/// The trace and the sockets' side of a session's outputs.
struct Wire<'a> {
    trace: Option<&'a mut TraceQueue>,
    trace_path: PathBuf,
    names: Vec<String>,
    multi: bool,
    /// Per drone: the image encoding its GET_INIT_DATA negotiated.
    encodings: Vec<ImageEncoding>,
    /// Encoded frames to write, in order: (drone, frame, close after it).
    outbox: Vec<(usize, Vec<u8>, bool)>,
    /// Per drone: a frame buffer to reuse.
    spare: Vec<Vec<u8>>,
    /// Per drone: the replies sent early (DESIGN.md §15), frame body and
    /// image, whose trace lines wait for their turn.
    early: Vec<VecDeque<(Vec<u8>, Option<protocol::Image>)>>,
    /// Per drone: its shared-memory image file, if it negotiated "shm"
    /// (removed when the run ends).
    shm: Vec<Option<ShmWriter>>,
}

impl Wire<'_> {
    /// Writes `img` into drone `d`'s shared-memory file (created at its
    /// first image).
    fn shm_frame(&mut self, d: usize, img: &protocol::Image) -> Result<ShmFrame, ShmError> {
        if self.shm[d].is_none() {
            self.shm[d] = Some(ShmWriter::create(ShmWriter::default_path(d))?);
        }
        self.shm[d].as_mut().expect("created above").write(img)
    }

    fn traced(&mut self, ev: &FrameEvent<'_>, d: usize, now: Millis) -> Result<(), SessionError> {
        let drone = self.multi.then(|| self.names[d].as_str());
        match self.trace.as_deref_mut() {
            Some(t) => t
                .push_for(ev, now.0, drone)
                .map_err(|source| SessionError::Output {
                    path: self.trace_path.clone(),
                    source,
                }),
            None => Ok(()),
        }
    }
}

impl Outputs for Wire<'_> {
    fn request(
        &mut self,
        drone: usize,
        body: &[u8],
        valid: bool,
        now: Millis,
    ) -> Result<(), SessionError> {
        let ev = FrameEvent {
            dir: Direction::ToWorld,
            bytes: body,
            image: None,
            valid,
        };
        self.traced(&ev, drone, now)
    }

    fn reply(&mut self, drone: usize, reply: Reply, now: Millis) -> Result<(), SessionError> {
        self.send(drone, &reply)?;
        let image = match &reply {
            Reply::Image(img) => Some(img),
            _ => None,
        };
        // Out of the outbox while the trace (also in `self`) reads it.
        let sent = self.outbox.pop().expect("sent above");
        let traced = self.traced(&reply_event(&sent.1[HEADER_LEN..], image), drone, now);
        self.outbox.push(sent);
        traced
    }

    fn reply_early(
        &mut self,
        drone: usize,
        reply: Reply,
        _now: Millis,
    ) -> Result<(), SessionError> {
        self.send(drone, &reply)?;
        // Kept only for the trace line written at the request's turn: an
        // untraced run copies nothing (a GET_IMAGE frame is 100-400 KB).
        if self.trace.is_none() {
            return Ok(());
        }
        let frame = self.outbox.last().expect("sent above").1[HEADER_LEN..].to_vec();
        let image = match reply {
            Reply::Image(img) => Some(img),
            _ => None,
        };
        self.early[drone].push_back((frame, image));
        Ok(())
    }

    fn trace_early(&mut self, drone: usize, now: Millis) -> Result<(), SessionError> {
        let Some((frame, image)) = self.early[drone].pop_front() else {
            return Ok(());
        };
        self.traced(&reply_event(&frame, image.as_ref()), drone, now)
    }
}

/// The trace's view of a reply's frame body.
fn reply_event<'a>(body: &'a [u8], image: Option<&'a protocol::Image>) -> FrameEvent<'a> {
    FrameEvent {
        dir: Direction::ToPlatform,
        bytes: body,
        image,
        valid: true,
    }
}

impl Wire<'_> {
    /// Encodes `reply` into drone `drone`'s outbox (the last frame there).
    fn send(&mut self, drone: usize, reply: &Reply) -> Result<(), SessionError> {
        if let Reply::InitData { image_encoding, .. } = reply {
            self.encodings[drone] = *image_encoding;
        }
        let encoding = self.encodings[drone];
        // `"image_encoding":"shm"`: the pixels go to this connection's file,
        // the reply names it (protocol::shm).
        let shm_reply = match (reply, encoding) {
            (Reply::Image(img), ImageEncoding::Shm) => Some(Reply::ShmImage(
                self.shm_frame(drone, img)
                    .map_err(|e| SessionError::Drone {
                        drone,
                        name: self.names[drone].clone(),
                        message: e.to_string(),
                    })?,
            )),
            _ => None,
        };
        let mut frame = std::mem::take(&mut self.spare[drone]);
        frame.clear();
        write_frame(&mut frame, DEFAULT_MAX_FRAME, |o| {
            encode_reply(shm_reply.as_ref().unwrap_or(reply), encoding, o)
        })
        .map_err(|e| SessionError::Drone {
            drone,
            name: self.names[drone].clone(),
            message: format!("cannot encode the {} reply: {e}", reply.command()),
        })?;
        let close = matches!(reply, Reply::Stop { .. });
        self.outbox.push((drone, frame, close));
        Ok(())
    }
}

/// A connection that claimed a drone, with its first frame.
struct Claimed {
    read: Frames,
    write: WriteHalf,
    first: Input,
}

fn split(conn: protocol::tokio_transport::ServerFramed) -> (ReadHalf, WriteHalf) {
    // Nothing has been read through the Framed yet: no buffered bytes lost.
    match conn.into_inner() {
        Either::Left(u) => {
            let (r, w) = u.into_split();
            (Either::Left(r), Either::Left(w))
        }
        Either::Right(t) => {
            let (r, w) = t.into_split();
            (Either::Right(r), Either::Right(w))
        }
    }
}

/// The next input of a connection.
async fn next_input(frames: &mut Frames) -> Input {
    match frames.next().await {
        Some(Ok(body)) => {
            let request = decode_request(&body);
            Input::Frame {
                body: Vec::from(body),
                request,
            }
        }
        Some(Err(e)) => Input::Broken(e),
        None => Input::Closed,
    }
}

/// A connection's inputs after its first, tagged with its drone; ends
/// with `Closed` (after `Broken`, the stream has nothing more either).
fn tagged(d: usize, frames: Frames) -> Inputs {
    Box::pin(stream::unfold(Some(frames), move |state| async move {
        let mut frames = state?;
        let input = next_input(&mut frames).await;
        let more = matches!(input, Input::Frame { .. });
        Some((Event::Input(d, input), more.then_some(frames)))
    }))
}

/// Accepts connections until every drone is claimed (or the timeout).
async fn claim_all(
    listener: &Listener,
    world: &WorldDesc,
    timeout: Duration,
) -> Result<Vec<Claimed>, ServerError> {
    let n = world.drones.len();
    let mut claims: Vec<Option<Claimed>> = (0..n).map(|_| None).collect();
    let mut first_frames = FuturesUnordered::new();
    let deadline = tokio::time::sleep(timeout);
    tokio::pin!(deadline);
    while claims.iter().any(Option::is_none) {
        tokio::select! {
            conn = listener.accept() => {
                let (read, write) = split(conn?);
                first_frames.push(async move {
                    let mut read = FramedRead::new(read, FrameCodec::default());
                    let first = next_input(&mut read).await;
                    (read, write, first)
                });
            }
            Some((read, write, first)) = first_frames.next(), if !first_frames.is_empty() => {
                match claim(world, &claims, &first) {
                    Ok(d) => {
                        tracing::info!(drone = %world.drones[d].name, "claimed");
                        claims[d] = Some(Claimed { read, write, first });
                    }
                    Err(Some(reason)) => {
                        tracing::warn!("claim refused: {reason}");
                        refuse(write, &reason).await;
                    }
                    Err(None) => tracing::warn!("a connection closed before claiming a drone"),
                }
            }
            () = &mut deadline => {
                let names = world
                    .drones
                    .iter()
                    .zip(&claims)
                    .filter(|(_, c)| c.is_none())
                    .map(|(d, _)| d.name.clone())
                    .collect();
                let e = ServerError::Unclaimed { names, secs: timeout.as_secs_f64() };
                // The platforms that did claim are waiting for their reply.
                for c in claims.into_iter().flatten() {
                    refuse(c.write, &e.to_string()).await;
                }
                return Err(e);
            }
        }
    }
    Ok(claims
        .into_iter()
        .map(|c| c.expect("all claimed"))
        .collect())
}

/// Which drone a connection's first input claims: `Err(Some(reason))` to
/// refuse it with an ERROR, `Err(None)` to drop it silently (it closed).
fn claim(
    world: &WorldDesc,
    claims: &[Option<Claimed>],
    first: &Input,
) -> Result<usize, Option<String>> {
    let named = match first {
        Input::Frame {
            request: Ok(Request::GetInitData { drone, .. }),
            ..
        } => drone.as_deref(),
        _ => None,
    };
    if !world.is_multi() {
        // A thesis-era platform names no drone; whatever it sends first is
        // served (or refused) by the session, as before.
        return match named {
            Some(name) if name != world.drones[0].name => Err(Some(unknown(world, name))),
            _ => Ok(0),
        };
    }
    let name = match (first, named) {
        (_, Some(name)) => name,
        (
            Input::Frame {
                request: Ok(Request::GetInitData { .. }),
                ..
            },
            None,
        ) => {
            return Err(Some(format!(
                "this world has {} drones ({}): GET_INIT_DATA must claim one with \"drone\"",
                world.drones.len(),
                list(world)
            )))
        }
        (Input::Frame { request: Ok(r), .. }, None) => {
            return Err(Some(format!(
                "the first request must be GET_INIT_DATA with \"drone\", not {}",
                r.command()
            )))
        }
        (
            Input::Frame {
                request: Err(e), ..
            },
            None,
        ) => return Err(Some(e.to_string())),
        (Input::Broken(e), None) => return Err(Some(e.to_string())),
        (Input::Closed, None) => return Err(None),
    };
    match world.drone_index(name) {
        None => Err(Some(unknown(world, name))),
        Some(d) if claims[d].is_some() => Err(Some(format!("drone {name:?} is already claimed"))),
        Some(d) => Ok(d),
    }
}

fn list(world: &WorldDesc) -> String {
    let names: Vec<&str> = world.drones.iter().map(|d| d.name.as_str()).collect();
    names.join(", ")
}

fn unknown(world: &WorldDesc, name: &str) -> String {
    format!("unknown drone {name:?} (this world has {})", list(world))
}

/// ERROR [`EVERY_DRONE_CLAIMED`] to a connection made after the claims,
/// without reading from it, then close it (logged, not traced).
async fn refuse_late(conn: protocol::Result<protocol::tokio_transport::ServerFramed>) {
    match conn {
        Ok(conn) => {
            tracing::warn!("a connection after every drone was claimed: refused");
            let (mut read, write) = split(conn);
            refuse(write, EVERY_DRONE_CLAIMED).await;
            // Read what it sent (its claim) until it closes, so that closing
            // does not reset a TCP connection before it read the ERROR.
            tokio::spawn(async move {
                let mut sink = tokio::io::sink();
                let _ = tokio::time::timeout(DRAIN, tokio::io::copy(&mut read, &mut sink)).await;
            });
        }
        Err(e) => tracing::warn!("cannot accept a connection: {e}"),
    }
}

/// ERROR to a refused connection, then close it (best effort).
async fn refuse(mut write: WriteHalf, reason: &str) {
    let mut frame = Vec::new();
    if write_frame(&mut frame, DEFAULT_MAX_FRAME, |o| {
        encode_reply(&Reply::error(reason), ImageEncoding::Array, o)
    })
    .is_ok()
    {
        let _ = write.write_all(&frame).await;
    }
    let _ = write.shutdown().await;
}
