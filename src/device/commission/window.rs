//! The averaging windows: the applied voltage, the current and the position over a
//! window, and the resistance from two of them.

use super::{Abort, Resistance};
use crate::control::math;
use crate::control::sense::Measurement;

/// One hold's averaging window: sums of deviations from its first reading (which keeps
/// the sums of squares well conditioned).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Window {
    n: u32,
    u: f32,
    vbus: f32,
    i: Moments,
    x: Moments,
    pub(super) x_min: f32,
    pub(super) x_max: f32,
    /// `x_min` and `x_max` hold a reading.
    spanned: bool,
    /// The position's sum of deviations and the count at the window's half.
    x_half: f32,
    n_half: u32,
}

/// Running sums of one reading's deviations from the window's first.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Moments {
    first: f32,
    sum: f32,
    squares: f32,
}

impl Moments {
    pub(super) const EMPTY: Self = Self {
        first: 0.0,
        sum: 0.0,
        squares: 0.0,
    };

    pub(super) fn add(&mut self, first: bool, v: f32) {
        if first {
            self.first = v;
        }
        let d = v - self.first;
        self.sum += d;
        self.squares += d * d;
    }

    /// Mean and the variance of the mean over `n` readings.
    fn mean(&self, n: f32) -> (f32, f32) {
        let mean_d = self.sum / n;
        let var = math::max(self.squares / n - mean_d * mean_d, 0.0);
        (self.first + mean_d, var / n)
    }
}

impl Window {
    pub(super) const EMPTY: Self = Self {
        n: 0,
        u: 0.0,
        vbus: 0.0,
        i: Moments::EMPTY,
        x: Moments::EMPTY,
        x_min: 0.0,
        x_max: 0.0,
        spanned: false,
        x_half: 0.0,
        n_half: 0,
    };

    /// Widens the span of positions by `x_m` (a reading of the window, or one just
    /// before it).
    pub(super) fn span(&mut self, x_m: f32) {
        if !self.spanned {
            self.spanned = true;
            self.x_min = x_m;
            self.x_max = x_m;
        }
        self.x_min = math::min(self.x_min, x_m);
        self.x_max = math::max(self.x_max, x_m);
    }

    pub(super) fn add(&mut self, u_v: f32, m: &Measurement) {
        let first = self.n == 0;
        self.span(m.x_m);
        self.n = self.n.saturating_add(1);
        self.u += u_v;
        self.vbus += m.vbus_v;
        self.i.add(first, m.i_a);
        self.x.add(first, m.x_m);
    }

    fn n(&self) -> f32 {
        self.n.max(1) as f32
    }

    /// Mean voltage, mean current, variance of the mean current.
    pub(super) fn current(&self) -> (f32, f32, f32) {
        let (i, var) = self.i.mean(self.n());
        (self.u / self.n(), i, var)
    }

    /// Mean position and the variance of that mean.
    pub(super) fn position(&self) -> (f32, f32) {
        self.x.mean(self.n())
    }

    /// Marks the window's half.
    pub(super) fn halve(&mut self) {
        self.x_half = self.x.sum;
        self.n_half = self.n;
    }

    /// The second half's mean position less the first's \[m\] (zero before the half).
    pub(super) fn drift(&self) -> f32 {
        let second_n = self.n.saturating_sub(self.n_half);
        if self.n_half == 0 || second_n == 0 {
            return 0.0;
        }
        let second = (self.x.sum - self.x_half) / second_n as f32;
        second - self.x_half / self.n_half as f32
    }
}

/// The resistance from two holds' windows, `expected_a` the difference of their currents
/// the plan aims at; [`Abort::NoResponse`] when less than a tenth of it answers.
pub(super) fn resistance(
    first: &Window,
    second: &Window,
    expected_a: f32,
) -> Result<Resistance, Abort> {
    let (u1, i1, var1) = first.current();
    let (u2, i2, var2) = second.current();
    let di = i2 - i1;
    if di.is_nan() || di <= 0.1 * expected_a {
        return Err(Abort::NoResponse);
    }
    let ohm = (u2 - u1) / di;
    let uncertainty_ohm = 2.0 * ohm * math::sqrt(var1 + var2) / di;
    let n = first.n.saturating_add(second.n).max(1) as f32;
    Ok(Resistance {
        ohm,
        uncertainty_ohm,
        i_a: [i1, i2],
        u_v: [u1, u2],
        vbus_v: (first.vbus + second.vbus) / n,
    })
}
