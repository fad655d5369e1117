//! The platform's end of the socket to the world (the thesis's
//! VirtualConnector as the sensors use it, §4.1.1): typed requests, typed
//! replies, and the traffic figures for `summary.json`.

use protocol::{Reply, Request};
use thiserror::Error;

use crate::units::Picos;

/// A failed exchange with the world.
#[derive(Debug, Error)]
pub enum LinkError {
    #[error(transparent)]
    Protocol(#[from] protocol::ProtocolError),
    #[error("the world refused {request}: {message}")]
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

    /// [`WorldLink::call`] whose reply may still be decoding when this
    /// returns ([`DeferredReply::wait`] gives what `call` would have given).
    /// This default decodes at once.
    fn call_deferred(&mut self, request: &Request, now: Picos) -> Result<DeferredReply, LinkError> {
        Ok(DeferredReply::ready(self.call(request, now)))
    }

    /// Pipelining: sends `requests` together and returns the replies of the
    /// ones that have a reply, in order. A conforming world answers in order
    /// (DESIGN.md §2), so this needs no negotiation; what the world sees,
    /// and what the traces record, is the same as from one
    /// [`WorldLink::call`] or [`WorldLink::send`] after another (which is
    /// what this default does).
    fn exchange(&mut self, requests: &[Request], now: Picos) -> Result<Vec<Reply>, LinkError> {
        let mut replies = Vec::new();
        for r in requests {
            if r.expects_reply() {
                replies.push(self.call(r, now)?);
            } else {
                self.send(r, now)?;
            }
        }
        Ok(replies)
    }

    /// Work to do while waiting for the world's replies (the power logs,
    /// [`crate::power::PowerLogger::idle_work`]). A link that never waits
    /// (an in-process world) drops it, and the work is done when its owner
    /// asks for it.
    fn add_idle_work(&mut self, _work: protocol::busy_poll::IdleWork) {}
}

/// A borrowed link is a link (so a caller can keep an in-process world and
/// look at it after the run).
impl<T: WorldLink + ?Sized> WorldLink for &mut T {
    fn call(&mut self, request: &Request, now: Picos) -> Result<Reply, LinkError> {
        (**self).call(request, now)
    }
    fn send(&mut self, request: &Request, now: Picos) -> Result<(), LinkError> {
        (**self).send(request, now)
    }
    fn stats(&self) -> LinkStats {
        (**self).stats()
    }
    fn exchange(&mut self, requests: &[Request], now: Picos) -> Result<Vec<Reply>, LinkError> {
        (**self).exchange(requests, now)
    }
    fn call_deferred(&mut self, request: &Request, now: Picos) -> Result<DeferredReply, LinkError> {
        (**self).call_deferred(request, now)
    }
    fn add_idle_work(&mut self, work: protocol::busy_poll::IdleWork) {
        (**self).add_idle_work(work)
    }
}

/// A reply received, perhaps still being decoded on another thread
/// ([`WorldLink::call_deferred`]).
#[derive(Debug)]
pub struct DeferredReply {
    request: &'static str,
    state: Deferred,
}

#[derive(Debug)]
enum Deferred {
    Ready(Result<Reply, LinkError>),
    Decoding(protocol::blocking::PendingReply),
}

impl DeferredReply {
    /// A reply already decoded (or the error in its place).
    pub fn ready(reply: Result<Reply, LinkError>) -> Self {
        DeferredReply {
            request: "",
            state: Deferred::Ready(reply),
        }
    }

    /// Whether the reply is already decoded.
    pub fn is_ready(&self) -> bool {
        matches!(self.state, Deferred::Ready(_))
    }

    /// Waits for the decoded reply.
    pub fn wait(self) -> Result<Reply, LinkError> {
        match self.state {
            Deferred::Ready(r) => r,
            Deferred::Decoding(p) => p.wait().map_err(|e| SocketWorld::map(self.request, e)),
        }
    }
}

/// **Test-only knob**: when this environment variable holds a number N, the
/// platform sleeps N µs of wall time before every request it sends. It
/// slows a platform down on purpose, so the end-to-end tests can check that
/// a swarm's outputs do not depend on the processes' speeds (the lockstep,
/// docs/SWARM.md §2). Wall time never enters a simulated result, so the knob
/// changes nothing but the run's duration; it is not meant for users.
pub const SLOW_LINK_ENV: &str = "SIM_CORE_TEST_SLOW_LINK_US";

/// The world server at the other end of a socket, with an optional trace
/// of every frame (`--trace`, DESIGN.md §2).
pub struct SocketWorld {
    conn: protocol::blocking::Connection,
    /// Test-only: wall-clock pause before each request (see [`SLOW_LINK_ENV`]).
    slow: Option<std::time::Duration>,
    counters: std::sync::Arc<Counters>,
    trace: Option<std::sync::Arc<std::sync::Mutex<protocol::trace::TraceQueue>>>,
}

/// Shared between the link and its frame observer (which must be `Send`).
#[derive(Default)]
struct Counters {
    messages: std::sync::atomic::AtomicU64,
    to_world: std::sync::atomic::AtomicU64,
    to_platform: std::sync::atomic::AtomicU64,
    /// The platform's time of the frame being sent or received (ps).
    now_ps: std::sync::atomic::AtomicU64,
}

impl SocketWorld {
    /// Connects to `endpoint`, retrying for `patience` (the world may start
    /// second), and traces to `trace` if given.
    pub fn connect(
        endpoint: &protocol::Endpoint,
        patience: std::time::Duration,
        busy_poll: protocol::busy_poll::BusyPoll,
        trace: Option<(&std::path::Path, bool)>,
    ) -> Result<SocketWorld, LinkError> {
        use std::sync::atomic::Ordering::Relaxed;
        use std::sync::{Arc, Mutex};
        let mut conn = protocol::blocking::Client::connect_retry(
            endpoint,
            protocol::blocking::Options {
                busy_poll,
                ..Default::default()
            },
            patience,
        )?;
        let counters = Arc::new(Counters::default());
        let trace = match trace {
            Some((path, keep_images)) => {
                Some(Arc::new(Mutex::new(protocol::trace::TraceQueue::new(
                    protocol::trace::TraceWriter::create(
                        path,
                        protocol::trace::TraceClock::PlatformPs,
                        keep_images,
                    )
                    .map_err(protocol::ProtocolError::Io)?,
                ))))
            }
            None => None,
        };
        let c = Arc::clone(&counters);
        let t = trace.clone();
        conn.set_observer(Box::new(move |ev| {
            c.messages.fetch_add(1, Relaxed);
            let bytes = ev.bytes.len() as u64 + 4;
            match ev.dir {
                protocol::Direction::ToWorld => c.to_world.fetch_add(bytes, Relaxed),
                protocol::Direction::ToPlatform => c.to_platform.fetch_add(bytes, Relaxed),
            };
            // debug_level = HIGH (trace) logs every frame (§4.2.4
            // "Configuration files and debug mode"); images are cut short.
            if tracing::enabled!(target: "cosim::frames", tracing::Level::TRACE) {
                let head = &ev.bytes[..ev.bytes.len().min(200)];
                tracing::trace!(
                    target: "cosim::frames",
                    dir = ev.dir.as_str(),
                    len = ev.bytes.len(),
                    "{}{}",
                    String::from_utf8_lossy(head),
                    if ev.bytes.len() > head.len() { "…" } else { "" }
                );
            }
            if let Some(t) = &t {
                let now = c.now_ps.load(Relaxed);
                t.lock().expect("trace lock").push(ev, now)?;
            }
            Ok(())
        }));
        let slow = match std::env::var(SLOW_LINK_ENV) {
            Ok(v) => Some(std::time::Duration::from_micros(v.trim().parse().map_err(
                |_| {
                    protocol::ProtocolError::Io(std::io::Error::new(
                        std::io::ErrorKind::InvalidInput,
                        format!("{SLOW_LINK_ENV}={v:?} is not a number of microseconds"),
                    ))
                },
            )?)),
            Err(_) => None,
        };
        // The trace's hashing and writing while waiting for the world.
        if let Some(t) = &trace {
            let t = Arc::clone(t);
            conn.add_idle_work(Box::new(move || t.lock().expect("trace lock").work()));
        }
        Ok(SocketWorld {
            conn,
            slow,
            counters,
            trace,
        })
    }

    /// Writes the rest of the trace and ends its file (done when the link
    /// is dropped, at the end of the run).
    pub fn finish_trace(&self) -> std::io::Result<()> {
        match &self.trace {
            Some(t) => t.lock().expect("trace lock").finish(),
            None => Ok(()),
        }
    }

    /// Before `requests` requests go out at platform time `now`: the
    /// test-only pause (one per request) and the time the trace stamps.
    fn before_send(&self, requests: usize, now: Picos) {
        if let Some(d) = self.slow {
            std::thread::sleep(d * requests as u32);
        }
        self.counters
            .now_ps
            .store(now.0, std::sync::atomic::Ordering::Relaxed);
    }

    fn map(request: &'static str, e: protocol::ProtocolError) -> LinkError {
        match e {
            protocol::ProtocolError::Remote(message) => LinkError::Remote { request, message },
            protocol::ProtocolError::Closed(_) => LinkError::Closed { request },
            other => LinkError::Protocol(other),
        }
    }
}

impl Drop for SocketWorld {
    fn drop(&mut self) {
        if let Err(e) = self.finish_trace() {
            tracing::error!("cannot write the trace: {e}");
        }
    }
}

impl WorldLink for SocketWorld {
    fn add_idle_work(&mut self, work: protocol::busy_poll::IdleWork) {
        self.conn.add_idle_work(work);
    }

    fn call(&mut self, request: &Request, now: Picos) -> Result<Reply, LinkError> {
        self.before_send(1, now);
        match self.conn.request(request) {
            Ok(Some(reply)) => Ok(reply),
            Ok(None) => Err(LinkError::Unexpected {
                request: request.command(),
                reply: "no reply",
            }),
            Err(e) => Err(Self::map(request.command(), e)),
        }
    }

    fn send(&mut self, request: &Request, now: Picos) -> Result<(), LinkError> {
        self.before_send(1, now);
        match self.conn.send(request) {
            Ok(()) => Ok(()),
            Err(e) => {
                // A world refusing a reply-less request sends ERROR and
                // closes (DESIGN.md §2); our next write then fails. The
                // ERROR frame says why: report that, not the broken pipe.
                if let Ok(Some(Reply::Error { error })) = self.conn.recv_reply() {
                    return Err(LinkError::Remote {
                        request: request.command(),
                        message: error,
                    });
                }
                Err(Self::map(request.command(), e))
            }
        }
    }

    /// Without a trace, a reply is decoded later, by the connection once
    /// the next deferred request is sent (a trace records an image's hash
    /// in its reply's line, so with one the reply is decoded at once).
    fn call_deferred(&mut self, request: &Request, now: Picos) -> Result<DeferredReply, LinkError> {
        if self.trace.is_some() {
            return Ok(DeferredReply::ready(self.call(request, now)));
        }
        self.before_send(1, now);
        let command = request.command();
        Ok(match self.conn.request_deferred(request) {
            Ok(p) => DeferredReply {
                request: command,
                state: Deferred::Decoding(p),
            },
            Err(e) => DeferredReply::ready(Err(Self::map(command, e))),
        })
    }

    /// One write for all of `requests`, then their replies
    /// ([`protocol::blocking::Connection::pipeline`]).
    fn exchange(&mut self, requests: &[Request], now: Picos) -> Result<Vec<Reply>, LinkError> {
        self.before_send(requests.len(), now);
        self.conn
            .pipeline(requests)
            .map_err(|(i, e)| Self::map(requests[i].command(), e))
    }

    fn stats(&self) -> LinkStats {
        use std::sync::atomic::Ordering::Relaxed;
        LinkStats {
            messages: self.counters.messages.load(Relaxed),
            bytes_to_world: self.counters.to_world.load(Relaxed),
            bytes_to_platform: self.counters.to_platform.load(Relaxed),
        }
    }
}
