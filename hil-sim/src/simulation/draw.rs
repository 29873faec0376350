//! One Monte Carlo draw: the drawn plant, its metrics and, when drawn, its converter's
//! errors. Judged against the targets ([`crate::simulation::targets`]); drawn by
//! [`crate::analysis::montecarlo::montecarlo()`].

use serde::{Deserialize, Serialize};

use crate::simulation::hal::Adc;
use crate::simulation::metrics::Metrics;
use crate::simulation::plant::Params;

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
    /// The bridge coasted at every sample from the first latched fault on (`true` without a
    /// fault).
    #[serde(default = "yes")]
    pub coasting_after_fault: bool,
    /// The converter errors drawn for this plant, with
    /// [`Options::sensor_errors`](crate::analysis::montecarlo::Options::sensor_errors).
    #[serde(default)]
    pub sensor: Option<SensorDraw>,
}

fn yes() -> bool {
    true
}

/// The converter errors of one draw and what they alone do to the position.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorDraw {
    /// The converter with the drawn errors.
    pub adc: Adc,
    /// Per segment of the run, the sensor's share of the steady error at the segment's
    /// reference
    /// ([`sensor_position_error_m`](crate::simulation::hal::sensor_position_error_m))
    /// \[% of the reference\]: what no controller acting on this reading can remove.
    pub steady_error_pct: Vec<f64>,
    /// Per segment, the overshoot on the true position past the end the sensor's share
    /// shifts the armature to: the controller's part of the overshoot \[% of the step;
    /// 0 for a segment without a step\].
    pub controller_overshoot_pct: Vec<f64>,
}
