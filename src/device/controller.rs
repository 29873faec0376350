//! The interrupt's half: the [`Controller`] that runs every tick, its inputs and outputs,
//! and the interrupt's cycle counts.

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

use super::analog::Source as SetpointSource;
use super::guard::{End, Start};
use super::protocol::{CaptureState, Chunk, Commissioned, Mode, Refusal, Sample, Status, Trigger};
use super::{
    analog, commission, guard, liveness, protocol, Answer, Install, IsrEnds, Order, Outcome,
    Telemetered,
};
use crate::control::bridge::{HBridge, Mode as BridgeMode};
use crate::control::math;
use crate::control::sense::{Frame, Measurement};
use crate::control::supervisor::{Fault, FAULT_COUNT};
use crate::control::{self, Status as TickStatus};

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
pub(super) struct Meta {
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
pub(super) fn sensed(cfg: &control::Config, frame: &Frame) -> (Measurement, Option<Fault>) {
    match cfg.sense().convert(frame) {
        Ok(m) => (m, cfg.limits().check(&m)),
        Err(f) => (Measurement::default(), Some(f)),
    }
}

/// One commissioning tick: the codes converted and checked as in every tick (a fault
/// latches and coasts), the identification's voltage applied, or the bridge coasted and
/// the result handed out when it ends. Gives the tick's status, the check's verdict
/// (what arming would meet) and the identification's end, if this tick ended it.
pub(super) fn commission_tick<P: SetDutyCycle, O: OutputPin>(
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
