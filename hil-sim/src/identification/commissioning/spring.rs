//! The spring's rate and preload from the holds, and the magnet's pull they are read with.

use ema::device::commission::Report;

use super::Circuit;

/// The spring measured by [`mechanics`](super::mechanics).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    /// Rate \[N/m\].
    pub n_per_m: f64,
    /// Preload at the open stop \[N\] (a fit below zero, a spring without preload read
    /// through the noise, is taken as none).
    pub preload_n: f64,
    /// Two standard errors of the rate, from the holds' fit's residuals (kept when the
    /// moves correct the rate: [`Mechanics::fit`](super::Mechanics::fit)) \[N/m\].
    pub uncertainty_n_per_m: f64,
    /// The holds: corrected position \[m\] and mean magnetic force \[N\].
    pub holds: [(f64, f64); crate::simulation::actuator::SEQUENCE.len()],
}

/// The spring's rate and preload from the readings `(position [m], current [A])` of each
/// hold's window (the loop holding the armature), one every `dt_s`, the commissioning's
/// `report`, the magnetic `circuit` measured and, once the moves have read them, the
/// armature's mass and friction (`dynamics`, `(m [kg], c [N s/m])`).
///
/// The pull is `F = i^2 L'(x) / 2` with the `circuit` measured ([`Circuit::fit`]). Each
/// reading's position is corrected with the measured end stops, `x = stroke (y - y_open)
/// / (y_closed - y_open)`. Each window's force and position are averaged reading by
/// reading with a weight that vanishes at both ends, `w(t) = sin^2(pi t / T)`: over the
/// window the equation of motion averages to `<F> - m <a> - c <v> = K <x> + F0`, and by
/// parts `<a> = <w'' x>` and `<v> = -<w' x>` (w and w' vanish at the ends), read from the
/// positions alone, without differencing their noise. A loop that limit-cycles about a
/// hold does not end its window at the speed it started it: a 1 kg plunger's hold near
/// its closed stop, a tenth of a cycle past a whole one, read the pull 1 % above the
/// spring without these terms, and the rate 5.8 % off. `K` and `F0` are the least
/// squares line through the holds.
#[must_use]
pub fn fit_spring(
    report: &Report,
    circuit: Circuit,
    holds: &[Vec<(f64, f64)>; crate::simulation::actuator::SEQUENCE.len()],
    dt_s: f64,
    dynamics: Option<(f64, f64)>,
) -> Spring {
    use core::f64::consts::PI;
    let force = pull(report, circuit);
    let (mass_kg, friction) = dynamics.unwrap_or((0.0, 0.0));
    let means = holds.each_ref().map(|w| {
        #[expect(clippy::cast_precision_loss)]
        let n = w.len() as f64;
        let rate = PI / (n * dt_s);
        let (sw, sx, sf, sa, sv) = w.iter().enumerate().fold(
            (0.0, 0.0, 0.0, 0.0, 0.0),
            |(sw, sx, sf, sa, sv), (k, &(y, i))| {
                let (x, f) = force(y, i);
                #[expect(clippy::cast_precision_loss)]
                let phase = PI * (k as f64 + 0.5) / n;
                let w = phase.sin().powi(2);
                let w1 = rate * (2.0 * phase).sin();
                let w2 = 2.0 * rate * rate * (2.0 * phase).cos();
                (sw + w, sx + w * x, sf + w * f, sa + w2 * x, sv - w1 * x)
            },
        );
        (sx / sw, (sf - mass_kg * sa - friction * sv) / sw)
    });
    #[expect(clippy::cast_precision_loss)]
    let n = means.len() as f64;
    let mx = means.iter().map(|h| h.0).sum::<f64>() / n;
    let mf = means.iter().map(|h| h.1).sum::<f64>() / n;
    let sxx: f64 = means.iter().map(|h| (h.0 - mx).powi(2)).sum();
    let k = means.iter().map(|h| (h.0 - mx) * (h.1 - mf)).sum::<f64>() / sxx;
    let preload = mf - k * mx;
    let residual: f64 = means
        .iter()
        .map(|h| (h.1 - preload - k * h.0).powi(2))
        .sum();
    Spring {
        n_per_m: k,
        preload_n: preload.max(0.0),
        uncertainty_n_per_m: 2.0 * (residual / (n - 2.0) / sxx).sqrt(),
        holds: means,
    }
}

/// The magnet's pull the commissioning's `report` reads from a position reading `y` \[m\]
/// and a current `i` \[A\], with the position corrected by the measured end stops and
/// the `circuit` measured: `(x [m], F [N])`, `F = i^2 L'(x) / 2`
/// ([`Circuit::force_coefficient_h_per_m`]), `x = stroke (y - y_open) / (y_closed -
/// y_open)`.
pub(super) fn pull(report: &Report, circuit: Circuit) -> impl Fn(f64, f64) -> (f64, f64) {
    let position = corrected(report, circuit.stroke_m);
    move |y: f64, i: f64| {
        let x = position(y);
        (x, 0.5 * i * i * circuit.force_coefficient_h_per_m(x))
    }
}

/// The position \[m\] of a reading `y` \[m\] corrected with the end stops the
/// commissioning's `report` measured, `x = stroke (y - y_open) / (y_closed - y_open)`,
/// within the stroke.
pub(super) fn corrected(report: &Report, stroke_m: f64) -> impl Fn(f64) -> f64 {
    let (open, closed) = (
        f64::from(report.ends.open_m),
        f64::from(report.ends.closed_m),
    );
    move |y: f64| (stroke_m * (y - open) / (closed - open)).clamp(0.0, stroke_m)
}
