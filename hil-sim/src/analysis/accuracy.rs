//! How many RK4 substeps per ISR period a scenario needs, measured rather than assumed.
//!
//! The scenario runs once closed loop with RK4 steps of [`REFERENCE_STEP_S`] (1 us); its
//! bridge commands and its true states at every sample are recorded. A substep count is
//! then judged period by period: from the reference's state at the start of each period,
//! the plant alone is advanced over that period under that period's command with the
//! substeps in question, and compared with the reference's state at the end of it. The
//! error is the largest `|x - x_ref|` of one period relative to the stroke, and the largest
//! `|i - i_ref|` relative to the reference run's peak current.
//!
//! Why one period at a time, and not the whole run replayed open loop: the closed loop is
//! what keeps a reluctance actuator where it is. In the physical convention, where the
//! magnet holds the armature near the closed stop its stiffness exceeds the spring's (at
//! 3 mm on the product's actuator, the magnet's -2F/g is several times the 120 N/m
//! spring; on the coil's time scale, 0.9 ms there, the voltage drive acts as a current
//! drive), so the plant without its controller diverges there at about 60 rad/s: a replay
//! under recorded commands amplifies any difference, down to the last bit of rounding,
//! whatever the step (test `an_open_loop_replay_of_the_physical_plant_drifts_whatever_the_step`:
//! 1e-14 of the stroke grows to 0.22 over the product's sequence). That is what once
//! reported a replay "within 0.25 of the stroke" for a step size whose closed-loop metrics
//! agreed with a 1 us solution to three digits. The error made within each period is what
//! the integrator contributes; the closed loop forgets it within its own time constant
//! (`1/alpha`, some hundred periods), so the trajectory's error stays within a few hundred
//! times the one-period error, which [`TOLERANCE_REL`] bounds.

use crate::simulation::hal::Switches;
use crate::simulation::scenario::{BridgeMode, Scenario, Sensors};
use crate::simulation::sim::{run, Stepper};
use crate::simulation::Error;

/// RK4 step of the reference solution \[s\].
pub const REFERENCE_STEP_S: f64 = 1e-6;

/// Largest error of one period accepted by [`fewest_substeps`], relative to the stroke
/// and to the peak current \[-\].
pub const TOLERANCE_REL: f64 = 1e-6;

/// RK4 substeps per period of the benchmark loop ([`bench_scenario`]) at 20 kHz: the
/// fewest within [`TOLERANCE_REL`] of the 1 us solution over one period (test
/// `the_bench_substep_count_is_the_fewest_within_tolerance_of_a_1_us_solution`).
pub const BENCH_SUBSTEPS: u32 = 3;

/// The benchmark loop: `Scenario::product(20e3, 24.0)` (the practical law, averaged
/// bridge, 24 V) with ideal sensors so that the trajectory is deterministic and smooth,
/// 0.5 s, [`BENCH_SUBSTEPS`] substeps per period.
///
/// # Errors
/// None today: the product's settings always derive.
pub fn bench_scenario() -> Result<Scenario, Error> {
    Ok(Scenario::product(20_000.0, 24.0)?
        .with_sensors(Sensors::Ideal)
        .with_duration_s(0.5)
        .with_substeps(BENCH_SUBSTEPS))
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

/// The reference run of a scenario, ready to be compared with.
#[derive(Clone, Debug)]
pub struct Reference {
    scenario: Scenario,
    drives: Vec<Switches>,
    samples: Vec<crate::simulation::sim::Sample>,
    peak_a: f64,
    stroke_m: f64,
}

/// Substeps that make every RK4 step at most [`REFERENCE_STEP_S`] long at `rate_hz`.
#[must_use]
pub fn reference_substeps(rate_hz: f64) -> u32 {
    let n = (1.0 / (rate_hz * REFERENCE_STEP_S)).round();
    // Bounded to [1, 1e6] before the cast.
    #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let n = if n.is_finite() {
        n.clamp(1.0, 1e6) as u32
    } else {
        1
    };
    n
}

impl Reference {
    /// Runs `scenario` closed loop with 1 us RK4 steps and records its bridge commands and
    /// true states.
    ///
    /// # Errors
    /// An invalid scenario, by name.
    pub fn new(scenario: &Scenario) -> Result<Self, Error> {
        let sc = scenario
            .clone()
            .with_substeps(reference_substeps(scenario.rate_hz()));
        let r = run(&sc)?;
        let drives = r
            .samples
            .iter()
            .map(|s| Switches::from_mode(s.mode, s.duty, sc.bridge.max_duty))
            .collect();
        Ok(Self {
            peak_a: r.metrics.i_peak_a,
            stroke_m: r.plant.stroke_m,
            scenario: sc,
            drives,
            samples: r.samples,
        })
    }

    /// Advances every period alone from the reference's state with `substeps` per period
    /// and compares with the reference's next state.
    ///
    /// # Errors
    /// A substep count of zero.
    pub fn accuracy(&self, substeps: u32) -> Result<Accuracy, Error> {
        let sc = &self.scenario;
        let plant = sc.plant.resolve(&sc.controller.plant);
        let mut st = Stepper::for_scenario(sc, plant, substeps)?;
        let (mut dx, mut di) = (0.0_f64, 0.0_f64);
        for (k, ((d, now), next)) in self
            .drives
            .iter()
            .zip(&self.samples)
            .zip(self.samples.iter().skip(1))
            .enumerate()
        {
            st.resync(k as u64, now);
            st.advance(*d, sc.bridge.mode);
            let end = st.sample();
            dx = dx.max((end.x_m - next.x_m).abs());
            di = di.max((end.i_a - next.i_a).abs());
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
