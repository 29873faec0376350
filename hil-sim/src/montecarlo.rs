//! Monte Carlo over the uncertainty set: the same scenario with `n` true plants drawn from
//! seeds derived from one seed, run in parallel (rayon), with a progress bar (indicatif, on
//! standard error, drawn only on a terminal). Deterministic given the seed: draw `k` always
//! uses the same plant and the results come back in draw order.

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::metrics::Metrics;
use crate::plant::Params;
use crate::scenario::{Scenario, TruePlant, Uncertainty};
use crate::sim::run;
use crate::Error;

/// One Monte Carlo draw.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Draw {
    /// Index of the draw, `0..n`.
    pub index: usize,
    /// Seed of the plant draw (and of the converter noise, when the scenario has one).
    pub seed: u64,
    /// The drawn true plant.
    pub plant: Params,
    /// Its metrics.
    pub metrics: Metrics,
}

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
    scenario.validate()?;
    scenario.controller.build()?;
    let uncertainty = match &scenario.plant {
        TruePlant::Drawn { uncertainty, .. } => *uncertainty,
        _ => Uncertainty::of(&scenario.controller.plant),
    };
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
    let out = (0..n)
        .into_par_iter()
        .map(|index| {
            let seed = draw_seed(seed, index);
            let mut sc = scenario.clone();
            sc.plant = TruePlant::Drawn { seed, uncertainty };
            if let crate::scenario::Sensors::Adc(adc) = &mut sc.sensors {
                adc.seed = seed;
            }
            let r = run(&sc).map(|r| Draw {
                index,
                seed,
                plant: r.plant,
                metrics: r.metrics,
            });
            bar.inc(1);
            r
        })
        .collect::<Result<Vec<_>, _>>();
    bar.finish_and_clear();
    out
}
