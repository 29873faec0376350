//! The true plant's initial state and how far it is drawn from the controller's model.

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::simulation::plant::{ForceModel, Params, Surface};
use crate::simulation::Error;

/// Initial state of the true plant.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Initial {
    /// Position \[m\].
    pub x_m: f64,
    /// Velocity \[m/s\].
    #[serde(default)]
    pub v_mps: f64,
    /// Coil current \[A\].
    #[serde(default)]
    pub i_a: f64,
}

/// The uncertainty set plants are drawn from (all draws uniform). A field left out of a
/// scenario file takes its value from [`Uncertainty::default`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Uncertainty {
    /// Relative tolerance of the coil resistance (`0.2` = +-20 %) \[-\].
    pub resistance_rel: f64,
    /// Relative tolerance of the spring constant and, drawn on its own, of the preload \[-\].
    pub spring_rel: f64,
    /// Relative tolerance of the moving mass \[-\].
    pub mass_rel: f64,
    /// Relative tolerance of the viscous friction \[-\].
    pub friction_rel: f64,
    /// Probability that a drawn plant uses the energy-consistent force model (else the
    /// paper's frozen one) \[-\].
    pub energy_consistent_probability: f64,
    /// Probability that a gap's surface grows with the gap (square pole with fringing,
    /// `S(g) = (a + k g)^2`) rather than being constant \[-\].
    pub rectangular_probability: f64,
}

impl Default for Uncertainty {
    /// R +-20 %, K +-10 %, m +-10 %, lambda +-50 %, both force models and both surface
    /// models equally likely.
    fn default() -> Self {
        Self {
            resistance_rel: 0.2,
            spring_rel: 0.1,
            mass_rel: 0.1,
            friction_rel: 0.5,
            energy_consistent_probability: 0.5,
            rectangular_probability: 0.5,
        }
    }
}

/// Relative margin kept inside the controller's surface bounds when drawing, so that `f32`
/// rounding in the controller's envelope never puts a draw outside \[-\].
const DRAW_MARGIN: f64 = 1e-6;

impl Uncertainty {
    /// The controller's own uncertainty set: the tolerances its plant states,
    /// both force models and both surface models equally likely.
    #[must_use]
    pub fn of(plant: &ema::control::model::Plant) -> Self {
        let t = &plant.tolerance;
        Self {
            resistance_rel: f64::from(t.resistance),
            spring_rel: f64::from(t.spring),
            mass_rel: f64::from(t.mass),
            friction_rel: f64::from(t.friction),
            ..Self::default()
        }
    }

    /// Checks the tolerances (in `[0, 1)`) and the probabilities (in `[0, 1]`).
    ///
    /// # Errors
    /// The first bad field, by name.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, v) in [
            ("resistance_rel", self.resistance_rel),
            ("spring_rel", self.spring_rel),
            ("mass_rel", self.mass_rel),
            ("friction_rel", self.friction_rel),
        ] {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return Err(Error::param(
                    format!("plant.uncertainty.{name}"),
                    v,
                    "must be in [0, 1)",
                ));
            }
        }
        for (name, v) in [
            (
                "energy_consistent_probability",
                self.energy_consistent_probability,
            ),
            ("rectangular_probability", self.rectangular_probability),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::param(
                    format!("plant.uncertainty.{name}"),
                    v,
                    "must be in [0, 1]",
                ));
            }
        }
        Ok(())
    }

    /// Draws a true plant around the controller's nominal plant `nominal`: mechanics and
    /// resistance within the relative tolerances, each gap's surface anywhere within the
    /// physical surface bounds `[S_lo, S_hi]` over the whole stroke
    /// (`ema::control::model::Plant::physical_bounds`: the paper's bounds, which the
    /// controller's contain) (constant, or a square pole `(a + k g)^2` whose surface at the
    /// two ends of the gap range is drawn inside the bounds), and the force model.
    ///
    /// Never panics: tolerances and probabilities outside their ranges (see
    /// [`Uncertainty::validate`]) are clamped into them, and degenerate bounds give the
    /// middle surface.
    pub fn draw<R: Rng + ?Sized>(
        &self,
        nominal: &ema::control::model::Plant,
        rng: &mut R,
    ) -> Params {
        let mut p = Params::from_core(nominal, ForceModel::Frozen);
        let physical = nominal.physical_bounds();
        let s_lo = f64::from(physical.s_lo_m2) * (1.0 + DRAW_MARGIN);
        let s_hi = f64::from(physical.s_hi_m2) * (1.0 - DRAW_MARGIN);
        let (s_lo, s_hi) = if s_lo < s_hi {
            (s_lo, s_hi)
        } else {
            let mid = 0.5 * (s_lo + s_hi);
            (mid, mid)
        };
        let probability = |v: f64| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
        let rel = |v: f64| if v.is_nan() { 0.0 } else { v.clamp(0.0, 0.99) };
        let (g_lo, g_hi) = p.gap_range_m();
        for gap in &mut p.gaps {
            let s1 = rng.random_range(s_lo..=s_hi);
            *gap = if rng.random_bool(probability(self.rectangular_probability)) && g_hi > g_lo {
                let s2 = rng.random_range(s1..=s_hi);
                let (r1, r2) = (s1.sqrt(), s2.sqrt());
                let k = (r2 - r1) / (g_hi - g_lo);
                let a = r1 - k * g_lo;
                if a > 0.0 {
                    Surface::Rectangular {
                        a_m: a,
                        b_m: a,
                        spread: k,
                    }
                } else {
                    Surface::Constant { s_m2: s1 }
                }
            } else {
                Surface::Constant { s_m2: s1 }
            };
        }
        let mut vary = |v: f64, r: f64| v * (1.0 + rng.random_range(-rel(r)..=rel(r)));
        p.resistance_ohm = vary(p.resistance_ohm, self.resistance_rel);
        p.spring_n_per_m = vary(p.spring_n_per_m, self.spring_rel);
        p.preload_n = vary(p.preload_n, self.spring_rel);
        p.mass_kg = vary(p.mass_kg, self.mass_rel);
        p.friction_n_s_per_m = vary(p.friction_n_s_per_m, self.friction_rel);
        p.force = if rng.random_bool(probability(self.energy_consistent_probability)) {
            ForceModel::EnergyConsistent
        } else {
            ForceModel::Frozen
        };
        p
    }
}
