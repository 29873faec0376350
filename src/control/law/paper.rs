//! The paper's law, exactly as published (Theorems 1-3), with the two corrections that keep
//! it well defined: the desired current's square, negative whenever `z2 > 0`, is clipped
//! to zero, and Theorem 3's `eps` takes absolute values of `x3` and `x3d`.
//!
//! ```text
//! z1 = x1 - y_r
//! z2 = x2 + alpha1 z1
//! x3d^2 = -(2 m / mu_lo(g)) alpha2 z2       x3d = sqrt(max(0, x3d^2))    (1)
//! S = x3 - x3d
//! eps    = (2/m) (|x3| + |x3d|) mu_hi(g) + eps1                          (2)
//! alpha3 = R |x3d| + |x2 x3| mu_hi(g) + |x3d'| L_hi(g) + eps
//! u = -alpha3 sign(S)
//! ```
//!
//! `g` is the airgap at `x1` ([`crate::control::model::Convention`]); `x3d'` is the
//! backward difference of the sampled `x3d` over the configured sample period.
//!
//! Corrections: (1) `x3d^2` is negative whenever `z2 > 0` (the magnet cannot pull the
//! other way), so `x3d` is clipped to 0 there; (2) Theorem 3's `eps` is written with
//! `x3 + x3d`, which can be negative; its proof needs the absolute values.
//!
//! This law is kept unchanged for reproduction. Sampled at firmware rates it chatters (one
//! sample at `+-alpha3` moves the current by `alpha3 Ts / L`, about 15 A at 20 kHz); the
//! practical laws live beside it.
//!
//! ```
//! use ema::control::law::{self, Law};
//! use ema::control::model::Plant;
//!
//! let plant = Plant::paper();
//! let cfg = law::paper::Gains::paper().build(&plant, 1.0 / 20_000.0).unwrap();
//! let mut state = law::paper::State::default();
//!
//! // At the 3 mm target, 0.1 mm/s closing, 6 A in the coil: z2 = -1e-4 < 0 asks for
//! // current; x3d^2 = (2 m / mu_lo) alpha2 1e-4 = 25.7 A^2, x3d = 5.07 A < 6 A: S > 0,
//! // so the law applies -alpha3.
//! let out = cfg.step(&mut state, &law::Input {
//!     x_m: 3e-3, v_mps: -1e-4, i_a: 6.0, vbus_v: 150.0,
//!     reference: law::Reference::hold(3e-3), ..Default::default()
//! });
//! assert!((out.i_d_a - 5.07).abs() < 0.01);
//! assert!(out.s_a > 0.0 && out.u_v < -10.0);
//! ```

use super::{Input, Law, Output};
use crate::control::config::{self, Error, Reason};
use crate::control::math;
use crate::control::model::{Convention, Envelope, Plant};

/// The paper's gains.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Gains {
    /// Backstepping gain on the position error `alpha1` \[1/s\].
    pub alpha1: f32,
    /// Backstepping gain on `z2` `alpha2` \[1/s\].
    pub alpha2: f32,
    /// Sliding-mode margin `eps1` \[V\].
    pub eps1_v: f32,
}

impl Gains {
    /// The gains of the paper's example: `alpha1 = 10`, `alpha2 = 20000`, `eps1 = 10 V`.
    #[must_use]
    pub const fn paper() -> Self {
        Self {
            alpha1: 10.0,
            alpha2: 20_000.0,
            eps1_v: 10.0,
        }
    }

    /// Checks the gains against the plant (Theorem 1 included) and builds the law for the
    /// sample period `ts_s`.
    ///
    /// # Errors
    /// Any invalid plant parameter; a non-finite or non-positive gain or sample period;
    /// `alpha2` failing Theorem 1 ([`Reason::Theorem1`], with the smallest `alpha2` that
    /// passes).
    pub fn build(&self, plant: &Plant, ts_s: f32) -> Result<Config, Error> {
        let envelope = plant.envelope()?;
        config::sample_period(ts_s)?;
        config::positive("law.alpha1", self.alpha1)?;
        config::positive("law.alpha2", self.alpha2)?;
        config::positive("law.eps1_v", self.eps1_v)?;
        let theorem1 = Theorem1::new(plant, self.alpha1, self.alpha2);
        if !theorem1.holds() {
            return Err(Error {
                param: "alpha2",
                value: self.alpha2,
                reason: Reason::Theorem1 {
                    a: theorem1.a,
                    b: theorem1.b,
                    det_q: theorem1.det_q,
                    alpha2_min: theorem1.alpha2_min,
                },
            });
        }
        Ok(Config {
            gains: *self,
            theorem1,
            envelope,
            convention: plant.convention,
            mass_kg: plant.mass_kg,
            resistance_ohm: plant.resistance_ohm,
            two_m_alpha2: 2.0 * plant.mass_kg * self.alpha2,
            two_over_m: 2.0 / plant.mass_kg,
            inv_ts: 1.0 / ts_s,
            ts_s,
        })
    }
}

/// Theorem 1 of the paper, evaluated for a plant and a pair of gains.
///
/// `a = 1 - alpha1^2 + (lambda/m) alpha1 - K/m`, `b = alpha1 - lambda/m`,
/// `Q = [[-alpha1, a/2], [a/2, b - alpha2]]`; the theorem needs `Q` negative definite and
/// `alpha2 > |b|`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Theorem1 {
    /// `a` \[1/s^2\]-like, as in the paper.
    pub a: f32,
    /// `b` \[1/s\].
    pub b: f32,
    /// `Q[0][0] = -alpha1`.
    pub q11: f32,
    /// `Q[0][1] = Q[1][0] = a/2`.
    pub q12: f32,
    /// `Q[1][1] = b - alpha2`.
    pub q22: f32,
    /// `det Q`.
    pub det_q: f32,
    /// Most negative eigenvalue of `Q`.
    pub eig_min: f32,
    /// Eigenvalue of `Q` closest to zero; `Q` is negative definite when it is negative.
    pub eig_max: f32,
    /// Smallest `alpha2` that passes for this `alpha1`: `max(|b|, b + a^2/(4 alpha1))`.
    pub alpha2_min: f32,
    /// `K/m` \[1/s^2\], for the ultimate bound.
    pub k_over_m: f32,
    alpha2: f32,
}

impl Theorem1 {
    /// Evaluates Theorem 1 for `plant` and the gains `alpha1`, `alpha2`.
    #[must_use]
    pub fn new(plant: &Plant, alpha1: f32, alpha2: f32) -> Self {
        let lm = plant.friction_n_s_per_m / plant.mass_kg;
        let k_over_m = plant.spring_n_per_m / plant.mass_kg;
        let a = 1.0 - alpha1 * alpha1 + lm * alpha1 - k_over_m;
        let b = alpha1 - lm;
        let q11 = -alpha1;
        let q12 = 0.5 * a;
        let q22 = b - alpha2;
        let det_q = q11 * q22 - q12 * q12;
        // Symmetric 2x2: eigenvalues tr/2 -+ sqrt((tr/2)^2 - det). The one nearer zero is
        // computed as det / eig_min to avoid cancellation in f32.
        let half_tr = 0.5 * (q11 + q22);
        let disc = math::sqrt((half_tr * half_tr - det_q).max(0.0));
        let eig_min = half_tr - disc;
        let eig_max = if eig_min == 0.0 { 0.0 } else { det_q / eig_min };
        let alpha2_min = (b + a * a / (4.0 * alpha1)).max(b.abs());
        Self {
            a,
            b,
            q11,
            q12,
            q22,
            det_q,
            eig_min,
            eig_max,
            alpha2_min,
            k_over_m,
            alpha2,
        }
    }

    /// `true` when `Q` is negative definite and `alpha2 > |b|`.
    #[must_use]
    pub fn holds(&self) -> bool {
        self.q11 < 0.0 && self.det_q > 0.0 && self.eig_max < 0.0 && self.alpha2 > self.b.abs()
    }

    /// Radius of the ball that Theorem 1 guarantees for a reference `y_r_m`, in the
    /// `(z1, z2)` plane: `delta / (alpha theta)` with `delta = (K/m)|y_r|` and
    /// `alpha = |eig_max(Q)|`, the eigenvalue of smallest magnitude (the paper writes
    /// `lambda_min`, which would give a far smaller, unjustified radius), `0 < theta < 1`.
    ///
    /// This is a Lyapunov bound, not a precision figure: for the paper's example it is of
    /// the order of a metre, while the measured error is micrometres.
    #[must_use]
    pub fn ultimate_radius(&self, y_r_m: f32, theta: f32) -> f32 {
        self.k_over_m * y_r_m.abs() / (self.eig_max.abs() * theta)
    }
}

/// The paper's law, validated and ready for the tick.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    gains: Gains,
    theorem1: Theorem1,
    envelope: Envelope,
    convention: Convention,
    mass_kg: f32,
    resistance_ohm: f32,
    two_m_alpha2: f32,
    two_over_m: f32,
    inv_ts: f32,
    ts_s: f32,
}

impl Config {
    /// The gains.
    #[must_use]
    pub const fn gains(&self) -> &Gains {
        &self.gains
    }

    /// Theorem 1 as evaluated when the law was built.
    #[must_use]
    pub const fn theorem1(&self) -> &Theorem1 {
        &self.theorem1
    }

    /// Sample period \[s\].
    #[must_use]
    pub const fn ts_s(&self) -> f32 {
        self.ts_s
    }

    /// Moving mass used by the law \[kg\].
    #[must_use]
    pub const fn mass_kg(&self) -> f32 {
        self.mass_kg
    }
}

/// State of the paper's law: the previous desired current, for `x3d'`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    /// `x3d` at the previous tick \[A\].
    pub i_d_prev_a: f32,
    /// `false` until the first step (then `x3d'` is taken as 0).
    pub primed: bool,
}

/// The quantities both the paper's law and its boundary-layer variant switch on.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sliding {
    /// Airgap \[m\].
    pub g_m: f32,
    /// Desired current `x3d` \[A\].
    pub i_d_a: f32,
    /// `S = x3 - x3d` \[A\].
    pub s_a: f32,
    /// Switching gain `alpha3` \[V\].
    pub alpha3_v: f32,
}

impl Config {
    /// `x3d`, `S` and `alpha3` at this tick (updates the stored `x3d`).
    #[inline]
    pub(crate) fn sliding(&self, state: &mut State, input: &Input) -> Sliding {
        let g = self.convention.gap_m(input.x_m);
        let z1 = input.x_m - input.reference.x_m;
        let z2 = input.v_mps + self.gains.alpha1 * z1;
        let mu_lo = self.envelope.mu_lo(g);
        let mu_hi = self.envelope.mu_hi(g);
        let l_hi = self.envelope.l_hi(g);

        let i_d_sq = -self.two_m_alpha2 * z2 / mu_lo;
        let i_d = math::sqrt(math::max(i_d_sq, 0.0));
        let di_d = if state.primed {
            (i_d - state.i_d_prev_a) * self.inv_ts
        } else {
            0.0
        };
        state.i_d_prev_a = i_d;
        state.primed = true;

        let s = input.i_a - i_d;
        let eps = self.two_over_m * (input.i_a.abs() + i_d) * mu_hi + self.gains.eps1_v;
        let alpha3 = self.resistance_ohm * i_d
            + (input.v_mps * input.i_a).abs() * mu_hi
            + di_d.abs() * l_hi
            + eps;
        Sliding {
            g_m: g,
            i_d_a: i_d,
            s_a: s,
            alpha3_v: alpha3,
        }
    }

    /// The bounds envelope the law was built with.
    #[must_use]
    pub const fn envelope(&self) -> &Envelope {
        &self.envelope
    }
}

impl Law for Config {
    type State = State;

    #[inline]
    fn step(&self, state: &mut State, input: &Input) -> Output {
        let sl = self.sliding(state, input);
        Output {
            u_v: -sl.alpha3_v * math::sign(sl.s_a),
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

    fn law() -> Config {
        Gains::paper().build(&Plant::paper(), TS).unwrap()
    }

    fn input(x_m: f32, v_mps: f32, i_a: f32, r_m: f32) -> Input {
        Input {
            x_m,
            v_mps,
            i_a,
            vbus_v: 150.0,
            disturbance_mps2: 0.0,
            reference: Reference::hold(r_m),
            u_prev_v: 0.0,
            probe_a: 0.0,
        }
    }

    fn rel(a: f32, b: f32) -> f32 {
        ((a - b) / b).abs()
    }

    #[test]
    fn theorem1_for_the_paper_gains() {
        let th = *law().theorem1();
        assert_eq!(th.a, -799.0);
        assert_eq!(th.b, -40.0);
        assert!(rel(th.eig_min, -20_047.96) < 1e-6, "{}", th.eig_min);
        assert!(rel(th.eig_max, -2.035) < 1e-3, "{}", th.eig_max);
        // det Q = 10 * 20040 - 399.5^2 = 40 799.75
        assert!(rel(th.det_q, 40_799.75) < 1e-6);
        assert!(th.holds());
        // alpha2 must exceed b + a^2/(4 alpha1) = -40 + 638401/40.
        assert!(rel(th.alpha2_min, -40.0 + 638_401.0 / 40.0) < 1e-6);
    }

    #[test]
    fn ultimate_radius_is_of_the_order_of_a_metre() {
        let th = *law().theorem1();
        // delta = (K/m) y_r = 1200 * 0.003 = 3.6; alpha = 2.035; theta -> 1.
        let r = th.ultimate_radius(3e-3, 1.0);
        assert!(rel(r, 3.6 / 2.035) < 1e-3, "{r}");
        assert!(r > 1.0);
    }

    #[test]
    fn alpha2_of_ten_is_refused_with_the_reason() {
        let gains = Gains {
            alpha2: 10.0,
            ..Gains::paper()
        };
        let err = gains.build(&Plant::paper(), TS).unwrap_err();
        assert_eq!(err.param, "alpha2");
        assert_eq!(err.value, 10.0);
        match err.reason {
            Reason::Theorem1 {
                a,
                b,
                det_q,
                alpha2_min,
            } => {
                assert_eq!((a, b), (-799.0, -40.0));
                assert!(det_q < 0.0);
                assert!(alpha2_min > 15_920.0 && alpha2_min < 15_921.0);
            }
            other => panic!("unexpected reason {other:?}"),
        }
    }

    #[test]
    fn non_physical_parameters_are_refused() {
        let p = Plant::paper();
        assert_eq!(Gains::paper().build(&p, 0.0).unwrap_err().param, "rate_hz");
        assert_eq!(
            Gains::paper().build(&p, -1e-4).unwrap_err().param,
            "rate_hz"
        );
        let g = Gains {
            alpha1: f32::NAN,
            ..Gains::paper()
        };
        assert_eq!(g.build(&p, TS).unwrap_err().param, "law.alpha1");
        let g = Gains {
            eps1_v: 0.0,
            ..Gains::paper()
        };
        assert_eq!(g.build(&p, TS).unwrap_err().param, "law.eps1_v");
    }

    /// Hand computation at x1 = 2 mm, below the 3 mm target (z2 < 0).
    ///
    /// At g = 2 mm with S in [0.8, 1.2] x 56.84 mm^2: rho_x in [2.3334e10, 3.5001e10],
    /// mu_lo = 4900 * 3.5001e10 / (7.0002e7 + 630)^2 = 0.035000 H/m,
    /// mu_hi = 4900 * 2.3334e10 / (4.6667e7 + 630)^2 = 0.052497 H/m,
    /// L_hi = 4900 / (4.6667e7 + 630) = 104.996 uH.
    #[test]
    fn output_at_hand_computed_states() {
        let (mu_lo, mu_hi, l_hi) = (0.035_000_f32, 0.052_497_f32, 104.996e-6_f32);
        let cfg = law();
        let mut st = State::default();
        // Tick 1: x2 = 0, x3 = 3 A: z2 = 10 * (-1 mm) = -0.01.
        let out1 = cfg.step(&mut st, &input(2e-3, 0.0, 3.0, 3e-3));
        let x3d_1 = libm::sqrtf(2.0 * 0.1 * 20_000.0 * 0.01 / mu_lo); // 33.81 A
        assert!(rel(out1.i_d_a, x3d_1) < 1e-4, "{} vs {x3d_1}", out1.i_d_a);
        // Tick 2: x2 = -0.005 m/s: z2 = -0.015, x3d rises; S = 3 - x3d < 0 so u = +alpha3.
        let out2 = cfg.step(&mut st, &input(2e-3, -0.005, 3.0, 3e-3));
        let x3d_2 = libm::sqrtf(2.0 * 0.1 * 20_000.0 * 0.015 / mu_lo); // 41.40 A
        assert!(rel(out2.i_d_a, x3d_2) < 1e-4);
        assert!(rel(out2.s_a, 3.0 - x3d_2) < 1e-4);
        let dx3d = (x3d_2 - x3d_1) / TS;
        let eps = 2.0 / 0.1 * (3.0 + x3d_2) * mu_hi + 10.0;
        let alpha3 = 0.4 * x3d_2 + 0.005 * 3.0 * mu_hi + dx3d * l_hi + eps;
        assert!(rel(out2.u_v, alpha3) < 1e-3, "{} vs {alpha3}", out2.u_v);
        // 0.4 * 41.40 + 0.0008 + 151.8e3 A/s * 105.0 uH + (20 * 44.40 * 0.052497 + 10)
        assert!((out2.u_v - 89.14).abs() < 0.05, "{}", out2.u_v);
    }

    #[test]
    fn no_current_is_asked_when_z2_is_positive() {
        let cfg = law();
        let mut st = State::default();
        // Above the target and opening: z2 > 0, x3d^2 < 0 -> x3d = 0, S = x3.
        let out = cfg.step(&mut st, &input(3.5e-3, 0.02, 2.0, 3e-3));
        assert_eq!(out.i_d_a, 0.0);
        assert_eq!(out.s_a, 2.0);
        let env = Plant::paper().envelope().unwrap();
        let g = 3.5e-3;
        let alpha3 = (0.02_f32 * 2.0).abs() * env.mu_hi(g) + 2.0 / 0.1 * 2.0 * env.mu_hi(g) + 10.0;
        assert!(rel(out.u_v, -alpha3) < 1e-6, "{} vs {}", out.u_v, -alpha3);
    }

    #[test]
    fn first_step_has_no_derivative_kick() {
        let cfg = law();
        let mut st = State::default();
        let env = Plant::paper().envelope().unwrap();
        let out = cfg.step(&mut st, &input(1e-3, 0.0, 0.0, 3e-3));
        // x3d from z2 = -0.02; S < 0 so u = +alpha3 without the |x3d'| L_hi term.
        let g = 1e-3;
        let x3d = libm::sqrtf(2.0 * 0.1 * 20_000.0 * 0.02 / env.mu_lo(g));
        let alpha3 = 0.4 * x3d + 2.0 / 0.1 * x3d * env.mu_hi(g) + 10.0;
        assert!(rel(out.u_v, alpha3) < 1e-5, "{} vs {alpha3}", out.u_v);
        // The second step at the same state adds nothing either (x3d unchanged).
        let out2 = cfg.step(&mut st, &input(1e-3, 0.0, 0.0, 3e-3));
        assert_eq!(out2.u_v, out.u_v);
    }
}
