//! Out-of-sample judgement: actuators nobody tuned anything on ([`crate::analysis::drawn`]), each
//! tuned by [`crate::analysis::tune`] as a user would (its own rate, 20 kHz and a neighbour; the
//! default validation), then judged on plants and faults it was not tuned on.
//!
//! For each drawn actuator:
//!
//! - **tune**: the gains chosen, or the refusal (the target missed, where, by how much);
//! - **Monte Carlo**: the tuned actuator's evaluation sequence on plants drawn from its
//!   uncertainty set with a seed apart from the validation's ([`crate::analysis::seeds`]);
//!   it passes when at most [`MISS_SHARE`] of the draws miss a target (a latched fault is a
//!   miss);
//! - **faults**: the fixed-instant fault cases of [`crate::analysis::faults`], each passing
//!   when the expected fault is named within the deadline, the current stays under the trip
//!   and the bridge coasts.
//!
//! An actuator passes when all three do. A refusal is a failure of the product (the
//! generator keeps only actuators a user could have), not of the actuator.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::analysis::drawn::Drawn;
use crate::analysis::report::sig;
use crate::analysis::tune::{Refusal, Space};
use crate::analysis::{faults, montecarlo};
use crate::simulation::targets::{failing, Targets};
use crate::simulation::{actuator, Error};

/// Largest share of the Monte Carlo draws that may miss a target: one in a thousand.
pub const MISS_SHARE: f64 = 1e-3;

/// What one drawn actuator did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// Its name (`drawn-<seed>-<index>`).
    pub name: String,
    /// Its magnetic circuit's kind.
    pub circuit: String,
    /// Moving mass \[kg\].
    pub mass_kg: f64,
    /// Stroke \[m\].
    pub stroke_m: f64,
    /// Coil time constant at the closed stop \[s\].
    pub coil_s: f64,
    /// Its own interrupt rate \[Hz\].
    pub rate_hz: f64,
    /// The gains chosen (`alpha` \[1/s\], observer \[rad/s\], margin), or why none.
    pub tune: Result<Gains, Refusal>,
    /// Wall-clock seconds the tuning took (printed, never written to a results file).
    pub tune_s: f64,
    /// The Monte Carlo of the tuned actuator (`None`: not tuned).
    pub montecarlo: Option<MonteCarlo>,
    /// The fault cases of the tuned actuator (`None`: not tuned).
    pub faults: Option<Faults>,
}

/// The gains `tune` chose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Gains {
    /// `alpha1 = alpha2` \[1/s\].
    pub alpha: f64,
    /// Observer bandwidth \[rad/s\].
    pub observer_rad_s: f64,
    /// Shaping margin \[-\].
    pub margin: f64,
}

/// A Monte Carlo's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MonteCarlo {
    /// Plants drawn.
    pub draws: usize,
    /// Draws that miss a target.
    pub missing: usize,
    /// Of those, draws where a fault latched.
    pub faulted: usize,
    /// The targets missed, each with the number of draws that miss it.
    pub misses: Vec<(String, usize)>,
}

impl MonteCarlo {
    /// At most [`MISS_SHARE`] of the draws miss a target.
    #[must_use]
    pub fn pass(&self) -> bool {
        #[expect(clippy::cast_precision_loss)]
        let share = self.missing as f64 / self.draws.max(1) as f64;
        share <= MISS_SHARE
    }
}

/// The fault cases' outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Faults {
    /// Cases run.
    pub cases: usize,
    /// The cases that failed, each as `case: fault latched, microseconds after the
    /// injection` (or `none`), with the peak current when it passed the trip and whether
    /// the bridge did not coast.
    pub failed: Vec<String>,
}

impl Verdict {
    /// Tuned, and both the Monte Carlo and the fault cases pass.
    #[must_use]
    pub fn pass(&self) -> bool {
        self.tune.is_ok()
            && self.montecarlo.as_ref().is_some_and(MonteCarlo::pass)
            && self.faults.as_ref().is_some_and(|f| f.failed.is_empty())
    }
}

/// Tunes drawn actuator `d` and judges it on `plants` plants of seed `plant_seed`.
///
/// # Errors
/// A run that fails (a defect: a drawn actuator meets every rule the settings check).
pub fn judge(d: &Drawn, plants: usize, plant_seed: u64) -> Result<Verdict, Error> {
    let act = &d.actuator;
    let name = d.name();
    let own = f64::from(act.board.rate_hz);
    let rates = crate::analysis::tune::default_rates(own);
    let rate_min = rates.iter().copied().fold(f64::INFINITY, f64::min);
    let space = Space::for_actuator(act, rate_min)?;
    let started = Instant::now();
    let report = crate::analysis::tune::tune(
        &name,
        act,
        &rates,
        &space,
        1,
        crate::analysis::tune::DEFAULT_VALIDATE,
    )?;
    let tune_s = started.elapsed().as_secs_f64();
    let scales = act.time_scales().map_err(Error::Actuator)?;
    let Some(tune) = report.refusal.clone().map(Err).or_else(|| {
        report.chosen.as_ref().map(|c| {
            Ok(Gains {
                alpha: c.candidate.alpha,
                observer_rad_s: c.candidate.observer_rad_s,
                margin: c.candidate.margin,
            })
        })
    }) else {
        return Err(Error::param("tune", 0.0, "neither chose nor refused"));
    };
    let mut v = Verdict {
        name: name.clone(),
        circuit: d.circuit.to_owned(),
        mass_kg: f64::from(act.mechanics.mass_kg),
        stroke_m: f64::from(act.mechanics.stroke_m),
        coil_s: f64::from(scales.coil_closed_s),
        rate_hz: own,
        tune,
        tune_s,
        montecarlo: None,
        faults: None,
    };
    let Some(tuned) = &report.tuned else {
        return Ok(v);
    };
    let sc = actuator::scenario(&name, tuned)?;
    let t = Targets::for_scenario(&sc);
    let draws = montecarlo::montecarlo_with(&sc, plants, plant_seed, false)?;
    let missing = failing(&draws, &t);
    let mut misses: Vec<(String, usize)> = Vec::new();
    for (_, what) in &missing {
        for w in what {
            crate::analysis::report::tally(&mut misses, (*w).to_owned());
        }
    }
    v.montecarlo = Some(MonteCarlo {
        draws: draws.len(),
        missing: missing.len(),
        faulted: draws
            .iter()
            .filter(|d| d.metrics.first_fault.is_some())
            .count(),
        misses,
    });
    let cases = faults::table(&sc)?;
    v.faults = Some(Faults {
        cases: cases.len(),
        failed: cases
            .iter()
            .filter(|o| !o.pass())
            .map(|o| {
                let named = match (&o.fault, o.detected_after_s) {
                    (Some(f), Some(t)) => format!("{f} {} us", sig(t * 1e6, 3)),
                    _ => "none".into(),
                };
                let peak = if o.peak_current_a > o.trip_a {
                    format!(
                        ", peak {} A over the {} A trip",
                        sig(o.peak_current_a, 3),
                        sig(o.trip_a, 3)
                    )
                } else {
                    String::new()
                };
                let coast = if o.coasting { "" } else { ", not coasting" };
                format!("{}: {named}{peak}{coast}", o.name)
            })
            .collect(),
    });
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One draw in a thousand may miss a target, two may not.
    #[test]
    fn the_monte_carlo_passes_at_one_miss_in_a_thousand() {
        let mc = |missing| MonteCarlo {
            draws: 1000,
            missing,
            faulted: 0,
            misses: Vec::new(),
        };
        assert!(mc(1).pass());
        assert!(!mc(2).pass());
        assert!(MonteCarlo { draws: 50, ..mc(0) }.pass());
        assert!(!MonteCarlo { draws: 50, ..mc(1) }.pass());
    }
}
