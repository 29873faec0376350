//! Fault injection: one scenario per fault, the fault the supervisor must name,
//! how fast it does, and how high the coil current gets.
//!
//! Every case runs the product's realistic default ([`Scenario::product`]: 20 kHz, 24 V,
//! converter noise and delay) on the paper's step from 1 mm to 3 mm. Each must be
//! detected within 1 ms (20 ticks), with the expected code, the current never above the
//! trip level (limit + 10 %, 13.2 A), and the bridge coasting from then on.
//!
//! Most faults are injected while holding at 3 mm. A frozen sensor reading, though, looks
//! exactly like a steady state until the quantity must change, so those two are injected
//! where it must: the position sensor at the fastest point of a 3 mm move (the step
//! sequence's 0.5 -> 3.5 mm: the reference moves 51 um per ms there; a reading that stays
//! within its noise band for 0.7 ms while a fast reference moves 21 um is stuck), the current sensor
//! during the start-up current ramp (the current rises by about 0.5 A per tick). Frozen in a steady phase, the current reading
//! is found once the loop has wound up against it: measured 3.1 ms after a freeze in the
//! middle of the move, where the current only changes by milliamperes per tick.
//!
//! Two cases exercise the firmware's guard ([`ema::guard`]) and window watchdog
//! ([`crate::hal::Watchdog`]): four missed interrupts are seen by the guard when the
//! interrupt runs again (the gap is five periods), and an interrupt that stops for good,
//! while the start-up ramp drives the coil, is ended by the watchdog, which coasts the
//! bridge at the first sample instant at least its early-wakeup time (292.6 us at 20 kHz)
//! after the last feed.

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
    /// Time from the injection to the first sample with the fault latched \[s\].
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
            && self.detected_after_s.is_some_and(|t| t <= DEADLINE_S)
            && self.peak_current_a <= self.trip_a
            && self.coasting
    }
}

/// The cases, at `rate_hz` on a `supply_v` supply.
#[must_use]
pub fn cases(rate_hz: f64, supply_v: f64) -> Vec<Case> {
    let base = || Scenario::product(rate_hz, supply_v).with_duration_s(0.3);
    // Fastest point of the sequence's 0.5 -> 3.5 mm move, which starts at 0.3 s: the middle
    // of the planned quintic (about 0.1 s long).
    let moving = ((0.3 + 0.5 * planned_move_s(rate_hz, supply_v, 0.5e-3, 3.5e-3)) * rate_hz)
        .round()
        / rate_hz;
    // One tick into the start-up current ramp (half of the rise still to come).
    let ramping = 1.0 / rate_hz;
    let holding = 0.2;
    let case = |name, what, at_s, fault: Injected, expected| Case {
        name,
        what,
        scenario: base().with_fault(at_s, fault),
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
            "current sensor stuck",
            "output frozen in the start-up ramp",
            ramping,
            Injected::CurrentStuck,
            Fault::CurrentStuck,
        ),
        case(
            "current sensor offset",
            "zero steps by +2 A",
            holding,
            Injected::CurrentOffset { offset_a: 2.0 },
            Fault::CurrentOffset,
        ),
        case(
            "coil open",
            "circuit opens while holding 6 A",
            holding,
            Injected::CoilOpen,
            Fault::CoilOpen,
        ),
        case(
            "coil short",
            "R drops to 0.05 ohm",
            holding,
            Injected::CoilShort {
                resistance_ohm: 0.05,
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
            "source at 150 %",
            holding,
            Injected::Supply {
                voltage_v: 1.5 * supply_v,
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
    out.insert(
        2,
        Case {
            name: "position sensor stuck",
            what: "output frozen mid-move",
            scenario: Scenario::product(rate_hz, supply_v)
                .with_sequence()
                .with_fault(moving, Injected::PositionStuck),
            at_s: moving,
            expected: Fault::PositionStuck,
        },
    );
    // A plant outside the controller's bounds from the start: surfaces at half the lower
    // bound (a smaller pole than designed for: 2.5 times less inductance, a weaker
    // magnet). The coil answers the start-up voltage far faster than any coil in the
    // bounds. (Surfaces 60 % above the upper bound are controlled just as well, but their
    // slower answer stays inside the noise allowance and nothing is reported.)
    let mut outside = base();
    let mut p = crate::plant::Params::from_core(
        &outside.controller.plant,
        crate::plant::ForceModel::Frozen,
    );
    let s = 0.5 * f64::from(outside.controller.plant.bounds.s_lo_m2);
    for g in &mut p.gaps {
        *g = Surface::Constant { s_m2: s };
    }
    outside = outside.with_plant(TruePlant::Given(p));
    out.push(Case {
        name: "plant outside the bounds",
        what: "surfaces at half the lower bound",
        scenario: outside,
        at_s: 0.0,
        expected: Fault::ModelBounds,
    });
    out
}

/// Duration \[s\] of the move the product's planner makes from `x0_m` to `x1_m` (0.1 s
/// when the settings have no shaping).
#[allow(clippy::cast_possible_truncation)]
fn planned_move_s(rate_hz: f64, supply_v: f64, x0_m: f32, x1_m: f32) -> f64 {
    let settings = Scenario::product(rate_hz, supply_v).controller;
    let min_s = settings.shaping.map_or(0.0, |s| s.duration_min_s);
    settings
        .build()
        .ok()
        .and_then(|c| {
            c.shaping()
                .map(|p| f64::from(p.duration_s(x0_m, x1_m).max(min_s)))
        })
        .unwrap_or(0.1)
}

/// Runs one case.
///
/// # Errors
/// A scenario that does not validate.
pub fn evaluate(case: &Case) -> Result<Outcome, Error> {
    let r = run(&case.scenario)?;
    let first = r
        .trace
        .iter()
        .position(|s| s.fault.is_some())
        .and_then(|k| r.trace.get(k).map(|s| (k, s)));
    let (fault, detected_after_s, coasting) = match first {
        Some((k, s)) => (
            s.fault,
            Some(s.t_s - case.at_s),
            r.trace.iter().skip(k).all(|s| s.mode == Mode::Coast),
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

/// Every case, in parallel.
///
/// # Errors
/// A scenario that does not validate.
pub fn table(rate_hz: f64, supply_v: f64) -> Result<Vec<Outcome>, Error> {
    cases(rate_hz, supply_v).par_iter().map(evaluate).collect()
}
