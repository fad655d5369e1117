//! Busy polling: wait for the peer's next frame by polling the socket for a
//! short budget before going to sleep in the kernel.
//!
//! The lockstep is a ping-pong: each side sleeps while the other works, for
//! tens to hundreds of µs, about 40,000 times in the thesis's race. With the
//! two processes on two cores, every one of those waits ends with the
//! kernel waking a sleeping task on the other core, and on a virtual machine
//! that wake-up (an inter-processor interrupt, the idle core leaving its
//! halt) costs more than most of the work it waits for: the race spent as
//! much system time as user time (docs/COSIM.md "Performance"). A reader
//! that polls is not asleep when the frame arrives, so nothing has to wake
//! it. Linux's `SO_BUSY_POLL` does the same below the socket for network
//! devices, but not for UNIX sockets, hence this loop.
//!
//! Each poll gives the core away first (`sched_yield`): when the peer shares
//! the core (one core per run, or more runs than cores), it runs at once
//! instead of waiting for the poller's time slice to end, so polling never
//! delays the frame it waits for. Measured on the 2-core machine: the race
//! pinned to one core takes the same time with and without polling, and
//! four races two at a time on two cores the same total.
//!
//! A reader can also be given work that nothing waits for ([`IdleWork`],
//! e.g. the platform's CSV logs): it does a slice of it between polls
//! instead of giving the core away, so that work leaves the lockstep's
//! critical path.
//!
//! Polling never changes what is simulated: only when a process notices a
//! frame, never which frame or what it holds.

use std::io;
use std::os::fd::RawFd;
use std::time::{Duration, Instant};

/// The budget the two binaries poll for unless told otherwise
/// (`--busy-poll-us`). Measured with the thesis race on the 2-core machine
/// (docs/COSIM.md "Performance"): 20 µs helps little (1.9 → 1.7–1.9 s),
/// 100 µs gets most of it (1.2 s), 200–2000 µs all of it (1.16–1.36 s);
/// the world's longest answer, a rendered and encoded image, takes
/// about 150 µs.
pub const DEFAULT_US: u64 = 200;

/// Work a waiting reader does between polls: one short slice per call
/// (a few µs: the frame waited for is noticed after the slice), returning
/// whether more is left. It runs only while the peer's bytes have not
/// arrived, whatever the budget; then the budget's polling starts.
pub type IdleWork = Box<dyn FnMut() -> bool + Send>;

/// How long a reader polls before it sleeps; zero: it sleeps at once (the
/// library's default, and the plain blocking read).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusyPoll(Duration);

impl BusyPoll {
    /// No polling.
    pub const OFF: BusyPoll = BusyPoll(Duration::ZERO);

    pub const fn from_micros(us: u64) -> BusyPoll {
        BusyPoll(Duration::from_micros(us))
    }

    pub fn is_off(self) -> bool {
        self.0.is_zero()
    }

    /// Polls `fd` (a connected stream socket, blocking or not) for data
    /// until the budget is spent: `Some` with what one `recv` returned (bytes
    /// read, 0 at end of stream, or an error), `None` if nothing came in
    /// time (then block as usual). Uses `recv(MSG_DONTWAIT)` because std has
    /// no per-call non-blocking read: switching the socket to non-blocking
    /// and back would cost two `fcntl` per read.
    pub fn recv(self, fd: RawFd, buf: &mut [u8]) -> Option<io::Result<usize>> {
        self.recv_or_work(fd, buf, &mut [])
    }

    /// [`BusyPoll::recv`] that does slices of `work` between polls while
    /// there is any (a slice of the first with work left each time), and
    /// only then polls for the budget (even a zero budget does the work
    /// first).
    pub fn recv_or_work(
        self,
        fd: RawFd,
        buf: &mut [u8],
        work: &mut [IdleWork],
    ) -> Option<io::Result<usize>> {
        if self.is_off() && work.is_empty() {
            return None;
        }
        // The budget starts when the work has run out.
        let mut start: Option<Instant> = None;
        loop {
            // SAFETY: `buf` is valid for `buf.len()` writable bytes for the
            // whole call; `recv` writes at most that many.
            let n =
                unsafe { libc::recv(fd, buf.as_mut_ptr().cast(), buf.len(), libc::MSG_DONTWAIT) };
            if let Ok(n) = usize::try_from(n) {
                return Some(Ok(n));
            }
            let e = io::Error::last_os_error();
            match e.kind() {
                io::ErrorKind::WouldBlock => {}
                io::ErrorKind::Interrupted => continue,
                _ => return Some(Err(e)),
            }
            if start.is_none() {
                if work.iter_mut().any(|w| w()) {
                    continue;
                }
                start = Some(Instant::now());
            }
            if start.is_some_and(|s| s.elapsed() >= self.0) {
                return None;
            }
            std::thread::yield_now();
        }
    }

    /// The next item of `stream` (a tokio socket's frames), polling for the
    /// budget before waiting as `StreamExt::next` does. On tokio's
    /// single-threaded runtime each poll is a zero-timeout pass of its I/O
    /// driver (`yield_now`), which is what learns that the socket became
    /// readable.
    pub async fn next<S>(self, stream: &mut S) -> Option<S::Item>
    where
        S: futures::Stream + Unpin,
    {
        self.next_or_work(stream, || false).await
    }

    /// [`BusyPoll::next`] doing slices of `work` (as [`IdleWork`]) while
    /// nothing has arrived, before the budget starts.
    pub async fn next_or_work<S>(
        self,
        stream: &mut S,
        mut work: impl FnMut() -> bool,
    ) -> Option<S::Item>
    where
        S: futures::Stream + Unpin,
    {
        use futures::{FutureExt, StreamExt};
        let mut start: Option<Instant> = None;
        loop {
            if let Some(item) = stream.next().now_or_never() {
                return item;
            }
            if start.is_none() && !work() {
                start = Some(Instant::now());
            }
            match start {
                // Work done: poll the socket again at once.
                None => {}
                Some(s) if s.elapsed() >= self.0 => break,
                Some(_) => std::thread::yield_now(),
            }
            tokio::task::yield_now().await;
        }
        stream.next().await
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use std::os::fd::AsRawFd;
    use std::os::unix::net::UnixStream;

    #[test]
    fn off_never_reads() {
        let (a, mut b) = UnixStream::pair().unwrap();
        b.write_all(b"x").unwrap();
        let mut buf = [0u8; 4];
        assert!(BusyPoll::OFF.recv(a.as_raw_fd(), &mut buf).is_none());
    }

    #[test]
    fn data_already_there_is_read_at_once() {
        let (a, mut b) = UnixStream::pair().unwrap();
        b.write_all(b"abc").unwrap();
        let mut buf = [0u8; 8];
        let n = BusyPoll::from_micros(1_000_000)
            .recv(a.as_raw_fd(), &mut buf)
            .unwrap()
            .unwrap();
        assert_eq!(&buf[..n], b"abc");
    }

    /// Writes `bytes` into `b` 2 ms from now; join to get `b` back.
    fn write_later(mut b: UnixStream, bytes: &'static [u8]) -> std::thread::JoinHandle<UnixStream> {
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(2));
            b.write_all(bytes).unwrap();
            b
        })
    }

    #[test]
    fn data_arriving_while_polling_is_read() {
        let (a, b) = UnixStream::pair().unwrap();
        let writer = write_later(b, b"late");
        let mut buf = [0u8; 8];
        let n = BusyPoll::from_micros(5_000_000)
            .recv(a.as_raw_fd(), &mut buf)
            .unwrap()
            .unwrap();
        assert_eq!(&buf[..n], b"late");
        drop(writer.join().unwrap());
    }

    #[test]
    fn nothing_within_the_budget_gives_up_and_leaves_the_socket_blocking() {
        let (a, _b) = UnixStream::pair().unwrap();
        let mut buf = [0u8; 8];
        let t = Instant::now();
        assert!(BusyPoll::from_micros(2_000)
            .recv(a.as_raw_fd(), &mut buf)
            .is_none());
        assert!(t.elapsed() >= Duration::from_millis(2));
        // MSG_DONTWAIT is per call: the socket itself is still blocking.
        // SAFETY: F_GETFL on a descriptor we own.
        let flags = unsafe { libc::fcntl(a.as_raw_fd(), libc::F_GETFL) };
        assert_eq!(flags & libc::O_NONBLOCK, 0);
    }

    #[test]
    fn idle_work_runs_while_waiting_and_stops_when_the_data_is_there() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        use std::sync::Arc;
        // Nothing arrives: all the work is done, even with polling off,
        // then the call gives up.
        let (a, mut b) = UnixStream::pair().unwrap();
        let done = Arc::new(AtomicUsize::new(0));
        let d = Arc::clone(&done);
        let mut work: IdleWork = Box::new(move || d.fetch_add(1, Ordering::Relaxed) + 1 < 5);
        let mut buf = [0u8; 8];
        assert!(BusyPoll::OFF
            .recv_or_work(a.as_raw_fd(), &mut buf, std::slice::from_mut(&mut work))
            .is_none());
        assert_eq!(done.load(Ordering::Relaxed), 5);
        // Data already there: read before any work.
        b.write_all(b"now").unwrap();
        let n = BusyPoll::OFF
            .recv_or_work(a.as_raw_fd(), &mut buf, std::slice::from_mut(&mut work))
            .unwrap()
            .unwrap();
        assert_eq!(&buf[..n], b"now");
        assert_eq!(done.load(Ordering::Relaxed), 5);
        // Endless work: the data that arrives meanwhile is still read.
        let mut endless: IdleWork = Box::new(|| true);
        let writer = write_later(b, b"late");
        let n = BusyPoll::OFF
            .recv_or_work(a.as_raw_fd(), &mut buf, std::slice::from_mut(&mut endless))
            .unwrap()
            .unwrap();
        assert_eq!(&buf[..n], b"late");
        drop(writer.join().unwrap());
    }

    #[test]
    fn end_of_stream_is_zero_bytes() {
        let (a, b) = UnixStream::pair().unwrap();
        drop(b);
        let mut buf = [0u8; 8];
        let r = BusyPoll::from_micros(1_000).recv(a.as_raw_fd(), &mut buf);
        assert_eq!(r.unwrap().unwrap(), 0);
    }

    #[test]
    fn a_socket_error_is_reported() {
        // Not a socket: recv fails with ENOTSOCK, which must come back as
        // an error, not be polled until the budget ends.
        let f = tempfile::tempfile().unwrap();
        let mut buf = [0u8; 8];
        let t = Instant::now();
        let r = BusyPoll::from_micros(10_000_000).recv(f.as_raw_fd(), &mut buf);
        assert!(r.unwrap().is_err());
        assert!(t.elapsed() < Duration::from_secs(5));
    }

    #[test]
    fn the_async_next_takes_items_ready_now_and_later() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async {
            let (tx, rx) = tokio::sync::mpsc::unbounded_channel::<u32>();
            let mut s = tokio_stream_from(rx);
            tx.send(1).unwrap();
            let poll = BusyPoll::from_micros(1_000);
            assert_eq!(poll.next(&mut s).await, Some(1));
            // Nothing for longer than the budget: it waits, then gets it.
            let later = tx.clone();
            tokio::spawn(async move {
                tokio::time::sleep(Duration::from_millis(5)).await;
                later.send(2).unwrap();
            });
            assert_eq!(poll.next(&mut s).await, Some(2));
            drop(tx);
            assert_eq!(poll.next(&mut s).await, None);
        });
    }

    fn tokio_stream_from(
        mut rx: tokio::sync::mpsc::UnboundedReceiver<u32>,
    ) -> impl futures::Stream<Item = u32> + Unpin {
        Box::pin(futures::stream::poll_fn(move |cx| rx.poll_recv(cx)))
    }
}
