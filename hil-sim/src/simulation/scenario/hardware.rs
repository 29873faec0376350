//! The hardware around the controller: the true plant, sensors, bridge and the integrator.

use serde::{Deserialize, Serialize};

use super::Uncertainty;
use crate::simulation::hal::Adc;
use crate::simulation::plant::{ForceModel, Params};

/// The true plant of a scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TruePlant {
    /// Exactly the controller's nominal plant (its `f32` values widened), with a force
    /// model.
    Nominal {
        /// Force model.
        #[serde(default)]
        force: ForceModel,
    },
    /// Given explicitly.
    Given(Params),
    /// Drawn from the uncertainty set around the controller's nominal plant
    /// ([`Uncertainty::draw`]) with a PCG64 generator seeded by `seed`.
    Drawn {
        /// Seed of the draw.
        seed: u64,
        /// The uncertainty set.
        #[serde(default)]
        uncertainty: Uncertainty,
    },
}

impl TruePlant {
    /// The plant parameters this describes for a controller whose nominal plant is
    /// `nominal`.
    #[must_use]
    pub fn resolve(&self, nominal: &ema::control::model::Plant) -> Params {
        match self {
            TruePlant::Nominal { force } => Params::from_core(nominal, *force),
            TruePlant::Given(p) => p.clone(),
            TruePlant::Drawn { seed, uncertainty } => {
                use rand::SeedableRng;
                let mut rng = rand_pcg::Pcg64::seed_from_u64(*seed);
                uncertainty.draw(nominal, &mut rng)
            }
        }
    }
}

/// How the sampled measurement reaches the tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Sensors {
    /// Exact values at the sample instant, rounded to `f32`, through
    /// `Config::tick_measured` (no converter, no delay). The default in scenario files.
    #[default]
    Ideal,
    /// Raw codes from the converter model through `Config::tick`.
    Adc(Adc),
}

/// How the bridge's output reaches the coil.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BridgeMode {
    /// The coil sees the period average, `duty x Vbus` in the pins' direction.
    #[default]
    Averaged,
    /// The coil sees the pulses of a centre-aligned PWM at the ISR rate: off for
    /// `(1 - d) T / 2`, on (`+-Vbus`) for `d T`, off for `(1 - d) T / 2`; the samples fall in
    /// the middle of the off-time, where the current equals its period average to first order.
    Switching,
}

/// The power stage. Every field has a default in scenario files ([`Bridge::default`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Bridge {
    /// Averaged or switching-level.
    pub mode: BridgeMode,
    /// PWM full-scale compare value (4201 at 20 kHz: half a period of a 168 MHz timer, plus
    /// one for 100 %).
    pub max_duty: u16,
    /// Forward drop of one freewheeling diode \[V\].
    pub diode_drop_v: f64,
    /// The board's over-current comparator on the break input: at this `|i|` the bridge
    /// switches off within the substep, without the tick, and stays off; the next tick
    /// latches `hardware_trip` \[A\]. `None`: no comparator (the paper's setting). An
    /// actuator's scenario has [`ema::control::actuator::Actuator::break_current_a`].
    pub break_current_a: Option<f32>,
}

impl Default for Bridge {
    /// Averaged, the firmware's PWM resolution at 20 kHz (4201 counts,
    /// [`crate::simulation::actuator::pwm_full_scale`]), 0.7 V diodes.
    fn default() -> Self {
        Self {
            mode: BridgeMode::Averaged,
            max_duty: crate::simulation::hal::pwm_full_scale(20e3),
            diode_drop_v: 0.7,
            break_current_a: None,
        }
    }
}

/// Integration settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Integration {
    /// RK4 substeps per ISR period. In the switching-level model each PWM phase gets
    /// `ceil(substeps x its share of the period)` (at least one), so no substep is longer
    /// than `T / substeps` and every substep sees a constant bridge state.
    pub substeps: u32,
}

/// Longest RK4 substep [`Integration::for_rate`] allows \[s\].
pub const MAX_SUBSTEP_S: f64 = 5.0e-6;

impl Integration {
    /// Enough substeps that none is longer than [`MAX_SUBSTEP_S`] (10 at 20 kHz, 1 at
    /// 1 MHz).
    #[must_use]
    pub fn for_rate(rate_hz: f64) -> Self {
        let n = (1.0 / (rate_hz * MAX_SUBSTEP_S)).ceil();
        // Bounded to [1, 1e6] before the cast.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let substeps = if n.is_finite() {
            n.clamp(1.0, 1e6) as u32
        } else {
            1
        };
        Self { substeps }
    }
}
