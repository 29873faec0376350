//! Fault injection: one scenario per fault, the fault the supervisor must name, how fast
//! it does, and how high the coil current gets.
//!
//! Every case runs an actuator's evaluation scenario ([`crate::simulation::actuator::scenario`]:
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
//! Two cases exercise the firmware's guard ([`ema::device::guard`]) and window watchdog
//! ([`crate::simulation::hal::Watchdog`]): four missed interrupts are seen by the guard when the
//! interrupt runs again (the gap is five periods), and an interrupt that stops for good,
//! while the coil is driven, is ended by the watchdog, which coasts the bridge at the first
//! sample instant at least its early-wakeup time (292.6 us at 20 kHz) after the last feed.
//!
//! [`random`] injects each case again at random instants over the sequence, on plants
//! drawn from the controller's uncertainty set, and [`RandomCase`] gathers how they were found
//! and when each fault became observable ([`observable_after_s`]): a reading frozen while
//! nothing moves is what a healthy sensor reads, and no detector can name it then.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ema::control::bridge::Mode;
use ema::control::supervisor::Fault;

use crate::simulation::plant::Surface;
use crate::simulation::scenario::Scenario;
use crate::simulation::scenario::{Injected, Sensors, TruePlant, Uncertainty};
use crate::simulation::sim::with_run;
use crate::simulation::Error;

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
    /// Time from the injection to the first sample at which the fault could be seen
    /// \[s\] (`None`: not within the run): 0 for every fault but a frozen reading, which
    /// is what a healthy sensor could read until the true quantity moves (see
    /// [`observable_after_s`]).
    pub observable_after_s: Option<f64>,
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

/// The cases on an actuator's evaluation scenario `base` (a
/// [`crate::simulation::actuator::scenario`]: rest at the open stop, then 1/8, 7/8, 3/8 and
/// 3/4 of the stroke, one segment each).
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
    let crate::simulation::scenario::Reference::Sequence { initial_m, steps } = &base.reference
    else {
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
    let healthy = crate::simulation::sim::run(&base.clone().with_duration_s(first.at_s + move_s))?;
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
    let mut p = crate::simulation::plant::Params::from_core(
        &base.controller.plant,
        crate::simulation::plant::ForceModel::Frozen,
    );
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
#[expect(clippy::cast_possible_truncation)]
fn planned_move_s(settings: &ema::control::Settings, x0_m: f64, x1_m: f64) -> f64 {
    let min_s = settings.shaping.map_or(0.0, |s| s.duration_min_s);
    crate::simulation::actuator::planner(settings).map_or(0.1, |p| {
        f64::from(p.duration_s(x0_m as f32, x1_m as f32).max(min_s))
    })
}

/// Runs one case.
///
/// # Errors
/// A scenario that does not validate.
pub fn evaluate(case: &Case) -> Result<Outcome, Error> {
    with_run(&case.scenario, |r| {
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
        Outcome {
            name: case.name.to_owned(),
            what: case.what.to_owned(),
            expected: case.expected.name().to_owned(),
            fault: fault.map(|f| f.name().to_owned()),
            detected_after_s,
            peak_current_a: r.metrics.i_peak_a,
            trip_a: f64::from(case.scenario.controller.limits.current_trip_a),
            coasting,
            observable_after_s: observable_after_s(case, r),
        }
    })
}

/// When the fault of `case` became observable in its run `r`, from the injection \[s\].
///
/// A frozen reading (position or current sensor stuck) is, as long as the true quantity
/// stays where it was at the injection, exactly what a healthy sensor could read: it
/// becomes observable at the first sample at which the true position or current has
/// moved from its value at the injection by more than the converter's noise allowance
/// ([`ema::control::actuator::NOISE_ALLOWANCE_CODES`] codes of that channel, four standard
/// deviations of the difference of two readings). No detector can name it before; a
/// frozen reading whose quantity never moves within the run is not observable in it.
/// Every other fault changes what the tick reads, or the coil, at its injection: 0.
#[must_use]
pub fn observable_after_s(case: &Case, r: &crate::simulation::sim::Run) -> Option<f64> {
    let sense = &case.scenario.controller.sense;
    let allowance =
        |scale: f32| f64::from(ema::control::actuator::NOISE_ALLOWANCE_CODES * scale.abs());
    let (quantity, allowance): (fn(&crate::simulation::sim::Sample) -> f64, f64) =
        match case.scenario.faults.first().map(|f| f.fault) {
            Some(Injected::PositionStuck) => (|s| s.x_m, allowance(sense.position.scale)),
            Some(Injected::CurrentStuck) => (|s| s.i_a, allowance(sense.current.scale)),
            _ => return Some(0.0),
        };
    let mut after = r.samples.iter().filter(|s| s.t_s >= case.at_s - 1e-9);
    let at = quantity(after.next()?);
    after
        .find(|s| (quantity(s) - at).abs() > allowance)
        .map(|s| s.t_s - case.at_s)
}

/// Every case on `base`, in parallel.
///
/// # Errors
/// A scenario that does not validate.
pub fn table(base: &Scenario) -> Result<Vec<Outcome>, Error> {
    cases(base)?.par_iter().map(evaluate).collect()
}

/// One case injected at random instants on drawn plants: how it was found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RandomCase {
    /// Case name.
    pub name: String,
    /// Expected fault.
    pub expected: String,
    /// Injections.
    pub n: usize,
    /// Injections whose outcome passes ([`Outcome::pass`]).
    pub pass: usize,
    /// Detection times of the injections named as expected, after the injection, sorted
    /// \[s\].
    pub detected_s: Vec<f64>,
    /// Injections named as expected within [`DEADLINE_S`].
    pub within_deadline: usize,
    /// Injections after which a different fault was latched (after the injection), by
    /// fault name.
    pub misnamed: Vec<(String, usize)>,
    /// Injections after which nothing was latched by the end of the run.
    pub unnamed: usize,
    /// Injections with a fault latched before them (a false alarm on the drawn plant).
    pub before: usize,
    /// Injections after which the bridge did not coast at every sample.
    pub not_coasting: usize,
    /// Injections that became observable within their run ([`observable_after_s`]).
    pub observable: usize,
    /// Of those, the ones named as expected within [`DEADLINE_S`] of becoming observable
    /// (and after the injection).
    pub named_once_observable: usize,
    /// Largest coil current over all the runs \[A\].
    pub peak_current_a: f64,
    /// Trip level \[A\].
    pub trip_a: f64,
}

/// Share of the observable injections a case must name right within [`DEADLINE_S`] of
/// becoming observable, at random instants \[-\].
pub const NAMED_SHARE: f64 = 0.99;
/// Largest share of the injections a case may name as another fault \[-\].
pub const MISNAMED_SHARE: f64 = 0.01;

impl RandomCase {
    /// The targets a case misses at random instants, in words: at least [`NAMED_SHARE`]
    /// of the observable injections named right within the deadline of becoming
    /// observable, at most [`MISNAMED_SHARE`] misnamed, no false alarm before the
    /// injection, the bridge coasting after every detection, the current at or below the
    /// trip.
    #[must_use]
    pub fn misses(&self) -> Vec<&'static str> {
        let mut out = Vec::new();
        #[expect(clippy::cast_precision_loss)]
        let share = |k: usize, of: usize| k as f64 / of.max(1) as f64;
        if share(self.named_once_observable, self.observable) < NAMED_SHARE {
            out.push("named late or not");
        }
        let misnamed: usize = self.misnamed.iter().map(|(_, k)| k).sum();
        if share(misnamed, self.n) > MISNAMED_SHARE {
            out.push("misnamed");
        }
        if self.before > 0 {
            out.push("false alarm");
        }
        if self.not_coasting > 0 {
            out.push("not coasting");
        }
        if self.peak_current_a.is_nan() || self.peak_current_a > self.trip_a {
            out.push("over the trip");
        }
        out
    }

    /// Every target of [`RandomCase::misses`] met.
    #[must_use]
    pub fn pass(&self) -> bool {
        self.misses().is_empty()
    }

    /// The `q` quantile (`0..=1`, nearest rank) of the detection times \[s\].
    #[must_use]
    pub fn quantile_s(&self, q: f64) -> Option<f64> {
        let n = self.detected_s.len();
        if n == 0 {
            return None;
        }
        #[expect(
            clippy::cast_precision_loss,
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss
        )]
        let k = ((q.clamp(0.0, 1.0) * n as f64).ceil() as usize).clamp(1, n);
        self.detected_s.get(k - 1).copied()
    }
}

/// Each case of [`cases`] but the plant outside the bounds (a plant, not an instant)
/// injected `n` times on `base`: injection `k` on the plant drawn from the controller's
/// uncertainty set with seed `crate::analysis::montecarlo::draw_seed(seed, k)` (the converter noise
/// seeded likewise), at an instant on the ISR grid drawn uniformly (from the same seed)
/// between the first move and 20 ms before the sequence ends. The same `n` plants and
/// instants serve every case. Runs in parallel.
///
/// # Errors
/// As [`cases`]; a scenario that does not validate.
pub fn random(base: &Scenario, n: usize, seed: u64) -> Result<Vec<RandomCase>, Error> {
    use rand::{Rng, SeedableRng};
    let all = cases(base)?;
    let crate::simulation::scenario::Reference::Sequence { steps, .. } = &base.reference else {
        return Err(Error::param("reference", f64::NAN, "needs a sequence"));
    };
    let start_s = steps.first().map_or(0.0, |s| s.at_s);
    let end_s = base.duration_s - 0.02;
    let rate_hz = base.rate_hz();
    let uncertainty = Uncertainty::of(&base.controller.plant);
    let draws: Vec<(u64, f64)> = (0..n)
        .map(|k| {
            let seed = crate::analysis::montecarlo::draw_seed(seed, k);
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed ^ 0xFA17);
            let t = rng.random_range(start_s..end_s);
            (seed, (t * rate_hz).round() / rate_hz)
        })
        .collect();
    all.iter()
        .filter(|c| matches!(c.scenario.plant, TruePlant::Nominal { .. }))
        .map(|c| {
            let outcomes = draws
                .par_iter()
                .map(|&(seed, at_s)| {
                    let mut sc = c.scenario.clone().with_duration_s(at_s + 0.02);
                    for f in &mut sc.faults {
                        f.at_s = at_s;
                    }
                    sc.plant = TruePlant::Drawn { seed, uncertainty };
                    if let Sensors::Adc(adc) = &mut sc.sensors {
                        adc.seed = seed;
                    }
                    evaluate(&Case {
                        scenario: sc,
                        at_s,
                        ..c.clone()
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            Ok(random_case(c, &outcomes))
        })
        .collect()
}

fn random_case(c: &Case, outcomes: &[Outcome]) -> RandomCase {
    let expected = c.expected.name();
    let mut s = RandomCase {
        name: c.name.to_owned(),
        expected: expected.to_owned(),
        n: outcomes.len(),
        pass: 0,
        detected_s: Vec::new(),
        within_deadline: 0,
        misnamed: Vec::new(),
        unnamed: 0,
        before: 0,
        not_coasting: 0,
        observable: 0,
        named_once_observable: 0,
        peak_current_a: 0.0,
        trip_a: f64::from(c.scenario.controller.limits.current_trip_a),
    };
    for o in outcomes {
        s.pass += usize::from(o.pass());
        s.peak_current_a = if o.peak_current_a.is_nan() {
            f64::NAN
        } else {
            s.peak_current_a.max(o.peak_current_a)
        };
        s.not_coasting += usize::from(!o.coasting);
        if let Some(seen) = o.observable_after_s {
            s.observable += 1;
            s.named_once_observable += usize::from(
                o.fault.as_deref() == Some(expected)
                    && o.detected_after_s
                        .is_some_and(|t| t >= 0.0 && t <= seen + DEADLINE_S),
            );
        }
        match (&o.fault, o.detected_after_s) {
            (Some(_), Some(t)) if t < 0.0 => s.before += 1,
            (Some(f), Some(t)) if f == expected => {
                s.detected_s.push(t);
                s.within_deadline += usize::from(t <= DEADLINE_S);
            }
            (Some(f), _) => crate::analysis::report::tally(&mut s.misnamed, f.clone()),
            (None, _) => s.unnamed += 1,
        }
    }
    s.detected_s.sort_by(f64::total_cmp);
    s.misnamed.sort();
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A case at random instants passing every target: 99 of 100 observable injections
    /// named in time, 1 of 100 misnamed.
    fn passing() -> RandomCase {
        RandomCase {
            name: "coil short".into(),
            expected: "coil_short".into(),
            n: 100,
            pass: 99,
            detected_s: vec![1e-4; 99],
            within_deadline: 99,
            misnamed: vec![("model_bounds".into(), 1)],
            unnamed: 0,
            before: 0,
            not_coasting: 0,
            observable: 100,
            named_once_observable: 99,
            peak_current_a: 13.2,
            trip_a: 13.2,
        }
    }

    /// Each target of a random-instant row fails on its own, by name, one step past its
    /// limit.
    #[test]
    fn a_random_row_fails_on_each_target_by_name() {
        assert_eq!(passing().misses(), Vec::<&str>::new());
        let late = RandomCase {
            named_once_observable: 98,
            ..passing()
        };
        assert_eq!(late.misses(), ["named late or not"]);
        let misnamed = RandomCase {
            misnamed: vec![("model_bounds".into(), 1), ("current_stuck".into(), 1)],
            ..passing()
        };
        assert_eq!(misnamed.misses(), ["misnamed"]);
        let before = RandomCase {
            before: 1,
            ..passing()
        };
        assert_eq!(before.misses(), ["false alarm"]);
        let coasting = RandomCase {
            not_coasting: 1,
            ..passing()
        };
        assert_eq!(coasting.misses(), ["not coasting"]);
        let over = RandomCase {
            peak_current_a: 13.21,
            ..passing()
        };
        assert_eq!(over.misses(), ["over the trip"]);
        assert!(!over.pass());
    }
}
