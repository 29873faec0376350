//! The host's end of the link: requests out, replies in, over any byte stream (a serial
//! port, a pseudo-terminal, or a virtual board in the same process).

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context};
use ema::protocol::{
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

/// The host's end.
pub struct Link<P> {
    port: P,
    seq: u16,
    framer: Framer,
    frames: VecDeque<Frame>,
    telemetry: VecDeque<Telemetry>,
    started: Option<Frame>,
    timeout: Duration,
}

impl<P: Read + Write> Link<P> {
    /// Over `port`; a request waits at most `timeout` for its reply.
    pub fn new(port: P, timeout: Duration) -> Self {
        Self {
            port,
            seq: 0,
            framer: Framer::new(),
            frames: VecDeque::new(),
            telemetry: VecDeque::new(),
            started: None,
            timeout,
        }
    }

    /// The port.
    pub fn port(&mut self) -> &mut P {
        &mut self.port
    }

    /// Sends raw bytes (tests: damaged frames).
    ///
    /// # Errors
    /// The port failing.
    pub fn send_raw(&mut self, bytes: &[u8]) -> anyhow::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()?;
        Ok(())
    }

    /// Reads what is there (waiting at most the port's own timeout) into frames.
    ///
    /// # Errors
    /// The port failing.
    pub fn pump(&mut self) -> anyhow::Result<()> {
        let mut buf = [0u8; 512];
        let n = match self.port.read(&mut buf) {
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
            _ => self.frames.push_back(f),
        }
    }

    /// Sends `command` and waits for its reply (frames answering other requests and
    /// [`Message::Rejected`] answers are returned as errors only when they are this
    /// request's).
    ///
    /// # Errors
    /// No reply in time, the port failing, a frame the board rejected.
    pub fn request(&mut self, command: Command<'_>) -> anyhow::Result<Frame> {
        self.seq = self.seq.wrapping_add(1);
        let seq = self.seq;
        let mut out = [0u8; MAX_FRAME];
        let n = protocol::encode(&Request { seq, command }, &mut out)
            .map_err(|e| anyhow!("cannot encode the request: {e}"))?;
        self.send_raw(&out[..n])?;
        let deadline = Instant::now() + self.timeout;
        loop {
            while let Some(f) = self.frames.pop_front() {
                let mut scratch = Vec::new();
                match f.message(&mut scratch) {
                    Ok(Message::Reply { seq: s, .. }) if s == seq => return Ok(f),
                    Ok(Message::Rejected(e)) => bail!("the board could not read the request: {e}"),
                    _ => {}
                }
            }
            if Instant::now() > deadline {
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
