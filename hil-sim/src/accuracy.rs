//! How many RK4 substeps per ISR period a scenario needs, measured rather than assumed.
//!
//! The closed loop with an `f32` controller and a sign or quantising element is not a
//! smooth function of the integration error: one flipped `f32` rounding, one different
//! converter code or one sign change moves the next command by a whole step, and the two
//! runs part ways for reasons that have nothing to do with the integrator (the paper's
//! sign law does this at every tick). So the integrator is measured open loop, on the
//! loop's own input: the scenario runs once closed loop with
//! RK4 steps of [`REFERENCE_STEP_S`] (1 us), its bridge commands are recorded, and the
//! plant alone is replayed under those commands with fewer substeps. The error is the
//! largest `|x - x_ref|` over the run relative to the stroke, and the largest
//! `|i - i_ref|` relative to the reference run's peak current.

use crate::hal::Drive;
use crate::scenario::{BridgeMode, Scenario, Sensors};
use crate::sim::{run, Stepper};
use crate::Error;

/// RK4 step of the reference solution \[s\].
pub const REFERENCE_STEP_S: f64 = 1e-6;

/// Largest relative error accepted by [`fewest_substeps`] \[-\].
pub const TOLERANCE_REL: f64 = 1e-4;

/// RK4 substeps per period of the benchmark loop ([`bench_scenario`]) at 20 kHz: the
/// fewest within [`TOLERANCE_REL`] of the 1 us solution (test
/// `the_bench_substep_count_is_the_fewest_within_1e_4_of_a_1_us_solution`: one 50 us step
/// per period is within 5.7e-7 of the peak current and 2.1e-8 of the stroke).
pub const BENCH_SUBSTEPS: u32 = 1;

/// The benchmark loop: `Scenario::product(20e3, 24.0)` (the practical law, averaged
/// bridge, 24 V) with ideal sensors so that the trajectory is deterministic and smooth,
/// 0.5 s, [`BENCH_SUBSTEPS`] substeps per period.
#[must_use]
pub fn bench_scenario() -> Scenario {
    Scenario::product(20_000.0, 24.0)
        .with_sensors(Sensors::Ideal)
        .with_duration_s(0.5)
        .with_substeps(BENCH_SUBSTEPS)
}

/// Integration error of a substep count against the 1 us reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Accuracy {
    /// Substeps per period.
    pub substeps: u32,
    /// `max |x - x_ref| / stroke` \[-\].
    pub position_rel: f64,
    /// `max |i - i_ref| / peak |i_ref|` \[-\].
    pub current_rel: f64,
}

impl Accuracy {
    /// Both errors within `tolerance`.
    #[must_use]
    pub fn within(&self, tolerance: f64) -> bool {
        self.position_rel <= tolerance && self.current_rel <= tolerance
    }
}

/// The reference run of a scenario, ready to be replayed.
#[derive(Clone, Debug)]
pub struct Reference {
    scenario: Scenario,
    drives: Vec<Drive>,
    truth: Vec<(f64, f64)>,
    peak_a: f64,
    stroke_m: f64,
}

/// Substeps that make every RK4 step at most [`REFERENCE_STEP_S`] long at `rate_hz`.
#[must_use]
pub fn reference_substeps(rate_hz: f64) -> u32 {
    let n = (1.0 / (rate_hz * REFERENCE_STEP_S)).round();
    // Bounded to [1, 1e6] before the cast.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let n = if n.is_finite() {
        n.clamp(1.0, 1e6) as u32
    } else {
        1
    };
    n
}

impl Reference {
    /// Runs `scenario` closed loop with 1 us RK4 steps and records its bridge commands.
    ///
    /// # Errors
    /// An invalid scenario, by name.
    pub fn new(scenario: &Scenario) -> Result<Self, Error> {
        let sc = scenario
            .clone()
            .with_substeps(reference_substeps(scenario.rate_hz()));
        let r = run(&sc)?;
        let drives = r
            .trace
            .iter()
            .map(|s| Drive::from_mode(s.mode, s.duty, sc.bridge.max_duty))
            .collect();
        let truth = r.trace.iter().map(|s| (s.x_m, s.i_a)).collect();
        Ok(Self {
            peak_a: r.metrics.i_peak_a,
            stroke_m: r.plant.stroke_m,
            scenario: sc,
            drives,
            truth,
        })
    }

    /// Replays the recorded commands with `substeps` per period and compares.
    ///
    /// # Errors
    /// A substep count of zero.
    pub fn accuracy(&self, substeps: u32) -> Result<Accuracy, Error> {
        let sc = &self.scenario;
        let plant = sc.plant.resolve(&sc.controller.plant);
        let mut st = Stepper::for_scenario(sc, plant, substeps)?;
        let (mut dx, mut di) = (0.0_f64, 0.0_f64);
        for (d, (x_ref, i_ref)) in self.drives.iter().zip(&self.truth) {
            let now = st.sample();
            dx = dx.max((now.x_m - x_ref).abs());
            di = di.max((now.i_a - i_ref).abs());
            st.advance(*d, sc.bridge.mode);
        }
        Ok(Accuracy {
            substeps,
            position_rel: dx / self.stroke_m,
            current_rel: di / self.peak_a.max(f64::MIN_POSITIVE),
        })
    }
}

/// The fewest substeps per period, at most `max`, whose replay stays within `tolerance`
/// of the 1 us reference (`max` itself when none does), with its accuracy. Only the
/// averaged bridge is searched below `max`: the switching-level bridge splits every
/// period at the PWM edges and keeps `max`.
///
/// # Errors
/// An invalid scenario, by name.
pub fn fewest_substeps(scenario: &Scenario, max: u32, tolerance: f64) -> Result<Accuracy, Error> {
    let max = max.max(1);
    let reference = Reference::new(scenario)?;
    if scenario.bridge.mode == BridgeMode::Averaged {
        for n in 1..max {
            let a = reference.accuracy(n)?;
            if a.within(tolerance) {
                return Ok(a);
            }
        }
    }
    reference.accuracy(max)
}
