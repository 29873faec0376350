//! The host's end of the link: requests out, replies in, over any byte stream (a serial
//! port, a pseudo-terminal, or a virtual board in the same process).
//!
//! * **Sequence numbers.** Each process starts at a random one, and a reply is paired with
//!   its request by number only: a late reply to an earlier process's request, or to a
//!   request that timed out, is never taken for this one's.
//! * **Rejections.** A [`Message::Rejected`] says the board could not read a frame; it
//!   names no request (its sequence number could not be trusted), so it fails none: the
//!   request waits for its own reply, and the error on a timeout counts the rejections
//!   seen meanwhile.
//! * **Heartbeat.** While the link is open, a thread sends
//!   [`Command::Heartbeat`] whenever no request has gone out for [`HEARTBEAT`], a quarter
//!   of the shortest timeout a board accepts ([`ema::device::liveness::MIN_TIMEOUT_S`]): an
//!   armed board keeps its host for as long as this process runs, computing or waiting
//!   included, and disarms within its `link.timeout_s` once the process ends.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU16, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context};
use ema::device::protocol::{
    self, Command, Framer, Message, Reply, Request, Started, Telemetry, MAX_FRAME,
};

/// A frame received, kept as its bytes; [`Frame::message`] decodes it.
#[derive(Clone, Debug)]
pub struct Frame(Vec<u8>);

impl Frame {
    /// The message (decoded into `scratch`).
    ///
    /// # Errors
    /// What is wrong with the frame.
    pub fn message<'s>(
        &self,
        scratch: &'s mut Vec<u8>,
    ) -> Result<Message<'s>, protocol::FrameError> {
        scratch.clear();
        scratch.extend_from_slice(&self.0);
        protocol::decode::<Message>(scratch)
    }
}

/// A byte stream the link runs over: a serial port, a pseudo-terminal (its heartbeat
/// thread shares it).
pub trait Port: Read + Write + Send + 'static {}

impl<P: Read + Write + Send + 'static> Port for P {}

/// How long the link may go without a request before the heartbeat thread sends one.
pub const HEARTBEAT: Duration =
    Duration::from_micros((ema::device::liveness::MIN_TIMEOUT_S * 250_000.0) as u64);

/// Frames kept for a request to find its reply among (older ones are replies nobody
/// waits for: the heartbeat's, or a timed-out request's).
const KEPT_FRAMES: usize = 64;

/// What the link's two threads share: the port, the next sequence number, when the last
/// request went out.
struct Shared<P> {
    port: Mutex<P>,
    seq: AtomicU16,
    last_sent: Mutex<Instant>,
    stop: AtomicBool,
}

impl<P: Write> Shared<P> {
    fn port(&self) -> MutexGuard<'_, P> {
        self.port
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Sends `command` with the next sequence number; returns the number.
    fn send(&self, command: Command<'_>) -> anyhow::Result<u16> {
        let seq = self.seq.fetch_add(1, Ordering::Relaxed).wrapping_add(1);
        let mut out = [0u8; MAX_FRAME];
        let n = protocol::encode(&Request { seq, command }, &mut out)
            .map_err(|e| anyhow!("cannot encode the request: {e}"))?;
        {
            let mut port = self.port();
            port.write_all(&out[..n])?;
            port.flush()?;
        }
        *self
            .last_sent
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Instant::now();
        Ok(seq)
    }

    /// Time since the last request.
    fn quiet(&self) -> Duration {
        self.last_sent
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .elapsed()
    }
}

/// The host's end.
pub struct Link<P: Port> {
    shared: Arc<Shared<P>>,
    heartbeat: Option<thread::JoinHandle<()>>,
    framer: Framer,
    frames: VecDeque<Frame>,
    telemetry: VecDeque<Telemetry>,
    started: Option<Frame>,
    rejected: u32,
    timeout: Duration,
}

impl<P: Port> Link<P> {
    /// Over `port` (whose input holds nothing older than this link: see
    /// [`super::cli::open`]), starting at a random sequence number, with the heartbeat
    /// running; a request waits at most `timeout` for its reply.
    pub fn new(port: P, timeout: Duration) -> Self {
        let shared = Arc::new(Shared {
            port: Mutex::new(port),
            seq: AtomicU16::new(rand::random()),
            last_sent: Mutex::new(Instant::now()),
            stop: AtomicBool::new(false),
        });
        let mut link = Self {
            shared,
            heartbeat: None,
            framer: Framer::new(),
            frames: VecDeque::new(),
            telemetry: VecDeque::new(),
            started: None,
            rejected: 0,
            timeout,
        };
        link.start_heartbeat();
        link
    }

    /// Starts the heartbeat (if it is not running).
    pub fn start_heartbeat(&mut self) {
        if self.heartbeat.is_some() {
            return;
        }
        self.shared.stop.store(false, Ordering::Relaxed);
        let beat = self.shared.clone();
        self.heartbeat = Some(thread::spawn(move || {
            while !beat.stop.load(Ordering::Relaxed) {
                let quiet = beat.quiet();
                if quiet >= HEARTBEAT {
                    // A failing port fails the next request of the main thread.
                    let _ = beat.send(Command::Heartbeat);
                } else {
                    thread::sleep(HEARTBEAT - quiet);
                }
            }
        }));
    }

    /// Stops the heartbeat: the board hears from this host only when it asks something
    /// (a host that hangs with its port open, in tests).
    pub fn stop_heartbeat(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.heartbeat.take() {
            let _ = h.join();
        }
    }

    /// The port, locked (the heartbeat waits meanwhile).
    pub fn port(&mut self) -> MutexGuard<'_, P> {
        self.shared.port()
    }

    /// Frames the board rejected ([`Message::Rejected`]) since the link opened.
    #[must_use]
    pub const fn rejected(&self) -> u32 {
        self.rejected
    }

    /// Sends raw bytes (tests: damaged frames).
    ///
    /// # Errors
    /// The port failing.
    pub fn send_raw(&mut self, bytes: &[u8]) -> anyhow::Result<()> {
        let mut port = self.shared.port();
        port.write_all(bytes)?;
        port.flush()?;
        Ok(())
    }

    /// Reads what is there (waiting at most the port's own timeout) into frames.
    ///
    /// # Errors
    /// The port failing.
    pub fn pump(&mut self) -> anyhow::Result<()> {
        let mut buf = [0u8; 512];
        let read = self.shared.port().read(&mut buf);
        let n = match read {
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::Interrupted
                ) =>
            {
                0
            }
            Err(e) => return Err(e.into()),
        };
        for &b in &buf[..n] {
            let got = self.framer.push(b).map(|r| r.map(|raw| raw.to_vec()));
            if let Some(r) = got {
                self.framer.clear();
                if let Ok(raw) = r {
                    self.sort(Frame(raw));
                }
            }
        }
        Ok(())
    }

    fn sort(&mut self, f: Frame) {
        let mut scratch = Vec::new();
        match f.message(&mut scratch) {
            Ok(Message::Telemetry(t)) => self.telemetry.push_back(t),
            Ok(Message::Started(_)) => self.started = Some(f),
            Ok(Message::Rejected(_)) => self.rejected = self.rejected.saturating_add(1),
            _ => {
                if self.frames.len() >= KEPT_FRAMES {
                    self.frames.pop_front();
                }
                self.frames.push_back(f);
            }
        }
    }

    /// Sends `command` and waits for the reply with its sequence number (every other frame
    /// is left aside: see the module documentation).
    ///
    /// # Errors
    /// No reply in time, the port failing.
    pub fn request(&mut self, command: Command<'_>) -> anyhow::Result<Frame> {
        let rejected = self.rejected;
        let seq = self.shared.send(command)?;
        let deadline = Instant::now() + self.timeout;
        loop {
            let mut scratch = Vec::new();
            let mine = self.frames.iter().position(|f| {
                matches!(f.message(&mut scratch), Ok(Message::Reply { seq: s, .. }) if s == seq)
            });
            if let Some(k) = mine {
                return self.frames.remove(k).ok_or_else(|| anyhow!("lost frame"));
            }
            if Instant::now() > deadline {
                let seen = self.rejected - rejected;
                if seen > 0 {
                    bail!(
                        "no reply within {:?}; the board could not read {seen} frame(s) \
                         meanwhile (line noise, or another program on the port?)",
                        self.timeout
                    );
                }
                bail!("no reply within {:?}", self.timeout);
            }
            self.pump()?;
        }
    }

    /// Sends `command`, expects [`Reply::Done`] (or one of the named replies that mean
    /// "done": saving, restarting).
    ///
    /// # Errors
    /// A refusal (described), or as [`Link::request`].
    pub fn done(&mut self, command: Command<'_>) -> anyhow::Result<()> {
        let f = self.request(command)?;
        let mut scratch = Vec::new();
        match f.message(&mut scratch)? {
            Message::Reply {
                reply: Reply::Done | Reply::Saving | Reply::Restarting,
                ..
            } => Ok(()),
            Message::Reply {
                reply: Reply::Refused(r),
                ..
            } => Err(Refused(super::refusal(&r)).into()),
            other => Err(anyhow!("unexpected reply: {other:?}")),
        }
    }

    /// Telemetry received so far (taken).
    pub fn telemetry(&mut self) -> Vec<Telemetry> {
        self.telemetry.drain(..).collect()
    }

    /// Waits for the board's start announcement (after a save or a restart).
    ///
    /// # Errors
    /// None within `timeout`, or the port failing.
    pub fn wait_started(&mut self, timeout: Duration) -> anyhow::Result<Started<'static>> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(f) = self.started.take() {
                let mut scratch = Vec::new();
                if let Message::Started(s) = f.message(&mut scratch)? {
                    return Ok(owned_started(&s));
                }
            }
            if Instant::now() > deadline {
                bail!("the board did not announce a start within {timeout:?}");
            }
            self.pump().context("waiting for the board to start")?;
        }
    }

    /// Forgets a start announcement received so far.
    pub fn forget_started(&mut self) {
        self.started = None;
    }
}

impl<P: Port> Drop for Link<P> {
    fn drop(&mut self) {
        self.stop_heartbeat();
    }
}

/// A start announcement without borrowed text (a refused stored set's field name is kept
/// as a `'static` string: the process is short-lived and does it at most once per start).
fn owned_started(s: &Started<'_>) -> Started<'static> {
    Started {
        params: super::owned_source(&s.params),
        saved: s.saved,
        capture_capacity: s.capture_capacity,
        rate_hz: s.rate_hz,
    }
}

/// The board refused a command: the refusal, in words ([`super::refusal`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refused(pub String);

impl core::fmt::Display for Refused {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "refused: {}", self.0)
    }
}

impl std::error::Error for Refused {}
