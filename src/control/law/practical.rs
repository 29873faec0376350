//! The practical law: the paper's structure (backstepping outer loop, sliding-mode current
//! loop built on the uncertainty bounds), redesigned for a sampled, delayed, noisy loop.
//!
//! ## Outer loop: backstepping with the nominal model and a disturbance estimate
//!
//! With the shaped reference `(r, r', r'')` ([`crate::control::shaping`]), the estimate
//! `(x, v, d)` from the extended-state observer ([`crate::control::observer`]):
//!
//! ```text
//! z1 = x - r                       z2 = v - r' + alpha1 z1
//! a_d = r'' - (alpha1 + alpha2) z2 + (alpha1^2 - 1) z1 - d                       (1)
//! F_d = m a_d + K x + F0 + lambda v                                              (2)
//! x3d = min(I_max, sqrt(max(0, 2 F_d / mu(g))))                                  (3)
//! ```
//!
//! `m`, `K`, `lambda` and `mu` are the *robust design model*
//! ([`crate::control::model::Plant::robust_dynamics`]): every uncertain parameter at the
//! bound that makes the actuator slowest to follow a force command (`mu = mu_lo`, the
//! heaviest mass, the softest spring, the most friction). This is the paper's use of
//! `mu_lo` in `x3d`, extended to every parameter, and it is what keeps the overshoot small
//! over the whole uncertainty set: a plant stronger than the model leads the reference a
//! little and is pulled back; a plant weaker than the model would lag during the move while
//! `d` builds up, and `d` would then overshoot as the move ends. The observer must use the
//! same model ([`crate::control::observer::Model::Robust`]).
//!
//! (1) is backstepping for `x'' = a`: with `V = (z1^2 + z2^2)/2` it gives
//! `V' = -alpha1 z1^2 - alpha2 z2^2` when the model is exact, i.e. Theorem 1's `Q` becomes
//! `diag(-alpha1, -alpha2)`: the cross term `a` of the paper comes from the spring and the
//! friction, which (2) now compensates with the nominal model instead of leaving them to
//! the gains. The closed loop is `s^2 + (alpha1 + alpha2) s + alpha1 alpha2 + 1`.
//! `- d` cancels what the nominal model does not explain (surfaces anywhere in their
//! bounds, mass, spring, friction, resistance): the observer estimates it from the
//! *measured* current, so it is integral action without wind-up: when `x3d` is clipped
//! (0 or `I_max`) the observer sees the force that was really applied.
//! (3) inverts `F = mu x3^2 / 2`; the magnet can only pull along `+x`, so a negative `F_d`
//! asks for no current (the spring does the rest), the paper's `x3d = 0` case.
//!
//! ## Current loop: discrete-time sliding mode with equivalent control
//!
//! The coil over one period with a constant voltage (Tustin, accurate to second order
//! where `R Ts / L` reaches 0.7):
//!
//! ```text
//! i[k+1] = al i[k] + be (u[k] + e[k])    al = (1 - rho)/(1 + rho), be = (Ts/L)/(1 + rho)
//! rho = R Ts / (2 L),   e = s_emf v i mu(g)   (motional back-EMF)
//! ```
//!
//! With one sample of measurement delay the measured current is `i[k-1]`; the voltage
//! applied since is known, so the current now is predicted first (`i_p`). Sliding variable
//! `S = i_p - x3d`; discrete reaching law `S[k+1] = (1 - kappa) S[k]`:
//!
//! ```text
//! u = (x3d + (1 - kappa) S - al i_p) / be - e + w,       |u| <= Vbus               (4)
//! w[k+1] = w[k] - ki (kappa / be) (i_m - x3d_prev)   (not while saturated)          (5)
//! ```
//!
//! (4) is the equivalent control (the voltage that puts the nominal coil exactly on
//! `x3d` at the next sample) plus a linear reaching term. No switching term: one sample
//! at `+-alpha3` is what makes the paper's law chatter at firmware rates. Robustness comes
//! from the bounds instead: with the true inductance `L` anywhere in `[L_lo, L_hi]` the
//! loop pole is `1 - kappa L_nom / L`; `kappa = reach * L_lo / L_nom` keeps it in `[0, 1)`
//! (no oscillation, no instability) over the whole uncertainty set. (5) integrates the
//! error of the *measured* current `i_m` against the previous desired current, so the coil
//! carries exactly `x3d` in steady state whatever the true resistance: the prediction
//! across the delay uses the nominal resistance and is biased when it is off (by about
//! 7 % of the current for +17 % of resistance at 3.5 mm), so integrating `S` itself would
//! leave that bias in the coil, where the outer loop's disturbance estimate (built on the
//! measured current) cannot see it.
//!
//! ```
//! use ema::control::law::{self, practical, Law};
//! use ema::control::model::Plant;
//!
//! let plant = Plant::paper();
//! let cfg = practical::Gains::new(130.0, 12.0).build(&plant, 1.0 / 20_000.0, 0).unwrap();
//! // At rest on the 3 mm target with no disturbance estimate, the law asks for the current
//! // that holds the softest spring with the weakest magnet: sqrt(2 * 108 * 3e-3 / mu_lo).
//! let input = law::Input {
//!     x_m: 3e-3, i_a: 6.45, vbus_v: 24.0,
//!     reference: law::Reference::hold(3e-3), ..Default::default()
//! };
//! let out = cfg.step(&mut practical::State::default(), &input);
//! assert!((out.i_d_a - 6.45).abs() < 0.01);
//! // Already there: a small voltage, about the resistive drop R x3d = 2.6 V.
//! assert!((out.u_v - 0.4 * 6.45).abs() < 0.3);
//! ```

use super::{Input, Law, Output};
use crate::control::config::{self, Error};
use crate::control::math;
use crate::control::model::{Convention, Dynamics, Nominal, Plant};

/// Reaching factor of the current loop: its pole sits at `1 - 0.7 L_lo / L` for a coil
/// of inductance `L`, in `[0.3, 1)` over the bounds (no oscillation, a margin for the
/// delay's prediction error) \[-\].
pub const REACH: f32 = 0.7;
/// Integral gain of the current loop relative to the reaching gain: slow enough to stay
/// out of the reaching dynamics, fast enough to remove a resistance error within a few
/// milliseconds \[-\].
pub const INTEGRAL: f32 = 0.05;

/// Gains of the practical law.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Gains {
    /// Backstepping gain on the position error `alpha1` \[1/s\].
    pub alpha1: f32,
    /// Backstepping gain on `z2` `alpha2` \[1/s\].
    pub alpha2: f32,
    /// Limit on the desired current \[A\].
    pub current_max_a: f32,
    /// Reaching factor as a fraction of the largest one that keeps the current-loop pole
    /// non-negative for every inductance in the bounds, in (0, 1].
    pub reach: f32,
    /// Integral gain of the current loop relative to the reaching gain, in \[0, 0.5\].
    pub integral: f32,
}

impl Gains {
    /// Gains `alpha1 = alpha2 = alpha_per_s` with the desired current limited to
    /// `current_max_a`, and the current loop's [`REACH`] and [`INTEGRAL`].
    #[must_use]
    pub const fn new(alpha_per_s: f32, current_max_a: f32) -> Self {
        Self {
            alpha1: alpha_per_s,
            alpha2: alpha_per_s,
            current_max_a,
            reach: REACH,
            integral: INTEGRAL,
        }
    }

    /// Validates the gains and builds the law for `plant` at the sample period `ts_s` with
    /// `delay_ticks` (0 or 1) samples of measurement delay.
    ///
    /// # Errors
    /// The first bad parameter, by name.
    pub fn build(&self, plant: &Plant, ts_s: f32, delay_ticks: u8) -> Result<Config, Error> {
        let envelope = plant.envelope()?;
        config::sample_period(ts_s)?;
        config::positive("law.alpha1", self.alpha1)?;
        config::positive("law.alpha2", self.alpha2)?;
        config::positive("law.current_max_a", self.current_max_a)?;
        config::within("law.reach", self.reach, f32::MIN_POSITIVE, 1.0)?;
        config::within("law.integral", self.integral, 0.0, 0.5)?;
        config::delay_ticks(delay_ticks)?;
        let nominal = envelope.nominal();
        let dynamics = plant.robust_dynamics()?;
        // L_lo / L_nom = (rho_x_nom g + rho0) / (rho_x_hi g + rho0) >= rho_x_nom / rho_x_hi.
        let (_, rho_x_hi) = envelope.rho_x_range();
        let kappa = self.reach * nominal.rho_x_per_h_m() / rho_x_hi;
        Ok(Config {
            gains: *self,
            nominal,
            dynamics,
            convention: plant.convention,
            half_r_ts: 0.5 * plant.resistance_ohm * ts_s,
            ts_s,
            kappa,
            k_sum: self.alpha1 + self.alpha2,
            k_pos: self.alpha1 * self.alpha1 - 1.0,
            delayed: delay_ticks > 0,
        })
    }
}

/// The practical law, validated.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    gains: Gains,
    nominal: Nominal,
    dynamics: Dynamics,
    convention: Convention,
    half_r_ts: f32,
    ts_s: f32,
    kappa: f32,
    k_sum: f32,
    k_pos: f32,
    delayed: bool,
}

impl Config {
    /// The gains.
    #[must_use]
    pub const fn gains(&self) -> &Gains {
        &self.gains
    }

    /// The design model of the outer loop.
    #[must_use]
    pub const fn dynamics(&self) -> &Dynamics {
        &self.dynamics
    }

    /// Reaching factor `kappa` actually used (after the bound on the inductance).
    #[must_use]
    pub const fn kappa(&self) -> f32 {
        self.kappa
    }
}

/// State of the practical law.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    /// Integral voltage correction `w` \[V\].
    pub w_v: f32,
    /// Desired current of the previous tick \[A\].
    pub i_d_prev_a: f32,
}

impl Law for Config {
    type State = State;

    #[inline]
    fn step(&self, state: &mut State, input: &Input) -> Output {
        let g = self.convention.gap_m(input.x_m);
        let mu = self.dynamics.circuit.force_coefficient_h_per_m(g);
        let r = &input.reference;

        // Outer loop, (1)-(3).
        let z1 = input.x_m - r.x_m;
        let z2 = input.v_mps - r.v_mps + self.gains.alpha1 * z1;
        let a_d = r.a_mps2 - self.k_sum * z2 + self.k_pos * z1 - input.disturbance_mps2;
        let d = &self.dynamics;
        let f_d =
            d.mass_kg * a_d + d.spring_force_n(input.x_m) + d.friction_n_s_per_m * input.v_mps;
        let i_d = math::min(
            math::sqrt(math::max(2.0 * f_d / mu, 0.0)) + input.probe_a,
            self.gains.current_max_a,
        );

        // Current loop, (4)-(5).
        let l = self.nominal.inductance_h(g);
        let inv = 1.0 / (1.0 + self.half_r_ts / l);
        let al = (1.0 - self.half_r_ts / l) * inv;
        let be = self.ts_s / l * inv;
        let emf = self.convention.emf_sign()
            * input.v_mps
            * input.i_a
            * self.nominal.force_coefficient_h_per_m(g);
        let i_p = if self.delayed {
            al * input.i_a + be * (input.u_prev_v + emf)
        } else {
            input.i_a
        };
        let s = i_p - i_d;
        let u_raw = (i_d + (1.0 - self.kappa) * s - al * i_p) / be - emf + state.w_v;
        let u = math::sat(u_raw, input.vbus_v);
        // Anti-windup: integrate only when not pushing further into saturation.
        let dw = -self.gains.integral * self.kappa / be * (input.i_a - state.i_d_prev_a);
        if u == u_raw || (dw > 0.0) != (u_raw > 0.0) {
            state.w_v = math::sat(state.w_v + dw, input.vbus_v);
        }
        state.i_d_prev_a = i_d;
        Output {
            u_v: u,
            i_d_a: i_d,
            s_a: s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::law::Reference;

    const TS: f32 = 1.0 / 20_000.0;

    /// Gains with round numbers for the hand computations: alpha1 = alpha2 = 100.
    fn gains() -> Gains {
        Gains::new(100.0, 12.0)
    }

    fn law(delay: u8) -> Config {
        gains().build(&Plant::paper(), TS, delay).unwrap()
    }

    fn input(x_m: f32, i_a: f32, r: Reference) -> Input {
        Input {
            x_m,
            v_mps: 0.0,
            i_a,
            vbus_v: 24.0,
            disturbance_mps2: 0.0,
            reference: r,
            u_prev_v: 0.0,
            probe_a: 0.0,
        }
    }

    #[test]
    fn holds_the_spring_with_the_design_model_current() {
        // At rest on target, no disturbance estimate: F_d = K_d x with the softest spring
        // (108 N/m), inverted with mu_lo(3 mm) = 0.8 mu(3 mm): sqrt(2 * 0.324 / 0.01556).
        let cfg = law(0);
        let mut st = State::default();
        let out = cfg.step(&mut st, &input(3e-3, 6.0, Reference::hold(3e-3)));
        let env = Plant::paper().envelope().unwrap();
        let expect = libm::sqrtf(2.0 * 108.0 * 3e-3 / env.mu_lo(3e-3));
        assert!(
            (out.i_d_a - expect).abs() < 1e-4,
            "{} vs {expect}",
            out.i_d_a
        );
        assert!((expect - 6.45).abs() < 0.01, "{expect}");
    }

    /// On the nominal coil (delay 0), one step moves the current by kappa of the error:
    /// simulate the Tustin model with the law's own coefficients.
    #[test]
    fn current_error_shrinks_by_one_minus_kappa_per_tick() {
        // Without the integral term, which would add its own (small) correction.
        let cfg = Gains {
            integral: 0.0,
            ..gains()
        }
        .build(&Plant::paper(), TS, 0)
        .unwrap();
        let mut st = State::default();
        let nominal = Plant::paper().envelope().unwrap().nominal();
        let l = nominal.inductance_h(3e-3);
        let rho = 0.5 * 0.4 * TS / l;
        let (al, be) = ((1.0 - rho) / (1.0 + rho), TS / l / (1.0 + rho));
        let mut i = 4.0_f32;
        let i_d = cfg
            .step(
                &mut State::default(),
                &input(3e-3, 6.0, Reference::hold(3e-3)),
            )
            .i_d_a;
        let mut s_prev = i - i_d;
        for _ in 0..5 {
            let out = cfg.step(&mut st, &input(3e-3, i, Reference::hold(3e-3)));
            i = al * i + be * out.u_v;
            let s = i - i_d;
            let ratio = s / s_prev;
            assert!((ratio - (1.0 - cfg.kappa())).abs() < 1e-3, "{ratio}");
            s_prev = s;
        }
    }

    #[test]
    fn kappa_respects_the_inductance_bound() {
        let cfg = law(0);
        // rho_x_nom / rho_x_hi = (1/1.0) / (1/0.8) = 0.8 -> kappa = 0.7 * 0.8.
        assert!((cfg.kappa() - 0.56).abs() < 1e-5, "{}", cfg.kappa());
    }

    /// Nominal Tustin coefficients `(al, be)` of the coil at gap `g`.
    fn coil(g: f32) -> (f32, f32) {
        let l = Plant::paper().envelope().unwrap().nominal().inductance_h(g);
        let rho = 0.5 * 0.4 * TS / l;
        ((1.0 - rho) / (1.0 + rho), TS / l / (1.0 + rho))
    }

    #[test]
    fn no_current_is_asked_when_the_spring_must_do_the_work() {
        let cfg = law(0);
        let mut st = State::default();
        // 1 mm above the target at rest: a_d = -(200)(0.1) + 9999 (1e-3) = -10 m/s^2,
        // F_d = -1.1 + 0.324 < 0, so x3d = 0 and the coil is driven down at the reaching rate:
        // the voltage puts the nominal current at (1 - kappa) 5 A next tick.
        let out = cfg.step(&mut st, &input(3e-3, 5.0, Reference::hold(2e-3)));
        assert_eq!(out.i_d_a, 0.0);
        let (al, be) = coil(3e-3);
        let next = al * 5.0 + be * out.u_v;
        assert!((next - (1.0 - cfg.kappa()) * 5.0).abs() < 0.01, "{next}");
        assert!(out.u_v < 0.0);
    }

    #[test]
    fn the_desired_current_is_limited_and_the_voltage_saturates() {
        let cfg = law(0);
        let mut st = State::default();
        // At 3 mm, closing at 5 cm/s, 1 mm below the target: z2 = -0.15,
        // a_d = 200 * 0.15 - 9999e-3 = 20 m/s^2, F_d = 2.2 + 0.324 - 0.375 = 2.15 N, which
        // needs 16.6 A with mu_lo: the desired current is clipped at 12 A.
        let moving = Input {
            v_mps: -0.05,
            ..input(3e-3, 0.0, Reference::hold(4e-3))
        };
        let out = cfg.step(&mut st, &moving);
        assert_eq!(out.i_d_a, 12.0);
        // kappa 12 A in one tick at 3 mm needs 6.72 A / be = 9.2 V.
        let (_, be) = coil(3e-3);
        assert!(
            (out.u_v - cfg.kappa() * 12.0 / be).abs() < 0.01,
            "{}",
            out.u_v
        );
        // On a 5 V bus the same request saturates.
        let out = cfg.step(
            &mut State::default(),
            &Input {
                vbus_v: 5.0,
                ..moving
            },
        );
        assert_eq!(out.u_v, 5.0);
    }

    #[test]
    fn the_desired_current_follows_the_inductance_probe() {
        let cfg = law(1);
        let base = input(3e-3, 6.0, Reference::hold(3e-3));
        let plain = cfg.step(&mut State::default(), &base);
        let probed = |probe_a: f32| {
            cfg.step(&mut State::default(), &Input { probe_a, ..base })
                .i_d_a
        };
        assert!(plain.i_d_a > 1.0, "{}", plain.i_d_a);
        assert!((probed(0.5) - plain.i_d_a - 0.5).abs() < 1e-6);
        assert!((probed(-0.5) - plain.i_d_a + 0.5).abs() < 1e-6);
        // Never above the law's current limit.
        assert_eq!(probed(1e3), cfg.gains().current_max_a);
        // A stopped probe adds nothing, bit for bit.
        assert_eq!(probed(0.0).to_bits(), plain.i_d_a.to_bits());
    }

    #[test]
    fn the_predictor_uses_the_voltage_applied_since_the_sample() {
        // With delay 1 and 2 V applied over the last period, the law predicts a larger
        // current than measured and asks for less voltage than without the prediction.
        let cfg = law(1);
        let r = Reference::hold(3e-3);
        let with = cfg.step(
            &mut State::default(),
            &Input {
                u_prev_v: 2.0,
                ..input(3e-3, 6.0, r)
            },
        );
        let without = cfg.step(&mut State::default(), &input(3e-3, 6.0, r));
        assert!(with.s_a > without.s_a);
        assert!(with.u_v < without.u_v);
    }

    #[test]
    fn bad_gains_are_named() {
        let p = Plant::paper();
        let g = Gains {
            reach: 1.5,
            ..Gains::new(130.0, 12.0)
        };
        assert_eq!(g.build(&p, TS, 0).unwrap_err().param, "law.reach");
        let g = Gains {
            alpha1: -1.0,
            ..Gains::new(130.0, 12.0)
        };
        assert_eq!(g.build(&p, TS, 0).unwrap_err().param, "law.alpha1");
        assert_eq!(
            Gains::new(130.0, 12.0).build(&p, TS, 2).unwrap_err().param,
            "delay_ticks"
        );
    }
}
