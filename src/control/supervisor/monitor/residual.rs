//! The electrical residual: the corner bank, the fit and the one-step check (see the
//! [monitors' documentation](super)).

use super::{Config, Inputs, State};
use crate::control::math;
use crate::control::supervisor::Fault;

/// Relative allowance on the motional back-EMF in the residual: the force coefficient
/// anywhere in its bounds (at most +-25 % of nominal for +-20 % surfaces) and the
/// velocity estimate's error during a move \[-\].
pub const EMF_ALLOWANCE: f32 = 0.5;

/// Electrical residual (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Residual {
    /// Absolute widening of the admissible envelope (converter noise), in steps of the
    /// current converter \[code\].
    pub noise_codes: f32,
    /// Relative widening of the admissible change, per period \[-\].
    pub margin: f32,
    /// Consecutive ticks outside the envelope, on one side, before a fault \[tick\]
    /// (at least 2).
    pub confirm_ticks: u16,
    /// One-step excess that no coil can produce \[A\].
    pub jump_a: f32,
    /// Current below which the coil counts as open \[A\].
    pub open_a: f32,
    /// Factor between "outside the bounds" and "broken" \[-\].
    pub gross: f32,
    /// Length of the corner bank's window \[tick\] (at least 2).
    pub window: u16,
    /// Length of a block over which the coil's resistance is learned \[tick\] (0: the
    /// bank keeps the resistance bounds).
    pub learn_ticks: u16,
    /// Relative half-width of the learned resistance's interval \[-\].
    pub learn_tol: f32,
    /// The most a healthy channel's zero is off (its offset class) \[A\].
    pub offset_a: f32,
    /// How long a learned resistance holds without a block that confirms it \[tick\].
    pub learn_age_ticks: u16,
}

/// The four corner coils of a step: gain `k / (1 + R k / 2)` and resistance.
type Corners = [(f32, f32); 4];

impl Config {
    pub(super) fn residual(&self, st: &mut State, inp: &Inputs) -> Option<Fault> {
        let settings = self.monitors.residual.as_ref()?;
        // The voltage between the two samples: the drive `delay` ticks before the newer.
        let (u, driving) = if self.delayed {
            st.u_hist[1]
        } else {
            st.u_hist[0]
        };
        if !driving {
            st.jumped = false;
            st.bank_ticks = 0;
            restart_block(st);
            return None;
        }
        let g = self.convention.gap_m(inp.x_m);
        let i0 = st.i_prev;
        // Applied voltage plus the motional back-EMF, with its allowance.
        let emf = self.emf_sign * inp.v_mps * i0 * self.nominal.force_coefficient_h_per_m(g);
        let u = u + emf;
        let du = EMF_ALLOWANCE * emf.abs();
        // The four corner coils (L_lo or L_hi, R_lo or R_hi): gain and resistance of
        // `di = k (u - R i) / (1 + R k / 2)`, with `k = Ts / L = Ts rho(g) / N^2`.
        // `k_fast` (`Ts / L_lo`) is the larger gain, `k_slow` (`Ts / L_hi`) the smaller.
        let (k_fast, k_slow) = (
            self.ts_over_n2 * self.envelope.rho_hi(g),
            self.ts_over_n2 * self.envelope.rho_lo(g),
        );
        let gain = |k: f32, res: f32| k / (1.0 + 0.5 * res * k);
        let (r_lo, r_hi) = self.resistance_bounds(settings, st, i0);
        let corners = [
            (gain(k_fast, r_lo), r_lo),
            (gain(k_fast, r_hi), r_hi),
            (gain(k_slow, r_lo), r_lo),
            (gain(k_slow, r_hi), r_hi),
        ];
        // Folds from +-inf, never NaN: the one-comparison running extremes are exact.
        // Every gain is positive, so the least change takes the least voltage.
        let (mut d_min, mut d_max) = (f32::INFINITY, f32::NEG_INFINITY);
        for &(f, res) in &corners {
            d_min = math::running_min(d_min, f * (u - du - res * i0));
            d_max = math::running_max(d_max, f * (u + du - res * i0));
        }
        let d_meas = inp.i_a - i0;
        // One step: beyond the interval by more than a coil `gross` times the fastest
        // admissible one could explain, then back inside: the reading stepped.
        let largest = math::running_max(d_min.abs(), d_max.abs());
        let widen = settings.margin * largest + self.noise_a;
        let (lo, hi) = (d_min - widen, d_max + widen);
        let offset =
            st.jumped && self.admissible_after_step(settings, st, &corners, u, du, i0, d_meas);
        let reach = settings.jump_a + (settings.gross - 1.0) * largest;
        let jumped =
            (d_meas > hi + reach || d_meas < lo - reach) && inp.i_a.abs() >= settings.open_a;
        // Two jumps in a row, both away from zero, the second not what the first would
        // leave behind had the reading stepped: the coil carries ever more current than
        // any admissible coil (or one `gross` times faster) on this voltage, a resistance
        // that dropped.
        let excess = d_meas - 0.5 * (d_min + d_max);
        let short =
            !offset && st.jumped && jumped && st.step_a * inp.i_a > 0.0 && excess * inp.i_a > 0.0;
        st.jumped = jumped;
        if jumped {
            st.step_a = excess;
            st.step_tol_a = 0.5 * (d_max - d_min) + widen;
        }
        // The nominal prediction and the regressors of the fit.
        let k = self.ts_over_n2 * self.nominal.reluctance_per_h(g);
        let p = gain(k, self.r_nom) * (u - self.r_nom * i0);
        let fit = (k * i0, d_meas - p, p);
        let bank = self.bank(
            settings,
            st,
            inp.i_a,
            i0,
            u,
            du * gain(k_fast, self.r_lo) + settings.margin * largest,
            &corners,
            fit,
        );
        if offset {
            return Some(Fault::CurrentOffset);
        }
        if short {
            return Some(Fault::CoilShort);
        }
        if bank.is_none() {
            self.learn(
                settings,
                st,
                u,
                du,
                d_meas / k,
                i0 + 0.5 * d_meas,
                (k_fast, k_slow),
            );
        }
        bank
    }

    /// The resistance interval of the corners at the current `i0`: the learned one,
    /// while it holds and `i0` is within a factor 2 of the current it was learned at;
    /// the bounds otherwise.
    fn resistance_bounds(&self, settings: &Residual, st: &State, i0: f32) -> (f32, f32) {
        let i = i0.abs();
        if st.learned_age < settings.learn_age_ticks
            && i >= 0.5 * st.i_learned
            && i <= 2.0 * st.i_learned
        {
            st.r_learned
        } else {
            (self.r_lo, self.r_hi)
        }
    }

    /// Learns the coil's resistance over blocks of `learn_ticks` steps on which the bank
    /// found nothing: with Tustin's step, `u - di / k = R (i0 + i1) / 2` exactly for the
    /// true `k = Ts / L`, so over a block `R = (sum (u + e) - sum di / k) / sum i_mid`.
    /// The block counts when what the estimate cannot know stays within half the
    /// interval's width: the inductance anywhere in its bounds (a relative
    /// `(k_fast - k_slow) / (k_fast + k_slow)` of the inductive sum) and the back-EMF's
    /// allowance `du`; when its mean current is above the channel's offset class; and
    /// when the resistance lies within the bounds (a coil outside them is the bank's to
    /// name).
    #[expect(clippy::too_many_arguments)]
    fn learn(
        &self,
        settings: &Residual,
        st: &mut State,
        u: f32,
        du: f32,
        inductive_v: f32,
        i_mid: f32,
        (k_fast, k_slow): (f32, f32),
    ) {
        st.learned_age = st.learned_age.saturating_add(1);
        if settings.learn_ticks == 0 {
            return;
        }
        if st.bank_out != 0 || st.jumped {
            restart_block(st);
            return;
        }
        let [su, sl, sd, si] = st.learn;
        st.learn = [su + u, sl + inductive_v, sd + du, si + i_mid];
        st.learn_ticks = st.learn_ticks.saturating_add(1);
        if st.learn_ticks < settings.learn_ticks {
            return;
        }
        let [su, sl, sd, si] = st.learn;
        restart_block(st);
        let n = f32::from(settings.learn_ticks);
        let i_mean = si.abs() / n;
        if i_mean <= settings.offset_a {
            return;
        }
        let r = (su - sl) / si;
        let unknown = (k_fast - k_slow) / (k_fast + k_slow) * sl.abs() + sd;
        if unknown <= 0.5 * settings.learn_tol * r * si.abs() && r >= self.r_lo && r <= self.r_hi {
            // Used down to half the block's current, the channel's offset `o` reads as
            // `R o / i_mean` more or less resistance.
            let tol = settings.learn_tol + settings.offset_a / i_mean;
            st.r_learned = (
                math::running_max(self.r_lo, r * (1.0 - tol)),
                math::running_min(self.r_hi, r * (1.0 + tol)),
            );
            st.i_learned = i_mean;
            st.learned_age = 0;
        }
    }

    /// The step after a jump, under the hypothesis that the jump was the reading
    /// stepping by `o` (`st.step_a`, known within `st.step_tol_a`): the coil's current
    /// before this step was then the reading less `o`, and each corner `(f, R)` moves it
    /// by `f (u - R (i0 - o)) = f (u - R i0) + f R o`. Whether `d_meas` lies in that
    /// interval, widened as the one-step interval is. A short makes the reading run on
    /// ahead by as much as on the jump; an offset shifts the next step by only `f R o`,
    /// the jump times the period over the coil's time constant.
    #[expect(clippy::too_many_arguments)]
    fn admissible_after_step(
        &self,
        settings: &Residual,
        st: &State,
        corners: &Corners,
        u: f32,
        du: f32,
        i0: f32,
        d_meas: f32,
    ) -> bool {
        let (o_lo, o_hi) = (st.step_a - st.step_tol_a, st.step_a + st.step_tol_a);
        let (mut d_min, mut d_max) = (f32::INFINITY, f32::NEG_INFINITY);
        for &(f, res) in corners {
            // `f res > 0`: the least change takes the least offset.
            d_min = math::running_min(d_min, f * (u - du - res * (i0 - o_lo)));
            d_max = math::running_max(d_max, f * (u + du - res * (i0 - o_hi)));
        }
        let largest = math::running_max(d_min.abs(), d_max.abs());
        let widen = settings.margin * largest + self.noise_a;
        d_meas >= d_min - widen && d_meas <= d_max + widen
    }

    /// The corner bank (see the module documentation): advances the four corner coils by
    /// one period under `u` and compares the reading with their envelope, widened by the
    /// allowance `allow_a` of each period since the anchor (the back-EMF's and the
    /// model's margin on the period's largest admissible change); accumulates the fit's
    /// sums with the regressor `q = k i`, the deviation `e` and the prediction `p`.
    #[expect(clippy::too_many_arguments)]
    fn bank(
        &self,
        settings: &Residual,
        st: &mut State,
        i_a: f32,
        i0: f32,
        u: f32,
        allow_a: f32,
        corners: &Corners,
        (q, e, p): (f32, f32, f32),
    ) -> Option<Fault> {
        if st.bank_ticks == 0 || (st.bank_ticks >= settings.window && st.bank_out == 0) {
            st.bank = [i0; 4];
            st.bank_anchor = i0;
            st.bank_ticks = 0;
            st.bank_out = 0;
            st.bank_side = 0;
            st.bank_allow = 0.0;
        }
        st.bank_ticks = st.bank_ticks.saturating_add(1);
        st.bank_allow += allow_a;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for (c, &(f, res)) in st.bank.iter_mut().zip(corners.iter()) {
            *c += f * (u - res * *c);
            lo = math::running_min(lo, *c);
            hi = math::running_max(hi, *c);
        }
        let anchor = st.bank_anchor;
        // The margin is paid on every period's change, not on the net excursion: a drive
        // that swings about the holding voltage moves the coil back and forth, and what
        // the model leaves out adds up over the swings, not over their net.
        let widen = self.noise_a + st.bank_allow;
        let side: i8 = if i_a > hi + widen {
            1
        } else if i_a < lo - widen {
            -1
        } else {
            0
        };
        st.bank_out = if side == 0 {
            0
        } else if side == st.bank_side {
            st.bank_out.saturating_add(1)
        } else {
            1
        };
        st.bank_side = side;
        // The fit covers the excursion only, from the step that carried the reading out:
        // a window that began before a fault would dilute it with healthy steps.
        let [pp, pq, qq, pe, qe] = if st.bank_out <= 1 { [0.0; 5] } else { st.fit };
        st.fit = [pp + p * p, pq + p * q, qq + q * q, pe + p * e, qe + q * e];
        if st.bank_out < settings.confirm_ticks {
            return None;
        }
        if i_a.abs() < settings.open_a {
            // Every admissible coil is beyond the allowance on one side of the reading.
            return Some(Fault::CoilOpen);
        }
        // The direction the admissible coils were driven: all up, all down, or holding.
        let drive: i8 = if lo > anchor {
            1
        } else if hi < anchor {
            -1
        } else {
            0
        };
        let along = (i_a - anchor) * f32::from(drive);
        // `side` is 1 or -1 here (the reading is outside): opposite a drive that is not 0.
        if drive != 0 && side != drive && along > -self.noise_a {
            // Behind every admissible coil, and not against the drive. The least
            // admissible change: every corner lies on the drive's side of the anchor and
            // (rounding is monotonic) the nearest is `lo` when rising, `hi` when falling.
            let least = if drive > 0 { lo - anchor } else { anchor - hi };
            return Some(if along * settings.gross < least {
                Fault::CurrentStuck
            } else {
                Fault::ModelBounds
            });
        }
        // Ahead of the drive, against it, or away while holding: a coil that carries more
        // current than any admissible one on this voltage.
        Some(
            if self.resistance_fit(&st.fit) < self.r_lo / settings.gross {
                Fault::CoilShort
            } else {
                Fault::ModelBounds
            },
        )
    }

    /// Resistance fitted over the bank's window, `R_nom - b`; all of the deviation is
    /// taken as resistance when the two regressors cannot be separated.
    fn resistance_fit(&self, fit: &[f32; 5]) -> f32 {
        let [pp, pq, qq, pe, qe] = *fit;
        let det = pp * qq - pq * pq;
        let b = if det > 1e-3 * pp * qq && det > 0.0 {
            (pp * qe - pq * pe) / det
        } else if qq > 0.0 {
            // Proportional regressors (holding on a constant voltage): all resistance.
            qe / qq
        } else {
            0.0
        };
        self.r_nom - b
    }
}

/// Starts the resistance's learning block afresh.
fn restart_block(st: &mut State) {
    st.learn = [0.0; 4];
    st.learn_ticks = 0;
}
