//! Golden traces: ticks recorded on one machine, replayed bit for bit on another.
//!
//! A trace is the evidence that the Cortex-M4F computes exactly what the host computed: a
//! generator (host) runs [`Config::tick`] and records, per tick, the converter codes and
//! the set point that went in and the outputs that came out, as IEEE bit patterns. A
//! checker (the QEMU test `tests/qemu_golden.rs`, and the host test `tests/golden_host.rs`)
//! rebuilds the same configuration, replays the inputs through the tick and compares every
//! output bit ([`replay`]).
//!
//! # Format, version 1 (all integers little-endian)
//!
//! Header, [`HEADER_LEN`] = 64 bytes:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"EMAT"` |
//! | 4 | 2 | format version ([`VERSION`]) |
//! | 6 | 2 | header length in bytes (64) |
//! | 8 | 2 | record length in bytes ([`RECORD_LEN`] = 27) |
//! | 10 | 2 | `max_duty` of the PWM the bridge drove (the duty codes depend on it) |
//! | 12 | 4 | number of ticks (records) |
//! | 16 | 8 | settings identity: [`settings_hash`] of the [`Settings`] the trace was made with |
//! | 24 | 20 | case name, UTF-8, NUL-padded: which entry of [`CASES`] rebuilds the settings |
//! | 44 | 20 | law name ([`crate::control::law::Config::name`]), UTF-8, NUL-padded |
//!
//! Then one record of [`RECORD_LEN`] = 27 bytes per tick:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 2 | input: position code ([`Frame::position`]) |
//! | 2 | 2 | input: coil-current code |
//! | 4 | 2 | input: bus-voltage code |
//! | 6 | 4 | input: set point \[m\], `f32` bits |
//! | 10 | 1 | input: flags; bit 0: [`Config::rearm`] before this tick; other bits 0 |
//! | 11 | 4 | output: law command `u` \[V\] before saturation ([`crate::control::law::Output::u_v`]), `f32` bits |
//! | 15 | 4 | output: voltage applied by the bridge \[V\] ([`crate::control::bridge::Drive::u_v`]), `f32` bits |
//! | 19 | 4 | output: desired current \[A\] ([`crate::control::law::Output::i_d_a`]), `f32` bits |
//! | 23 | 2 | output: PWM duty code |
//! | 25 | 1 | output: bridge mode ([`crate::control::bridge::Mode::code`]: 0 coast, 1 forward, 2 reverse) |
//! | 26 | 1 | output: latched fault code ([`Fault::code`]), 0 for none |
//!
//! Every `NaN` is stored as [`CANONICAL_NAN`]: NaN payloads legitimately differ between
//! x86-64 and the Cortex-M4F (IEEE 754 leaves them open), every finite and infinite value
//! must not.
//! 10 000 ticks take 270 kB: three traces fit in the 1 MiB flash of the emulated
//! STM32F405 next to the test program.
//!
//! # Replay semantics
//!
//! The tick starts from [`Config::initial_state`] and a bridge fresh from
//! [`HBridge::new`] (coasting) whose PWM reports the header's `max_duty`; the records are
//! applied in order with [`Config::tick`], preceded by [`Config::rearm`] where the record's
//! flag says so (a generator re-arms after a latched fault to keep the tick running its
//! whole path); nothing else happens between ticks.
//!
//! # Writing a trace (the generator's side)
//!
//! For each tick call [`tick_record`] instead of [`Config::tick`]: it re-arms first if
//! asked, runs the tick and returns the [`Record`] to append ([`Record::encode`]). Write
//! [`Header::encode`] first.

use core::fmt;

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

use crate::control::bridge::HBridge;
use crate::control::sense::Frame;
use crate::control::supervisor::Fault;
use crate::control::{Config, Settings, State, Status};

/// First four bytes of every trace.
pub const MAGIC: [u8; 4] = *b"EMAT";
/// Format version this module reads and writes.
pub const VERSION: u16 = 1;
/// Header length \[bytes\].
pub const HEADER_LEN: usize = 64;
/// Record length \[bytes\].
pub const RECORD_LEN: usize = 27;
/// Length of the case and law name fields \[bytes\].
pub const NAME_LEN: usize = 20;
/// The one `NaN` bit pattern a trace stores.
pub const CANONICAL_NAN: u32 = 0x7fc0_0000;
/// Fewest ticks a golden trace must hold.
pub const MIN_GOLDEN_TICKS: u32 = 10_000;

/// A reference configuration: what golden traces and instruction counts are recorded for.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    /// Short stable name (at most [`NAME_LEN`] bytes): the trace file is
    /// `tests/golden/<name>.emat`.
    pub name: &'static str,
    /// Builds the settings.
    pub settings: fn() -> Result<Settings, crate::control::config::Error>,
}

/// The paper's law on the paper's actuator at 20 kHz from a 24 V bus.
#[cfg(feature = "paper")]
fn paper_20khz_24v() -> Result<Settings, crate::control::config::Error> {
    Ok(Settings::paper(20_000.0, 24.0))
}

/// The paper's law with its boundary layer, one sample of measurement delay, otherwise as
/// [`paper_20khz_24v`].
#[cfg(feature = "paper")]
fn boundary_layer_20khz_24v() -> Result<Settings, crate::control::config::Error> {
    Ok(Settings {
        law: crate::control::law::Settings::BoundaryLayer(
            crate::control::law::paper::Gains::paper(),
        ),
        delay_ticks: 1,
        ..Settings::paper(20_000.0, 24.0)
    })
}

/// The product's default (the practical discrete-time law, the physical convention) at
/// 20 kHz from a 24 V bus.
fn practical_20khz_24v() -> Result<Settings, crate::control::config::Error> {
    Settings::practical(20_000.0, 24.0)
}

/// The reference configurations, one per law of [`crate::control::law::NAMES`], in its
/// order. Golden traces, the bit-exactness checks and the per-law instruction counts on the
/// Cortex-M4F all iterate over this list; a new law gets its entry here.
pub const CASES: &[Case] = &[
    #[cfg(feature = "paper")]
    Case {
        name: crate::control::law::NAMES[0],
        settings: paper_20khz_24v,
    },
    #[cfg(feature = "paper")]
    Case {
        name: crate::control::law::NAMES[1],
        settings: boundary_layer_20khz_24v,
    },
    Case {
        name: crate::control::law::NAMES[2],
        settings: practical_20khz_24v,
    },
];

/// The case called `name`.
#[must_use]
pub fn case(name: &str) -> Option<&'static Case> {
    CASES.iter().find(|c| c.name == name)
}

/// Settings identity: 64-bit FNV-1a of the `Debug` rendering of `settings`. Every field
/// (gains, plant, limits, law variant) takes part, and `core` renders every `f32`
/// exactly (shortest round-trip form) the same way on every target, so the host and the
/// Cortex-M4F agree. A change of the settings, or of their types, changes the identity
/// and makes saved traces stale, which is what it is for.
#[must_use]
pub fn settings_hash(settings: &Settings) -> u64 {
    let mut h = Fnv1a(FNV_OFFSET);
    // `Fnv1a::write_str` never fails.
    let _ = fmt::write(&mut h, format_args!("{settings:?}"));
    h.0
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

struct Fnv1a(u64);

impl fmt::Write for Fnv1a {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for b in s.bytes() {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(FNV_PRIME);
        }
        Ok(())
    }
}

/// A fixed-size, NUL-padded UTF-8 name.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Name([u8; NAME_LEN]);

impl Name {
    /// `s` truncated to [`NAME_LEN`] bytes (at a character boundary) and NUL-padded.
    #[must_use]
    pub fn new(s: &str) -> Self {
        let mut out = [0u8; NAME_LEN];
        let mut end = s.len().min(NAME_LEN);
        while !s.is_char_boundary(end) {
            end = end.saturating_sub(1);
        }
        for (dst, src) in out.iter_mut().zip(s.bytes().take(end)) {
            *dst = src;
        }
        Self(out)
    }

    /// The name without its padding (empty if it is not UTF-8).
    #[must_use]
    pub fn as_str(&self) -> &str {
        let len = self.0.iter().position(|&b| b == 0).unwrap_or(NAME_LEN);
        core::str::from_utf8(self.0.get(..len).unwrap_or(&[])).unwrap_or("")
    }
}

impl fmt::Debug for Name {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

/// The trace header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// `max_duty` of the PWM the bridge drove.
    pub max_duty: u16,
    /// Number of records.
    pub ticks: u32,
    /// [`settings_hash`] of the settings.
    pub settings_hash: u64,
    /// The case ([`CASES`]) that rebuilds the settings.
    pub case: Name,
    /// The law's name.
    pub law: Name,
}

impl Header {
    /// The header for `ticks` records of `case`, whose `settings` were built into `cfg`,
    /// with a PWM of `max_duty`.
    #[must_use]
    pub fn new(case: &Case, settings: &Settings, cfg: &Config, max_duty: u16, ticks: u32) -> Self {
        Self {
            max_duty,
            ticks,
            settings_hash: settings_hash(settings),
            case: Name::new(case.name),
            law: Name::new(cfg.law().name()),
        }
    }

    /// The 64 header bytes.
    #[must_use]
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut w = Put::<HEADER_LEN>::new();
        w.put(&MAGIC);
        w.put(&VERSION.to_le_bytes());
        w.put(&len_u16(HEADER_LEN).to_le_bytes());
        w.put(&len_u16(RECORD_LEN).to_le_bytes());
        w.put(&self.max_duty.to_le_bytes());
        w.put(&self.ticks.to_le_bytes());
        w.put(&self.settings_hash.to_le_bytes());
        w.put(&self.case.0);
        w.put(&self.law.0);
        w.finish()
    }
}

/// Inputs of one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Input {
    /// Converter codes.
    pub frame: Frame,
    /// Set point \[m\].
    pub setpoint_m: f32,
    /// [`Config::rearm`] before the tick.
    pub rearm: bool,
}

/// Flag bit of [`Input::rearm`].
const FLAG_REARM: u8 = 1;

/// Outputs of one tick, as bit patterns (so that `==` is bit-exact).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Output {
    /// Law command before saturation, `f32` bits.
    pub u_cmd: u32,
    /// Voltage the bridge applies, `f32` bits.
    pub u_applied: u32,
    /// Desired current, `f32` bits.
    pub i_d: u32,
    /// PWM duty code.
    pub duty: u16,
    /// Bridge mode ([`crate::control::bridge::Mode::code`]).
    pub mode: u8,
    /// Latched fault code, 0 for none.
    pub fault: u8,
}

/// `f32` bits with every `NaN` made [`CANONICAL_NAN`].
#[must_use]
pub fn bits(x: f32) -> u32 {
    if x.is_nan() {
        CANONICAL_NAN
    } else {
        x.to_bits()
    }
}

impl Output {
    /// The outputs of a tick.
    #[must_use]
    pub fn of(status: &Status) -> Self {
        Self {
            u_cmd: bits(status.output.u_v),
            u_applied: bits(status.drive.u_v),
            i_d: bits(status.output.i_d_a),
            duty: status.drive.duty,
            mode: status.drive.mode.code(),
            fault: status.fault.map_or(0, Fault::code),
        }
    }

    /// The first field that differs from `actual`: `(name, expected, actual)`.
    #[must_use]
    pub fn first_difference(&self, actual: &Output) -> Option<(&'static str, u32, u32)> {
        let fields = [
            ("u_cmd", self.u_cmd, actual.u_cmd),
            ("u_applied", self.u_applied, actual.u_applied),
            ("i_d", self.i_d, actual.i_d),
            ("duty", self.duty.into(), actual.duty.into()),
            ("mode", self.mode.into(), actual.mode.into()),
            ("fault", self.fault.into(), actual.fault.into()),
        ];
        fields.into_iter().find(|(_, e, a)| e != a)
    }
}

/// One tick: inputs and outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    /// What went in.
    pub input: Input,
    /// What came out.
    pub output: Output,
}

impl Record {
    /// The record's bytes.
    #[must_use]
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        let mut w = Put::<RECORD_LEN>::new();
        w.put(&self.input.frame.position.to_le_bytes());
        w.put(&self.input.frame.current.to_le_bytes());
        w.put(&self.input.frame.vbus.to_le_bytes());
        w.put(&bits(self.input.setpoint_m).to_le_bytes());
        w.put(&[if self.input.rearm { FLAG_REARM } else { 0 }]);
        w.put(&self.output.u_cmd.to_le_bytes());
        w.put(&self.output.u_applied.to_le_bytes());
        w.put(&self.output.i_d.to_le_bytes());
        w.put(&self.output.duty.to_le_bytes());
        w.put(&[self.output.mode, self.output.fault]);
        w.finish()
    }

    /// The record in `bytes`.
    #[must_use]
    pub fn decode(bytes: &[u8; RECORD_LEN]) -> Self {
        let mut r = Take(bytes);
        let frame = Frame {
            position: u16::from_le_bytes(r.take()),
            current: u16::from_le_bytes(r.take()),
            vbus: u16::from_le_bytes(r.take()),
        };
        let setpoint_m = f32::from_bits(u32::from_le_bytes(r.take()));
        let rearm = u8::from_le_bytes(r.take()) & FLAG_REARM != 0;
        let output = Output {
            u_cmd: u32::from_le_bytes(r.take()),
            u_applied: u32::from_le_bytes(r.take()),
            i_d: u32::from_le_bytes(r.take()),
            duty: u16::from_le_bytes(r.take()),
            mode: u8::from_le_bytes(r.take()),
            fault: u8::from_le_bytes(r.take()),
        };
        Self {
            input: Input {
                frame,
                setpoint_m,
                rearm,
            },
            output,
        }
    }
}

/// One tick as the golden generator records it: [`Config::rearm`] first when `rearm`,
/// then [`Config::tick`] on `frame` and `setpoint_m`; returns the tick's status and the
/// record of what went in and came out.
pub fn tick_record<P: SetDutyCycle, O: OutputPin>(
    cfg: &Config,
    state: &mut State,
    bridge: &mut HBridge<P, O>,
    frame: &Frame,
    setpoint_m: f32,
    rearm: bool,
) -> (Status, Record) {
    if rearm {
        cfg.rearm(state);
    }
    let status = cfg.tick(state, bridge, frame, setpoint_m);
    let record = Record {
        input: Input {
            frame: *frame,
            setpoint_m,
            rearm,
        },
        output: Output::of(&status),
    };
    (status, record)
}

/// Why bytes are not a trace this module can read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormatError {
    /// Shorter than a header.
    Truncated,
    /// The magic is not `EMAT`.
    Magic,
    /// A format version this module does not read.
    Version(u16),
    /// Header or record length other than this version's.
    Layout,
    /// The byte count does not match the number of ticks in the header.
    Length,
}

/// A parsed trace (borrows the bytes; nothing is copied).
#[derive(Clone, Copy, Debug)]
pub struct Trace<'a> {
    header: Header,
    records: &'a [u8],
}

impl<'a> Trace<'a> {
    /// Checks the header and the length.
    ///
    /// # Errors
    /// [`FormatError`] naming what is wrong.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, FormatError> {
        let (head, records) = bytes
            .split_first_chunk::<HEADER_LEN>()
            .ok_or(FormatError::Truncated)?;
        let mut r = Take(head);
        if r.take::<4>() != MAGIC {
            return Err(FormatError::Magic);
        }
        let version = u16::from_le_bytes(r.take());
        if version != VERSION {
            return Err(FormatError::Version(version));
        }
        let header_len = u16::from_le_bytes(r.take());
        let record_len = u16::from_le_bytes(r.take());
        if usize::from(header_len) != HEADER_LEN || usize::from(record_len) != RECORD_LEN {
            return Err(FormatError::Layout);
        }
        let header = Header {
            max_duty: u16::from_le_bytes(r.take()),
            ticks: u32::from_le_bytes(r.take()),
            settings_hash: u64::from_le_bytes(r.take()),
            case: Name(r.take()),
            law: Name(r.take()),
        };
        let expected = usize::try_from(header.ticks)
            .ok()
            .and_then(|t| t.checked_mul(RECORD_LEN));
        if expected != Some(records.len()) {
            return Err(FormatError::Length);
        }
        Ok(Self { header, records })
    }

    /// The header.
    #[must_use]
    pub const fn header(&self) -> &Header {
        &self.header
    }

    /// The records, in tick order.
    pub fn records(&self) -> impl Iterator<Item = Record> + 'a {
        self.records
            .chunks_exact(RECORD_LEN)
            .filter_map(|c| <&[u8; RECORD_LEN]>::try_from(c).ok())
            .map(Record::decode)
    }
}

/// Why a trace cannot be replayed against the current core.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OpenError {
    /// Not a readable trace.
    Format(FormatError),
    /// The case named in the header is not in [`CASES`].
    UnknownCase,
    /// The case's settings have changed since the trace was made (the trace is stale).
    Settings {
        /// Identity in the trace.
        trace: u64,
        /// Identity of the case's settings now.
        current: u64,
    },
    /// The case's settings no longer build.
    Build(crate::control::config::Error),
    /// The law's name differs from the one in the trace.
    Law,
}

/// Parses `bytes`, finds its case, checks that the case's settings are the ones the trace
/// was made with, and builds them.
///
/// # Errors
/// [`OpenError`] saying why the trace does not belong to the current core.
pub fn open(bytes: &[u8]) -> Result<(Trace<'_>, &'static Case, Config), OpenError> {
    let trace = Trace::parse(bytes).map_err(OpenError::Format)?;
    let case = case(trace.header.case.as_str()).ok_or(OpenError::UnknownCase)?;
    let settings = (case.settings)().map_err(OpenError::Build)?;
    let current = settings_hash(&settings);
    if current != trace.header.settings_hash {
        return Err(OpenError::Settings {
            trace: trace.header.settings_hash,
            current,
        });
    }
    let cfg = settings.build().map_err(OpenError::Build)?;
    if cfg.law().name() != trace.header.law.as_str() {
        return Err(OpenError::Law);
    }
    Ok((trace, case, cfg))
}

/// The first output that differs from the trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mismatch {
    /// Tick index (0-based).
    pub tick: u32,
    /// Which output.
    pub field: &'static str,
    /// Bits in the trace.
    pub expected: u32,
    /// Bits computed now.
    pub actual: u32,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "tick {}: {} expected {:#010x}, got {:#010x}",
            self.tick, self.field, self.expected, self.actual
        )
    }
}

/// Replays `trace` through [`Config::tick`] of `cfg` on `bridge` (fresh, coasting, with
/// the header's `max_duty`) and compares every output bit.
///
/// # Errors
/// The first [`Mismatch`].
pub fn replay<P: SetDutyCycle, O: OutputPin>(
    trace: &Trace<'_>,
    cfg: &Config,
    bridge: &mut HBridge<P, O>,
) -> Result<u32, Mismatch> {
    let mut state = cfg.initial_state();
    let mut ticks = 0u32;
    for rec in trace.records() {
        let (_, now) = tick_record(
            cfg,
            &mut state,
            bridge,
            &rec.input.frame,
            rec.input.setpoint_m,
            rec.input.rearm,
        );
        if let Some((field, expected, actual)) = rec.output.first_difference(&now.output) {
            return Err(Mismatch {
                tick: ticks,
                field,
                expected,
                actual,
            });
        }
        ticks = ticks.saturating_add(1);
    }
    Ok(ticks)
}

/// Little-endian reader over a fixed array; reads past the end give zeros (the lengths are
/// checked before reading, so this never happens).
struct Take<'a>(&'a [u8]);

impl Take<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        match self.0.split_first_chunk::<N>() {
            Some((head, rest)) => {
                self.0 = rest;
                *head
            }
            None => [0; N],
        }
    }
}

/// Little-endian writer into a fixed array; writes past the end are dropped (the layouts
/// above fill the arrays exactly; the unit tests check it).
struct Put<const N: usize> {
    buf: [u8; N],
    at: usize,
}

impl<const N: usize> Put<N> {
    const fn new() -> Self {
        Self { buf: [0; N], at: 0 }
    }

    fn put(&mut self, bytes: &[u8]) {
        if let Some(dst) = self.buf.get_mut(self.at..) {
            for (d, s) in dst.iter_mut().zip(bytes) {
                *d = *s;
            }
        }
        self.at = self.at.saturating_add(bytes.len());
    }

    fn finish(self) -> [u8; N] {
        self.buf
    }
}

const fn len_u16(n: usize) -> u16 {
    // HEADER_LEN and RECORD_LEN are small constants.
    #[expect(clippy::cast_possible_truncation)]
    let v = n as u16;
    v
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::control::bridge::{HBridge, NullPin, NullPwm, BOARD_MAX_DUTY};
    use std::vec::Vec;

    /// A short trace of `case` with a position ramp (re-armed after every fault the
    /// synthetic codes cause), then the position sensor on its rail for 3 ticks.
    fn make(case: &Case, ticks: u32) -> Vec<u8> {
        let settings = (case.settings)().unwrap();
        let cfg = settings.build().unwrap();
        let mut st = cfg.initial_state();
        let mut b =
            HBridge::new(NullPwm::new(BOARD_MAX_DUTY), NullPin(false), NullPin(false)).unwrap();
        let mut out = Vec::from(Header::new(case, &settings, &cfg, BOARD_MAX_DUTY, ticks).encode());
        let mut tripped = false;
        for k in 0..u16::try_from(ticks).unwrap() {
            let rail = u32::from(k) + 3 >= ticks;
            let position = if rail { 0 } else { 1000 + k };
            let frame = Frame {
                position,
                current: 2048 + k % 50,
                vbus: 1354,
            };
            let rearm = tripped && !rail;
            let (status, rec) = tick_record(&cfg, &mut st, &mut b, &frame, 3e-3, rearm);
            tripped = status.fault.is_some();
            out.extend_from_slice(&rec.encode());
        }
        out
    }

    #[test]
    fn layouts_fill_their_arrays_and_round_trip() {
        let h = Header {
            max_duty: BOARD_MAX_DUTY,
            ticks: 7,
            settings_hash: 0x0123_4567_89ab_cdef,
            case: Name::new("paper"),
            law: Name::new("a-law-with-a-name-longer-than-twenty"),
        };
        let bytes = h.encode();
        assert_eq!(&bytes[..4], b"EMAT");
        // The law name is the last field: it ends exactly at the end of the header.
        assert_eq!(&bytes[44..64], b"a-law-with-a-name-lo");
        assert_eq!(h.law.as_str(), "a-law-with-a-name-lo");
        let r = Record {
            input: Input {
                frame: Frame {
                    position: 1,
                    current: 0x0203,
                    vbus: 0xfffe,
                },
                setpoint_m: 3e-3,
                rearm: true,
            },
            output: Output {
                u_cmd: 0xdead_beef,
                u_applied: 1,
                i_d: 2,
                duty: BOARD_MAX_DUTY,
                mode: 2,
                fault: 15,
            },
        };
        let e = r.encode();
        assert_eq!(e[2..4], [0x03, 0x02]);
        assert_eq!(e[10], 1);
        assert_eq!(e[25..], [2, 15]);
        assert_eq!(Record::decode(&e), r);
        let mut t = Vec::from(bytes);
        for _ in 0..7 {
            t.extend_from_slice(&e);
        }
        let trace = Trace::parse(&t).unwrap();
        assert_eq!(*trace.header(), h);
        assert_eq!(trace.records().count(), 7);
        assert!(trace.records().all(|x| x == r));
    }

    #[test]
    fn malformed_traces_are_refused_by_reason() {
        let good = make(&CASES[0], 5);
        assert!(Trace::parse(&good).is_ok());
        assert_eq!(
            Trace::parse(&good[..10]).unwrap_err(),
            FormatError::Truncated
        );
        assert_eq!(
            Trace::parse(&good[..good.len() - 1]).unwrap_err(),
            FormatError::Length
        );
        let mut bad = good.clone();
        bad[0] = b'X';
        assert_eq!(Trace::parse(&bad).unwrap_err(), FormatError::Magic);
        let mut bad = good.clone();
        bad[4] = 9;
        assert_eq!(Trace::parse(&bad).unwrap_err(), FormatError::Version(9));
        let mut bad = good.clone();
        bad[8] = 26;
        assert_eq!(Trace::parse(&bad).unwrap_err(), FormatError::Layout);
        let mut bad = good.clone();
        bad[16] ^= 1;
        assert!(matches!(open(&bad), Err(OpenError::Settings { .. })));
        let mut bad = good;
        bad[24] = b'x';
        assert_eq!(open(&bad).unwrap_err(), OpenError::UnknownCase);
    }

    #[test]
    fn replay_finds_the_first_flipped_bit() {
        let mut t = make(&CASES[0], 40);
        let (trace, _, cfg) = open(&t).unwrap();
        assert_eq!(trace.header().max_duty, BOARD_MAX_DUTY);
        let mut b =
            HBridge::new(NullPwm::new(BOARD_MAX_DUTY), NullPin(false), NullPin(false)).unwrap();
        assert_eq!(replay(&trace, &cfg, &mut b), Ok(40));
        // The synthetic codes trip the monitors: the trace re-arms, and the replay follows.
        assert!(trace.records().filter(|r| r.input.rearm).count() > 0);
        // The last ticks saw the position sensor on the rail: a latched fault is recorded.
        let last = trace.records().last().unwrap();
        assert_eq!(last.output.fault, Fault::PositionSensor.code());
        // Flip the lowest bit of the desired current of tick 17.
        t[HEADER_LEN + 17 * RECORD_LEN + 19] ^= 1;
        let (trace, _, cfg) = open(&t).unwrap();
        let mut b =
            HBridge::new(NullPwm::new(BOARD_MAX_DUTY), NullPin(false), NullPin(false)).unwrap();
        let m = replay(&trace, &cfg, &mut b).unwrap_err();
        assert_eq!((m.tick, m.field), (17, "i_d"));
        assert_eq!(m.expected ^ m.actual, 1);
    }

    #[test]
    fn nan_is_stored_canonically() {
        assert_eq!(bits(f32::from_bits(0xffc0_0001)), CANONICAL_NAN);
        assert_eq!(bits(-0.0), 0x8000_0000);
        assert_eq!(bits(f32::INFINITY), 0x7f80_0000);
    }

    #[test]
    fn settings_identity_follows_a_limit_and_the_rate() {
        // Every field: hil-sim/tests/settings_identity.rs (it reads the settings as a
        // document, which needs the `serde` feature).
        let s = (CASES[0].settings)().unwrap();
        let h = settings_hash(&s);
        let mut t = s;
        t.limits.current_trip_a = f32::from_bits(t.limits.current_trip_a.to_bits() + 1);
        assert_ne!(settings_hash(&t), h);
        let mut t = s;
        t.rate_hz = 10_000.0;
        assert_ne!(settings_hash(&t), h);
    }

    #[test]
    fn every_case_builds_and_has_a_short_unique_name() {
        for (k, c) in CASES.iter().enumerate() {
            assert!(c.name.len() <= NAME_LEN, "{}", c.name);
            assert!(CASES[..k].iter().all(|o| o.name != c.name), "{}", c.name);
            (c.settings)().unwrap().build().unwrap();
            assert_eq!(case(c.name).unwrap().name, c.name);
        }
    }
}
