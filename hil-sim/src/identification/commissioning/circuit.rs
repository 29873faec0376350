//! The magnetic circuit fitted to the inductances along the stroke.

use ema::control::actuator::Actuator;
use ema::device::commission::Report;

use super::{coverage_factor, HoldInductance, IRON_SHARE};

/// How well the routine's step responses read an end stop's inductance at best, two
/// standard errors, relative: the weight of the stops' readings in [`Circuit::fit`] unless
/// the converter's noise leaves them less certain ([`stop_uncertainty`]). About what the
/// holds' probes read: the family's drawn
/// plants read the stops with median errors of 0.1 % to 1 % (`hil-sim commission`),
/// the holds with two standard errors of 0.2 % to 0.9 %. Weighed as the 5 % the
/// routine is held to, the stops counted for nothing beside the holds, and the line
/// through the holds alone, extrapolated, read the 12 V solenoid's force near its closed
/// stop 2 % off and its spring up to 10 % off (100 drawn plants). Either way of 1 % it
/// does worse: on 1000 drawn 12 V solenoids, weighed as 0.5 % the stops read 10
/// springs more than 5 % off, as 2 % five, as 1 % one (5.4 %).
pub const STOP_INDUCTANCE_CLASS: f64 = 0.01;

/// Two standard errors of the inductances the commissioning's `report` read at the open
/// and at the closed stop of the actuator file `a`, relative: what the converter's noise
/// leaves the step-response fits ([`ema::device::commission::Plan::inductance_uncertainty`],
/// the board's noise [`ema::control::sense::NOISE_RMS_CODES`] on the file's current
/// channel), at least [`STOP_INDUCTANCE_CLASS`] (what the noise leaves a slow coil is far
/// below what the method's other errors do). A coil whose time constant at the open stop
/// is about the period reads that stop from few, small readings: on the development seed's
/// actuators whose open stop's time constant is under 2.5 periods, the errors' spread over
/// this prediction's standard error is 1.0 to 1.2 in each band of time constants (drawn
/// plants and converters, `hil-sim commission`'s draws).
#[must_use]
#[expect(clippy::cast_possible_truncation)]
pub fn stop_uncertainty(report: &Report, a: &Actuator) -> [f64; 2] {
    // An f32 widened and narrowed again: the same value.
    let noise_a = super::ChannelNoise::of(a).current_a as f32;
    let predicted = ema::device::commission::Plan::for_actuator(a, a.board.rate_hz)
        .map_or([f32::NAN; 2], |plan| {
            plan.inductance_uncertainty(report, noise_a)
        });
    predicted.map(|u| STOP_INDUCTANCE_CLASS.max(f64::from(u)))
}

/// The open stop's inductance a commissioned file starts from \[H\], and two standard
/// errors of it, relative: the one the commissioning's `report` read, unless what the
/// converter's noise leaves it ([`stop_uncertainty`]), as a 99 % interval
/// ([`coverage_factor`]), is wider than the file `a`'s surface tolerance: then the file's,
/// whose tolerance is taken as that interval. A coil whose time constant at the open stop
/// is about the period reads it from few, small readings, and the datasheet knows it
/// better; with the holds' probes the circuit is fitted mostly to them, and the open
/// stop's value matters where they read nothing.
#[must_use]
pub fn open_stop(report: &Report, a: &Actuator) -> (f64, f64) {
    let [open, _] = stop_uncertainty(report, a);
    let coverage = interval_per_two_se();
    let surface = f64::from(a.tolerance.surface);
    match a.time_scales() {
        Ok(t) if coverage * open > surface => (
            f64::from(t.coil_open_s) * f64::from(a.coil.resistance_ohm),
            surface / coverage,
        ),
        _ => (f64::from(report.inductance.open_h), open),
    }
}

/// A 99 % interval ([`coverage_factor`]) per unit of two standard errors.
pub(super) fn interval_per_two_se() -> f64 {
    0.5 * coverage_factor(usize::MAX)
}

/// The 99 % interval ([`coverage_factor`]) of the open stop's inductance the
/// commissioning's `report` read for the file `a`, relative: what [`open_stop`] judges the
/// reading by.
#[must_use]
pub fn open_stop_interval(report: &Report, a: &Actuator) -> f64 {
    interval_per_two_se() * stop_uncertainty(report, a)[0]
}

/// How much better, in standard deviations, a surface growing with the gap must explain
/// the inductances than a constant one for [`Circuit::fit`] to keep it (the weighted sum of
/// squared residuals falls by at least its square). A growth fitted to the readings'
/// noise bends the force's slope, and a stop read a few times further off than
/// [`STOP_INDUCTANCE_CLASS`] (the 12 V solenoid's open stop, up to 2.7 %) looks like
/// growth: on 1000 drawn 12 V solenoids, whose surface is constant, a growth kept at
/// three deviations read 4 springs more than 5 % off (up to 8.4 %), at five one to
/// three in a thousand (up to 5.4 %, on two sets of draws; with the open stop's probe
/// twice as long, [`ema::device::commission::PROBE_READINGS`], none and one, 5.2 %). A
/// growth that matters is still kept: a pole whose sides grow by 0.3 of the gap, 14 % off
/// the stops' line, is read within 2 % of its growth (the tests).
pub const GROWTH_SIGNIFICANCE: f64 = 5.0;

/// The largest surface growth [`Circuit::fit`] considers, as `q g` at the open stop: at
/// `q g = 1` a square pole's airgap reluctance `g / S(g)` stops rising with the gap and
/// the pull at the open stop vanishes, which no reluctance actuator does.
pub const GROWTH_MAX: f64 = 0.9;

/// The magnetic circuit a commissioning reads, in the paper's reluctance model with
/// fringing: `N^2 / L(g) = rho_0 + rho_x(g) g`, each airgap's surface growing with the
/// gap as a rectangular pole's does, `S(g) = S(0) (1 + q g)(1 + q g / beta)` (the
/// pole's sides `a` and `b = beta a` each grown by `k g`, `q = k / a`), so
/// `1/L(g) = c0 + c1 g / ((1 + q g)(1 + q g / beta))`.
///
/// Through the stops alone ([`Circuit::through_stops`]) it is the two-inductance form,
/// `q = 0`; with the holds' probes ([`Circuit::fit`]) six inductances along the stroke
/// fix `c0`, `c1` and `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circuit {
    /// `c0 = rho_0 / N^2`, the iron's share of `1/L` \[1/H\].
    pub iron_per_h: f64,
    /// `c1 = rho_x(0) / N^2`, the slope of `1/L` against the gap at a closed gap
    /// \[1/(H m)\].
    pub gap_per_h_m: f64,
    /// The surface's growth `q` \[1/m\].
    pub growth_per_m: f64,
    /// The pole's aspect `beta = b / a` \[-\].
    pub aspect: f64,
    /// The airgap at the open stop, the file's residual gap and stroke \[m\].
    pub open_gap_m: f64,
    /// The stroke \[m\].
    pub stroke_m: f64,
}

impl Circuit {
    /// The airgap at position `x_m` \[m\].
    #[must_use]
    pub fn gap_m(&self, x_m: f64) -> f64 {
        self.open_gap_m - x_m
    }

    /// `g / ((1 + q g)(1 + q g / beta))` and its derivative against `g`.
    fn shape(&self, g_m: f64) -> (f64, f64) {
        shape(self.growth_per_m, self.aspect, g_m)
    }

    /// `1/L` at position `x_m` \[1/H\].
    #[must_use]
    pub fn inverse_h(&self, x_m: f64) -> f64 {
        self.iron_per_h + self.gap_per_h_m * self.shape(self.gap_m(x_m)).0
    }

    /// The inductance at position `x_m` \[H\].
    #[must_use]
    pub fn inductance_h(&self, x_m: f64) -> f64 {
        1.0 / self.inverse_h(x_m)
    }

    /// `dL/dx` at position `x_m`, the force coefficient: the pull is `i^2 / 2` times it
    /// \[H/m\]. (The airgap closes as `x` grows: `dL/dx = (d(1/L)/dg) L^2`.)
    #[must_use]
    pub fn force_coefficient_h_per_m(&self, x_m: f64) -> f64 {
        let inverse = self.inverse_h(x_m);
        self.gap_per_h_m * self.shape(self.gap_m(x_m)).1 / (inverse * inverse)
    }

    /// The airgap surface at the open stop over the surface at the closed stop \[-\].
    #[must_use]
    pub fn surface_growth(&self) -> f64 {
        let (q, b) = (self.growth_per_m, self.aspect);
        let s = |g: f64| (1.0 + q * g) * (1.0 + q * g / b);
        s(self.open_gap_m) / s(self.open_gap_m - self.stroke_m)
    }

    /// The two-inductance form through the inductances the commissioning's `report`
    /// measured at the stops, for the actuator file `a` (its residual gap and stroke):
    /// `1/L` linear in the gap, `q = 0`.
    #[must_use]
    pub fn through_stops(report: &Report, a: &Actuator) -> Self {
        Self::line(
            f64::from(report.inductance.open_h),
            f64::from(report.inductance.closed_h),
            a,
        )
    }

    /// The two-inductance form through the inductances `open_h` and `closed_h` \[H\] at
    /// the stops of the actuator file `a` (its residual gap and stroke): `1/L` linear in
    /// the gap, `q = 0`.
    #[must_use]
    pub fn line(open_h: f64, closed_h: f64, a: &Actuator) -> Self {
        let (open_gap_m, stroke_m) = gaps(a);
        let (y_open, y_closed) = (1.0 / open_h, 1.0 / closed_h);
        let slope = (y_open - y_closed) / stroke_m;
        Self {
            iron_per_h: y_closed - slope * (open_gap_m - stroke_m),
            gap_per_h_m: slope,
            growth_per_m: 0.0,
            aspect: aspect(a),
            open_gap_m,
            stroke_m,
        }
    }

    /// The circuit in the pole geometry form of `file` (`Magnetics::Geometry`, returned
    /// unchanged otherwise) for a coil of `turns`: its gap count, fringing coefficient and
    /// aspect kept, the sides scaled to the surface the circuit's `c1` asks (`c1 = gaps /
    /// (mu0 S(0) N^2)`, `S(0)` the fringing coefficient times the sides), the growth as
    /// `fringing_spread = q a` and the iron's reluctance `c0 N^2`.
    #[must_use]
    #[expect(clippy::cast_possible_truncation)]
    pub fn geometry(
        &self,
        turns: f32,
        file: ema::control::actuator::Magnetics,
    ) -> ema::control::actuator::Magnetics {
        let ema::control::actuator::Magnetics::Geometry {
            gaps,
            pole_a_m,
            pole_b_m,
            fringing_coefficient,
            ..
        } = file
        else {
            return file;
        };
        let n2 = f64::from(turns).powi(2);
        let surface =
            f64::from(gaps) / (f64::from(ema::control::model::MU0_H_PER_M) * self.gap_per_h_m * n2);
        let scale = (surface
            / (f64::from(fringing_coefficient) * f64::from(pole_a_m) * f64::from(pole_b_m)))
        .sqrt();
        let side = scale * f64::from(pole_a_m);
        ema::control::actuator::Magnetics::Geometry {
            gaps,
            pole_a_m: side as f32,
            pole_b_m: (scale * f64::from(pole_b_m)) as f32,
            fringing_coefficient,
            fringing_spread: (self.growth_per_m * side) as f32,
            iron_reluctance_per_h: (self.iron_per_h * n2) as f32,
        }
    }

    /// The circuit that best fits the stops' inductances (the commissioning's `report`)
    /// and the holds' (none where no probe read one), for the actuator file `a` (its
    /// residual gap, stroke and pole's aspect; a file in the two-inductance form: a square
    /// pole).
    ///
    /// Weighted least squares on `1/L`, each reading by its own uncertainty (the holds': their
    /// probes'; the stops': [`stop_uncertainty`], the open stop's as [`open_stop`] gives it): for each growth `q` the line in
    /// `c0`, `c1` is exact, and `q` is searched from none to [`GROWTH_MAX`], on a grid
    /// and then by golden section about its best point, and kept only where it explains
    /// the readings [`GROWTH_SIGNIFICANCE`] standard deviations better than none. The
    /// iron's `c0` is kept at least [`IRON_SHARE`] of the closed stop's `1/L` (the form
    /// the file writes needs a positive iron reluctance). Fewer than two holds read: the
    /// growth is not fitted (a line through the readings).
    #[must_use]
    pub fn fit(report: &Report, a: &Actuator, holds: &[Option<HoldInductance>]) -> Self {
        let stops = Self::through_stops(report, a);
        let ((open_h, open_u), closed_h) =
            (open_stop(report, a), f64::from(report.inductance.closed_h));
        let [_, closed_u] = stop_uncertainty(report, a);
        // (gap, 1/L, weight): the weight 1 / sd(1/L)^2, sd(1/L) = (sd(L) / L) / L, and
        // two standard errors `u` of `L`, relative, are `2 sd(L) / L`.
        let weight = |h: f64, u: f64| (2.0 * h / u).powi(2);
        let mut points = vec![
            (stops.gap_m(0.0), 1.0 / open_h, weight(open_h, open_u)),
            (
                stops.gap_m(stops.stroke_m),
                1.0 / closed_h,
                weight(closed_h, closed_u),
            ),
        ];
        points.extend(holds.iter().flatten().map(|h| {
            let (x, l, two_se) = (h.x_m, h.inductance_h, h.uncertainty_h);
            let sd = 0.5 * two_se / l;
            (stops.gap_m(x), 1.0 / l, (l / sd).powi(2))
        }));
        let floor = IRON_SHARE as f64 / closed_h;
        let line = |q: f64| line_fit(&points, q, stops.aspect, floor);
        let best = if holds.iter().flatten().count() < 2 {
            0.0
        } else {
            let most = GROWTH_MAX / stops.open_gap_m;
            let grid = 64;
            #[expect(clippy::cast_precision_loss)]
            let at = |j: usize| most * (j as f64 / grid as f64).powi(2);
            let j = (0..=grid)
                .min_by(|&p, &q| line(at(p)).2.total_cmp(&line(at(q)).2))
                .unwrap_or(0);
            let q = golden(
                |q| line(q).2,
                at(j.saturating_sub(1)),
                at((j + 1).min(grid)),
            );
            let q = if line(q).2 <= line(at(j)).2 { q } else { at(j) };
            // A growth the readings do not ask for is their noise.
            if line(0.0).2 - line(q).2 > GROWTH_SIGNIFICANCE * GROWTH_SIGNIFICANCE {
                q
            } else {
                0.0
            }
        };
        let (c0, c1, _) = line(best);
        Self {
            iron_per_h: c0,
            gap_per_h_m: c1,
            growth_per_m: best,
            ..stops
        }
    }

    /// The largest deviation, relative, of this circuit's inductance from each of the
    /// holds' readings (`None` when none was read).
    #[must_use]
    pub fn deviation(&self, holds: &[Option<HoldInductance>]) -> Option<f64> {
        holds
            .iter()
            .flatten()
            .map(|h| (self.inductance_h(h.x_m) / h.inductance_h - 1.0).abs())
            .reduce(crate::simulation::targets::worse)
    }
}

/// The file `a`'s airgap at the open stop and its stroke \[m\].
pub(super) fn gaps(a: &Actuator) -> (f64, f64) {
    let m = &a.mechanics;
    (
        f64::from(m.residual_gap_m) + f64::from(m.stroke_m),
        f64::from(m.stroke_m),
    )
}

/// The pole's aspect `b / a` in file `a` (a square one for the two-inductance form).
pub(super) fn aspect(a: &Actuator) -> f64 {
    match a.magnetics {
        ema::control::actuator::Magnetics::Geometry {
            pole_a_m, pole_b_m, ..
        } => f64::from(pole_b_m) / f64::from(pole_a_m),
        ema::control::actuator::Magnetics::Inductance { .. } => 1.0,
    }
}

/// `g / ((1 + q g)(1 + q g / beta))` and its derivative against `g`.
pub(super) fn shape(q: f64, beta: f64, g: f64) -> (f64, f64) {
    let (p1, p2) = (1.0 + q * g, 1.0 + q * g / beta);
    let d = p1 * p2;
    let dd = q * p2 + q / beta * p1;
    (g / d, (d - g * dd) / (d * d))
}

/// The weighted least squares line `1/L = c0 + c1 shape(g)` through `points`
/// (`(gap, 1/L, weight)`) at growth `q`, `c0` at least `floor`: `(c0, c1, weighted sum
/// of the squared residuals)`.
pub(super) fn line_fit(
    points: &[(f64, f64, f64)],
    q: f64,
    beta: f64,
    floor: f64,
) -> (f64, f64, f64) {
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(g, y, w) in points {
        let x = shape(q, beta, g).0;
        sw += w;
        sx += w * x;
        sy += w * y;
        sxx += w * x * x;
        sxy += w * x * y;
    }
    let det = sw * sxx - sx * sx;
    let (mut c0, mut c1) = ((sy * sxx - sx * sxy) / det, (sw * sxy - sx * sy) / det);
    // Below the floor, or no number at all (a singular fit).
    if c0.partial_cmp(&floor) == Some(std::cmp::Ordering::Less) || c0.is_nan() {
        c0 = floor;
        c1 = (sxy - c0 * sx) / sxx;
    }
    let ssr = points
        .iter()
        .map(|&(g, y, w)| w * (y - c0 - c1 * shape(q, beta, g).0).powi(2))
        .sum();
    (c0, c1, ssr)
}

/// The minimum of `f` between `lo` and `hi` by golden-section search (to a millionth of
/// the interval).
pub(super) fn golden(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let r = 0.5 * (5.0_f64.sqrt() - 1.0);
    let (mut a, mut b) = (hi - r * (hi - lo), lo + r * (hi - lo));
    let (mut fa, mut fb) = (f(a), f(b));
    for _ in 0..30 {
        if fa < fb {
            hi = b;
            b = a;
            fb = fa;
            a = hi - r * (hi - lo);
            fa = f(a);
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + r * (hi - lo);
            fb = f(b);
        }
    }
    0.5 * (lo + hi)
}
