//! A scripted bench session through the board's application (`ema::device`), `no_std`:
//! the host (`tests/device_host.rs`) and the Cortex-M4F under QEMU (`tests/qemu_device.rs`)
//! run the same script and must send byte-identical frames ([`FRAMES_HASH`],
//! [`FRAMES_LEN`]).
//!
//! The script: the start announcement; 40 ticks disarmed; status; arm; a set while armed
//! (refused); a get; 200 ticks; a stream of two signals every 20 ticks; a capture of 32 samples every
//! 10 ticks triggered by a move; the move to 3 mm; 3320 ticks (the position checked); the capture read back; an
//! inductance probe above its limit (refused), one within it (run out over 64 ticks); a
//! frame with a bit flipped (rejected by name); disarm; a set (accepted); status. Every
//! answer is checked as it arrives ([`Session::run`] returns the first one that is not as
//! expected).
#![allow(dead_code)]

use ema::control::actuator::Actuator;
use ema::control::bridge::{HBridge, Mode as BridgeMode};
use ema::control::supervisor::Fault;
use ema::device::guard::{End, Start};
use ema::device::params::{Board, Params};
use ema::device::protocol::{
    self, Build, CaptureState, Command, FrameError, Framer, LoadError, Message, Mode, Refusal,
    Reply, Request, Sample, Signal, Source, Trigger, Value, MAX_FRAME,
};
use ema::device::{Boot, Controller, Dispatcher, Inputs, IsrEnds, MainEnds, Storage};
use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

use super::plant::Plant;

/// The board of the session (the firmware's rate).
pub const BOARD: Board = Board {
    rate_hz: 20_000.0,
    current_zero_code: None,
};
/// Counts between ticks, for the guard (168 MHz / 20 kHz, as the firmware).
pub const PERIOD: u32 = 8_400;
/// Samples of the session's capture buffer.
pub const CAPTURE: usize = 32;
/// Ticks of commissioning the session measures.
pub const COMMISSIONING_TICKS: u32 = 300;

/// FNV-1a (64 bit) of every byte the board sent, in order (the host computes it: see
/// `tests/device_host.rs`).
pub const FRAMES_HASH: u64 = 0x0629_2c60_5855_5c7e;
/// Bytes the board sent.
pub const FRAMES_LEN: usize = 16094;

/// The build the session's board reports (fixed, so that the frames' hash does not
/// depend on the commit).
pub const BUILD: Build<'static> = Build {
    version: "0.0.0",
    id: "session",
};

/// The link's timeout in ticks (the default, at [`BOARD`]'s rate).
pub const LINK_TIMEOUT_TICKS: u32 =
    (ema::device::liveness::DEFAULT_TIMEOUT_S * BOARD.rate_hz) as u32;
/// The main loop's deadline in ticks.
pub const MAIN_LOOP_TICKS: u32 =
    (ema::device::liveness::MAIN_LOOP_DEADLINE_S * BOARD.rate_hz) as u32;

/// Nothing stored.
pub struct Empty;

impl Storage for Empty {
    fn load(&mut self) -> Result<Params, LoadError<'static>> {
        Err(LoadError::Empty)
    }
}

/// FNV-1a, 64 bit.
#[derive(Clone, Copy, Debug)]
pub struct Fnv(pub u64, pub usize);

impl Fnv {
    /// Empty.
    pub const fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325, 0)
    }
    fn add(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        self.1 += bytes.len();
    }
}

/// Instructions (or whatever `clock` counts) of ticks of one phase, those that carried
/// no order from the main loop.
#[derive(Clone, Copy, Debug, Default)]
pub struct PhaseCost {
    /// Ticks.
    pub n: u32,
    /// The largest.
    pub max: u32,
    sum: u64,
}

impl PhaseCost {
    fn add(&mut self, v: u32) {
        self.n += 1;
        self.max = self.max.max(v);
        self.sum += u64::from(v);
    }

    /// The mean (0 without ticks).
    pub fn mean(&self) -> u32 {
        self.sum.checked_div(u64::from(self.n)).unwrap_or(0) as u32
    }
}

/// The tick's cost per phase: the application's tick (`Controller::tick`, with the guard,
/// the queue poll, the operating state, telemetry and capture) and, on a copy of the same
/// state and inputs, the bare control tick (`Config::tick`) it wraps.
#[derive(Clone, Copy, Debug, Default)]
pub struct Cost {
    /// Disarmed: sensors read and checked, bridge coasting.
    pub disarmed: PhaseCost,
    /// Armed, holding, nothing streamed or captured.
    pub armed: PhaseCost,
    /// The bare control tick on the same ticks.
    pub armed_bare: PhaseCost,
    /// Armed with telemetry streaming (one sample every 20 ticks), moving with a capture
    /// recording (one sample every 10 ticks) too, then holding, still streaming.
    pub recording: PhaseCost,
    /// The bare control tick on the same ticks.
    pub recording_bare: PhaseCost,
    /// Ticks that carried an order (its largest: an order such as a new configuration
    /// is applied by the tick that takes it).
    pub with_order: PhaseCost,
    /// Commissioning: the codes checked, the identification stepped, the bridge driven.
    pub commissioning: PhaseCost,
    /// The main loop's passes: the dispatcher taking bytes (decoding, answering,
    /// validating and building a parameter set), and its polls.
    pub main_pass: PhaseCost,
}

/// What the session saw.
#[derive(Clone, Copy, Debug, Default)]
pub struct Outcome {
    /// Bytes sent and their hash.
    pub hash: u64,
    /// Bytes sent.
    pub len: usize,
    /// Telemetry frames.
    pub telemetry: u32,
    /// Capture samples read back.
    pub captured: usize,
    /// The position 0.17 s after the move's start, before disarming \[m\].
    pub x_m: f32,
    /// Ticks from the arming request to the tick that disarmed with `link_timeout`, the
    /// host silent.
    pub link_lost_after: u32,
    /// Ticks from the main loop's last pass to the first tick that did not feed the
    /// watchdogs, with `main_loop_stalled` latched and the bridge coasting.
    pub main_stalled_after: u32,
    /// The tick's cost.
    pub cost: Cost,
}

/// The board's two halves on a plant.
pub struct Session<'q, P: SetDutyCycle, O: OutputPin> {
    controller: Controller<[Sample; CAPTURE]>,
    dispatcher: Dispatcher,
    main: MainEnds<'q>,
    isr: IsrEnds<'q>,
    bridge: HBridge<P, O>,
    plant: Plant,
    ticks: u32,
    hash: Fnv,
    rx: Framer,
    out: Outcome,
    phase: u8,
    /// The last answer to a request, by sequence number.
    answer: Option<(u16, Answer)>,
    /// A request is in flight (its ticks may carry an order).
    requesting: bool,
    /// The bare control tick's bridge.
    shadow: HBridge<P, O>,
    /// The main loop hangs: the ticks run without it.
    main_hung: bool,
    /// The last tick fed the watchdogs.
    fed: bool,
}

/// An answer, as far as the script checks it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Answer {
    Done,
    Refused(Kind),
    Value(Value),
    Status {
        mode: Mode,
        capture: CaptureState,
        fault: Option<u8>,
    },
    Chunk {
        offset: u16,
        total: u16,
        n: usize,
    },
    Other,
}

/// A refusal's kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    Armed,
    Invalid,
    Other,
}

impl<'q, P: SetDutyCycle, O: OutputPin> Session<'q, P, O> {
    /// A board started on its defaults (nothing stored), on a plant at rest at 1 mm.
    pub fn new(
        main: MainEnds<'q>,
        isr: IsrEnds<'q>,
        bridge: HBridge<P, O>,
        shadow: HBridge<P, O>,
    ) -> Result<Self, &'static str> {
        let params = Params::new(Actuator::PRODUCT);
        let settings = params.settings(&BOARD).map_err(|_| "settings")?;
        let boot = Boot {
            params,
            source: Source::Defaults,
            saved: None,
            install: params.build(&BOARD).map_err(|_| "build")?,
        };
        let dispatcher = Dispatcher::new(BOARD, BUILD, params, &boot, CAPTURE as u16);
        let controller = Controller::new(boot.install, PERIOD, [Sample::default(); CAPTURE]);
        let mut s = Self {
            controller,
            dispatcher,
            main,
            isr,
            bridge,
            plant: Plant::new(&settings, 1e-3, 24.0),
            ticks: 0,
            hash: Fnv::new(),
            rx: Framer::new(),
            out: Outcome::default(),
            phase: 0,
            answer: None,
            requesting: false,
            shadow,
            main_hung: false,
            fed: true,
        };
        s.drain()?;
        Ok(s)
    }

    /// The bytes the dispatcher has to send: hashed, and the answers read.
    fn drain(&mut self) -> Result<(), &'static str> {
        let n = self.dispatcher.tx().len();
        let mut bytes = [0u8; ema::device::TX_CAPACITY];
        bytes[..n].copy_from_slice(self.dispatcher.tx());
        self.dispatcher.sent(n);
        self.hash.add(&bytes[..n]);
        for &b in &bytes[..n] {
            let Some(raw) = self.rx.push(b) else { continue };
            let raw = raw.map_err(|_| "the board sent a frame too long")?;
            let m =
                protocol::decode::<Message<'_>>(raw).map_err(|_| "the board sent a bad frame")?;
            match m {
                Message::Telemetry(_) => self.out.telemetry += 1,
                Message::Started(_) => {}
                Message::Rejected(e) => {
                    if e != FrameError::Crc {
                        return Err("rejected, but not for its CRC");
                    }
                    self.answer = Some((u16::MAX, Answer::Other));
                }
                Message::Reply { seq, reply } => {
                    let a = match reply {
                        Reply::Done => Answer::Done,
                        Reply::Refused(Refusal::Armed) => Answer::Refused(Kind::Armed),
                        Reply::Refused(Refusal::Invalid(_)) => Answer::Refused(Kind::Invalid),
                        Reply::Refused(_) => Answer::Refused(Kind::Other),
                        Reply::Value(v) => Answer::Value(v),
                        Reply::Status(s) => Answer::Status {
                            mode: s.mode,
                            capture: s.capture,
                            fault: s.fault,
                        },
                        Reply::Capture(c) => {
                            self.out.captured += c.samples.len();
                            Answer::Chunk {
                                offset: c.offset,
                                total: c.total,
                                n: c.samples.len(),
                            }
                        }
                        _ => Answer::Other,
                    };
                    self.answer = Some((seq, a));
                }
            }
            self.rx.clear();
        }
        Ok(())
    }

    /// One period: the controller's tick (timed by `clock`) on the plant's conversions,
    /// the plant, then the dispatcher's answers and telemetry.
    pub fn tick(&mut self, clock: &mut dyn FnMut() -> u32) -> Result<(), &'static str> {
        let inputs = Inputs {
            frame: self.plant.frame(),
            analog: 0,
            start: Start {
                now: self.ticks.wrapping_mul(PERIOD),
                hardware_trip: false,
            },
            break_active: false,
        };
        let armed = self.controller.mode().armed();
        let commissioning = self.controller.mode() == Mode::Commissioning;
        let bare = if armed && !self.requesting {
            let mut state = *self.controller.state();
            let (cfg, frame, setpoint) = (
                self.controller.config(),
                inputs.frame,
                self.controller.setpoint_m(),
            );
            let t0 = clock();
            let _ = cfg.tick(&mut state, &mut self.shadow, &frame, setpoint);
            clock().wrapping_sub(t0)
        } else {
            0
        };
        let t0 = clock();
        let t = self
            .controller
            .tick(&mut self.bridge, &inputs, &mut self.isr, End::default);
        let n = clock().wrapping_sub(t0);
        self.fed = t.feed;
        self.plant.advance(&t.status.drive);
        self.ticks = self.ticks.wrapping_add(1);
        let c = &mut self.out.cost;
        match (self.requesting, armed, self.phase) {
            (true, ..) => c.with_order.add(n),
            (false, false, _) if commissioning => c.commissioning.add(n),
            (false, false, _) => c.disarmed.add(n),
            (false, true, 1 | 2) => {
                c.recording.add(n);
                c.recording_bare.add(bare);
            }
            (false, true, _) => {
                c.armed.add(n);
                c.armed_bare.add(bare);
            }
        }
        if self.main_hung {
            return Ok(());
        }
        let t0 = clock();
        self.dispatcher.poll(&mut self.main);
        let n = clock().wrapping_sub(t0);
        self.out.cost.main_pass.add(n);
        self.drain()
    }

    /// Sends `bytes` and ticks until the dispatcher has taken them and answered.
    fn send_raw(
        &mut self,
        bytes: &[u8],
        clock: &mut dyn FnMut() -> u32,
    ) -> Result<(), &'static str> {
        self.answer = None;
        self.requesting = true;
        let r = self.exchange(bytes, clock);
        self.requesting = false;
        r
    }

    fn exchange(
        &mut self,
        bytes: &[u8],
        clock: &mut dyn FnMut() -> u32,
    ) -> Result<(), &'static str> {
        let mut rest = bytes;
        for _ in 0..100 {
            let t0 = clock();
            let k = self.dispatcher.receive(rest, &mut self.main, &mut Empty);
            let n = clock().wrapping_sub(t0);
            self.out.cost.main_pass.add(n);
            rest = rest.get(k..).unwrap_or(&[]);
            self.drain()?;
            if rest.is_empty() && !self.dispatcher.busy() && self.answer.is_some() {
                return Ok(());
            }
            self.tick(clock)?;
            if rest.is_empty() && !self.dispatcher.busy() && self.answer.is_some() {
                return Ok(());
            }
        }
        Err("no answer within 100 ticks")
    }

    /// Sends a request; its answer.
    fn request(
        &mut self,
        seq: u16,
        command: Command<'_>,
        clock: &mut dyn FnMut() -> u32,
    ) -> Result<Answer, &'static str> {
        let mut frame = [0u8; MAX_FRAME];
        let n = protocol::encode(&Request { seq, command }, &mut frame)
            .map_err(|_| "a request does not fit")?;
        self.send_raw(&frame[..n], clock)?;
        match self.answer {
            Some((s, a)) if s == seq => Ok(a),
            _ => Err("an answer to another request"),
        }
    }

    /// The script; what the board sent and how long its ticks took.
    #[expect(
        clippy::too_many_lines,
        reason = "the session's script, step after step in the order the board sees them: \
                  split, the order would be scattered over functions"
    )]
    pub fn run(mut self, clock: &mut dyn FnMut() -> u32) -> Result<Outcome, &'static str> {
        for _ in 0..40 {
            self.tick(clock)?;
        }
        let status = self.request(1, Command::Status, clock)?;
        if !matches!(
            status,
            Answer::Status {
                mode: Mode::Disarmed,
                ..
            }
        ) {
            return Err("not disarmed after the start");
        }
        if self.request(2, Command::Arm, clock)? != Answer::Done {
            return Err("arming refused");
        }
        let set = Command::Set {
            name: "tuning.margin",
            value: Value::Number(0.6),
        };
        if self.request(3, set, clock)? != Answer::Refused(Kind::Armed) {
            return Err("a set while armed was not refused as armed");
        }
        let get = Command::Get {
            name: "tuning.margin",
        };
        if self.request(4, get, clock)? != Answer::Value(Value::Number(0.7)) {
            return Err("the margin is not the default 0.7");
        }
        for _ in 0..200 {
            self.tick(clock)?;
        }
        self.phase = 1;
        let stream = Command::Stream {
            signals: Signal::Position.bit() | Signal::Current.bit(),
            decimation: 20,
        };
        if self.request(5, stream, clock)? != Answer::Done {
            return Err("stream refused");
        }
        let capture = Command::Capture {
            samples: CAPTURE as u16,
            decimation: 10,
            trigger: Trigger::Move,
        };
        if self.request(6, capture, clock)? != Answer::Done {
            return Err("capture refused");
        }
        let go = Command::Move {
            position_m: 3e-3,
            time_s: None,
        };
        if self.request(7, go, clock)? != Answer::Done {
            return Err("move refused");
        }
        for _ in 0..(CAPTURE * 10) {
            self.tick(clock)?;
        }
        self.phase = 2;
        for _ in 0..3_000 {
            self.tick(clock)?;
        }
        self.out.x_m = self.plant.x_m;
        let mut seq = 8;
        let mut offset = 0u16;
        while usize::from(offset) < CAPTURE {
            match self.request(seq, Command::ReadCapture { offset }, clock)? {
                Answer::Chunk {
                    offset: o,
                    total,
                    n,
                } if o == offset && usize::from(total) == CAPTURE && n > 0 => {
                    offset += n as u16;
                }
                _ => return Err("a capture chunk is not as asked"),
            }
            seq += 1;
        }
        // An inductance probe while holding: one above its limit refused, one run out.
        let rated = Actuator::PRODUCT.coil.rated_current_a;
        let probe = |share: f32| Command::Probe {
            amplitude_a: share * rated,
            half_ticks: 8,
            cycles: 4,
        };
        if self.request(seq, probe(0.2), clock)? != Answer::Refused(Kind::Invalid) {
            return Err("a probe above its limit was not refused as invalid");
        }
        seq += 1;
        if self.request(seq, probe(0.05), clock)? != Answer::Done {
            return Err("a probe while holding was refused");
        }
        if self.controller.state().probe.ticks_left == 0 {
            return Err("the probe did not start");
        }
        seq += 1;
        for _ in 0..64 {
            self.tick(clock)?;
        }
        if self.controller.state().probe.ticks_left != 0 {
            return Err("the probe did not end");
        }
        // A frame damaged on the way: rejected for its CRC, nothing else happens.
        let mut frame = [0u8; MAX_FRAME];
        let n = protocol::encode(
            &Request {
                seq,
                command: Command::Disarm,
            },
            &mut frame,
        )
        .map_err(|_| "a request does not fit")?;
        frame[3] ^= 0x04;
        self.send_raw(&frame[..n], clock)?;
        if self.controller.mode() == Mode::Disarmed {
            return Err("a damaged frame disarmed");
        }
        seq += 1;
        if self.request(seq, Command::Disarm, clock)? != Answer::Done {
            return Err("disarm refused");
        }
        seq += 1;
        let set = Command::Set {
            name: "tuning.margin",
            value: Value::Number(0.6),
        };
        if self.request(seq, set, clock)? != Answer::Done {
            return Err("a set while disarmed was refused");
        }
        seq += 1;
        match self.request(seq, Command::Status, clock)? {
            Answer::Status {
                mode: Mode::Disarmed,
                capture: CaptureState::Done(n),
                ..
            } if usize::from(n) == CAPTURE => {}
            _ => return Err("the last status is not disarmed with the capture done"),
        }
        // Commissioning: a few hundred ticks of the identification's first step, then a
        // disarm ends it.
        seq += 1;
        if self.request(seq, Command::Commission, clock)? != Answer::Done {
            return Err("commissioning refused");
        }
        for _ in 0..COMMISSIONING_TICKS {
            self.tick(clock)?;
        }
        if self.controller.mode() != Mode::Commissioning {
            return Err("the commissioning ended early");
        }
        seq += 1;
        if self.request(seq, Command::Disarm, clock)? != Answer::Done {
            return Err("a disarm did not end the commissioning");
        }
        if self.controller.mode() != Mode::Disarmed {
            return Err("not disarmed after the commissioning");
        }
        // A heartbeat is answered.
        seq += 1;
        if self.request(seq, Command::Heartbeat, clock)? != Answer::Done {
            return Err("a heartbeat was not answered done");
        }
        // Armed, the host falls silent: the board disarms with link_timeout one tick after
        // the timeout.
        seq += 1;
        if self.request(seq, Command::Arm, clock)? != Answer::Done {
            return Err("arming again refused");
        }
        let armed_at = self.ticks;
        while self.controller.mode().armed() {
            if self.ticks.wrapping_sub(armed_at) > 2 * LINK_TIMEOUT_TICKS {
                return Err("still armed long after the link's timeout");
            }
            self.tick(clock)?;
        }
        self.out.link_lost_after = self.ticks.wrapping_sub(armed_at);
        seq += 1;
        match self.request(seq, Command::Status, clock)? {
            Answer::Status {
                mode: Mode::Fault,
                fault: Some(f),
                ..
            } if f == Fault::LinkTimeout.code() => {}
            _ => return Err("the silent host did not leave link_timeout latched"),
        }
        seq += 1;
        if self.request(seq, Command::Clear, clock)? != Answer::Done {
            return Err("link_timeout did not clear");
        }
        // The main loop hangs: the ticks go on, latch main_loop_stalled and stop feeding
        // the watchdogs.
        self.main_hung = true;
        let last_pass = self.ticks;
        while self.fed {
            if self.ticks.wrapping_sub(last_pass) > 2 * MAIN_LOOP_TICKS {
                return Err("the ticks still feed the watchdogs long after the main loop hung");
            }
            self.tick(clock)?;
        }
        self.out.main_stalled_after = self.ticks.wrapping_sub(last_pass);
        if self.controller.state().supervisor.latched() != Some(Fault::MainLoopStalled)
            || self.bridge.mode() != BridgeMode::Coast
        {
            return Err(
                "a hung main loop did not latch main_loop_stalled with the bridge coasting",
            );
        }
        self.out.hash = self.hash.0;
        self.out.len = self.hash.1;
        Ok(self.out)
    }
}
