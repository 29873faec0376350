//! The three queues between the two halves and what they carry: the main loop's orders, the
//! interrupt's answers, telemetry; each half's ends of them.

use heapless::spsc::{Consumer, Producer, Queue};

use super::liveness::Pulse;
use super::protocol::{Chunk, Commissioned, Refusal, Sample, Status, Trigger};
use super::{analog, commission, liveness, ANSWER_SLOTS, ORDER_SLOTS, SAMPLE_SLOTS};
use crate::control::{self};

/// A new configuration for the interrupt, built and validated by the main loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Install {
    /// The controller.
    pub control: control::Config,
    /// The analog input.
    pub analog: analog::Config,
    /// The link's timeout.
    pub link: liveness::Config,
}

/// What the main loop asks of the interrupt.
// An install carries a whole configuration; there is no heap to box it, and the queue
// holds one order at a time.
#[expect(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Order {
    /// Arm (see [`Command::Arm`](super::protocol::Command::Arm)).
    Arm,
    /// Disarm.
    Disarm,
    /// Move to `x_m` in at least `time_s` (0: as fast as the limits allow).
    Move {
        /// Target \[m\], within the stroke (checked by the main loop).
        x_m: f32,
        /// Duration \[s\].
        time_s: f32,
    },
    /// Clear a latched fault whose cause is gone.
    Clear,
    /// One telemetry sample every `decimation` ticks (0: none).
    Stream {
        /// Ticks per sample.
        decimation: u16,
    },
    /// Start a capture.
    Capture {
        /// Samples (at most the buffer's length).
        samples: u16,
        /// Ticks per sample, at least 1.
        decimation: u16,
        /// When.
        trigger: Trigger,
    },
    /// A chunk of the finished capture from `offset`.
    ReadCapture {
        /// First sample.
        offset: u16,
    },
    /// The state.
    Status,
    /// Done when disarmed (and then the board stays disarmed until the main loop itself
    /// orders otherwise); refused when armed.
    Disarmed,
    /// Use a new configuration (disarmed only).
    Install(Install),
    /// Start a commissioning with this plan (disarmed only, see
    /// [`Command::Commission`](super::protocol::Command::Commission)).
    Commission(commission::Plan),
    /// The last commissioning's outcome.
    Commissioned,
    /// Start an inductance probe (armed only; checked by the main loop).
    Probe(control::Probe),
}

/// An order and its number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ticket {
    /// Echoed by the answer.
    pub id: u8,
    /// The order.
    pub order: Order,
}

/// The interrupt's answer to an order.
#[derive(Clone, Debug, PartialEq)]
pub struct Answer {
    /// The order's number.
    pub id: u8,
    /// What it gave.
    pub outcome: Outcome,
}

/// What an order gave.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Done, or refused and why.
    Done(Result<(), Refusal<'static>>),
    /// The state (the main loop adds its own part).
    Status(Status<'static>),
    /// Part of the capture.
    Chunk(Chunk),
    /// The last commissioning's outcome.
    Commissioned(Commissioned),
}

/// One telemetry sample and its tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Telemetered {
    /// Tick.
    pub tick: u32,
    /// The sample.
    pub sample: Sample,
}

/// The three queues between the halves, and the main loop's pulse.
pub struct Queues {
    orders: Queue<Ticket, ORDER_SLOTS>,
    answers: Queue<Answer, ANSWER_SLOTS>,
    samples: Queue<Telemetered, SAMPLE_SLOTS>,
    pulse: Pulse,
}

impl Default for Queues {
    fn default() -> Self {
        Self::new()
    }
}

impl Queues {
    /// Empty.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            orders: Queue::new(),
            answers: Queue::new(),
            samples: Queue::new(),
            pulse: Pulse::new(),
        }
    }

    /// The main loop's ends and the interrupt's ends.
    pub fn split(&mut self) -> (MainEnds<'_>, IsrEnds<'_>) {
        let (op, oc) = self.orders.split();
        let (ap, ac) = self.answers.split();
        let (sp, sc) = self.samples.split();
        let pulse = &self.pulse;
        (
            MainEnds {
                orders: op,
                answers: ac,
                samples: sc,
                pulse,
            },
            IsrEnds {
                orders: oc,
                answers: ap,
                samples: sp,
                pulse,
            },
        )
    }
}

/// The main loop's ends of the queues.
pub struct MainEnds<'q> {
    /// Orders out.
    pub orders: Producer<'q, Ticket>,
    /// Answers in.
    pub answers: Consumer<'q, Answer>,
    /// Telemetry in.
    pub samples: Consumer<'q, Telemetered>,
    /// Its passes and the requests it decodes, for the interrupt's liveness checks.
    pub pulse: &'q Pulse,
}

/// The interrupt's ends of the queues.
pub struct IsrEnds<'q> {
    /// Orders in.
    pub orders: Consumer<'q, Ticket>,
    /// Answers out.
    pub answers: Producer<'q, Answer>,
    /// Telemetry out.
    pub samples: Producer<'q, Telemetered>,
    /// The main loop's passes and requests.
    pub pulse: &'q Pulse,
}
