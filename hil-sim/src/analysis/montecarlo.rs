//! Monte Carlo over the uncertainty set: the same scenario with `n` true plants drawn from
//! seeds derived from one seed, run in parallel (rayon), with a progress bar (indicatif, on
//! standard error, drawn only on a terminal). Deterministic given the seed: draw `k` always
//! uses the same plant and the results come back in draw order.
//!
//! [`Options`] widen the draws: converter gain and offset errors drawn per plant from a
//! [`CalibrationClass`] (the controller's calibration is not changed, so the errors are
//! what a production board carries uncorrected), and the plant's tolerances widened beyond
//! the controller's.

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use ema::control::bridge::Mode;

pub use crate::simulation::draw::{Draw, SensorDraw};
use crate::simulation::hal::{sensor_position_error_m, Adc, CalibrationClass};
use crate::simulation::scenario::{Scenario, Sensors, TruePlant, Uncertainty};
use crate::simulation::sim::with_run;
use crate::simulation::targets::{worse, Targets, Worst};
use crate::simulation::Error;

/// How the draws are widened beyond the plant uncertainty set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Draw converter gain and offset errors per plant from this class.
    pub sensor_errors: Option<CalibrationClass>,
    /// Factor on the relative tolerances of resistance, spring, mass and friction (1: the
    /// controller's own set). The pole surfaces stay drawn within the physical bounds.
    pub widen: f64,
}

impl Default for Options {
    /// No converter errors, the design tolerances.
    fn default() -> Self {
        Self {
            sensor_errors: None,
            widen: 1.0,
        }
    }
}

impl Options {
    /// The uncertainty set the plants are drawn from for `scenario`: its own (a drawn
    /// plant's) or the controller's, the tolerances scaled by [`Options::widen`] (kept below 1).
    #[must_use]
    pub fn uncertainty(&self, scenario: &Scenario) -> Uncertainty {
        let mut u = match &scenario.plant {
            TruePlant::Drawn { uncertainty, .. } => *uncertainty,
            _ => Uncertainty::of(&scenario.controller.plant),
        };
        let k = self.widen;
        for v in [
            &mut u.resistance_rel,
            &mut u.spring_rel,
            &mut u.mass_rel,
            &mut u.friction_rel,
        ] {
            *v = (*v * k).min(0.95);
        }
        u
    }

    /// The scenario of draw `index` of a Monte Carlo of `scenario` with seed `seed`: the
    /// drawn plant, the converter's noise seeded by the draw and, with
    /// [`Options::sensor_errors`], its gain and offset errors drawn from a seed derived from
    /// the draw's.
    ///
    /// # Errors
    /// Sensor errors asked for on a scenario without a converter model.
    pub fn scenario(
        &self,
        scenario: &Scenario,
        seed: u64,
        index: usize,
    ) -> Result<(Scenario, Option<Adc>), Error> {
        let seed = draw_seed(seed, index);
        let mut sc = scenario.clone();
        sc.plant = TruePlant::Drawn {
            seed,
            uncertainty: self.uncertainty(scenario),
        };
        let mut drawn = None;
        match &mut sc.sensors {
            Sensors::Adc(adc) => {
                adc.seed = seed;
                if let Some(class) = self.sensor_errors {
                    *adc = class.apply(adc, draw_seed(seed, SENSOR_STREAM));
                    drawn = Some(*adc);
                }
            }
            Sensors::Ideal if self.sensor_errors.is_some() => {
                return Err(Error::param(
                    "sensors",
                    f64::NAN,
                    "converter errors need a converter model (`kind = \"adc\"`)",
                ));
            }
            Sensors::Ideal => {}
        }
        Ok((sc, drawn))
    }
}

/// Index that derives the converter errors' seed from a draw's seed (a stream of its own,
/// apart from the plant's and the noise's).
const SENSOR_STREAM: usize = 0x5E_2502;

/// Seed of draw `index` of a Monte Carlo with seed `seed` (SplitMix64 of both).
#[must_use]
pub fn draw_seed(seed: u64, index: usize) -> u64 {
    let mut z = seed
        .wrapping_add((index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Runs `n` draws of `scenario` with the default uncertainty set (or the scenario's own, when
/// its plant is already [`TruePlant::Drawn`]).
///
/// # Errors
/// An invalid scenario (checked once, before any draw) or, should one occur, the first
/// failing draw.
pub fn montecarlo(scenario: &Scenario, n: usize, seed: u64) -> Result<Vec<Draw>, Error> {
    montecarlo_with(scenario, n, seed, true)
}

/// As [`montecarlo`], with the progress bar on or off.
///
/// # Errors
/// As [`montecarlo`].
pub fn montecarlo_with(
    scenario: &Scenario,
    n: usize,
    seed: u64,
    progress: bool,
) -> Result<Vec<Draw>, Error> {
    montecarlo_opts(scenario, n, seed, progress, &Options::default())
}

/// As [`montecarlo_with`], the draws widened by `options`.
///
/// # Errors
/// As [`montecarlo`]; sensor errors asked for on a scenario without a converter model.
pub fn montecarlo_opts(
    scenario: &Scenario,
    n: usize,
    seed: u64,
    progress: bool,
    options: &Options,
) -> Result<Vec<Draw>, Error> {
    scenario.validate()?;
    scenario.controller.build()?;
    let bar = if progress {
        ProgressBar::new(n as u64)
    } else {
        ProgressBar::hidden()
    };
    if let Ok(style) =
        ProgressStyle::with_template("{prefix} {bar:40} {pos}/{len} draws, {elapsed} (eta {eta})")
    {
        bar.set_style(style);
    }
    bar.set_prefix(scenario.name.clone());
    let out = draws(scenario, 0..n, seed, &bar, options);
    bar.finish_and_clear();
    out
}

/// Draws of a set that a candidate must pass in full, run [`UNTIL_MISS_CHUNK`] at a time:
/// the first `n` draws of [`montecarlo_with`], or those up to the end of the first chunk
/// in which a draw misses a target of `targets`. A set that passes is the same as
/// [`montecarlo_with`]'s; one that misses stops, at a fraction of the runs.
///
/// # Errors
/// As [`montecarlo`].
pub fn montecarlo_until_miss(
    scenario: &Scenario,
    n: usize,
    seed: u64,
    targets: &Targets,
) -> Result<Vec<Draw>, Error> {
    scenario.validate()?;
    scenario.controller.build()?;
    let bar = ProgressBar::hidden();
    let mut out = Vec::with_capacity(n);
    for start in (0..n).step_by(UNTIL_MISS_CHUNK) {
        let chunk = draws(
            scenario,
            start..n.min(start + UNTIL_MISS_CHUNK),
            seed,
            &bar,
            &Options::default(),
        )?;
        let missed = !Worst::of_draws(&chunk, targets).misses(targets).is_empty();
        out.extend(chunk);
        if missed {
            break;
        }
    }
    Ok(out)
}

/// Draws [`montecarlo_until_miss`] runs at a time: a fixed number, so that where it
/// stops does not depend on the machine's threads; a few per core keeps both busy.
pub const UNTIL_MISS_CHUNK: usize = 16;

/// Draws `indices` of `scenario` from `seed`, widened by `options`, in parallel.
fn draws(
    scenario: &Scenario,
    indices: std::ops::Range<usize>,
    seed: u64,
    bar: &ProgressBar,
    options: &Options,
) -> Result<Vec<Draw>, Error> {
    let cal = scenario.controller.sense.position;
    indices
        .into_par_iter()
        .map(|index| {
            let (sc, adc) = options.scenario(scenario, seed, index)?;
            let r = with_run(&sc, |r| {
                let coasting_after_fault = r
                    .samples
                    .iter()
                    .skip_while(|s| s.fault.is_none())
                    .all(|s| s.mode == Mode::Coast);
                let sensor = adc.map(|adc| {
                    let segs = &r.metrics.segments;
                    let share_m = |to_m: f64| sensor_position_error_m(&cal, &adc.position, to_m);
                    SensorDraw {
                        adc,
                        steady_error_pct: segs
                            .iter()
                            .map(|s| 100.0 * share_m(s.spec.to_m) / s.spec.to_m.abs())
                            .collect(),
                        controller_overshoot_pct: segs
                            .iter()
                            .map(|s| {
                                let step = s.spec.to_m - s.spec.from_m;
                                if step == 0.0 {
                                    return 0.0;
                                }
                                let end = s.spec.to_m + share_m(s.spec.to_m);
                                r.samples
                                    .iter()
                                    .filter(|p| p.t_s >= s.spec.start_s && p.t_s < s.spec.end_s)
                                    .map(|p| 100.0 * (p.x_m - end) * step.signum() / step.abs())
                                    .fold(0.0, worse)
                            })
                            .collect(),
                    }
                });
                Draw {
                    index,
                    seed: draw_seed(seed, index),
                    plant: r.plant.clone(),
                    metrics: r.metrics.clone(),
                    coasting_after_fault,
                    sensor,
                }
            });
            bar.inc(1);
            r
        })
        .collect::<Result<Vec<_>, _>>()
}
