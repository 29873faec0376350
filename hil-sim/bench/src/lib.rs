//! # bench: a board on a bench, and the virtual board
//!
//! The host tool for a board running the `ema` firmware (the `bench` binary of this
//! package, [`cli`]), its serial link ([`link`]), and the virtual board it is tested
//! against ([`board`], on a simulated flash, [`flash`]).
//!
//! The virtual board is the firmware's own application ([`ema::device`]: the same state
//! machine, commands, parameter store and tick) run against the simulated actuator of
//! `hil-sim` ([`hil_sim::simulation`]) on a pseudo-terminal, so that the tool is exercised
//! through its real serial path without a board.
//!
//! The messages, the framing and the board's application are the core's
//! ([`ema::device::protocol`], [`ema::device`]): the host tool, the virtual board and the
//! firmware share one definition. A capture is judged with the simulator's own metrics
//! ([`hil_sim::simulation::metrics`]) against the simulator's prediction for the board's
//! parameters ([`prediction`]); `commission` fits what it measures with `hil-sim`'s
//! identification library ([`hil_sim::identification::commissioning`]) and tunes it with
//! `hil-sim tune`.
//!
//! This package depends on `hil-sim`; nothing in `hil-sim` depends on it.
//!
//! ## Operate a board
//!
//! The host tool is the `bench` binary of this package; it talks to a serial port given by
//! `--port` (or `EMA_PORT`). Without a board, start the virtual board: it runs the
//! board's application ([`ema::device`], the same state machine, commands, parameter
//! store and tick) against the simulated actuator, on a pseudo-terminal, so the tool uses
//! its real serial path.
//!
//! ```text
//! cargo build --release -p bench
//! B=target/release/bench
//! $B virtual --link /tmp/ema-board &        # prints the pseudo-terminal; stdin: stimuli
//! export EMA_PORT=/tmp/ema-board
//! $B status                                 # disarmed after every start, where the parameters came from
//! $B console <<'END'                        # one link, kept alive between the lines
//! arm
//! move 3 --time-s 0.05
//! capture 2 --out out/capture
//! watch --signals x_m,i_a --seconds 2
//! disarm
//! END
//! $B set tuning.margin 0.6                  # disarmed only; refused values name field and value
//! $B save                                   # stored in flash; the board restarts to write it
//! $B restart && $B get tuning.margin        # kept
//! $B clear                                  # after a fault, disarmed, once its cause is gone
//! $B backup params.toml && $B restore params.toml   # every parameter, across a firmware update
//! ```
//!
//! **The link.** The tool starts each process at a random sequence number with the port's
//! input flushed, pairs every reply with its request by number, and keeps a heartbeat
//! going while it runs ([`link`]): an armed board stays armed for as long as the tool
//! talks to it and disarms `link.timeout_s` after it stops ([`ema::device::liveness`]). The
//! single-command `arm` and `move` therefore leave the board armed only for that long;
//! `console` runs a whole session over one link and disarms at the end of its input.
//!
//! On the virtual board's standard input, one stimulus ([`board::Stimulus`]) per line: `supply V` (the
//! supply's voltage), `position-open`, `position-ok`, `analog-v V`, `analog-ma MA`,
//! `cut-save STEP` (the power goes at that step of the next save), `resistance OHM`,
//! `surfaces SCALE` and `spring N_PER_M PRELOAD_N` (an actuator off its file, to
//! commission), `hang-main` and `run-main` (the main loop hangs: the board coasts, latches
//! `main_loop_stalled` and restarts). `virtual --speed 0` runs as fast as it can (the
//! tests do), with the link's timeout off: its ticks outrun a heartbeat paced in real
//! time.
//!
//! What the tests hold the board to: `tests/bench.rs` (a whole session over a
//! pseudo-terminal: arm, move, capture with the simulator's metrics, a supply fault by
//! name, clear, a set while armed refused, save and restart kept, power cuts during saves;
//! a silent host in real time, a hung main loop, two megabytes of noise with nobody
//! reading, a backup restored on a fresh board, the console),
//! `tests/power_cut.rs` (a power cut at every single step of a save leaves the old or the
//! new set), `tests/frames.rs` (a million random and mutated frames; a noisy line at the
//! link's rate).

#![deny(missing_docs)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod board;
pub mod cli;
pub mod flash;
pub mod link;

use ema::control::supervisor::Fault;
use ema::device::params::Params;
use ema::device::protocol::{Chunk, Invalid, LoadError, Reason, Refusal, Sample, Source};
use hil_sim::simulation::metrics::{self, Metrics};
use hil_sim::simulation::scenario::{Initial, Reference};
use hil_sim::simulation::sim::{self, Run};
use hil_sim::{Error, Scenario};

/// A fault code by name (`over_current (code 6)`), or the bare code if unknown.
#[must_use]
pub fn fault_name(code: u8) -> String {
    Fault::from_code(code).map_or_else(|| format!("unknown fault code {code}"), |f| f.to_string())
}

/// A refusal, in words.
#[must_use]
pub fn refusal(r: &Refusal<'_>) -> String {
    match r {
        Refusal::Armed => "the board is armed: disarm it first".into(),
        Refusal::NotArmed => "the board is not armed".into(),
        Refusal::Faulted { fault } => {
            format!("fault {} is latched: clear it first", fault_name(*fault))
        }
        Refusal::NotReady { fault } => {
            format!("arming now would latch {}", fault_name(*fault))
        }
        Refusal::CauseActive { fault } => {
            format!(
                "the cause of the fault is still there: {}",
                fault_name(*fault)
            )
        }
        Refusal::UnknownParam { name } => format!("no parameter is called `{name}`"),
        Refusal::ReadOnly { name, why } => format!("`{name}` cannot be changed here: {why}"),
        Refusal::WrongKind { name } => format!("`{name}` takes another kind of value"),
        Refusal::Invalid(i) => i.to_string(),
        Refusal::AnalogSetpoint => {
            "the set point comes from the analog input (setpoint.source)".into()
        }
        Refusal::CaptureRunning => "a capture is running".into(),
        Refusal::NoCapture => "no finished capture".into(),
        Refusal::Load(e) => format!("the stored parameters cannot be used: {}", load_error(e)),
    }
}

/// Why a stored set was not used, in words.
#[must_use]
pub fn load_error(e: &LoadError<'_>) -> String {
    match e {
        LoadError::Empty => "nothing stored".into(),
        LoadError::Version { found, expected } => {
            format!("stored by format {found}, this firmware reads {expected}")
        }
        LoadError::Crc => "the stored set's CRC does not match".into(),
        LoadError::Decode => "the stored set does not decode".into(),
        LoadError::Invalid(i) => format!("the stored set is refused: {i}"),
        LoadError::Store(s) => format!("the flash store failed: {}", board::store_error(*s)),
    }
}

/// Where the parameters came from, in words.
#[must_use]
pub fn source(s: &Source<'_>) -> String {
    match s {
        Source::Defaults => "built-in defaults (nothing stored)".into(),
        Source::Fallback(e) => format!("built-in defaults, because {}", load_error(e)),
        Source::Stored => "stored set".into(),
    }
}

/// A source whose text outlives its frame (the names are leaked: a host tool reads one
/// start announcement or status per request).
#[must_use]
pub fn owned_source(s: &Source<'_>) -> Source<'static> {
    let leak = |t: &str| -> &'static str { Box::leak(t.to_owned().into_boxed_str()) };
    match s {
        Source::Defaults => Source::Defaults,
        Source::Stored => Source::Stored,
        Source::Fallback(e) => Source::Fallback(match e {
            LoadError::Invalid(i) => LoadError::Invalid(Invalid {
                param: leak(i.param),
                value: i.value,
                reason: match i.reason {
                    Reason::NotBelow { other, limit } => Reason::NotBelow {
                        other: leak(other),
                        limit,
                    },
                    Reason::NotAbove { other, limit } => Reason::NotAbove {
                        other: leak(other),
                        limit,
                    },
                    Reason::Derived { what, derived } => Reason::Derived {
                        what: leak(what),
                        derived,
                    },
                    Reason::NotFinite => Reason::NotFinite,
                    Reason::NotPositive => Reason::NotPositive,
                    Reason::BelowMin { min } => Reason::BelowMin { min },
                    Reason::AboveMax { max } => Reason::AboveMax { max },
                    Reason::Theorem1 {
                        a,
                        b,
                        det_q,
                        alpha2_min,
                    } => Reason::Theorem1 {
                        a,
                        b,
                        det_q,
                        alpha2_min,
                    },
                },
            }),
            LoadError::Empty => LoadError::Empty,
            LoadError::Version { found, expected } => LoadError::Version {
                found: *found,
                expected: *expected,
            },
            LoadError::Crc => LoadError::Crc,
            LoadError::Decode => LoadError::Decode,
            LoadError::Store(s) => LoadError::Store(*s),
        }),
    }
}

/// A finished capture, read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Capture {
    /// Ticks per sample.
    pub decimation: u16,
    /// Ticks the board had been armed when it started.
    pub armed_ticks: u32,
    /// Set point before \[m\].
    pub from_m: f32,
    /// Set point after \[m\].
    pub to_m: f32,
    /// The planned move's duration \[s\] (0 for a step or no move).
    pub move_s: f32,
    /// The samples.
    pub samples: Vec<Sample>,
}

impl Capture {
    /// From its first chunk's header and every chunk's samples.
    #[must_use]
    pub fn from_chunks(chunks: &[Chunk]) -> Option<Self> {
        let first = chunks.first()?;
        Some(Self {
            decimation: first.decimation,
            armed_ticks: first.armed_ticks,
            from_m: first.from_m,
            to_m: first.to_m,
            move_s: first.move_s,
            samples: chunks
                .iter()
                .flat_map(|c| c.samples.iter().copied())
                .collect(),
        })
    }

    /// Time of sample `k` from the move \[s\]: the middle of its ticks, over which its
    /// position and current are averaged.
    #[must_use]
    pub fn t_s(&self, k: usize, rate_hz: f64) -> f64 {
        let d = f64::from(self.decimation.max(1));
        (k as f64 * d + 0.5 * (d - 1.0)) / rate_hz
    }
}

/// Longest hold before the move that a prediction simulates \[s\].
pub const MAX_HOLD_S: f64 = 1.0;

/// The simulator's prediction of a capture: the virtual board's scenario for `params`
/// (nominal plant, the converter model, `noise` or not), at rest, armed holding the set
/// point before the move for as long as the board was (at most [`MAX_HOLD_S`]), then the
/// move as a step of the set point, which the controller's own reference shaping turns into
/// the move the board planned; as many ticks after it as the capture spans.
///
/// From rest at the open end stop (a set point within one position code of it), this is
/// exactly what the virtual board ran: the same ticks on the same plant, bit for bit.
///
/// # Errors
/// Parameters whose settings do not derive; the run's own errors.
pub fn prediction(
    params: &Params,
    capture: &Capture,
    noise: bool,
) -> Result<(Scenario, Run), Error> {
    let mut sc = hil_sim::simulation::board::scenario(&params.actuator, noise)?;
    let rate = sc.rate_hz();
    let ts = 1.0 / rate;
    let hold_ticks = f64::from(capture.armed_ticks).min((MAX_HOLD_S * rate).round());
    let from = f64::from(capture.from_m);
    let code_m = f64::from(sc.controller.sense.position.scale.abs());
    sc.initial = if from.abs() <= code_m {
        Initial::default()
    } else {
        Initial {
            x_m: from,
            v_mps: 0.0,
            i_a: 0.0,
        }
    };
    let at_s = hold_ticks * ts;
    sc.reference = Reference::Step {
        from_m: from,
        to_m: f64::from(capture.to_m),
        at_s,
    };
    let span = capture.samples.len() as f64 * f64::from(capture.decimation);
    sc.duration_s = (hold_ticks + span) * ts;
    sc.name = "prediction".into();
    sc.probes_s.clear();
    let run = sim::run(&sc)?;
    Ok((sc, run))
}

/// A trace of what a board measures, in the simulator's trace type, so that the
/// simulator's metrics apply to a capture and to a prediction alike: position and current
/// as measured, the bridge's voltage, one sample every `decimation` ticks.
fn measured(t_s: f64, r_m: f64, s: &Sample) -> sim::Sample {
    let u = f64::from(s.u_v);
    sim::Sample {
        t_s,
        r_m,
        x_m: f64::from(s.x_m),
        i_a: f64::from(s.i_a),
        i_abs_max_a: f64::from(s.i_a).abs(),
        u_abs_max_v: u.abs(),
        u_rms_v: u.abs(),
        u_cmd_v: u,
        vbus_v: f64::from(s.vbus_v),
        fault: Fault::from_code(s.fault),
        ..sim::Sample::default()
    }
}

/// The capture as the simulator's trace type, on the prediction's clock (`at_s` is the
/// move's time there).
#[must_use]
pub fn capture_trace(capture: &Capture, at_s: f64, rate_hz: f64) -> Vec<sim::Sample> {
    capture
        .samples
        .iter()
        .enumerate()
        .map(|(k, s)| measured(at_s + capture.t_s(k, rate_hz), f64::from(capture.to_m), s))
        .collect()
}

/// The prediction decimated as the capture is, as the board would have measured it: each
/// sample's position the mean over its ticks, its current their root mean square signed
/// as at the last (summed, divided and rooted in `f32` as the board does), the rest as at
/// its last tick.
#[must_use]
pub fn prediction_samples(run: &Run, capture: &Capture, at_s: f64, rate_hz: f64) -> Vec<Sample> {
    let start = (at_s * rate_hz).round() as usize;
    let ticks_per_sample = capture.decimation.max(1);
    let d = usize::from(ticks_per_sample);
    (0..capture.samples.len())
        .filter_map(|k| {
            let ticks = run.samples.get(start + k * d..start + (k + 1) * d)?;
            let last = ticks.last()?;
            let mean = |f: &dyn Fn(&sim::Sample) -> f32| {
                let sum = ticks.iter().fold(None, |sum: Option<f32>, p| {
                    Some(sum.map_or(f(p), |s| s + f(p)))
                });
                sum.unwrap_or(0.0) / f32::from(ticks_per_sample)
            };
            let i_last = last.i_meas_a as f32;
            Some(Sample {
                r_m: last.r_shaped_m as f32,
                x_m: mean(&|p| p.x_meas_m as f32),
                v_mps: last.v_est_mps as f32,
                i_a: ema::control::math::sqrt(mean(&|p| {
                    let i = p.i_meas_a as f32;
                    i * i
                }))
                .copysign(i_last),
                u_v: last.u_drive_v as f32,
                duty: 0.0,
                vbus_v: last.vbus_v as f32,
                analog_m: 0.0,
                fault: last.fault.map_or(0, Fault::code),
                mode: 0,
            })
        })
        .collect()
}

/// The simulator's metrics of a capture (`scenario` gives the move and the steady window).
#[must_use]
pub fn capture_metrics(scenario: &Scenario, capture: &Capture) -> Metrics {
    let at_s = match scenario.reference {
        Reference::Step { at_s, .. } => at_s,
        _ => 0.0,
    };
    let trace = capture_trace(capture, at_s, scenario.rate_hz());
    // A capture says nothing about the plant's bounds; the field is not reported.
    let bounds = hil_sim::simulation::metrics::BoundsCheck {
        mu_lo_ratio_min: f64::NAN,
        mu_lo_worst_x_m: f64::NAN,
        mu_hi_ratio_max: f64::NAN,
        mu_hi_worst_x_m: f64::NAN,
        l_lo_ratio_min: f64::NAN,
        l_hi_ratio_max: f64::NAN,
        brackets: true,
        warning: None,
    };
    metrics::compute(scenario, bounds, &trace, &[])
}

/// The same metrics of the prediction, on the same decimated, measured samples.
#[must_use]
pub fn prediction_metrics(scenario: &Scenario, run: &Run, capture: &Capture) -> Metrics {
    let at_s = match scenario.reference {
        Reference::Step { at_s, .. } => at_s,
        _ => 0.0,
    };
    let rate = scenario.rate_hz();
    let samples = prediction_samples(run, capture, at_s, rate);
    let predicted = Capture {
        samples,
        ..capture.clone()
    };
    capture_metrics(scenario, &predicted)
}
