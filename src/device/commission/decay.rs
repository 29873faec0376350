//! The inductance from the current's decay after a voltage step.

use super::FIT_WEIGHT_FLOOR;
use crate::control::math;

/// A current's response to a voltage step towards a level `i_end` (measured before the
/// step, or by the hold after it: the sums are linear in it), the armature still:
/// `y(k) = i(k) - i_end` obeys `y(k) = A a^k` from the first reading the converter's
/// delay lets answer the step. Two weighted sums of the readings,
/// `S1 = sum w(k) y(k)` and `S2 = sum w(k) |w(k)| y(k)`, the weight `w(k) = +-g^k` (the
/// sign of the step's deviation, `+` for a step down) falling as the file's coil would
/// (`g`, its factor per period), are `A / (1 - g a)` and `A / (1 - g^2 a)`: their ratio
/// `r = S1 / S2` does not depend on the step's size, and `a = (r - 1) / (g (r - g))`.
/// Several steps add to both sums alike.
///
/// Both sums are linear in the readings, so their noise (zero mean) does not bias them,
/// as it biases a least squares on `y(k)` itself (whose regressor's noise variance a small
/// probe's readings are comparable with); and each distributes its weight over the whole
/// decay, so no single reading sets the estimate. (The instrument
/// `sum w(k) y(k+1) / sum w(k) y(k)` is unbiased too, but its two sums differ by the
/// first reading alone: one reading's noise on a 50-code step read a soft-sprung
/// plunger's inductance up to 20 % off, ten times what the two sums give.) The weight's
/// guess only costs efficiency, not accuracy.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Decay {
    /// The level the current settles at \[A\] (`NaN`: no fit in this phase).
    end_a: f32,
    /// Readings since the step (`u32::MAX`: the step has not come yet).
    since: u32,
    /// The weight of the next reading (0: this step's fit has ended).
    weight: f32,
    /// The file's coil's factor per period, the weight's decay.
    guess: f32,
    /// `S1` and `S2` of the deviations from `end_a`.
    s1: f32,
    s2: f32,
    /// Sums of the weights and of `w |w|`: the sums for an end other than `end_a`.
    sw1: f32,
    sw2: f32,
}

impl Decay {
    pub(super) const NONE: Self = Self::towards(f32::NAN, 1.0, 0.0);

    pub(super) const fn towards(end_a: f32, sign: f32, guess: f32) -> Self {
        Self {
            end_a,
            since: u32::MAX,
            weight: sign,
            guess,
            s1: 0.0,
            s2: 0.0,
            sw1: 0.0,
            sw2: 0.0,
        }
    }

    /// The next step goes to `end_a`, down for `sign` `+1`, up for `-1`; the sums so far
    /// are kept.
    pub(super) fn retarget(&mut self, end_a: f32, sign: f32) {
        self.end_a = end_a;
        self.since = u32::MAX;
        self.weight = sign;
    }

    /// A reading `i_a`; `stepped`: the voltage over the period it ends differs from the
    /// one before; `skip`: readings after the step that may still be the converter's
    /// earlier conversions.
    pub(super) fn add(&mut self, i_a: f32, stepped: bool, skip: u32) {
        if self.end_a.is_nan() || self.weight == 0.0 {
            return;
        }
        if self.since == u32::MAX {
            if !stepped {
                return;
            }
            self.since = 0;
        } else {
            self.since = self.since.saturating_add(1);
        }
        if self.since < skip {
            return;
        }
        let w = self.weight;
        let w2 = w * w.abs();
        let y = i_a - self.end_a;
        self.s1 += w * y;
        self.s2 += w2 * y;
        self.sw1 += w;
        self.sw2 += w2;
        self.weight *= self.guess;
        if self.weight.abs() < FIT_WEIGHT_FLOOR {
            // The file's coil would have settled: the rest is noise.
            self.weight = 0.0;
        }
    }

    /// The factor per period `a`, the current's end `shift_a` from `end_a` (the sums are
    /// linear in it); `None` unless `0 < a < 1`.
    pub(super) fn factor(&self, shift_a: f32) -> Option<f32> {
        let r = (self.s1 - shift_a * self.sw1) / (self.s2 - shift_a * self.sw2);
        let g = self.guess;
        let a = (r - 1.0) / (g * (r - g));
        (a > 0.0 && a < 1.0).then_some(a)
    }
}

/// One standard error of the time constant a [`Decay`] fit reads, relative, from the
/// converter's noise alone: `steps` steps of `step_a` each \[A\] towards their levels,
/// read with `noise_a` RMS per reading \[A\], decaying by `factor` per period, the fit's
/// weight by `guess`, its first reading `skip` periods after the step.
///
/// From the first reading on, step `s` reads `y(j) = B a^j + n(j)`, `B = step_a a^skip`,
/// weighted by `g^j` while `g^j` is at least [`FIT_WEIGHT_FLOOR`] (`J + 1` readings): each
/// sum is `steps B G(g a)` (`S1`) or `steps B G(g^2 a)` (`S2`), with `G(x) = sum x^j =
/// (1 - x^(J+1)) / (1 - x)`, and its noise has the variance `steps noise^2 G(g^2)` (`S1`),
/// `G(g^4)` (`S2`) and the covariance `G(g^3)`. To first order in the noise, the ratio `r =
/// S1 / S2` then carries `var r / r^2 = var S1 / S1^2 + var S2 / S2^2 - 2 cov / (S1 S2)`,
/// `a = (r - 1) / (g (r - g))` moves by `(1 - g) / (g (r - g)^2)` per unit of `r`, and
/// the time constant `-Ts / ln a` by `1 / (a |ln a|)` relatively per unit of `a`. `NaN`
/// for a factor or a guess outside `(0, 1)`.
///
/// The readings' noise is white (the converter's), the levels the deviations are taken
/// from are each a window's mean, whose noise is far smaller and is neglected.
pub(super) fn relative_error(
    step_a: f32,
    steps: f32,
    noise_a: f32,
    factor: f32,
    guess: f32,
    skip: u32,
) -> f32 {
    let (a, g) = (factor, guess);
    if !(a > 0.0 && a < 1.0 && g > 0.0 && g < 1.0) {
        return f32::NAN;
    }
    // Readings whose weight `g^j` is at least the floor: `j = 0..=J`.
    let readings = libm::floorf(libm::logf(FIT_WEIGHT_FLOOR) / libm::logf(g)) + 1.0;
    let sum = |x: f32| (1.0 - libm::powf(x, readings)) / (1.0 - x);
    #[expect(clippy::cast_precision_loss)]
    let b = steps * step_a * libm::powf(a, skip as f32);
    let (s1, s2) = (b * sum(g * a), b * sum(g * g * a));
    let n2 = steps * noise_a * noise_a;
    let (g2, g3) = (g * g, g * g * g);
    let r = s1 / s2;
    let var_r =
        r * r * n2 * (sum(g2) / (s1 * s1) + sum(g2 * g2) / (s2 * s2) - 2.0 * sum(g3) / (s1 * s2));
    let per_r = (1.0 - g) / (g * (r - g) * (r - g));
    per_r * math::sqrt(math::max(var_r, 0.0)) / (a * libm::logf(a).abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A standard normal deviate from a xorshift generator (Box-Muller).
    fn normal(state: &mut u64) -> f32 {
        let mut uniform = || {
            *state ^= *state << 13;
            *state ^= *state >> 7;
            *state ^= *state << 17;
            #[expect(clippy::cast_precision_loss)]
            let u = (*state >> 11) as f64 / (1u64 << 53) as f64;
            u
        };
        let (u1, u2) = (uniform().max(1e-300), uniform());
        #[expect(clippy::cast_possible_truncation)]
        let z = ((-2.0 * u1.ln()).sqrt() * (core::f64::consts::TAU * u2).cos()) as f32;
        z
    }

    #[test]
    fn the_predicted_error_of_a_fast_coil_s_decay_is_the_spread_its_noise_gives() {
        // 15 steps of 0.1 A, read with 0.5 mA of noise, two readings skipped; a coil of 1.2
        // periods weighed as the file's of one period.
        let (step_a, steps, noise_a, skip) = (0.1_f32, 15_u32, 5e-4_f32, 2_u32);
        let (tau, guess) = (1.2_f32, libm::expf(-1.0));
        let a = libm::expf(-1.0 / tau);
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let trials = 4000;
        let (mut sum, mut sum2) = (0.0_f64, 0.0_f64);
        for _ in 0..trials {
            let mut d = Decay::towards(0.0, 1.0, guess);
            for _ in 0..steps {
                d.retarget(0.0, 1.0);
                for k in 0..40_u8 {
                    let y = step_a * libm::powf(a, f32::from(k)) + noise_a * normal(&mut state);
                    d.add(y, k == 0, skip);
                }
            }
            let read = -1.0 / libm::logf(d.factor(0.0).unwrap_or(f32::NAN));
            let e = f64::from(read / tau - 1.0);
            sum += e;
            sum2 += e * e;
        }
        let mean = sum / f64::from(trials);
        let spread = (sum2 / f64::from(trials) - mean * mean).sqrt();
        #[expect(clippy::cast_precision_loss)]
        let predicted = f64::from(relative_error(
            step_a,
            steps as f32,
            noise_a,
            a,
            guess,
            skip,
        ));
        // 4000 trials read a spread within about 2 % of its own; the first-order
        // prediction is meant within 10 %.
        assert!(
            (spread / predicted - 1.0).abs() < 0.1,
            "spread {spread:.4}, predicted {predicted:.4}, bias {mean:.4}"
        );
        // It is a few per cent here: the noise, not a bias, is what the fit leaves.
        assert!(
            predicted > 0.01 && mean.abs() < 0.2 * predicted,
            "{predicted} {mean}"
        );
    }
}
