//! The board's application, the same on the STM32F405 and on `hil-sim`'s virtual board:
//! the operating states, the commands of the link, the parameters and their store,
//! telemetry and captures. Everything target-specific (the timer, the ADC, the UART, the
//! flash, the reset) stays in the firmware; `hil-sim` gives the same two halves a
//! simulated plant, a pseudo-terminal and a simulated flash.
//!
//! This module's root is the application (its two halves, the queues between them, the
//! start-up's [`boot`]); its submodules are what only the application uses: the link's
//! messages and frames ([`protocol`]), the parameters ([`params`]) and their store
//! ([`store`]), the analog set point ([`analog`]), the commissioning routine
//! ([`commission`]), the checks around each tick ([`guard`]) and the link's and main loop's
//! liveness ([`liveness`]). It runs the control layer ([`crate::control`]), which does not
//! know it.
//!
//! **Where it runs.** The firmware's control interrupt runs [`Controller::tick`] and its
//! main loop the [`Dispatcher`], over USART2 and the chip's flash; `hil-sim`'s virtual
//! board runs the same two halves (the host tool is tested against it), and
//! `tests/qemu_device.rs` runs a scripted session of it on the Cortex-M4F.
//!
//! ## Two halves and three queues
//!
//! | half | runs in | owns |
//! |---|---|---|
//! | [`Controller`] | the control interrupt, every tick | the controller's configuration and state, the operating state, the set point, the capture buffer |
//! | [`Dispatcher`] | the main loop | the link (frames in and out), the parameters, the store |
//!
//! They share nothing but three single-producer single-consumer queues from `heapless`
//! ([`Queues`]): orders from the main loop to the interrupt ([`Ticket`], one at a time),
//! answers back ([`Answer`]), and telemetry samples ([`Telemetered`]). The interrupt
//! takes at most one order per tick and never waits; a full telemetry queue drops the
//! sample and counts it. Every decision that needs the present measurement (arming,
//! clearing) is taken by the interrupt, at the tick the order arrives; everything that
//! takes time (validating and building a configuration, reading the store, encoding
//! frames) is done by the main loop.
//!
//! ## Operating states
//!
//! ```text
//!            arm (no fault, sensors plausible, bus in window, 4-20 mA loop closed)
//! Disarmed ---------------------------> Armed <----> Moving   (a move in progress)
//!    ^  <------------- disarm ------------|             |
//!    |                                    +---- fault --+--> Fault (latched, coasting)
//!    +------------ clear (disarmed, cause gone) ---------------------+
//! ```
//!
//! * **Disarmed** (after every start): the bridge coasts, the sensors are read and
//!   checked every tick; nothing is driven.
//! * **Armed**: closed loop, holding the position measured when armed (with the link as
//!   the set point's source) or following the analog set point.
//! * **Moving**: armed, a move in progress (the reference shaping's).
//! * **Commissioning** (entered from Disarmed by [`Command::Commission`], nothing
//!   latched, sensors and bus ready): the loop open, the bridge driven by the actuator's
//!   identification ([`commission`]); it returns to Disarmed when the result is in,
//!   when any order other than a status, stream or capture arrives (the bridge coasts at
//!   once), or to Fault when a fault latches (every tick still converts and checks the
//!   codes and the limits).
//! * **Fault**: a fault latched (by the tick, the guard, or the analog input's wire
//!   check); the bridge coasts until the fault is cleared, which leaves the board
//!   disarmed. Clearing is refused while the cause is still measured (a sensor
//!   implausible, the bus outside its window, the bridge's break input active, the
//!   4-20 mA loop open).
//!
//! ## Cost in the interrupt
//!
//! Disarmed, a tick converts and checks the codes and coasts the bridge. Armed, it is
//! `Config::tick` through the guard, plus: one queue poll, the analog input when chosen,
//! the operating state, and when due, one telemetry sample and one capture sample (a copy
//! of eight values). `tests/qemu_device.rs` counts the instructions on the Cortex-M4F.

pub mod analog;
pub mod commission;
pub mod guard;
pub mod liveness;
pub mod params;
pub mod protocol;
pub mod store;

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;
use heapless::spsc::{Consumer, Producer, Queue};

use crate::control::bridge::{HBridge, Mode as BridgeMode};
use crate::control::math;
use crate::control::sense::{Frame, Measurement};
use crate::control::supervisor::{Fault, FAULT_COUNT};
use crate::control::{self, Status as TickStatus};
use analog::Source as SetpointSource;
use guard::{End, Start};
use liveness::Pulse;
use params::{Board, Params, Refused};
use protocol::{
    Build, CaptureState, Chunk, Command, Commissioned, FrameError, Framer, Invalid, LoadError,
    Message, Mode, Refusal, Reply, Request, Sample, Signal, Source, Started, Status, StoreError,
    Telemetry, Trigger, MAX_FRAME,
};
use store::Store;

/// Samples the firmware's capture buffer holds (at 20 kHz with a decimation of 20: 0.256 s).
pub const CAPTURE_CAPACITY: usize = 256;
/// Slots of the order queue (one order in flight, plus the queue's empty slot).
pub const ORDER_SLOTS: usize = 2;
/// Slots of the answer queue.
pub const ANSWER_SLOTS: usize = 2;
/// Slots of the telemetry queue.
pub const SAMPLE_SLOTS: usize = 16;
/// Bytes the dispatcher buffers for the link.
pub const TX_CAPACITY: usize = 1024;
/// Longest move a [`Command::Move`] may ask for \[s\].
pub const MAX_MOVE_S: f32 = 10.0;
/// Rejections ([`Message::Rejected`]) the board sends at most per second: one per
/// millisecond, about 10 bytes each, a fifth of the link's 46 bytes per millisecond at
/// most, however noisy the line; the rest are counted, not answered.
pub const REJECTIONS_PER_S: f32 = 1000.0;
/// Largest amplitude a [`Command::Probe`] may ask for, as a share of the rated current:
/// a probe measures about a hold, it does not move the armature.
pub const PROBE_MAX_SHARE: f32 = 0.1;

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
    /// Arm (see [`Command::Arm`]).
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
    /// Start a commissioning with this plan (disarmed only, see [`Command::Commission`]).
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

/// What the interrupt knows at a tick's start.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    /// The control's three conversions.
    pub frame: Frame,
    /// The analog set-point input's conversion.
    pub analog: u16,
    /// Time and the break flag, for the guard.
    pub start: Start,
    /// The bridge's break input is active now (its cause is still there).
    pub break_active: bool,
}

/// What a tick did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ticked {
    /// The tick's status.
    pub status: TickStatus,
    /// It ran on time: feed the watchdog.
    pub feed: bool,
    /// A `hardware_trip` was cleared: re-enable the bridge's outputs (the firmware clears
    /// the timer's break flag, which this tick already read and consumed, and sets its
    /// main output again).
    pub restore_outputs: bool,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Meta {
    armed_ticks: u32,
    from_m: f32,
    to_m: f32,
    move_s: f32,
}

/// Cycle statistics of the ticks (the firmware measures them; zero elsewhere): per window
/// of ticks and since start.
///
/// The window's sum is a `u32`: the ticks of a window cannot take more cycles than the
/// window lasts, and a window of one second is 168 M cycles at 168 MHz, far from 2^32 (25
/// s); past that it saturates. A `u64` sum would bring a software 64-bit division
/// (`__aeabi_uldivmod`, about 900 bytes) into the interrupt.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cycles {
    sum: u32,
    count: u32,
    window_max: u32,
    /// Mean of the last whole window.
    mean: u32,
    /// Largest since start.
    max: u32,
}

/// One window of cycle counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CycleSummary {
    /// Mean cycles per tick over the window.
    pub mean: u32,
    /// Largest tick of the window \[cycles\].
    pub window_max: u32,
    /// Largest tick since start \[cycles\].
    pub max: u32,
    /// Ticks in the window.
    pub ticks: u32,
}

impl Cycles {
    /// Adds one tick of `cycles`; every `window` ticks returns the window's summary and
    /// starts the next window.
    pub fn record(&mut self, cycles: u32, window: u32) -> Option<CycleSummary> {
        self.sum = self.sum.saturating_add(cycles);
        self.count = self.count.saturating_add(1);
        self.window_max = self.window_max.max(cycles);
        self.max = self.max.max(cycles);
        if self.count < window.max(1) {
            return None;
        }
        // `count` is at least 1 here (checked against `window.max(1)` above).
        self.mean = self.sum.checked_div(self.count).unwrap_or(0);
        let summary = CycleSummary {
            mean: self.mean,
            window_max: self.window_max,
            max: self.max,
            ticks: self.count,
        };
        self.sum = 0;
        self.count = 0;
        self.window_max = 0;
        Some(summary)
    }
}

/// The interrupt's half. `C` is the capture buffer (`&'static mut [Sample; N]` in the
/// firmware, a `Vec` in `hil-sim`).
pub struct Controller<C> {
    cfg: control::Config,
    analog: analog::Config,
    link: liveness::Config,
    watch: liveness::Watch,
    state: control::State,
    analog_state: analog::State,
    guard: guard::Config,
    guarded: guard::State,
    mode: Mode,
    setpoint_m: f32,
    ticks: u32,
    armed_ticks: u32,
    /// The last tick's reading and its verdict (what arming or clearing would meet).
    measurement: Measurement,
    verdict: Option<Fault>,
    analog_m: f32,
    analog_fault: Option<Fault>,
    break_active: bool,
    stream: u16,
    stream_count: u16,
    dropped: u32,
    capture: C,
    capture_state: CaptureState,
    capture_target: u16,
    capture_decimation: u16,
    capture_count: u16,
    /// Sums of the position and the current's square over the capture sample's ticks so
    /// far.
    capture_sum: [f32; 2],
    capture_trigger: Trigger,
    meta: Meta,
    cycles: Cycles,
    /// The commissioning in progress (mode [`Mode::Commissioning`]).
    identification: Option<commission::Identification>,
    /// The last commissioning's outcome.
    commissioned: Commissioned,
    /// The voltage the last tick set the bridge to \[V\].
    last_drive_v: f32,
}

impl<C: AsRef<[Sample]> + AsMut<[Sample]>> Controller<C> {
    /// Disarmed, with `install`, the guard for ticks `period` counts apart, and
    /// `capture` as the capture buffer.
    #[must_use]
    #[inline(never)]
    pub fn new(install: Install, period: u32, capture: C) -> Self {
        Self {
            cfg: install.control,
            analog: install.analog,
            link: install.link,
            watch: liveness::Watch::default(),
            state: install.control.initial_state(),
            analog_state: analog::State::default(),
            guard: guard::Config::for_period(period),
            guarded: guard::State::default(),
            mode: Mode::Disarmed,
            setpoint_m: 0.0,
            ticks: 0,
            armed_ticks: 0,
            measurement: Measurement::default(),
            verdict: None,
            analog_m: 0.0,
            analog_fault: None,
            break_active: false,
            stream: 0,
            stream_count: 0,
            dropped: 0,
            capture,
            capture_state: CaptureState::Idle,
            capture_target: 0,
            capture_decimation: 1,
            capture_count: 0,
            capture_sum: [0.0; 2],
            capture_trigger: Trigger::Now,
            meta: Meta::default(),
            cycles: Cycles::default(),
            identification: None,
            commissioned: Commissioned::Never,
            last_drive_v: 0.0,
        }
    }

    /// The operating state.
    #[must_use]
    pub const fn mode(&self) -> Mode {
        self.mode
    }

    /// The controller's configuration.
    #[must_use]
    pub const fn config(&self) -> &control::Config {
        &self.cfg
    }

    /// The controller's state.
    #[must_use]
    pub const fn state(&self) -> &control::State {
        &self.state
    }

    /// The guard's state (overruns).
    #[must_use]
    pub const fn guarded(&self) -> &guard::State {
        &self.guarded
    }

    /// The set point \[m\].
    #[must_use]
    pub const fn setpoint_m(&self) -> f32 {
        self.setpoint_m
    }

    /// Latches `fault` (one found outside a tick, for example at start) and coasts.
    pub fn trip<P: SetDutyCycle, O: OutputPin>(
        &mut self,
        bridge: &mut HBridge<P, O>,
        fault: Fault,
    ) {
        self.cfg.trip(&mut self.state, bridge, fault);
        self.mode = Mode::Fault;
    }

    /// Adds one tick's measured cycles ([`Cycles::record`]): the status reports the mean
    /// of the last window of `window` ticks and the largest since start; every `window`
    /// ticks, the window's summary.
    pub fn record_cycles(&mut self, cycles: u32, window: u32) -> Option<CycleSummary> {
        self.cycles.record(cycles, window)
    }

    /// One tick: takes at most one order, reads the analog input, runs the controller
    /// (armed) or checks the sensors with the bridge coasting (disarmed, fault) through
    /// the guard, and records telemetry and capture samples when due. Infallible and
    /// panic-free.
    #[inline]
    pub fn tick<P: SetDutyCycle, O: OutputPin>(
        &mut self,
        bridge: &mut HBridge<P, O>,
        inputs: &Inputs,
        ends: &mut IsrEnds<'_>,
        end: impl FnOnce() -> End,
    ) -> Ticked {
        self.ticks = self.ticks.wrapping_add(1);
        self.break_active = inputs.break_active;
        let mut restore_outputs = false;
        if let Some(ticket) = ends.orders.peek() {
            let id = ticket.id;
            let outcome = self.apply(&ticket.order, bridge, &mut restore_outputs);
            // Read where it lies, then released: an order is as large as its largest kind
            // (an install carries a whole configuration: 540 bytes), and a copy out of
            // the queue cost every order, an arm as much as an install.
            let _ = ends.orders.dequeue();
            // The main loop has at most one order in flight: the answer fits.
            let _ = ends.answers.enqueue(Answer { id, outcome });
        }

        let seen = self
            .watch
            .check(&self.link, ends.pulse, self.ticks, self.drives_for_link());
        if seen.main_loop_stalled {
            self.stop(bridge, Fault::MainLoopStalled);
        } else if seen.link_lost {
            if self.link.holds() && self.mode.armed() {
                self.state.supervisor.note(Fault::LinkTimeout);
            } else {
                self.stop(bridge, Fault::LinkTimeout);
            }
        }

        if self.analog.source() != SetpointSource::Link {
            let r = self.analog.step(&mut self.analog_state, inputs.analog);
            self.analog_m = r.filtered_m;
            self.analog_fault = if self.analog.source() == SetpointSource::Current {
                r.fault
            } else {
                None
            };
            if self.mode.armed() {
                if let Some(f) = self.analog_fault {
                    self.cfg.trip(&mut self.state, bridge, f);
                } else if r.setpoint_m != self.setpoint_m {
                    self.start_capture_on(Trigger::Move, r.setpoint_m, 0.0);
                    self.setpoint_m = r.setpoint_m;
                }
            }
        }

        let cfg = &self.cfg;
        let setpoint = self.setpoint_m;
        let frame = inputs.frame;
        // Armed, the guard runs the tick alone: the commissioning's bookkeeping stays out
        // of the closed loop's path (tests/qemu_device.rs counts what the application adds).
        let outcome = if self.mode.armed() {
            self.guard.run(
                &mut self.guarded,
                cfg,
                &mut self.state,
                bridge,
                inputs.start,
                |st, b| cfg.tick(st, b, &frame, setpoint),
                end,
            )
        } else {
            // The break flag was read before this tick's order: a clear that has just
            // accepted the hardware trip (its cause gone) consumes it, or the same tick
            // would latch it again. Only a disarmed board clears.
            let start = Start {
                hardware_trip: inputs.start.hardware_trip && !restore_outputs,
                ..inputs.start
            };
            let mut verdict = None;
            let mut identified = None;
            let identification = &mut self.identification;
            let last_drive_v = &mut self.last_drive_v;
            let outcome = self.guard.run(
                &mut self.guarded,
                cfg,
                &mut self.state,
                bridge,
                start,
                |st, b| {
                    if let Some(id) = identification.as_mut() {
                        let (status, checked, ended) =
                            commission_tick(cfg, id, st, b, &frame, last_drive_v);
                        verdict = checked;
                        identified = ended;
                        status
                    } else {
                        let (m, refused) = sensed(cfg, &frame);
                        verdict = refused;
                        let mut status = TickStatus {
                            fault: st.supervisor.latched(),
                            measurement: m,
                            ..TickStatus::default()
                        };
                        if b.coast().is_err() {
                            status.fault = Some(st.supervisor.trip(Fault::BridgeIo));
                        }
                        status
                    }
                },
                end,
            );
            self.verdict = verdict;
            if self.mode == Mode::Commissioning {
                let ended = if self.state.supervisor.latched().is_some() {
                    Some(Err(commission::Abort::Fault))
                } else {
                    identified
                };
                if let Some(r) = ended {
                    self.identification = None;
                    self.last_drive_v = 0.0;
                    self.commissioned = match r {
                        Ok(r) => Commissioned::Done(r),
                        Err(a) => Commissioned::Aborted(a),
                    };
                    self.mode = Mode::Disarmed;
                }
            }
            outcome
        };
        let status = outcome.status;
        self.measurement = status.measurement;
        if self.state.supervisor.latched().is_some() {
            self.mode = Mode::Fault;
        } else if self.mode.armed() {
            self.armed_ticks = self.armed_ticks.saturating_add(1);
            self.mode = if self.state.shaping.moving() {
                Mode::Moving
            } else {
                Mode::Armed
            };
        }

        let streaming = self.stream != 0;
        let capturing = matches!(self.capture_state, CaptureState::Running(_));
        if streaming || capturing {
            let sample = self.sample(&status, bridge.max_duty());
            if streaming {
                self.stream_count = self.stream_count.saturating_add(1);
                if self.stream_count >= self.stream {
                    self.stream_count = 0;
                    let t = Telemetered {
                        tick: self.ticks,
                        sample,
                    };
                    if ends.samples.enqueue(t).is_err() {
                        self.dropped = self.dropped.saturating_add(1);
                    }
                }
            }
            if let CaptureState::Running(n) = self.capture_state {
                self.record(n, sample);
            }
        }
        Ticked {
            status,
            // A stalled main loop no longer serves the link: the watchdogs end it.
            feed: outcome.feed && !seen.main_loop_stalled,
            restore_outputs,
        }
    }

    /// The board drives the coil for the link: armed with the set point from it, or
    /// commissioning.
    fn drives_for_link(&self) -> bool {
        (self.mode.armed() && self.analog.source() == SetpointSource::Link)
            || self.mode == Mode::Commissioning
    }

    /// Ends a commissioning in progress, latches `fault` and coasts.
    fn stop<P: SetDutyCycle, O: OutputPin>(&mut self, bridge: &mut HBridge<P, O>, fault: Fault) {
        if self.mode == Mode::Commissioning {
            self.identification = None;
            self.last_drive_v = 0.0;
            self.commissioned = Commissioned::Aborted(commission::Abort::Fault);
        }
        self.trip(bridge, fault);
    }

    /// Adds the tick's `sample` to the capture's sample `n`, which spans `decimation` ticks
    /// (a boxcar before the decimation, so that a current alternating from tick to tick, as
    /// a sliding-mode current does, is not read at whichever tick the decimation falls
    /// on): the position is its mean over those ticks, the current its root mean square
    /// (the magnet's pull goes with its square) signed as at the last tick, the rest as at
    /// the last tick.
    fn record(&mut self, n: u16, mut sample: Sample) {
        let first = self.capture_count == 0;
        for (sum, v) in self
            .capture_sum
            .iter_mut()
            .zip([sample.x_m, sample.i_a * sample.i_a])
        {
            *sum = if first { v } else { *sum + v };
        }
        self.capture_count = self.capture_count.saturating_add(1);
        if self.capture_count >= self.capture_decimation {
            let ticks = f32::from(self.capture_count);
            let [x_m, i2_a2] = self.capture_sum.map(|sum| sum / ticks);
            sample.x_m = x_m;
            sample.i_a = math::sqrt(i2_a2).copysign(sample.i_a);
            if let Some(slot) = self.capture.as_mut().get_mut(usize::from(n)) {
                *slot = sample;
            }
            let n = n.saturating_add(1);
            self.capture_state = if n >= self.capture_target {
                CaptureState::Done(n)
            } else {
                CaptureState::Running(n)
            };
            self.capture_count = 0;
        }
    }

    fn sample(&self, status: &TickStatus, max_duty: u16) -> Sample {
        let fraction = f32::from(status.drive.duty) / f32::from(max_duty.max(1));
        Sample {
            r_m: status.reference.x_m,
            x_m: status.measurement.x_m,
            v_mps: status.estimate.v_mps,
            i_a: status.measurement.i_a,
            u_v: status.drive.u_v,
            duty: if status.drive.mode == BridgeMode::Reverse {
                -fraction
            } else {
                fraction
            },
            vbus_v: status.measurement.vbus_v,
            analog_m: self.analog_m,
            fault: status.fault.map_or(0, Fault::code),
            mode: self.mode.code(),
        }
    }

    /// What arming would meet now: a sensor, the bus, the analog loop.
    fn not_ready(&self) -> Option<Fault> {
        self.verdict.or(self.analog_fault)
    }

    /// Starts a capture waiting on `trigger`: a move to `to_m` lasting `move_s`, or a probe
    /// about the set point.
    fn start_capture_on(&mut self, trigger: Trigger, to_m: f32, move_s: f32) {
        if self.capture_state == CaptureState::Waiting && self.capture_trigger == trigger {
            self.meta = Meta {
                armed_ticks: self.armed_ticks,
                from_m: self.setpoint_m,
                to_m,
                move_s,
            };
            self.capture_count = 0;
            self.capture_state = CaptureState::Running(0);
        }
    }

    fn apply<P: SetDutyCycle, O: OutputPin>(
        &mut self,
        order: &Order,
        bridge: &mut HBridge<P, O>,
        restore_outputs: &mut bool,
    ) -> Outcome {
        let done = |r: Result<(), Refusal<'static>>| Outcome::Done(r);
        if self.mode == Mode::Commissioning
            && !matches!(
                order,
                Order::Status | Order::Commissioned | Order::Stream { .. } | Order::Capture { .. }
            )
        {
            // Any other order ends a commissioning first (the bridge coasts at once).
            let _ = bridge.coast();
            self.identification = None;
            self.commissioned = Commissioned::Aborted(commission::Abort::Stopped);
            self.mode = Mode::Disarmed;
        }
        match *order {
            Order::Arm => {
                if self.mode.armed() {
                    return done(Ok(()));
                }
                if let Some(f) = self.state.supervisor.latched() {
                    return done(Err(Refusal::Faulted { fault: f.code() }));
                }
                if let Some(f) = self.not_ready() {
                    return done(Err(Refusal::NotReady { fault: f.code() }));
                }
                self.cfg.rearm(&mut self.state);
                let stroke = self.cfg.limits().position_max_m / 1.1;
                self.setpoint_m = math::clamp(self.measurement.x_m, 0.0, stroke);
                if self.analog.source() != SetpointSource::Link {
                    self.setpoint_m = self.analog_state_setpoint();
                }
                self.armed_ticks = 0;
                self.mode = Mode::Armed;
                done(Ok(()))
            }
            Order::Disarm => {
                if self.mode.armed() {
                    let _ = bridge.coast();
                    self.mode = Mode::Disarmed;
                }
                done(Ok(()))
            }
            Order::Move { x_m, time_s } => {
                if !self.mode.armed() {
                    return done(Err(Refusal::NotArmed));
                }
                if self.analog.source() != SetpointSource::Link {
                    return done(Err(Refusal::AnalogSetpoint));
                }
                // Planned here rather than by the next tick, with the tick's own planner
                // and, without a duration, the same arithmetic: the same bits either way.
                let mut move_s = 0.0;
                if let Some(shaping) = self.cfg.shaping() {
                    if x_m != self.state.shaping.target_m || time_s > 0.0 {
                        shaping.retarget(
                            &mut self.state.shaping,
                            self.measurement.x_m,
                            x_m,
                            time_s,
                        );
                        move_s = self.state.shaping.duration_s();
                    }
                }
                self.start_capture_on(Trigger::Move, x_m, move_s);
                self.setpoint_m = x_m;
                done(Ok(()))
            }
            Order::Clear => {
                if self.mode.armed() {
                    return done(Err(Refusal::Armed));
                }
                let Some(latched) = self.state.supervisor.latched() else {
                    return done(Ok(()));
                };
                let cause = if latched == Fault::HardwareTrip && self.break_active {
                    Some(Fault::HardwareTrip)
                } else {
                    self.not_ready()
                };
                if let Some(f) = cause {
                    return done(Err(Refusal::CauseActive { fault: f.code() }));
                }
                self.cfg.rearm(&mut self.state);
                *restore_outputs = latched == Fault::HardwareTrip;
                self.mode = Mode::Disarmed;
                done(Ok(()))
            }
            Order::Stream { decimation } => {
                self.stream = decimation;
                self.stream_count = 0;
                done(Ok(()))
            }
            Order::Capture {
                samples,
                decimation,
                trigger,
            } => {
                let fits = usize::from(samples) <= self.capture.as_ref().len();
                if samples == 0 || decimation == 0 || !fits {
                    return done(Err(Refusal::NoCapture));
                }
                self.capture_target = samples;
                self.capture_decimation = decimation;
                self.capture_count = 0;
                self.capture_trigger = trigger;
                self.meta = Meta {
                    armed_ticks: self.armed_ticks,
                    from_m: self.setpoint_m,
                    to_m: self.setpoint_m,
                    move_s: 0.0,
                };
                self.capture_state = match trigger {
                    Trigger::Now => CaptureState::Running(0),
                    Trigger::Move | Trigger::Probe => CaptureState::Waiting,
                };
                done(Ok(()))
            }
            Order::ReadCapture { offset } => {
                let CaptureState::Done(total) = self.capture_state else {
                    return done(Err(Refusal::NoCapture));
                };
                let mut samples = heapless::Vec::new();
                let from = usize::from(offset);
                let to = usize::from(total).min(from.saturating_add(protocol::CHUNK_SAMPLES));
                for s in self.capture.as_ref().get(from..to).unwrap_or(&[]) {
                    let _ = samples.push(*s);
                }
                Outcome::Chunk(Chunk {
                    offset,
                    total,
                    decimation: self.capture_decimation,
                    armed_ticks: self.meta.armed_ticks,
                    from_m: self.meta.from_m,
                    to_m: self.meta.to_m,
                    move_s: self.meta.move_s,
                    samples,
                })
            }
            Order::Status => Outcome::Status(self.snapshot()),
            Order::Disarmed => done(if self.mode.armed() {
                Err(Refusal::Armed)
            } else {
                Ok(())
            }),
            Order::Install(ref install) => {
                if self.mode.armed() {
                    return done(Err(Refusal::Armed));
                }
                let supervisor = self.state.supervisor;
                self.cfg = install.control;
                self.analog = install.analog;
                self.link = install.link;
                self.state = self.cfg.initial_state();
                self.state.supervisor = supervisor;
                self.analog_state = analog::State::default();
                done(Ok(()))
            }
            Order::Commission(plan) => {
                if self.mode.armed() {
                    return done(Err(Refusal::Armed));
                }
                if let Some(f) = self.state.supervisor.latched() {
                    return done(Err(Refusal::Faulted { fault: f.code() }));
                }
                if let Some(f) = self.not_ready() {
                    return done(Err(Refusal::NotReady { fault: f.code() }));
                }
                self.identification = Some(commission::Identification::new(plan));
                self.last_drive_v = 0.0;
                self.commissioned = Commissioned::Running;
                self.mode = Mode::Commissioning;
                done(Ok(()))
            }
            Order::Commissioned => Outcome::Commissioned(self.commissioned),
            Order::Probe(probe) => {
                if !self.mode.armed() {
                    return done(Err(Refusal::NotArmed));
                }
                self.state.probe = probe;
                self.start_capture_on(Trigger::Probe, self.setpoint_m, 0.0);
                done(Ok(()))
            }
        }
    }

    fn analog_state_setpoint(&self) -> f32 {
        let stroke = self.cfg.limits().position_max_m / 1.1;
        math::clamp(self.analog_m, 0.0, stroke)
    }

    fn snapshot(&self) -> Status<'static> {
        let mut counts = [0u16; FAULT_COUNT];
        for (c, f) in counts.iter_mut().zip(Fault::ALL) {
            *c = self.state.supervisor.count(f);
        }
        Status {
            mode: self.mode,
            fault: self.state.supervisor.latched().map(Fault::code),
            not_ready: self.not_ready().map(Fault::code),
            fault_counts: counts,
            x_m: self.measurement.x_m,
            i_a: self.measurement.i_a,
            vbus_v: self.measurement.vbus_v,
            setpoint_m: self.setpoint_m,
            analog_m: self.analog_m,
            ticks: self.ticks,
            isr_cycles_mean: self.cycles.mean,
            isr_cycles_max: self.cycles.max,
            overruns: self.guarded.overruns(),
            telemetry_dropped: self.dropped,
            capture: self.capture_state,
            capture_capacity: u16::try_from(self.capture.as_ref().len()).unwrap_or(u16::MAX),
            ..Status::default()
        }
    }
}

/// The codes converted and checked as every tick checks them: the measurement (zero when
/// the codes are implausible) and what sense or the limits refuse, if anything.
fn sensed(cfg: &control::Config, frame: &Frame) -> (Measurement, Option<Fault>) {
    match cfg.sense().convert(frame) {
        Ok(m) => (m, cfg.limits().check(&m)),
        Err(f) => (Measurement::default(), Some(f)),
    }
}

/// One commissioning tick: the codes converted and checked as in every tick (a fault
/// latches and coasts), the identification's voltage applied, or the bridge coasted and
/// the result handed out when it ends. Gives the tick's status, the check's verdict
/// (what arming would meet) and the identification's end, if this tick ended it.
fn commission_tick<P: SetDutyCycle, O: OutputPin>(
    cfg: &control::Config,
    id: &mut commission::Identification,
    st: &mut control::State,
    b: &mut HBridge<P, O>,
    frame: &Frame,
    last_drive_v: &mut f32,
) -> (
    TickStatus,
    Option<Fault>,
    Option<Result<commission::Report, commission::Abort>>,
) {
    let (m, verdict) = sensed(cfg, frame);
    let mut status = TickStatus {
        fault: st.supervisor.latched(),
        measurement: m,
        ..TickStatus::default()
    };
    let mut identified = None;
    let applied_v = core::mem::replace(last_drive_v, 0.0);
    let step = match verdict {
        None => id.step(&m, applied_v),
        Some(f) => {
            status.fault = Some(st.supervisor.trip(f));
            commission::Step::Done(Err(commission::Abort::Fault))
        }
    };
    match step {
        commission::Step::Drive(u_v) => {
            match b.apply_clear(u_v, status.measurement.vbus_v, cfg.max_modulation()) {
                Ok(drive) => {
                    status.drive = drive;
                    *last_drive_v = drive.u_v;
                }
                Err(_) => {
                    status.fault = Some(st.supervisor.trip(Fault::BridgeIo));
                    identified = Some(Err(commission::Abort::Fault));
                }
            }
        }
        commission::Step::Done(r) => {
            if b.coast().is_err() {
                status.fault = Some(st.supervisor.trip(Fault::BridgeIo));
            }
            identified = Some(r);
        }
    }
    (status, verdict, identified)
}

/// Reads the stored parameters (the main loop's view of the store).
pub trait Storage {
    /// The stored set, decoded.
    ///
    /// # Errors
    /// Why there is none to use.
    fn load(&mut self) -> Result<Params, LoadError<'static>>;
}

impl<F: embedded_storage::nor_flash::NorFlash> Storage for Store<F> {
    fn load(&mut self) -> Result<Params, LoadError<'static>> {
        Store::load(self)
    }
}

/// What the platform does after the dispatcher has answered (the answer is in the
/// transmit buffer: send it first).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Store these parameters, with the control stopped, and start again
    /// ([`boot`] with the set to save).
    Save(Params),
    /// Start again.
    Restart,
}

/// How the parameters in use were found at start, and the configuration they build.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boot {
    /// The parameters in use.
    pub params: Params,
    /// Where they came from.
    pub source: Source<'static>,
    /// The outcome of the save this start made, if one was requested.
    pub saved: Option<Result<(), StoreError>>,
    /// The configuration they build.
    pub install: Install,
}

/// Starts the application's parameters: stores `save` first when a save was requested
/// before this start, then loads the stored set; a set that is missing, of another
/// format, damaged or invalid on this board gives way to `defaults`, and the source
/// says why.
///
/// # Errors
/// The defaults themselves do not build (a firmware built for an actuator it refuses).
#[inline(never)]
pub fn boot<F: embedded_storage::nor_flash::NorFlash>(
    store: &mut Store<F>,
    defaults: &Params,
    board: &Board,
    save: Option<&Params>,
) -> Result<Boot, crate::control::config::Error> {
    let saved = save.map(|p| store.save(p));
    let stored = store.load().and_then(|p| match p.build(board) {
        Ok(install) => Ok((p, install)),
        Err(e) => Err(LoadError::Invalid(Invalid::from(e))),
    });
    match stored {
        Ok((params, install)) => Ok(Boot {
            params,
            source: Source::Stored,
            saved,
            install,
        }),
        Err(why) => Ok(Boot {
            params: *defaults,
            source: match why {
                LoadError::Empty => Source::Defaults,
                other => Source::Fallback(other),
            },
            saved,
            install: defaults.build(board)?,
        }),
    }
}

/// What the dispatcher does once the interrupt answers.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Then {
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
struct Pending {
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
fn to_front(bytes: &mut [u8], n: usize) {
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

fn refused(name: &str, e: Refused) -> Refusal<'_> {
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
    use super::{to_front, Cycles};

    #[test]
    fn windows_give_mean_and_maxima() {
        let mut c = Cycles::default();
        assert_eq!(c.record(100, 3), None);
        assert_eq!(c.record(300, 3), None);
        let s = c.record(200, 3).unwrap();
        assert_eq!((s.mean, s.window_max, s.max, s.ticks), (200, 300, 300, 3));
        c.record(10, 3);
        c.record(20, 3);
        let s = c.record(30, 3).unwrap();
        // The window maximum restarts, the overall one does not.
        assert_eq!((s.mean, s.window_max, s.max), (20, 30, 300));
    }

    #[test]
    fn a_sum_past_the_counter_saturates_instead_of_wrapping() {
        let mut c = Cycles::default();
        assert_eq!(c.record(u32::MAX - 1, 2), None);
        let s = c.record(10, 2).unwrap();
        // Wrapped, the sum would be 8 and the mean 4.
        assert_eq!((s.mean, s.max), (u32::MAX / 2, u32::MAX - 1));
    }

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
