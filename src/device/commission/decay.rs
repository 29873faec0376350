//! The inductance from the current's decay after a voltage step.

use super::FIT_WEIGHT_FLOOR;

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
