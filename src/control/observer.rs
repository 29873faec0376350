//! Velocity (and force-disturbance) observer from the sampled position.
//!
//! Velocity is not measured. A model-based Luenberger observer predicts the motion with the
//! nominal model, driven by the measured coil current, and corrects with the position
//! error `e = y - x_pred`:
//!
//! ```text
//! correct:  x = x_pred + k1 e     v = v_pred + k2 e     d = d_pred + k3 e
//! predict:  a = (mu_nom(g) i^2 / 2 - K x - lambda v) / m + d
//!           x_pred = x + Ts v + Ts^2 a / 2     v_pred = v + Ts a     d_pred = d
//! ```
//!
//! `d` \[m/s^2\] is what the nominal model does not explain (uncertain surfaces, mass,
//! spring, friction); it is estimated only when enabled (`disturbance = true`, a
//! third-order extended-state observer), otherwise `k3 = 0` and `d = 0`.
//!
//! The gains place every pole of the a-priori estimation error at `z = exp(-w Ts)`, where
//! `w` is the bandwidth: with `q = 1 - exp(-w Ts)`,
//! second order `k1 = 2q - q^2`, `k2 = q^2 / Ts`;
//! third order `k1 = 3q - 3q^2 + q^3`, `k2 = (3q^2 - 3q^3/2) / Ts`, `k3 = q^3 / Ts^2`.
//! Because the model carries the known force, the bandwidth only has to cover the model
//! error, which keeps the position noise out of the velocity estimate.
//!
//! ## A disturbance that follows the magnet
//!
//! What the model gets wrong is mostly the magnet: the airgap surfaces are the paper's
//! uncertainty, and a magnet 1.5 times stronger than the design model pulls 1.5 times
//! harder at every current. A constant `d` found while holding then stays behind when a
//! move changes the current: it is still the old excess force, and the loop makes up the
//! difference only at the observer's bandwidth, which shows as overshoot at the end of a
//! move on a strong plant. With `force_scaled_above_a > 0` the predicted disturbance is
//! carried from one sample to the next in proportion to the design model's magnet force,
//!
//! ```text
//! d_pred <- d_pred (F(g, i_now) + F_floor) / (F(g, i_then) + F_floor)
//! ```
//!
//! where `F = mu(g) i^2 / 2` and `F_floor` is the force at `force_scaled_above_a` in the
//! middle of the stroke: far above the floor `d` scales with the force (a magnet-strength
//! error), far below it `d` stays constant (what the spring, the mass and friction leave).
//!
//! The position (estimate and prediction) is kept as an unevaluated pair of `f32`,
//! `x + x_lo`, updated with exact TwoSum additions: at high rates one period of motion is
//! below the resolution of `x` (at 1 MHz and 3 mm, `Ts v` drops out for any
//! `|v| < 0.12 mm/s`), and an observer that rounds it away freezes its velocity estimate
//! anywhere inside that band. The estimate handed out is the rounded `x`.

use crate::control::config::{self, Error};
use crate::control::model::{Dynamics, Plant};

/// Which model of the actuator the observer predicts with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Model {
    /// [`Plant::nominal_dynamics`].
    #[default]
    Nominal,
    /// [`Plant::robust_dynamics`]: must match a law built on it, so that the disturbance
    /// estimate is exactly what that law's model does not explain.
    Robust,
}

/// Observer design parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Settings {
    /// Bandwidth `w`: all error poles at `exp(-w Ts)` \[rad/s\].
    pub bandwidth_rad_s: f32,
    /// Also estimate the acceleration disturbance `d`.
    pub disturbance: bool,
    /// Model used for the prediction.
    #[cfg_attr(feature = "serde", serde(default))]
    pub model: Model,
    /// Current above which the disturbance is taken as proportional to the magnet's
    /// force rather than constant \[A\] (0: always constant, the plain extended-state
    /// observer). See the module documentation.
    #[cfg_attr(feature = "serde", serde(default))]
    pub force_scaled_above_a: f32,
}

impl Settings {
    /// Builds the observer for `plant` at the sample period `ts_s`. With `delay_ticks = 1`
    /// the measurement of a tick is one period old and the estimate given to the law is the
    /// one-step prediction (the state now, not at the sample).
    ///
    /// # Errors
    /// Invalid plant parameters; a bandwidth that is not finite or not positive; a
    /// bandwidth above the Nyquist rate `pi / Ts` (the discrete poles would not be real).
    pub fn build(&self, plant: &Plant, ts_s: f32, delay_ticks: u8) -> Result<Config, Error> {
        let dynamics = match self.model {
            Model::Nominal => plant.nominal_dynamics()?,
            Model::Robust => plant.robust_dynamics()?,
        };
        config::delay_ticks(delay_ticks)?;
        config::sample_period(ts_s)?;
        config::positive("observer.bandwidth_rad_s", self.bandwidth_rad_s)?;
        config::at_least(
            "observer.force_scaled_above_a",
            self.force_scaled_above_a,
            0.0,
        )?;
        config::within(
            "observer.bandwidth_rad_s",
            self.bandwidth_rad_s,
            0.0,
            core::f32::consts::PI / ts_s,
        )?;
        let q = 1.0 - libm::expf(-self.bandwidth_rad_s * ts_s);
        let (k1, k2, k3) = if self.disturbance {
            (
                3.0 * q - 3.0 * q * q + q * q * q,
                (3.0 * q * q - 1.5 * q * q * q) / ts_s,
                q * q * q / (ts_s * ts_s),
            )
        } else {
            (2.0 * q - q * q, q * q / ts_s, 0.0)
        };
        // The magnet force at the threshold current in the middle of the stroke: below it
        // the scaling fades into a constant disturbance.
        let force_floor_n = if self.force_scaled_above_a > 0.0 {
            let g = plant.gap_m(0.5 * plant.stroke_m);
            dynamics.magnet_force_n(g, self.force_scaled_above_a)
        } else {
            0.0
        };
        Ok(Config {
            gains: *self,
            force_floor_n,
            k1,
            k2,
            k3,
            ts_s,
            half_ts_sq: 0.5 * ts_s * ts_s,
            dynamics,
            delayed: delay_ticks > 0,
        })
    }
}

/// A built observer.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    gains: Settings,
    force_floor_n: f32,
    k1: f32,
    k2: f32,
    k3: f32,
    ts_s: f32,
    half_ts_sq: f32,
    dynamics: Dynamics,
    delayed: bool,
}

/// Observer state: the prediction for the next sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    /// Predicted position \[m\] (rounded to `f32`).
    pub x_m: f32,
    /// The part of the predicted position below the resolution of `x_m` \[m\]: the
    /// prediction is `x_m + x_lo_m` exactly.
    pub x_lo_m: f32,
    /// Predicted velocity \[m/s\].
    pub v_mps: f32,
    /// Predicted disturbance \[m/s^2\].
    pub d_mps2: f32,
    /// The design model's magnet force over the predicted interval \[N\].
    pub force_n: f32,
    /// `false` until the first measurement (which initialises the estimate at rest).
    pub primed: bool,
}

/// The observer's estimate at the current sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Estimate {
    /// Position \[m\].
    pub x_m: f32,
    /// Velocity \[m/s\].
    pub v_mps: f32,
    /// Acceleration disturbance \[m/s^2\].
    pub d_mps2: f32,
}

impl Config {
    /// The design parameters.
    #[must_use]
    pub const fn gains(&self) -> &Settings {
        &self.gains
    }

    /// Correction gains `(k1, k2, k3)`.
    #[must_use]
    pub const fn correction(&self) -> (f32, f32, f32) {
        (self.k1, self.k2, self.k3)
    }

    /// The model the observer predicts with.
    #[must_use]
    pub const fn dynamics(&self) -> &Dynamics {
        &self.dynamics
    }

    /// Takes the position measurement `y_m` and the coil current `i_a` of this sample,
    /// returns the estimate (of the state at the sample, or now when the measurement is
    /// delayed) and prepares the prediction for the next sample.
    #[inline]
    pub fn update(&self, state: &mut State, y_m: f32, i_a: f32) -> Estimate {
        // The magnet force the prediction will use, and the disturbance carried over to it.
        let g = self.dynamics.convention.gap_m(state.x_m);
        let force_n = self.dynamics.magnet_force_n(g, i_a);
        if self.force_floor_n > 0.0 {
            // Both sums are at least the floor: no division by zero.
            state.d_mps2 *= (force_n + self.force_floor_n) / (state.force_n + self.force_floor_n);
        }
        // The position estimate is the pair x + x_lo (see the module documentation).
        let (est, x_lo) = if state.primed {
            // y and x_m are close, so y - x_m is exact; x_lo_m is what x_m could not hold.
            let e = (y_m - state.x_m) - state.x_lo_m;
            let (x, x_lo) = two_sum(state.x_m, state.x_lo_m + self.k1 * e);
            (
                Estimate {
                    x_m: x,
                    v_mps: state.v_mps + self.k2 * e,
                    d_mps2: state.d_mps2 + self.k3 * e,
                },
                x_lo,
            )
        } else {
            (
                Estimate {
                    x_m: y_m,
                    v_mps: 0.0,
                    d_mps2: 0.0,
                },
                0.0,
            )
        };
        let a = self.dynamics.acceleration_mps2(est.x_m, est.v_mps, i_a) + est.d_mps2;
        let (x_pred, x_lo) = two_sum(
            est.x_m,
            x_lo + (self.ts_s * est.v_mps + self.half_ts_sq * a),
        );
        *state = State {
            x_m: x_pred,
            x_lo_m: x_lo,
            v_mps: est.v_mps + self.ts_s * a,
            d_mps2: est.d_mps2,
            force_n,
            primed: true,
        };
        if self.delayed {
            Estimate {
                x_m: state.x_m,
                v_mps: state.v_mps,
                d_mps2: state.d_mps2,
            }
        } else {
            est
        }
    }
}

/// `(s, e)` with `s = fl(a + b)` and `s + e = a + b` exactly (Knuth's TwoSum: six IEEE
/// additions, no condition on the magnitudes; bit-identical on every IEEE target).
#[inline]
fn two_sum(a: f32, b: f32) -> (f32, f32) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TS: f32 = 1.0 / 20_000.0;

    #[test]
    fn gains_place_the_poles() {
        // Second order: error matrix A (I - K C) has char. poly (z - p)^2.
        let plant = Plant::paper();
        let w = 2_000.0;
        let o = Settings {
            bandwidth_rad_s: w,
            disturbance: false,
            model: Model::Nominal,
            force_scaled_above_a: 0.0,
        }
        .build(&plant, TS, 0)
        .unwrap();
        let (k1, k2, _) = o.correction();
        // M = [[1 - k1 - Ts k2, Ts], [-k2, 1]]: trace 2p, det p^2.
        let p = libm::expf(-w * TS);
        let tr = 2.0 - k1 - TS * k2;
        let det = (1.0 - k1 - TS * k2) + TS * k2;
        assert!((tr - 2.0 * p).abs() < 1e-5, "{tr}");
        assert!((det - p * p).abs() < 1e-5, "{det}");
    }

    /// The true plant has an extra constant force the model does not know (a heavier
    /// spring preload, say): the disturbance estimate must find it and the velocity must
    /// follow the truth.
    #[test]
    fn extended_state_observer_learns_an_unknown_force() {
        let plant = Plant::paper();
        let o = Settings {
            bandwidth_rad_s: 1_000.0,
            disturbance: true,
            model: Model::Nominal,
            force_scaled_above_a: 0.0,
        }
        .build(&plant, TS, 0)
        .unwrap();
        let mut st = State::default();
        // Truth (f64, fine steps): x'' = (-K x - lambda v)/m + d0, no current.
        let (k, lam, m) = (120.0_f64, 5.0_f64, 0.1_f64);
        let d0 = 3.0_f64;
        let (mut x, mut v) = (1e-3_f64, 0.0_f64);
        let mut est = Estimate::default();
        for _ in 0..4000 {
            #[expect(clippy::cast_possible_truncation)]
            {
                est = o.update(&mut st, x as f32, 0.0);
            }
            for _ in 0..100 {
                let h = f64::from(TS) / 100.0;
                let a = (-k * x - lam * v) / m + d0;
                x += h * v + 0.5 * h * h * a;
                v += h * a;
            }
        }
        // Compare with the truth at the sample the estimate belongs to (one period ago).
        let (xt, vt) = {
            let (mut x2, mut v2) = (x, v);
            let h = -f64::from(TS) / 100.0;
            for _ in 0..100 {
                let a = (-k * x2 - lam * v2) / m + d0;
                x2 += h * v2 + 0.5 * h * h * a;
                v2 += h * a;
            }
            (x2, v2)
        };
        let dv = (f64::from(est.v_mps) - vt).abs();
        assert!(dv < 2e-4, "v error {dv} (v = {vt})");
        assert!((f64::from(est.x_m) - xt).abs() < 1e-8);
        assert!(
            (f64::from(est.d_mps2) - d0).abs() < 0.01 * d0,
            "{}",
            est.d_mps2
        );
    }

    #[test]
    fn first_sample_starts_at_rest() {
        let o = Settings {
            bandwidth_rad_s: 1_000.0,
            disturbance: false,
            model: Model::Nominal,
            force_scaled_above_a: 0.0,
        }
        .build(&Plant::paper(), TS, 0)
        .unwrap();
        let mut st = State::default();
        let est = o.update(&mut st, 2e-3, 0.0);
        assert_eq!((est.x_m, est.v_mps, est.d_mps2), (2e-3, 0.0, 0.0));
        assert!(st.primed);
    }

    /// At a 1 MHz rate one period of motion, `Ts v`, is far below the `f32` resolution of
    /// the position (2.3e-10 m at 3 mm): the prediction must not drop it, or the velocity
    /// estimate freezes anywhere inside +-ulp/(2 Ts) = +-0.12 mm/s.
    #[test]
    fn slow_velocities_are_not_lost_at_high_rates() {
        let ts = 1.0e-6;
        // No spring: a truth at rest with no current is exactly what the model predicts.
        let plant = Plant {
            spring_n_per_m: 0.0,
            ..Plant::paper()
        };
        let o = Settings {
            bandwidth_rad_s: 2_000.0,
            disturbance: false,
            model: Model::Nominal,
            force_scaled_above_a: 0.0,
        }
        .build(&plant, ts, 0)
        .unwrap();
        let y = 3e-3;
        // Start with a wrong velocity of 0.1 mm/s; the error poles are at exp(-0.002):
        // 20 000 samples are 40 time constants.
        let mut st = State {
            x_m: y,
            v_mps: 1e-4,
            primed: true,
            ..State::default()
        };
        let mut est = Estimate::default();
        for _ in 0..20_000 {
            est = o.update(&mut st, y, 0.0);
        }
        assert!(
            est.v_mps.abs() < 1e-7,
            "velocity estimate stuck at {}",
            est.v_mps
        );
        assert!((est.x_m - y).abs() < 1e-9, "{}", est.x_m);
    }

    #[test]
    fn bandwidth_beyond_nyquist_is_refused() {
        let e = Settings {
            bandwidth_rad_s: 1e6,
            disturbance: false,
            model: Model::Nominal,
            force_scaled_above_a: 0.0,
        }
        .build(&Plant::paper(), TS, 0)
        .unwrap_err();
        assert_eq!(e.param, "observer.bandwidth_rad_s");
        // A period that no rate gives is refused as the rate settings files contain.
        let e = Settings {
            bandwidth_rad_s: 100.0,
            disturbance: false,
            model: Model::Nominal,
            force_scaled_above_a: 0.0,
        }
        .build(&Plant::paper(), -TS, 0)
        .unwrap_err();
        assert_eq!((e.param, e.value), ("rate_hz", -1.0 / TS));
    }
}
