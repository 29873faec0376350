//! Fault injection: one scenario per fault, the fault the supervisor must name, how fast
//! it does, and how high the coil current gets.
//!
//! Every case runs an actuator's evaluation scenario ([`crate::actuator::scenario`]:
//! converter noise and delay, the sequence across the stroke); [`cases`] places each
//! injection on that scenario's own timing. Each must be detected within 1 ms, with the
//! expected code, after the injection, the current never above the trip level (the
//! actuator's peak current), and the bridge coasting from then on.
//!
//! Most faults are injected while holding. A frozen sensor reading, though, looks exactly
//! like a steady state until the quantity must change, so those two are injected where it
//! must: the position sensor at the fastest point of the long move up (a reading that
//! stays within its noise band for 0.7 ms while a fast reference moves is stuck), the
//! current sensor where the current changes fastest. Frozen in a steady phase, a current
//! reading is found only once the loop has wound up against it.
//!
//! Two cases exercise the firmware's guard ([`ema::guard`]) and window watchdog
//! ([`crate::hal::Watchdog`]): four missed interrupts are seen by the guard when the
//! interrupt runs again (the gap is five periods), and an interrupt that stops for good,
//! while the coil is driven, is ended by the watchdog, which coasts the bridge at the first
//! sample instant at least its early-wakeup time (292.6 us at 20 kHz) after the last feed.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ema::bridge::Mode;
use ema::supervisor::Fault;

use crate::error::Error;
use crate::plant::Surface;
use crate::scenario::{Injected, TruePlant};
use crate::{run, Scenario};

/// Detection deadline \[s\] (20 ticks at 20 kHz).
pub const DEADLINE_S: f64 = 1e-3;

/// One fault-injection case.
#[derive(Clone, Debug)]
pub struct Case {
    /// Short name.
    pub name: &'static str,
    /// What is injected, in words.
    pub what: &'static str,
    /// The scenario (its injection included).
    pub scenario: Scenario,
    /// Injection time \[s\].
    pub at_s: f64,
    /// The fault the supervisor must latch.
    pub expected: Fault,
}

/// What a case did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// Case name.
    pub name: String,
    /// What is injected.
    pub what: String,
    /// Expected fault.
    pub expected: String,
    /// Latched fault, if any.
    pub fault: Option<String>,
    /// Time from the injection to the first sample with the fault latched \[s\]
    /// (negative: a fault latched before the injection, which fails the case).
    pub detected_after_s: Option<f64>,
    /// Largest coil current over the run, also between samples \[A\].
    pub peak_current_a: f64,
    /// Trip level \[A\].
    pub trip_a: f64,
    /// The bridge coasted at every sample after the detection.
    pub coasting: bool,
}

impl Outcome {
    /// `true` when the expected fault latched within the deadline, the current stayed
    /// under the trip level and the bridge coasted after.
    #[must_use]
    pub fn pass(&self) -> bool {
        self.fault.as_deref() == Some(self.expected.as_str())
            && self
                .detected_after_s
                .is_some_and(|t| (0.0..=DEADLINE_S).contains(&t))
            && self.peak_current_a <= self.trip_a
            && self.coasting
    }
}

/// The cases on an actuator's evaluation scenario `base` (a [`crate::actuator::scenario`]:
/// rest at the open stop, then 1/8, 7/8, 3/8 and 3/4 of the stroke, one segment each).
///
/// Injection instants follow the scenario's own timing: "holding" is 10 % of a segment
/// before the last move, settled at 3/8 of the stroke, where the holding current is the
/// largest of the sequence; "moving" is the fastest point of the long move up (the middle
/// of its planned quintic); "ramping" is where the current changes most from one sample to
/// the next during that move, on a healthy run (a reading frozen at rest, near 0 A, is
/// indistinguishable from an open coil; one frozen while the current holds still carries
/// no information until the loop winds up against it). Each
/// run ends 20 ms after its injection. The current-offset step is 12 % of the current
/// channel's full scale (2 A on the reference board's +-16.5 A), the shorted coil keeps an
/// eighth of its resistance.
///
/// # Errors
/// A `base` whose reference is not a sequence of at least three steps.
pub fn cases(base: &Scenario) -> Result<Vec<Case>, Error> {
    let crate::Reference::Sequence { initial_m, steps } = &base.reference else {
        return Err(Error::param(
            "reference",
            f64::NAN,
            "fault injection needs an actuator's evaluation sequence",
        ));
    };
    let (Some(first), Some(last)) = (steps.first(), steps.get(2)) else {
        return Err(Error::param(
            "reference.steps",
            f64::NAN,
            "fault injection needs at least three steps",
        ));
    };
    let rate_hz = base.rate_hz();
    let tick = |t: f64| (t * rate_hz).round() / rate_hz;
    let segment_s = first.at_s;
    let holding = tick(last.at_s - 0.1 * segment_s);
    let moving = tick(first.at_s + 0.5 * planned_move_s(&base.controller, *initial_m, first.to_m));
    // Where the current must change most: the steepest sample-to-sample change of the
    // current over the long move up, on a healthy run.
    let move_s = planned_move_s(&base.controller, *initial_m, first.to_m);
    let healthy = crate::run(&base.clone().with_duration_s(first.at_s + move_s))?;
    let ramping = healthy
        .samples
        .windows(2)
        .filter(|w| w[0].t_s >= first.at_s)
        .max_by(|a, b| {
            (a[1].i_a - a[0].i_a)
                .abs()
                .total_cmp(&(b[1].i_a - b[0].i_a).abs())
        })
        .map_or(first.at_s, |w| w[0].t_s);
    let supply_v = base.supply.voltage_v;
    let full_scale_a = f64::from(base.controller.sense.current.scale.abs()) * 2048.0;
    let r_ohm = f64::from(base.controller.plant.resistance_ohm);
    let case = |name, what, at_s: f64, fault: Injected, expected| Case {
        name,
        what,
        scenario: base
            .clone()
            .with_duration_s(at_s + 0.02)
            .with_fault(at_s, fault),
        at_s,
        expected,
    };
    let mut out = vec![
        case(
            "position sensor open",
            "output at 0 V",
            holding,
            Injected::PositionOpen,
            Fault::PositionSensor,
        ),
        case(
            "position sensor shorted",
            "output at its supply",
            holding,
            Injected::PositionShorted,
            Fault::PositionSensor,
        ),
        case(
            "position sensor stuck",
            "output frozen mid-move",
            moving,
            Injected::PositionStuck,
            Fault::PositionStuck,
        ),
        case(
            "current sensor stuck",
            "output frozen where the current changes fastest",
            ramping,
            Injected::CurrentStuck,
            Fault::CurrentStuck,
        ),
        case(
            "current sensor offset",
            "zero steps by 12 % of full scale",
            holding,
            Injected::CurrentOffset {
                offset_a: 0.12 * full_scale_a,
            },
            Fault::CurrentOffset,
        ),
        case(
            "coil open",
            "circuit opens while holding",
            holding,
            Injected::CoilOpen,
            Fault::CoilOpen,
        ),
        case(
            "coil short",
            "R drops to 1/8",
            holding,
            Injected::CoilShort {
                resistance_ohm: r_ohm / 8.0,
            },
            Fault::CoilShort,
        ),
        case(
            "supply sag",
            "source at 50 %",
            holding,
            Injected::Supply {
                voltage_v: 0.5 * supply_v,
            },
            Fault::BusUnderVoltage,
        ),
        case(
            "supply over-voltage",
            "source at 140 %",
            holding,
            Injected::Supply {
                voltage_v: 1.4 * supply_v,
            },
            Fault::BusOverVoltage,
        ),
        case(
            "missed deadlines",
            "4 interrupts do not run",
            holding,
            Injected::MissedDeadlines { ticks: 4 },
            Fault::Overrun,
        ),
        case(
            "tick stops",
            "the interrupt stops in the start-up ramp",
            ramping,
            Injected::MissedDeadlines { ticks: u32::MAX },
            Fault::Overrun,
        ),
    ];
    // A plant outside the controller's bounds from the start: surfaces at half the lower
    // bound (a smaller pole than designed for: 2.5 times less inductance, a weaker
    // magnet). The coil answers the start-up voltage far faster than any coil in the
    // bounds. (Surfaces 60 % above the upper bound are controlled just as well, but their
    // slower answer stays inside the noise allowance and nothing is reported.)
    let mut p =
        crate::plant::Params::from_core(&base.controller.plant, crate::plant::ForceModel::Frozen);
    let s = 0.5 * f64::from(base.controller.plant.physical_bounds().s_lo_m2);
    for g in &mut p.gaps {
        *g = Surface::Constant { s_m2: s };
    }
    // The fault is there from power-up, so it is timed from power-up: the coil shows itself
    // as soon as it is driven (the start-up brings the armature to its first position, or
    // the long move up); a detection before the first move is a detection, not a false
    // alarm. The run covers the long move up.
    out.push(Case {
        name: "plant outside the bounds",
        what: "surfaces at half the lower bound, from power-up",
        scenario: base
            .clone()
            .with_duration_s(first.at_s + 0.02)
            .with_plant(TruePlant::Given(p)),
        at_s: 0.0,
        expected: Fault::ModelBounds,
    });
    Ok(out)
}

/// Duration \[s\] of the move the settings' planner makes from `x0_m` to `x1_m` (0.1 s
/// when the settings have no shaping).
#[allow(clippy::cast_possible_truncation)]
fn planned_move_s(settings: &ema::control::Settings, x0_m: f64, x1_m: f64) -> f64 {
    let min_s = settings.shaping.map_or(0.0, |s| s.duration_min_s);
    crate::actuator::planner(settings).map_or(0.1, |p| {
        f64::from(p.duration_s(x0_m as f32, x1_m as f32).max(min_s))
    })
}

/// Runs one case.
///
/// # Errors
/// A scenario that does not validate.
pub fn evaluate(case: &Case) -> Result<Outcome, Error> {
    let r = run(&case.scenario)?;
    let first = r
        .samples
        .iter()
        .position(|s| s.fault.is_some())
        .and_then(|k| r.samples.get(k).map(|s| (k, s)));
    let (fault, detected_after_s, coasting) = match first {
        Some((k, s)) => (
            s.fault,
            Some(s.t_s - case.at_s),
            r.samples.iter().skip(k).all(|s| s.mode == Mode::Coast),
        ),
        None => (None, None, true),
    };
    Ok(Outcome {
        name: case.name.to_owned(),
        what: case.what.to_owned(),
        expected: case.expected.name().to_owned(),
        fault: fault.map(|f| f.name().to_owned()),
        detected_after_s,
        peak_current_a: r.metrics.i_peak_a,
        trip_a: f64::from(case.scenario.controller.limits.current_trip_a),
        coasting,
    })
}

/// Every case on `base`, in parallel.
///
/// # Errors
/// A scenario that does not validate.
pub fn table(base: &Scenario) -> Result<Vec<Outcome>, Error> {
    cases(base)?.par_iter().map(evaluate).collect()
}
