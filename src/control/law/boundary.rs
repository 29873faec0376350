//! The paper's law with a boundary layer: `sign(S)` replaced by `sat(S / phi)`.
//!
//! ```text
//! u = -alpha3 sat(S / phi)        phi = (1 + 2 d) alpha3 Ts / L_lo(g)
//! ```
//!
//! `x3d`, `S` and `alpha3` are exactly the paper's ([`super::paper`]). Inside the layer the
//! law is linear, `u = -(alpha3 / phi) S`, and the sampled coil gives
//! `S[k+1] = (1 - (alpha3 / phi) Ts / L) S[k]` (plus a delayed copy when the measurement is
//! `d` samples old). `phi` is not hand-picked: it is the thinnest layer for which that
//! discrete loop keeps a pole in `[0, 1)` for every inductance `L >= L_lo(g)`, i.e. loop
//! gain `(alpha3 / phi) Ts / L <= 1` without delay; with one sample of delay the loop is
//! `z^2 - z + g`, stable for `g < 1`, and the factor `1 + 2 d` = 3 puts `g <= 1/3`, where
//! the poles are real (`g <= 1/4`) within a few percent and well damped.
//!
//! Then `alpha3 / phi = L_lo(g) / ((1 + 2 d) Ts)`: inside the layer the law is a
//! proportional current loop whose gain follows the inductance bound, and outside it the
//! paper's robust switching voltage `+-alpha3` remains. The price is the one the paper's
//! proof cannot avoid: `S` is no longer driven to 0, only into the layer, so the current
//! (and the position) keep an error that grows with `phi`.
//!
//! ```
//! use ema::control::law::{self, boundary, paper, Law};
//! use ema::control::model::Plant;
//!
//! let ts = 1.0 / 20_000.0;
//! let plant = Plant::paper();
//! let bl = boundary::Config::build(&paper::Gains::paper(), &plant, ts, 0).unwrap();
//! // At 3 mm on target, 0.1 mm/s closing, 5.2 A: x3d = 5.07 A, S = 0.13 A is inside the
//! // layer, so the law answers proportionally, not with the paper's +-alpha3.
//! let input = law::Input {
//!     x_m: 3e-3, v_mps: -1e-4, i_a: 5.2, vbus_v: 24.0,
//!     reference: law::Reference::hold(3e-3), ..Default::default()
//! };
//! let out = bl.step(&mut paper::State::default(), &input);
//! let gain = plant.envelope().unwrap().l_lo(3e-3) / ts; // L_lo / Ts, 0.93 ohm
//! assert!((out.u_v + gain * out.s_a).abs() < 1e-4);
//! assert!(out.u_v.abs() < 1.0);
//! ```

use super::paper::{self, State};
use super::{Input, Law, Output};
use crate::control::config::{self, Error};
use crate::control::math;
use crate::control::model::Plant;

/// The boundary-layer law, validated.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    paper: paper::Config,
    /// `1 / ((1 + 2 d) Ts)` \[1/s\].
    layer_gain: f32,
}

impl Config {
    /// Builds the law from the paper's gains (Theorem 1 checked) for `plant` at the sample
    /// period `ts_s` with `delay_ticks` (0 or 1) samples of measurement delay.
    ///
    /// # Errors
    /// As [`paper::Gains::build`]; a delay above 1 sample.
    pub fn build(
        gains: &paper::Gains,
        plant: &Plant,
        ts_s: f32,
        delay_ticks: u8,
    ) -> Result<Self, Error> {
        let paper = gains.build(plant, ts_s)?;
        config::delay_ticks(delay_ticks)?;
        Ok(Self {
            paper,
            layer_gain: 1.0 / ((1.0 + 2.0 * f32::from(delay_ticks)) * ts_s),
        })
    }

    /// The underlying paper law.
    #[must_use]
    pub const fn paper(&self) -> &paper::Config {
        &self.paper
    }

    /// Layer width `phi` \[A\] for a given `alpha3` and airgap.
    #[must_use]
    pub fn phi_a(&self, alpha3_v: f32, g_m: f32) -> f32 {
        alpha3_v / (self.layer_gain * self.paper.envelope().l_lo(g_m))
    }
}

impl Law for Config {
    type State = State;

    #[inline]
    fn step(&self, state: &mut State, input: &Input) -> Output {
        let sl = self.paper.sliding(state, input);
        // -alpha3 sat(S / phi) = -sat((alpha3 / phi) S, alpha3).
        let gain = self.layer_gain * self.paper.envelope().l_lo(sl.g_m);
        Output {
            u_v: -math::sat(gain * sl.s_a, sl.alpha3_v),
            i_d_a: sl.i_d_a,
            s_a: sl.s_a,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::law::Reference;

    const TS: f32 = 1.0 / 20_000.0;

    fn input(i_a: f32) -> Input {
        Input {
            x_m: 3e-3,
            v_mps: -1e-4,
            i_a,
            vbus_v: 150.0,
            disturbance_mps2: 0.0,
            reference: Reference::hold(3e-3),
            u_prev_v: 0.0,
            probe_a: 0.0,
        }
    }

    #[test]
    fn outside_the_layer_it_is_the_paper_law() {
        let plant = Plant::paper();
        let bl = Config::build(&paper::Gains::paper(), &plant, TS, 0).unwrap();
        let pl = paper::Gains::paper().build(&plant, TS).unwrap();
        // x3d = 5.07 A; the layer at 20 kHz is alpha3 Ts / L_lo, with alpha3 of tens of
        // volts and L_lo = 46.7 uH: tens of amperes wide (one sample at +-alpha3 moves the
        // current by that much). At 100 A the current is outside it.
        let a = bl.step(&mut State::default(), &input(100.0));
        let b = pl.step(&mut State::default(), &input(100.0));
        assert_eq!(a, b);
        let phi = bl.phi_a(-b.u_v, 3e-3);
        assert!(phi > 20.0 && phi < a.s_a, "{phi}");
    }

    #[test]
    fn inside_the_layer_it_is_proportional_with_the_bound_gain() {
        let plant = Plant::paper();
        let bl = Config::build(&paper::Gains::paper(), &plant, TS, 1).unwrap();
        let env = plant.envelope().unwrap();
        let mut st = State::default();
        let out = bl.step(&mut st, &input(5.1));
        // Gain L_lo(3 mm) / (3 Ts) = 46.67 uH / 150 us = 0.311 ohm.
        let gain = env.l_lo(3e-3) / (3.0 * TS);
        assert!((out.u_v + gain * out.s_a).abs() < 1e-5, "{}", out.u_v);
        assert!(out.s_a.abs() < bl.phi_a(20.0, 3e-3));
    }
}
