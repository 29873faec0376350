//! The comparison of the laws: the paper's law, its boundary-layer variant and the
//! practical law, at 10, 20 and 50 kHz and on 24, 48 and 150 V supplies, all on the
//! product's actuator in the physical convention and under the same realistic conditions
//! ([`Scenario::product`]: converter noise and delay, supply resistance, averaged bridge,
//! nominal plant, the paper's step from 1 to 3 mm), judged by the product's targets
//! ([`Targets::for_scenario`]).
//!
//! Each law runs with its own defaults: the paper-family laws with the paper's gains and
//! no reference shaping (`Settings::paper`, told about the one-sample delay), the practical
//! law with `Settings::practical`. So that the paper-family laws show what they do rather
//! than stop at the first sample, their current channel covers +-120 A, their current
//! trip is 100 A and the board's over-current comparator is left out; the practical law
//! keeps the product's 16.5 A channel, 13.2 A trip and 15.84 A comparator.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ema::control::law;
use ema::control::Settings;

use crate::simulation::hal;
use crate::simulation::scenario::Scenario;
use crate::simulation::sim::run;
use crate::simulation::targets::{Targets, Worst};
use crate::simulation::Error;

/// The laws compared: every law of the core.
pub const LAWS: [&str; 3] = ema::control::law::NAMES;
/// The ISR rates \[Hz\].
pub const RATES_HZ: [f64; 3] = [10e3, 20e3, 50e3];
/// The supplies \[V\].
pub const SUPPLIES_V: [f64; 3] = [24.0, 48.0, 150.0];

/// One cell of the comparison.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// Law name.
    pub law: String,
    /// ISR rate \[Hz\].
    pub rate_hz: f64,
    /// Supply \[V\].
    pub supply_v: f64,
    /// The worst of each metric over the run.
    pub worst: Worst,
    /// The first latched fault, by name.
    pub fault: Option<String>,
    /// Targets missed (empty: pass).
    pub misses: Vec<String>,
}

impl Row {
    /// `true` when every target holds.
    #[must_use]
    pub fn pass(&self) -> bool {
        self.misses.is_empty()
    }
}

/// The scenario of one cell.
///
/// # Errors
/// An unknown law name.
#[expect(clippy::cast_possible_truncation)]
pub fn scenario(law_name: &str, rate_hz: f64, supply_v: f64) -> Result<Scenario, Error> {
    let mut sc = Scenario::product(rate_hz, supply_v)?;
    sc.name = format!("{law_name}-{}khz-{supply_v}v", rate_hz / 1e3);
    let product_plant = sc.controller.plant;
    let paper_family = |law: law::Settings| {
        let mut s = Settings::paper(rate_hz as f32, supply_v as f32);
        // The product's actuator, in the physical convention, for every law.
        s.plant = product_plant;
        s.law = law;
        s.delay_ticks = 1;
        s.sense = hal::calibration(1.5 * supply_v, 120.0);
        s.limits.current_trip_a = 100.0;
        s
    };
    if law_name != "practical" {
        sc.bridge.break_current_a = None;
    }
    sc.controller = match law_name {
        "paper" => paper_family(law::Settings::Paper(law::paper::Gains::paper())),
        "boundary_layer" => paper_family(law::Settings::BoundaryLayer(law::paper::Gains::paper())),
        "practical" => sc.controller,
        other => {
            return Err(Error::param(
                "law",
                f64::NAN,
                format!("unknown law {other:?}, expected one of {LAWS:?}"),
            ))
        }
    };
    Ok(sc)
}

/// Runs the whole grid (in parallel).
///
/// # Errors
/// A scenario that does not validate.
pub fn grid(duration_s: f64) -> Result<Vec<Row>, Error> {
    let cells: Vec<(&str, f64, f64)> = LAWS
        .iter()
        .flat_map(|l| {
            RATES_HZ
                .iter()
                .flat_map(move |r| SUPPLIES_V.iter().map(move |v| (*l, *r, *v)))
        })
        .collect();
    cells
        .par_iter()
        .map(|&(law_name, rate_hz, supply_v)| {
            let sc = scenario(law_name, rate_hz, supply_v)?.with_duration_s(duration_s);
            let r = run(&sc)?;
            let targets = Targets::for_scenario(&sc);
            let worst = Worst::of([&r.metrics], &targets);
            let misses = worst
                .misses(&targets)
                .into_iter()
                .map(str::to_owned)
                .collect();
            Ok(Row {
                law: law_name.to_owned(),
                rate_hz,
                supply_v,
                worst,
                fault: r
                    .metrics
                    .first_fault
                    .and_then(|f| f.fault)
                    .map(|f| f.name().to_owned()),
                misses,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_practical_law_passes_at_firmware_rates() {
        // One cell per law at 20 kHz and 24 V (the whole grid is the `compare` command).
        for (law_name, pass) in [
            ("paper", false),
            ("boundary_layer", false),
            ("practical", true),
        ] {
            let sc = scenario(law_name, 20e3, 24.0).unwrap().with_duration_s(0.4);
            let t = Targets::for_scenario(&sc);
            let w = Worst::of([&run(&sc).unwrap().metrics], &t);
            let misses = w.misses(&t);
            assert_eq!(misses.is_empty(), pass, "{law_name}: {misses:?} {w:?}");
        }
    }

    #[test]
    fn unknown_laws_are_named() {
        let e = scenario("pid", 20e3, 24.0).unwrap_err();
        assert!(e.to_string().contains("pid"), "{e}");
    }
}
