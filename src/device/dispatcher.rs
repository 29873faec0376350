//! The main loop's half: the [`Dispatcher`] that decodes the link's commands, answers them,
//! hands orders to the interrupt and stores parameters.

use super::analog::Source as SetpointSource;
use super::params::{Board, Params, Refused};
use super::protocol::{
    Build, Command, FrameError, Framer, Invalid, LoadError, Message, Refusal, Reply, Request,
    Signal, Source, Started, Telemetry, MAX_FRAME,
};
use super::{
    commission, protocol, Action, Boot, MainEnds, Order, Outcome, Storage, Ticket, MAX_MOVE_S,
    PROBE_MAX_SHARE, REJECTIONS_PER_S, TX_CAPACITY,
};
use crate::control::math;
use crate::control::{self};

/// What the dispatcher does once the interrupt answers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Then {
    /// Answer with the outcome.
    Reply,
    /// On success, use these parameters.
    Commit {
        params: Params,
        source: Source<'static>,
        unsaved: bool,
    },
    /// On success, answer and hand the platform this action.
    Act(Action),
    /// On success, stream these signals.
    Signals(u16),
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Pending {
    seq: u16,
    id: u8,
    then: Then,
}

/// The main loop's half: frames in, frames out, parameters.
pub struct Dispatcher {
    board: Board,
    build: Build<'static>,
    defaults: Params,
    params: Params,
    source: Source<'static>,
    unsaved: bool,
    capacity: u16,
    framer: Framer,
    tx: heapless::Vec<u8, TX_CAPACITY>,
    pending: Option<Pending>,
    next_id: u8,
    signals: u16,
    rejected: u32,
    /// Bytes at the front of `tx` up to the end of the rejection waiting there (0: none).
    rejection_end: usize,
    /// Main-loop passes ([`Dispatcher::poll`]): the dispatcher's clock, one per tick
    /// while the main loop keeps up.
    passes: u32,
    /// The pass of the last rejection sent.
    rejection_pass: Option<u32>,
    /// Passes between two rejections sent.
    rejection_passes: u32,
    dropped: u32,
    action: Option<Action>,
}

/// Counts of what the dispatcher refused and dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Frames refused ([`Message::Rejected`]).
    pub rejected: u32,
    /// Telemetry frames not sent for lack of room.
    pub dropped: u32,
}

impl Dispatcher {
    /// After a start of the firmware `build`: `boot` says what the parameters are; the
    /// [`Message::Started`] announcement is the first frame out.
    #[must_use]
    pub fn new(
        board: Board,
        build: Build<'static>,
        defaults: Params,
        boot: &Boot,
        capacity: u16,
    ) -> Self {
        let mut d = Self {
            board,
            build,
            defaults,
            params: boot.params,
            source: boot.source,
            unsaved: false,
            capacity,
            framer: Framer::new(),
            tx: heapless::Vec::new(),
            pending: None,
            next_id: 0,
            signals: 0,
            rejected: 0,
            rejection_end: 0,
            passes: 0,
            rejection_pass: None,
            rejection_passes: math::whole_ticks(board.rate_hz / REJECTIONS_PER_S),
            dropped: 0,
            action: None,
        };
        d.send(&Message::Started(Started {
            params: boot.source,
            saved: boot.saved,
            capture_capacity: capacity,
            rate_hz: board.rate_hz,
        }));
        d
    }

    /// The parameters in use.
    #[must_use]
    pub const fn params(&self) -> &Params {
        &self.params
    }

    /// What was refused and dropped so far.
    #[must_use]
    pub const fn counts(&self) -> Counts {
        Counts {
            rejected: self.rejected,
            dropped: self.dropped,
        }
    }

    /// An order is waiting for the interrupt's answer (no byte is taken meanwhile).
    #[must_use]
    pub const fn busy(&self) -> bool {
        self.pending.is_some()
    }

    /// Bytes waiting to be sent.
    #[must_use]
    pub fn tx(&self) -> &[u8] {
        &self.tx
    }

    /// The first `n` bytes of [`Dispatcher::tx`] were sent.
    pub fn sent(&mut self, n: usize) {
        let n = n.min(self.tx.len());
        self.rejection_end = self.rejection_end.saturating_sub(n);
        let rest = self.tx.len().saturating_sub(n);
        to_front(&mut self.tx, n);
        self.tx.truncate(rest);
    }

    /// The action to carry out once the transmit buffer is empty.
    pub fn take_action(&mut self) -> Option<Action> {
        if self.tx.is_empty() {
            self.action.take()
        } else {
            None
        }
    }

    /// Takes received bytes until a request needs the interrupt, or until the transmit
    /// buffer lacks the room of a reply (a reply is never dropped: the request waits);
    /// returns how many were taken (give the rest again after [`Dispatcher::poll`] has
    /// seen the answer, or the line has taken some of the transmit buffer).
    pub fn receive(
        &mut self,
        bytes: &[u8],
        ends: &mut MainEnds<'_>,
        storage: &mut dyn Storage,
    ) -> usize {
        let mut taken = 0usize;
        for &b in bytes {
            if self.pending.is_some()
                || self.action.is_some()
                || TX_CAPACITY.saturating_sub(self.tx.len()) < MAX_FRAME
            {
                break;
            }
            taken = taken.saturating_add(1);
            let mut frame = [0u8; MAX_FRAME];
            let len = match self.framer.push(b) {
                None => continue,
                Some(Err(e)) => {
                    self.reject(e);
                    continue;
                }
                Some(Ok(raw)) => {
                    let n = raw.len().min(MAX_FRAME);
                    if let (Some(dst), Some(src)) = (frame.get_mut(..n), raw.get(..n)) {
                        dst.copy_from_slice(src);
                    }
                    n
                }
            };
            self.framer.clear();
            let Some(raw) = frame.get_mut(..len) else {
                continue;
            };
            match protocol::decode::<Request>(raw) {
                Ok(r) => {
                    ends.pulse.request_received();
                    self.handle(r.seq, r.command, ends, storage);
                }
                Err(e) => self.reject(e),
            }
        }
        taken
    }

    /// Completes a request the interrupt has answered, and turns telemetry samples into
    /// frames (dropping them when the link is behind).
    pub fn poll(&mut self, ends: &mut MainEnds<'_>) {
        ends.pulse.main_loop_ran();
        self.passes = self.passes.wrapping_add(1);
        if let Some(p) = self.pending {
            if let Some(answer) = ends.answers.dequeue() {
                if answer.id == p.id {
                    self.pending = None;
                    self.complete(p, answer.outcome);
                }
            }
        }
        while let Some(t) = ends.samples.dequeue() {
            if self.signals == 0 {
                continue;
            }
            if TX_CAPACITY.saturating_sub(self.tx.len()) < 2 * MAX_FRAME {
                self.dropped = self.dropped.saturating_add(1);
                continue;
            }
            let mut values = heapless::Vec::new();
            for s in Signal::ALL {
                if self.signals & s.bit() != 0 {
                    let _ = values.push(s.of(&t.sample));
                }
            }
            self.send(&Message::Telemetry(Telemetry {
                tick: t.tick,
                mode: t.sample.mode,
                fault: t.sample.fault,
                values,
            }));
        }
    }

    /// Counts a frame it could not read and answers it with [`Message::Rejected`], unless
    /// the last rejection is still waiting to be sent or was sent less than
    /// `1 / REJECTIONS_PER_S` ago ([`REJECTIONS_PER_S`]), or the answer would leave less
    /// than two frames' room (the reserve telemetry also keeps): line noise or a babbling
    /// host never crowd out a reply.
    #[inline(never)]
    fn reject(&mut self, e: FrameError) {
        self.rejected = self.rejected.saturating_add(1);
        let due = self
            .rejection_pass
            .is_none_or(|at| self.passes.wrapping_sub(at) >= self.rejection_passes);
        if due
            && self.rejection_end == 0
            && TX_CAPACITY.saturating_sub(self.tx.len()) >= 2 * MAX_FRAME
        {
            self.send(&Message::Rejected(e));
            self.rejection_end = self.tx.len();
            self.rejection_pass = Some(self.passes);
        }
    }

    fn send(&mut self, m: &Message<'_>) {
        let mut frame = [0u8; MAX_FRAME];
        if let Ok(n) = protocol::encode(m, &mut frame) {
            if let Some(bytes) = frame.get(..n) {
                // Replies are sent before telemetry fills the buffer (poll keeps two
                // frames free); a full buffer only ever drops telemetry.
                let _ = self.tx.extend_from_slice(bytes);
            }
        }
    }

    fn reply(&mut self, seq: u16, reply: Reply<'_>) {
        self.send(&Message::Reply { seq, reply });
    }

    fn order(&mut self, seq: u16, order: Order, then: Then, ends: &mut MainEnds<'_>) {
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1);
        // Nothing else is in flight (receive stops while a request is pending), so the
        // queue has room.
        let _ = ends.orders.enqueue(Ticket { id, order });
        self.pending = Some(Pending { seq, id, then });
    }

    /// The commissioning plan for the parameters in use.
    fn commission_plan(&self) -> Result<commission::Plan, Refusal<'static>> {
        commission::Plan::for_actuator(&self.params.actuator, self.board.rate_hz)
            .map_err(|e| Refusal::Invalid(Invalid::from(e)))
    }

    fn invalid(
        param: &'static str,
        value: f32,
        reason: crate::control::config::Reason,
    ) -> Refusal<'static> {
        Refusal::Invalid(Invalid::from(crate::control::config::Error {
            param,
            value,
            reason,
        }))
    }

    #[inline(never)]
    #[expect(
        clippy::too_many_lines,
        reason = "one short arm per command of the protocol: the match reads as the protocol's \
                  table, which split across functions would have to be read in pieces"
    )]
    fn handle(
        &mut self,
        seq: u16,
        command: Command<'_>,
        ends: &mut MainEnds<'_>,
        storage: &mut dyn Storage,
    ) {
        use crate::control::config::Reason;
        let then = Then::Reply;
        match command {
            Command::Status => self.order(seq, Order::Status, then, ends),
            Command::Heartbeat => self.reply(seq, Reply::Done),
            Command::Arm => self.order(seq, Order::Arm, then, ends),
            Command::Disarm => self.order(seq, Order::Disarm, then, ends),
            Command::Clear => self.order(seq, Order::Clear, then, ends),
            Command::Commission => match self.commission_plan() {
                Ok(plan) => self.order(seq, Order::Commission(plan), then, ends),
                Err(r) => self.reply(seq, Reply::Refused(r)),
            },
            Command::Commissioned => self.order(seq, Order::Commissioned, then, ends),
            Command::Probe {
                amplitude_a,
                half_ticks,
                cycles,
            } => {
                let rated = self.params.actuator.coil.rated_current_a;
                let checked = crate::control::config::within(
                    "probe.amplitude_a",
                    amplitude_a,
                    0.0,
                    PROBE_MAX_SHARE * rated,
                );
                match checked {
                    Err(e) => self.reply(seq, Reply::Refused(Refusal::Invalid(Invalid::from(e)))),
                    Ok(_) => self.order(
                        seq,
                        Order::Probe(control::Probe::new(amplitude_a, half_ticks, cycles)),
                        then,
                        ends,
                    ),
                }
            }
            Command::Move { position_m, time_s } => {
                let stroke = self.params.actuator.mechanics.stroke_m;
                let refusal = if let Err(e) =
                    crate::control::config::within("move.position_m", position_m, 0.0, stroke)
                {
                    Some(Refusal::Invalid(Invalid::from(e)))
                } else if let Some(Err(e)) = time_s
                    .map(|t| crate::control::config::within("move.time_s", t, 0.0, MAX_MOVE_S))
                {
                    Some(Refusal::Invalid(Invalid::from(e)))
                } else if self.params.setpoint.source != SetpointSource::Link {
                    Some(Refusal::AnalogSetpoint)
                } else {
                    None
                };
                match refusal {
                    Some(r) => self.reply(seq, Reply::Refused(r)),
                    None => self.order(
                        seq,
                        Order::Move {
                            x_m: position_m,
                            time_s: time_s.unwrap_or(0.0),
                        },
                        then,
                        ends,
                    ),
                }
            }
            Command::Get { name } => match self.params.get(name) {
                Ok(v) => self.reply(seq, Reply::Value(v)),
                Err(e) => self.reply(seq, Reply::Refused(refused(name, e))),
            },
            Command::Set { name, value } => {
                let mut candidate = self.params;
                if let Err(e) = candidate.set(name, value) {
                    self.reply(seq, Reply::Refused(refused(name, e)));
                    return;
                }
                match candidate.build(&self.board) {
                    Err(e) => self.reply(seq, Reply::Refused(Refusal::Invalid(e.into()))),
                    Ok(install) => self.order(
                        seq,
                        Order::Install(install),
                        Then::Commit {
                            params: candidate,
                            source: self.source,
                            unsaved: true,
                        },
                        ends,
                    ),
                }
            }
            Command::Load => match storage.load() {
                Err(e) => self.reply(seq, Reply::Refused(Refusal::Load(e))),
                Ok(p) => match p.build(&self.board) {
                    Err(e) => self.reply(
                        seq,
                        Reply::Refused(Refusal::Load(LoadError::Invalid(e.into()))),
                    ),
                    Ok(install) => self.order(
                        seq,
                        Order::Install(install),
                        Then::Commit {
                            params: p,
                            source: Source::Stored,
                            unsaved: false,
                        },
                        ends,
                    ),
                },
            },
            Command::Defaults => match self.defaults.build(&self.board) {
                Err(e) => self.reply(seq, Reply::Refused(Refusal::Invalid(e.into()))),
                Ok(install) => self.order(
                    seq,
                    Order::Install(install),
                    Then::Commit {
                        params: self.defaults,
                        source: Source::Defaults,
                        unsaved: true,
                    },
                    ends,
                ),
            },
            Command::Save => self.order(
                seq,
                Order::Disarmed,
                Then::Act(Action::Save(self.params)),
                ends,
            ),
            Command::Restart => {
                self.order(seq, Order::Disarmed, Then::Act(Action::Restart), ends);
            }
            Command::Stream {
                signals,
                decimation,
            } => {
                let all = (1u16 << Signal::ALL.len()).wrapping_sub(1);
                if signals & !all != 0 || (decimation != 0 && signals == 0) {
                    let r = Self::invalid(
                        "stream.signals",
                        f32::from(signals),
                        Reason::AboveMax {
                            max: f32::from(all),
                        },
                    );
                    self.reply(seq, Reply::Refused(r));
                } else {
                    self.order(
                        seq,
                        Order::Stream { decimation },
                        Then::Signals(signals),
                        ends,
                    );
                }
            }
            Command::Capture {
                samples,
                decimation,
                trigger,
            } => {
                let r = if samples == 0 || samples > self.capacity {
                    Some(Self::invalid(
                        "capture.samples",
                        f32::from(samples),
                        if samples == 0 {
                            Reason::NotPositive
                        } else {
                            Reason::AboveMax {
                                max: f32::from(self.capacity),
                            }
                        },
                    ))
                } else if decimation == 0 {
                    Some(Self::invalid(
                        "capture.decimation",
                        0.0,
                        Reason::NotPositive,
                    ))
                } else {
                    None
                };
                match r {
                    Some(r) => self.reply(seq, Reply::Refused(r)),
                    None => self.order(
                        seq,
                        Order::Capture {
                            samples,
                            decimation,
                            trigger,
                        },
                        then,
                        ends,
                    ),
                }
            }
            Command::ReadCapture { offset } => {
                self.order(seq, Order::ReadCapture { offset }, then, ends);
            }
        }
    }

    #[inline(never)]
    fn complete(&mut self, p: Pending, outcome: Outcome) {
        let reply = match outcome {
            Outcome::Done(Err(r)) => Reply::Refused(r),
            Outcome::Done(Ok(())) => match p.then {
                Then::Reply => Reply::Done,
                Then::Commit {
                    params,
                    source,
                    unsaved,
                } => {
                    self.params = params;
                    self.source = source;
                    self.unsaved = unsaved;
                    Reply::Done
                }
                Then::Signals(s) => {
                    self.signals = s;
                    Reply::Done
                }
                Then::Act(a) => {
                    self.action = Some(a);
                    match a {
                        Action::Save(_) => Reply::Saving,
                        Action::Restart => Reply::Restarting,
                    }
                }
            },
            Outcome::Status(mut s) => {
                s.params = self.source;
                s.unsaved = self.unsaved;
                s.frames_rejected = self.rejected;
                s.build = self.build;
                s.telemetry_dropped = s.telemetry_dropped.saturating_add(self.dropped);
                self.reply(p.seq, Reply::Status(s));
                return;
            }
            Outcome::Chunk(c) => Reply::Capture(c),
            Outcome::Commissioned(c) => Reply::Commissioned(c),
        };
        self.reply(p.seq, reply);
    }
}

/// Moves `bytes[n..]` to the front (as `copy_within(n.., 0)`), in pieces of `n` bytes,
/// none overlapping where it goes: copies (memcpy, in the image anyway), not one move
/// (memmove: 1.5 KiB of flash for this use alone).
#[inline(always)]
pub(super) fn to_front(bytes: &mut [u8], n: usize) {
    let rest = bytes.len().saturating_sub(n);
    let mut at = 0;
    while n > 0 && at < rest {
        // at < rest <= bytes.len() and n <= bytes.len(): nothing wraps.
        let len = n.min(rest.wrapping_sub(at));
        if let Some((head, tail)) = bytes.split_at_mut_checked(at.wrapping_add(n)) {
            if let (Some(to), Some(from)) =
                (head.get_mut(at..at.wrapping_add(len)), tail.get(..len))
            {
                to.copy_from_slice(from);
            }
        }
        at = at.wrapping_add(len);
    }
}

pub(super) fn refused(name: &str, e: Refused) -> Refusal<'_> {
    match e {
        Refused::Unknown => Refusal::UnknownParam { name },
        Refused::Fixed(why) => Refusal::ReadOnly { name, why },
        Refused::WrongKind => Refusal::WrongKind { name },
        Refused::Unused => Refusal::ReadOnly {
            name,
            why: "the actuator's magnetic circuit has the other form",
        },
        Refused::Invalid(e) => Refusal::Invalid(e.into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn to_front_moves_as_copy_within() {
        for len in 0..40usize {
            for n in 0..=len {
                let start: [u8; 40] =
                    core::array::from_fn(|k| u8::try_from(k + 1).unwrap_or(u8::MAX));
                let (mut got, mut want) = (start, start);
                to_front(&mut got[..len], n);
                want[..len].copy_within(n.., 0);
                assert_eq!(got[..len - n], want[..len - n], "len {len}, n {n}");
            }
        }
    }
}
