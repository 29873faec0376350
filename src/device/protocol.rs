//! The bench link: the messages between a host and the board, and their framing.
//!
//! One definition for the firmware, the virtual board in `hil-sim` and the host tool.
//!
//! ## A frame on the wire
//!
//! ```text
//! COBS( VERSION | postcard(message) | CRC-32C(VERSION | postcard(message)), little endian ) 0x00
//! ```
//!
//! * **COBS** removes every zero from the frame, so a zero byte always ends one: a receiver
//!   that starts in the middle of a frame, or loses bytes, finds the next frame at the next
//!   zero.
//! * **The CRC** (CRC-32C, Castagnoli) covers the version and the message: a frame whose
//!   bytes changed on the way is refused as a whole ([`FrameError::Crc`]).
//! * **The version** ([`VERSION`]) comes first, before anything whose layout it governs: a
//!   host and a board built from different definitions refuse each other's frames by name
//!   ([`FrameError::Version`]) instead of misreading them.
//! * **postcard** (serde) encodes the message: compact, `no_std`, no allocation; strings
//!   are borrowed from the frame's buffer when decoding.
//!
//! A frame is at most [`MAX_FRAME`] bytes with its delimiter ([`MAX_RAW`] before COBS); a
//! longer one is refused ([`FrameError::TooLong`]) and the receiver resynchronises at the
//! next zero.
//!
//! ## The exchange
//!
//! The host sends [`Request`]s, each with a sequence number; the board answers each with
//! [`Message::Reply`] carrying the same number, in order. A frame the board cannot read
//! has no trustworthy sequence number: it is answered with [`Message::Rejected`] naming
//! what was wrong. Unsolicited, the board sends [`Message::Telemetry`] while a stream is
//! on, and [`Message::Started`] once after every start (which says where its parameters
//! came from).
//!
//! ```
//! use ema::device::protocol::{self, Command, Request, Framer, MAX_FRAME};
//!
//! let mut frame = [0u8; MAX_FRAME];
//! let n = protocol::encode(&Request { seq: 7, command: Command::Arm }, &mut frame).unwrap();
//! assert_eq!(frame[n - 1], 0); // the delimiter
//! assert!(frame[..n - 1].iter().all(|&b| b != 0));
//!
//! // The receiver, fed byte by byte.
//! let mut framer = Framer::new();
//! let mut got = None;
//! for &b in &frame[..n] {
//!     if let Some(raw) = framer.push(b) {
//!         let request = protocol::decode::<Request>(raw.unwrap()).unwrap();
//!         got = Some((request.seq, request.command == Command::Arm));
//!     }
//! }
//! assert_eq!(got, Some((7, true)));
//!
//! // One bit flipped on the way: refused by name.
//! let mut bad = frame;
//! bad[2] ^= 0x10;
//! let mut framer = Framer::new();
//! let mut refused = None;
//! for &b in &bad[..n] {
//!     if let Some(raw) = framer.push(b) {
//!         refused = Some(protocol::decode::<Request>(raw.unwrap()).unwrap_err());
//!     }
//! }
//! assert!(refused.is_some());
//! ```

use core::fmt;

use serde::{Deserialize, Serialize};

use crate::control::config;

/// The link's speed on a serial line \[baud\]: the firmware's UART runs at it and the host
/// tool opens its port at it (a pseudo-terminal, the virtual board's, ignores it). 8 data
/// bits, no parity, one stop bit.
pub const BAUD: u32 = 460_800;

/// Version of the message definitions; the first byte of every frame.
pub const VERSION: u8 = 4;
/// Largest frame before COBS: version, message and CRC \[bytes\].
pub const MAX_RAW: usize = 250;
/// Largest frame on the wire, delimiter included \[bytes\]: COBS adds one byte per 254 and
/// one more.
pub const MAX_FRAME: usize = MAX_RAW + MAX_RAW / 254 + 2;
/// Bytes of the CRC at the end of a raw frame.
pub const CRC_LEN: usize = 4;
/// The frame CRC: CRC-32C (Castagnoli), bitwise (no table: 1 KiB of flash saved; the
/// link is slow next to it).
pub const CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISCSI);
/// Samples per capture chunk ([`Reply::Capture`]).
pub const CHUNK_SAMPLES: usize = 6;
/// Values per telemetry frame (one per selected [`Signal`]).
pub const MAX_SIGNALS: usize = 8;
/// Fault codes the status counts (codes `1..=FAULT_SLOTS`).
pub const FAULT_SLOTS: usize = crate::control::supervisor::FAULT_COUNT;

/// A host's request.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Request<'a> {
    /// Sequence number, echoed by the reply.
    pub seq: u16,
    /// What to do.
    #[serde(borrow)]
    pub command: Command<'a>,
}

/// What a host can ask.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Command<'a> {
    /// The board's state ([`Reply::Status`]).
    Status,
    /// Nothing but "the host is alive" ([`Reply::Done`]): every request counts against
    /// the link's timeout ([`crate::device::liveness`]); a host with nothing else to ask
    /// sends this.
    Heartbeat,
    /// Closed loop, holding the present position. Refused while a fault is latched, a
    /// sensor reads implausible, the bus is outside its window or (4-20 mA set point) the
    /// loop current is outside 3.6-21 mA.
    Arm,
    /// Bridge coasting, nothing driven; sensors still read.
    Disarm,
    /// Move to a position (armed, set point from the link).
    Move {
        /// Target \[m\], within the stroke.
        position_m: f32,
        /// Duration of the move \[s\]; `None` or shorter than the actuator allows: the
        /// fastest move its limits allow.
        time_s: Option<f32>,
    },
    /// Clears a latched fault: only disarmed, and only once its cause is gone.
    Clear,
    /// The value of a parameter ([`Reply::Value`]).
    Get {
        /// Dotted name, as in the actuator file (`coil.rated_current_a`).
        name: &'a str,
    },
    /// Changes a parameter: disarmed only; validated with everything else exactly as a
    /// build validates an actuator file. Not stored until [`Command::Save`].
    Set {
        /// Dotted name.
        name: &'a str,
        /// New value.
        value: Value,
    },
    /// Stores the parameters in flash (disarmed only). The board restarts to write
    /// ([`Reply::Saving`]), then announces the outcome ([`Message::Started`]).
    Save,
    /// Reloads the stored parameters, dropping unsaved changes (disarmed only).
    Load,
    /// Back to the built-in parameters (disarmed only); not stored until saved.
    Defaults,
    /// Restarts the board (disarmed only).
    Restart,
    /// Streams telemetry: the selected signals every `decimation` ticks (0: off).
    Stream {
        /// Bit `k` selects the [`Signal`] with code `k`.
        signals: u16,
        /// Ticks per telemetry frame; 0 stops the stream.
        decimation: u16,
    },
    /// Records `samples` samples, one every `decimation` ticks, into the board's RAM.
    Capture {
        /// How many samples (at most the board's capacity, [`Status::capture_capacity`]).
        samples: u16,
        /// Ticks per sample, at least 1.
        decimation: u16,
        /// When to start.
        trigger: Trigger,
    },
    /// Reads a finished capture from sample `offset` on ([`Reply::Capture`]).
    ReadCapture {
        /// First sample.
        offset: u16,
    },
    /// Measures the coil's resistance with the loop open (see
    /// [`crate::device::commission`]): disarmed only, with nothing latched and the sensors
    /// and bus ready. The board is [`Mode::Commissioning`] until it ends; any fault or
    /// order ends it.
    Commission,
    /// The last commissioning's outcome ([`Reply::Commissioned`]).
    Commissioned,
    /// Steps the loop's desired current `+-amplitude_a` about the hold's, `half_ticks`
    /// ticks at each level, for `cycles` cycles, starting up (an inductance probe,
    /// [`crate::control::Probe`]): armed only, the amplitude at most
    /// [`crate::device::PROBE_MAX_SHARE`] of the rated current (no level ticks or no cycle:
    /// no probe). A capture waiting on [`Trigger::Probe`] starts with its first tick.
    Probe {
        /// Half the step \[A\].
        amplitude_a: f32,
        /// Ticks at each level.
        half_ticks: u16,
        /// Cycles, up and down.
        cycles: u16,
    },
}

/// When a capture starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Trigger {
    /// At the next tick.
    Now,
    /// At the next change of the set point (a move).
    Move,
    /// At the first tick of the next inductance probe ([`Command::Probe`]).
    Probe,
}

/// A parameter's value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Value {
    /// A number, in the unit the name carries.
    Number(f32),
    /// Yes or no.
    Flag(bool),
    /// One of a parameter's named choices, by index
    /// ([`crate::device::params::Kind::Choice`]).
    Choice(u8),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Number(x) => write!(f, "{x}"),
            Value::Flag(b) => write!(f, "{b}"),
            Value::Choice(c) => write!(f, "choice {c}"),
        }
    }
}

/// What the board sends.
// Messages live on the stack while they are encoded, one at a time.
#[expect(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message<'a> {
    /// The answer to a request.
    Reply {
        /// The request's sequence number.
        seq: u16,
        /// The answer.
        #[serde(borrow)]
        reply: Reply<'a>,
    },
    /// A frame the board could not read (no sequence number can be trusted).
    Rejected(FrameError),
    /// Streamed values.
    Telemetry(Telemetry),
    /// Sent once after every start.
    #[serde(borrow)]
    Started(Started<'a>),
}

/// The answer to a request.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Reply<'a> {
    /// Done as asked.
    Done,
    /// The board's state.
    #[serde(borrow)]
    Status(Status<'a>),
    /// A parameter's value.
    Value(Value),
    /// The board restarts now to write its flash, with the bridge off.
    Saving,
    /// The board restarts now.
    Restarting,
    /// Part of a finished capture.
    Capture(Chunk),
    /// Not done, and why.
    #[serde(borrow)]
    Refused(Refusal<'a>),
    /// The last commissioning's outcome: none yet, still running (`None`), or its result.
    Commissioned(Commissioned),
}

/// A commissioning's outcome.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Commissioned {
    /// None since the start.
    Never,
    /// In progress.
    Running,
    /// Finished: the coil's resistance and the position sensor's end stops.
    Done(crate::device::commission::Report),
    /// Stopped without a result.
    Aborted(crate::device::commission::Abort),
}

/// Why a request was not carried out. Nothing changed on the board.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Refusal<'a> {
    /// Needs the board disarmed.
    Armed,
    /// Needs the board armed.
    NotArmed,
    /// Arming with a fault latched (its code): clear it first.
    Faulted {
        /// The latched fault's code.
        fault: u8,
    },
    /// Arming now would latch this fault at once: a sensor reads implausible, the bus is
    /// outside its window or the 4-20 mA loop is open.
    NotReady {
        /// The fault's code.
        fault: u8,
    },
    /// Clearing while the fault's cause is still there.
    CauseActive {
        /// The fault's code.
        fault: u8,
    },
    /// No parameter has this name.
    UnknownParam {
        /// The name asked for.
        name: &'a str,
    },
    /// This parameter cannot be changed over the link.
    ReadOnly {
        /// Its name.
        name: &'a str,
        /// Why.
        why: &'a str,
    },
    /// The value is of another kind than the parameter (a number for a flag...).
    WrongKind {
        /// The parameter.
        name: &'a str,
    },
    /// A value refused by validation: the field, its value and why, exactly as a build
    /// refuses an actuator file ([`crate::control::config::Error`]).
    Invalid(Invalid<'a>),
    /// The set point comes from the analog input (`setpoint.source`).
    AnalogSetpoint,
    /// A capture is running.
    CaptureRunning,
    /// No finished capture to read.
    NoCapture,
    /// The stored parameters could not be read.
    #[serde(borrow)]
    Load(LoadError<'a>),
}

/// A value refused by validation (the wire form of [`crate::control::config::Error`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Invalid<'a> {
    /// Dotted name of the field.
    pub param: &'a str,
    /// The refused value.
    pub value: f32,
    /// Why.
    #[serde(borrow)]
    pub reason: Reason<'a>,
}

/// Why a value was refused: [`crate::control::config::Reason`] with borrowed names.
pub type Reason<'a> = config::Reason<&'a str>;

impl From<config::Error> for Invalid<'static> {
    fn from(e: config::Error) -> Self {
        Invalid {
            param: e.param,
            value: e.value,
            reason: e.reason,
        }
    }
}

impl fmt::Display for Invalid<'_> {
    /// The same text as [`crate::control::config::Error`]'s.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} = {}: {}", self.param, self.value, self.reason)
    }
}

/// The board's operating state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub enum Mode {
    /// Bridge coasting, sensors read, nothing driven (the state after every start).
    #[default]
    Disarmed,
    /// Closed loop, holding the set point.
    Armed,
    /// Closed loop, a move in progress.
    Moving,
    /// A fault is latched: bridge coasting until it is cleared (which leaves the board
    /// disarmed).
    Fault,
    /// Commissioning: the loop open, the bridge driven by the identification.
    Commissioning,
}

impl Mode {
    /// Lower-case name.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Mode::Disarmed => "disarmed",
            Mode::Armed => "armed",
            Mode::Moving => "moving",
            Mode::Fault => "fault",
            Mode::Commissioning => "commissioning",
        }
    }

    /// Stable code (in samples).
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            Mode::Disarmed => 0,
            Mode::Armed => 1,
            Mode::Moving => 2,
            Mode::Fault => 3,
            Mode::Commissioning => 4,
        }
    }

    /// The mode with code `code`.
    #[must_use]
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Mode::Disarmed),
            1 => Some(Mode::Armed),
            2 => Some(Mode::Moving),
            3 => Some(Mode::Fault),
            4 => Some(Mode::Commissioning),
            _ => None,
        }
    }

    /// `true` in closed loop (armed or moving).
    #[must_use]
    pub const fn armed(self) -> bool {
        matches!(self, Mode::Armed | Mode::Moving)
    }
}

/// The board's state ([`Command::Status`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Status<'a> {
    /// Operating state.
    pub mode: Mode,
    /// Latched fault's code.
    pub fault: Option<u8>,
    /// The fault arming would be refused for now (sensor, bus, 4-20 mA loop), if any.
    pub not_ready: Option<u8>,
    /// How many times each fault latched since start (index = code - 1).
    pub fault_counts: [u16; FAULT_SLOTS],
    /// Position \[m\].
    pub x_m: f32,
    /// Coil current \[A\].
    pub i_a: f32,
    /// Bus voltage \[V\].
    pub vbus_v: f32,
    /// Set point \[m\].
    pub setpoint_m: f32,
    /// Analog set point, filtered and scaled to the stroke \[m\] (0 when not used).
    pub analog_m: f32,
    /// Ticks since start.
    pub ticks: u32,
    /// Mean cycles per tick over the last second (0 where not measured).
    pub isr_cycles_mean: u32,
    /// Most cycles of one tick since start.
    pub isr_cycles_max: u32,
    /// Ticks that overran (started or ended late).
    pub overruns: u32,
    /// Telemetry samples dropped because the link was busy.
    pub telemetry_dropped: u32,
    /// Frames received that were refused ([`Message::Rejected`]).
    pub frames_rejected: u32,
    /// Where the parameters in use came from.
    #[serde(borrow)]
    pub params: Source<'a>,
    /// Parameters changed since they were loaded or saved.
    pub unsaved: bool,
    /// Capture state.
    pub capture: CaptureState,
    /// Samples the board can capture.
    pub capture_capacity: u16,
    /// The firmware running.
    #[serde(borrow)]
    pub build: Build<'a>,
}

/// A firmware build: its version and the commit it was built from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Build<'a> {
    /// The `ema` package's version.
    pub version: &'a str,
    /// The commit (`git rev-parse --short=12 HEAD` at build time; `unknown` outside a
    /// repository).
    pub id: &'a str,
}

impl Build<'static> {
    /// This build of the `ema` package.
    pub const THIS: Build<'static> = Build {
        version: env!("CARGO_PKG_VERSION"),
        id: env!("EMA_BUILD_ID"),
    };
}

/// Where the parameters in use came from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub enum Source<'a> {
    /// The built-in defaults (the actuator the firmware was built for), and why.
    #[default]
    Defaults,
    /// The built-in defaults, because the stored set could not be used.
    #[serde(borrow)]
    Fallback(LoadError<'a>),
    /// The stored set.
    Stored,
}

/// Why a stored parameter set was not used.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum LoadError<'a> {
    /// Nothing stored.
    Empty,
    /// Stored by another format version.
    Version {
        /// Found.
        found: u16,
        /// This firmware's.
        expected: u16,
    },
    /// The set's own CRC does not match.
    Crc,
    /// The set does not decode.
    Decode,
    /// The set decodes but does not validate (field, value, reason: as on a build).
    #[serde(borrow)]
    Invalid(Invalid<'a>),
    /// The flash store failed.
    Store(StoreError),
}

/// A failure of the flash store.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum StoreError {
    /// The flash refused a read, write or erase.
    Flash,
    /// No room even after compaction.
    Full,
    /// The store found corruption it could not repair.
    Corrupted,
    /// The store's own consistency check failed.
    Internal,
    /// The set does not fit the store's buffer.
    TooBig,
}

/// Where a capture is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum CaptureState {
    /// None requested.
    #[default]
    Idle,
    /// Waiting for its trigger.
    Waiting,
    /// Recording: samples so far.
    Running(u16),
    /// Finished: samples recorded.
    Done(u16),
}

/// Sent once after every start.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Started<'a> {
    /// Where the parameters came from.
    #[serde(borrow)]
    pub params: Source<'a>,
    /// A save was requested before this start: its outcome.
    pub saved: Option<Result<(), StoreError>>,
    /// Samples the board can capture.
    pub capture_capacity: u16,
    /// Control rate \[Hz\].
    pub rate_hz: f32,
}

/// Signals a telemetry stream can carry; the code is the bit in [`Command::Stream`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// Reference the law follows \[m\].
    Reference = 0,
    /// Measured position \[m\].
    Position = 1,
    /// Velocity estimate \[m/s\].
    Velocity = 2,
    /// Measured coil current \[A\].
    Current = 3,
    /// Average coil voltage applied \[V\].
    Voltage = 4,
    /// PWM duty, fraction of the period (negative in reverse) \[-\].
    Duty = 5,
    /// Measured bus voltage \[V\].
    Bus = 6,
    /// Analog set point, filtered \[m\].
    Analog = 7,
}

impl Signal {
    /// Every signal, in code order.
    pub const ALL: [Signal; 8] = [
        Signal::Reference,
        Signal::Position,
        Signal::Velocity,
        Signal::Current,
        Signal::Voltage,
        Signal::Duty,
        Signal::Bus,
        Signal::Analog,
    ];

    /// Name, as the host tool shows it.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Signal::Reference => "reference_m",
            Signal::Position => "x_m",
            Signal::Velocity => "v_mps",
            Signal::Current => "i_a",
            Signal::Voltage => "u_v",
            Signal::Duty => "duty",
            Signal::Bus => "vbus_v",
            Signal::Analog => "analog_m",
        }
    }

    /// Bit in a signal mask.
    #[must_use]
    pub const fn bit(self) -> u16 {
        1 << (self as u16)
    }

    /// The signal's value in a sample.
    #[must_use]
    pub fn of(self, s: &Sample) -> f32 {
        match self {
            Signal::Reference => s.r_m,
            Signal::Position => s.x_m,
            Signal::Velocity => s.v_mps,
            Signal::Current => s.i_a,
            Signal::Voltage => s.u_v,
            Signal::Duty => s.duty,
            Signal::Bus => s.vbus_v,
            Signal::Analog => s.analog_m,
        }
    }
}

/// Streamed values: the selected signals, in code order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Telemetry {
    /// Tick of the sample.
    pub tick: u32,
    /// Operating state's code ([`Mode::code`]).
    pub mode: u8,
    /// Latched fault's code (0: none).
    pub fault: u8,
    /// The selected signals' values.
    pub values: heapless::Vec<f32, MAX_SIGNALS>,
}

/// One tick as telemetry and captures record it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Reference the law followed \[m\].
    pub r_m: f32,
    /// Measured position \[m\].
    pub x_m: f32,
    /// Velocity estimate \[m/s\].
    pub v_mps: f32,
    /// Measured coil current \[A\].
    pub i_a: f32,
    /// Average coil voltage applied \[V\].
    pub u_v: f32,
    /// PWM duty, fraction of the period, negative in reverse \[-\].
    pub duty: f32,
    /// Measured bus voltage \[V\].
    pub vbus_v: f32,
    /// Analog set point, filtered \[m\].
    pub analog_m: f32,
    /// Latched fault's code (0: none).
    pub fault: u8,
    /// Operating state's code.
    pub mode: u8,
}

/// Part of a finished capture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Chunk {
    /// Index of the first sample.
    pub offset: u16,
    /// Samples in the capture.
    pub total: u16,
    /// Ticks per sample.
    pub decimation: u16,
    /// Ticks the board had been armed when the capture started (0: disarmed).
    pub armed_ticks: u32,
    /// Set point before the trigger \[m\].
    pub from_m: f32,
    /// Set point after the trigger \[m\].
    pub to_m: f32,
    /// Duration of the planned move \[s\] (0: a step, or no move).
    pub move_s: f32,
    /// The samples.
    pub samples: heapless::Vec<Sample, CHUNK_SAMPLES>,
}

/// Why a frame could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum FrameError {
    /// Longer than [`MAX_FRAME`].
    TooLong,
    /// Not valid COBS.
    Cobs,
    /// Shorter than a version byte and a CRC.
    Short,
    /// The CRC does not match: the bytes changed on the way.
    Crc,
    /// Another version of the definitions.
    Version {
        /// The frame's.
        found: u8,
        /// This side's ([`VERSION`]).
        expected: u8,
    },
    /// The message ends early.
    Truncated,
    /// A message or value of a kind that does not exist (unknown variant, bad flag, bad
    /// text).
    Malformed,
    /// Bytes left after the message.
    Trailing,
    /// The message does not fit a frame (sending side).
    Overflow,
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::TooLong => write!(f, "frame longer than {MAX_FRAME} bytes"),
            FrameError::Cobs => write!(f, "frame is not valid COBS"),
            FrameError::Short => write!(f, "frame shorter than a version byte and a CRC"),
            FrameError::Crc => write!(f, "CRC mismatch: the frame changed on the way"),
            FrameError::Version { found, expected } => {
                write!(f, "protocol version {found}, expected {expected}")
            }
            FrameError::Truncated => write!(f, "message ends early"),
            FrameError::Malformed => write!(f, "message of an unknown kind or with a bad value"),
            FrameError::Trailing => write!(f, "bytes left after the message"),
            FrameError::Overflow => write!(f, "message does not fit a frame"),
        }
    }
}

impl core::error::Error for FrameError {}

/// Encodes `message` as one frame, delimiter included, into `out`; returns its length.
///
/// # Errors
/// [`FrameError::Overflow`] when the message does not fit.
pub fn encode<T: Serialize>(message: &T, out: &mut [u8; MAX_FRAME]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_RAW];
    let (first, rest) = raw.split_at_mut(1);
    if let Some(v) = first.first_mut() {
        *v = VERSION;
    }
    let body = postcard::to_slice(message, rest)
        .map_err(|_| FrameError::Overflow)?
        .len();
    let len = body.checked_add(1).ok_or(FrameError::Overflow)?;
    let with_crc = len.checked_add(CRC_LEN).ok_or(FrameError::Overflow)?;
    let (covered, tail) = raw.split_at_mut(len);
    let crc = CRC.checksum(covered).to_le_bytes();
    tail.get_mut(..CRC_LEN)
        .ok_or(FrameError::Overflow)?
        .copy_from_slice(&crc);
    let framed = raw.get(..with_crc).ok_or(FrameError::Overflow)?;
    let n = cobs::try_encode(framed, out).map_err(|_| FrameError::Overflow)?;
    let delimiter = out.get_mut(n).ok_or(FrameError::Overflow)?;
    *delimiter = 0;
    n.checked_add(1).ok_or(FrameError::Overflow)
}

/// Decodes one frame (its bytes without the delimiter, decoded in place).
///
/// # Errors
/// What is wrong with the frame, by name.
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a mut [u8]) -> Result<T, FrameError> {
    let n = cobs::decode_in_place(frame).map_err(|_| FrameError::Cobs)?;
    let raw: &'a [u8] = frame.get(..n).ok_or(FrameError::Cobs)?;
    let body_len = n
        .checked_sub(CRC_LEN)
        .filter(|&b| b >= 1)
        .ok_or(FrameError::Short)?;
    let (covered, crc) = raw.split_at(body_len);
    let mut got = [0u8; CRC_LEN];
    got.copy_from_slice(crc);
    if CRC.checksum(covered) != u32::from_le_bytes(got) {
        return Err(FrameError::Crc);
    }
    let (version, body) = covered.split_first().ok_or(FrameError::Short)?;
    if *version != VERSION {
        return Err(FrameError::Version {
            found: *version,
            expected: VERSION,
        });
    }
    let (message, rest) = postcard::take_from_bytes::<T>(body).map_err(|e| match e {
        postcard::Error::DeserializeUnexpectedEnd => FrameError::Truncated,
        _ => FrameError::Malformed,
    })?;
    if rest.is_empty() {
        Ok(message)
    } else {
        Err(FrameError::Trailing)
    }
}

/// Collects received bytes into frames: a frame ends at a zero byte.
#[derive(Clone, Debug, Default)]
pub struct Framer {
    buf: heapless::Vec<u8, MAX_FRAME>,
    overflow: bool,
}

impl Framer {
    /// Empty.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            buf: heapless::Vec::new(),
            overflow: false,
        }
    }

    /// Takes one byte. At a delimiter returns the frame's bytes (for [`decode`]), or
    /// [`FrameError::TooLong`] for a frame that did not fit; empty frames (two zeros in a
    /// row) are skipped.
    pub fn push(&mut self, byte: u8) -> Option<Result<&mut [u8], FrameError>> {
        if byte != 0 {
            if self.buf.push(byte).is_err() {
                self.overflow = true;
            }
            return None;
        }
        if self.overflow {
            self.overflow = false;
            self.buf.clear();
            return Some(Err(FrameError::TooLong));
        }
        if self.buf.is_empty() {
            return None;
        }
        let frame: &mut [u8] = &mut self.buf;
        Some(Ok(frame))
    }

    /// Forgets the frame returned by the last [`Framer::push`]; call before the next byte.
    pub fn clear(&mut self) {
        self.buf.clear();
    }

    /// Bytes of a frame in progress.
    #[must_use]
    pub fn pending(&self) -> usize {
        self.buf.len()
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    fn roundtrip<'a, T: Serialize + Deserialize<'a> + PartialEq + fmt::Debug>(
        m: &T,
        buf: &'a mut [u8; MAX_FRAME],
    ) -> T {
        let n = encode(m, buf).unwrap();
        assert_eq!(buf[n - 1], 0);
        decode::<T>(&mut buf[..n - 1]).unwrap()
    }

    #[test]
    fn every_command_round_trips() {
        let commands = [
            Command::Status,
            Command::Arm,
            Command::Disarm,
            Command::Move {
                position_m: 3e-3,
                time_s: Some(0.25),
            },
            Command::Move {
                position_m: -0.0,
                time_s: None,
            },
            Command::Clear,
            Command::Get {
                name: "coil.rated_current_a",
            },
            Command::Set {
                name: "board.supply_v",
                value: Value::Number(12.0),
            },
            Command::Save,
            Command::Load,
            Command::Defaults,
            Command::Restart,
            Command::Stream {
                signals: 0b1010,
                decimation: 20,
            },
            Command::Capture {
                samples: 256,
                decimation: 20,
                trigger: Trigger::Move,
            },
            Command::ReadCapture { offset: 12 },
        ];
        for command in commands {
            let mut buf = [0; MAX_FRAME];
            let r = Request { seq: 513, command };
            assert_eq!(roundtrip(&r, &mut buf), r);
        }
    }

    #[test]
    fn the_largest_replies_fit_a_frame() {
        let mut samples = heapless::Vec::new();
        for _ in 0..CHUNK_SAMPLES {
            samples
                .push(Sample {
                    r_m: f32::MAX,
                    x_m: -f32::MAX,
                    v_mps: f32::NAN,
                    i_a: 1.0,
                    u_v: 2.0,
                    duty: -1.0,
                    vbus_v: 24.0,
                    analog_m: 0.0,
                    fault: 255,
                    mode: 3,
                })
                .unwrap();
        }
        let chunk = Message::Reply {
            seq: u16::MAX,
            reply: Reply::Capture(Chunk {
                offset: u16::MAX,
                total: u16::MAX,
                decimation: u16::MAX,
                armed_ticks: u32::MAX,
                from_m: 1.0,
                to_m: 2.0,
                move_s: 3.0,
                samples,
            }),
        };
        let status = Message::Reply {
            seq: u16::MAX,
            reply: Reply::Status(Status {
                fault: Some(255),
                not_ready: Some(255),
                fault_counts: [u16::MAX; FAULT_SLOTS],
                ticks: u32::MAX,
                isr_cycles_mean: u32::MAX,
                isr_cycles_max: u32::MAX,
                overruns: u32::MAX,
                telemetry_dropped: u32::MAX,
                frames_rejected: u32::MAX,
                params: Source::Fallback(LoadError::Invalid(Invalid {
                    param: "magnetics.geometry.iron_reluctance_per_h",
                    value: 1.0,
                    reason: Reason::NotBelow {
                        other: "magnetics.inductance.closed_h",
                        limit: 2.0,
                    },
                })),
                capture: CaptureState::Running(u16::MAX),
                capture_capacity: u16::MAX,
                ..Status::default()
            }),
        };
        let invalid = Message::Reply {
            seq: u16::MAX,
            reply: Reply::Refused(Refusal::Invalid(Invalid {
                param: "magnetics.geometry.iron_reluctance_per_h",
                value: 1.0,
                reason: Reason::Derived {
                    what: "the magnet's pull at the current limit less the spring, at the open \
                           stop on the weakest plant the surfaces allow [N]",
                    derived: 1.0,
                },
            })),
        };
        for m in [chunk, status, invalid] {
            let mut buf = [0; MAX_FRAME];
            let n = encode(&m, &mut buf).unwrap();
            assert!(n <= MAX_FRAME, "{n}");
            let back = decode::<Message>(&mut buf[..n - 1]).unwrap();
            assert_eq!(std::format!("{back:?}"), std::format!("{m:?}"));
        }
    }

    #[test]
    fn bad_frames_are_refused_by_name() {
        let mut buf = [0; MAX_FRAME];
        let n = encode(
            &Request {
                seq: 1,
                command: Command::Disarm,
            },
            &mut buf,
        )
        .unwrap();
        // Every single-bit flip of the COBS bytes is caught: by COBS, the CRC or the length.
        for byte in 0..n - 1 {
            for bit in 0..8 {
                let mut b = buf;
                b[byte] ^= 1 << bit;
                if b[byte] == 0 {
                    continue; // a new delimiter: two frames, each refused on its own
                }
                assert!(decode::<Request>(&mut b[..n - 1]).is_err(), "{byte}.{bit}");
            }
        }
        // Another version, with a correct CRC.
        let mut raw = [VERSION + 1, 1, 2, 0, 0, 0, 0];
        let crc = CRC.checksum(&raw[..3]).to_le_bytes();
        raw[3..].copy_from_slice(&crc);
        let mut frame = [0u8; 16];
        let k = cobs::encode(&raw, &mut frame);
        assert_eq!(
            decode::<Request>(&mut frame[..k]),
            Err(FrameError::Version {
                found: VERSION + 1,
                expected: VERSION
            })
        );
        // Correct CRC and version, an unknown command (variant 200).
        let mut raw = [VERSION, 1, 200, 1, 0, 0, 0, 0];
        let crc = CRC.checksum(&raw[..4]).to_le_bytes();
        raw[4..].copy_from_slice(&crc);
        let k = cobs::encode(&raw, &mut frame);
        assert_eq!(
            decode::<Request>(&mut frame[..k]),
            Err(FrameError::Malformed)
        );
        // A message cut short, with its CRC recomputed.
        let mut raw = [VERSION, 1, 0, 0, 0, 0];
        let crc = CRC.checksum(&raw[..2]).to_le_bytes();
        raw[2..].copy_from_slice(&crc);
        let k = cobs::encode(&raw, &mut frame);
        assert_eq!(
            decode::<Request>(&mut frame[..k]),
            Err(FrameError::Truncated)
        );
        // Too short for a CRC.
        let mut short = [1u8, 2, 3];
        let k = cobs::encode(&[5u8, 6], &mut short);
        assert_eq!(decode::<Request>(&mut short[..k]), Err(FrameError::Short));
        assert_eq!(
            FrameError::Crc.to_string(),
            "CRC mismatch: the frame changed on the way"
        );
    }

    #[test]
    fn the_framer_resynchronises_after_garbage_and_long_frames() {
        let mut buf = [0; MAX_FRAME];
        let n = encode(
            &Request {
                seq: 9,
                command: Command::Status,
            },
            &mut buf,
        )
        .unwrap();
        let mut stream = std::vec::Vec::new();
        stream.extend_from_slice(&[7u8; 300]); // garbage longer than a frame
        stream.push(0);
        stream.extend_from_slice(&buf[..n]);
        let mut f = Framer::new();
        let mut results = std::vec::Vec::new();
        for &b in &stream {
            let got = f
                .push(b)
                .map(|r| r.and_then(|raw| decode::<Request>(raw).map(|q| q.seq)));
            if let Some(r) = got {
                results.push(r);
                f.clear();
            }
        }
        assert_eq!(results, [Err(FrameError::TooLong), Ok(9)]);
    }

    #[test]
    fn refusals_read_as_the_build_writes_them() {
        use crate::control::config::{Error, Reason as R};
        let cases = [
            R::NotFinite,
            R::NotPositive,
            R::BelowMin { min: 1.5 },
            R::AboveMax { max: 2.5 },
            R::NotBelow {
                other: "b",
                limit: 3.0,
            },
            R::NotAbove {
                other: "c",
                limit: 4.0,
            },
            R::Theorem1 {
                a: 1.0,
                b: 2.0,
                det_q: -3.0,
                alpha2_min: 4.0,
            },
            R::Derived {
                what: "w",
                derived: 5.0,
            },
        ];
        for reason in cases {
            let e = Error {
                param: "board.supply_v",
                value: 12.0,
                reason,
            };
            assert_eq!(Invalid::from(e).to_string(), e.to_string());
        }
    }

    #[test]
    fn modes_and_signals_have_stable_codes() {
        for code in 0..5 {
            assert_eq!(Mode::from_code(code).unwrap().code(), code);
        }
        assert_eq!(Mode::from_code(4), Some(Mode::Commissioning));
        assert_eq!(Mode::from_code(5), None);
        for (k, s) in Signal::ALL.iter().enumerate() {
            assert_eq!(s.bit(), 1 << k);
        }
    }
}
