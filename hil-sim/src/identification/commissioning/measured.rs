//! The actuator file a commissioning writes: the measured values, and the tolerances their
//! measurement leaves.

use ema::control::actuator::Actuator;
use ema::device::commission::Report;

use super::Mechanics;
use crate::simulation::hal::CONVERTER_GAIN_CLASS;
use crate::simulation::Error;

/// How far the converters alone may scale what a commissioning measures, relative: a
/// current channel reading `g i` and a bus channel reading `h u` read the resistance and
/// every inductance `h / g` times theirs (`R = u / i`, `L = psi / i` with `psi` integrated
/// from `u - R i`), and so the pull `i^2 L' / 2`, and with it the spring, the mass and the
/// friction the pull is read against, `g h` times. Each gain within
/// [`CONVERTER_GAIN_CLASS`], either product is within twice it, to first order. No fit
/// sees this error: it scales every reading alike.
pub const CONVERTER_SCALE: f64 = 2.0 * CONVERTER_GAIN_CLASS;

/// The coverage factor of a fit's expanded uncertainty at 99 % for `dof` degrees of
/// freedom: Student's `t` at 0.995, by which a standard error is multiplied so that the
/// interval holds the true value 99 times in 100 when the fit's error is its readings'
/// scatter (two standard errors hold it 95 times only with many degrees of freedom; a
/// line through four holds has two). 99 %, not the 95 % of a datasheet: the tolerance
/// written is the uncertainty set `tune` validates on and the robust law is built for, a
/// plant outside it is one nothing was checked on. Beyond ten degrees of freedom the
/// table's last entry, 23 % above the limit 2.576: on the safe side.
#[must_use]
pub fn coverage_factor(dof: usize) -> f64 {
    const T_995: [f64; 10] = [
        63.657, 9.925, 5.841, 4.604, 4.032, 3.707, 3.499, 3.355, 3.250, 3.169,
    ];
    T_995.get(dof.max(1) - 1).copied().unwrap_or(T_995[9])
}

/// The relative tolerance a fit leaves on a `value` it read with two standard errors
/// `uncertainty` on `dof` degrees of freedom: the converters' scale ([`CONVERTER_SCALE`])
/// plus the fit's 99 % interval ([`coverage_factor`]); NaN where the fit has no
/// uncertainty (one move: nothing to compare it with), which keeps the file's
/// ([`measured`]).
#[must_use]
pub fn fitted_tolerance(value: f64, uncertainty: f64, dof: usize) -> f64 {
    CONVERTER_SCALE + coverage_factor(dof) * 0.5 * uncertainty / value.abs()
}

/// The least iron reluctance an actuator measured by a commissioning keeps, as a share of
/// the closed gap's total (see [`measured`], [`Circuit::fit`](super::Circuit::fit)): above
/// none, as the model needs, and far below any real iron's (the paper's actuator's is
/// 4.5e-5), so that the floor bends no line the readings give: a floor near a real
/// iron's share would move the fitted line at the closed stop, where the iron's share of
/// the reluctance is largest.
pub const IRON_SHARE: f32 = 1e-6;

/// The actuator a commissioning measured: `file` (the board's) with the measured resistance
/// and magnetic circuit, the spring, the mass and the friction where the holds measured
/// them ([`mechanics`](super::mechanics); below), the tuning dropped (it was for another
/// actuator); and the factor the two-inductance form's inductances were moved by (below).
///
/// The magnetic circuit: with the holds measured, the one fitted to their inductances and
/// the stops' ([`Circuit::fit`](super::Circuit::fit)), in the file's form: a pole
/// geometry's sides, growth (`fringing_spread`) and iron reluctance (its gap count,
/// fringing coefficient and aspect kept), or the fitted circuit's inductances at the two
/// stops. Without them, the stops' two inductances, the open stop's as
/// [`open_stop`](super::open_stop) gives it (the file's where the reading is the less
/// certain).
///
/// The surfaces, the paper's uncertainty, carry what the circuit's readings leave: the
/// converters' scale, plus the largest deviation of the written form from the holds'
/// probes ([`Mechanics::form_deviation`]) or the 99 % interval of the least certain
/// reading the circuit was fitted to (from two standard errors of a hold's probe, or
/// [`STOP_INDUCTANCE_CLASS`](super::STOP_INDUCTANCE_CLASS) at the stops, each read over
/// many samples) where that is larger; never more than the file's unless the probes ask
/// for it. The resistance keeps the file's: it moves with the coil's temperature.
///
/// A measured spring (with its preload), mass and friction carry the tolerance their
/// measurement leaves, whether it is narrower or wider than the file's: the file's value
/// is the one the measurement replaces, so its tolerance says nothing of the measured
/// one. That tolerance is the fit's own ([`fitted_tolerance`]: the converters' scale and
/// the fit's 99 % interval, the spring's from the scatter of the holds about its line,
/// two degrees of freedom over the four holds, the mass's and the friction's from their
/// scatter over the moves, the jackknife of [`fit_armature`](super::fit_armature), one
/// less degree of freedom than moves), plus the circuit's share of the surface tolerance
/// above (the tolerance less the converters' scale, which both carry): each is
/// read against the pull the circuit gives, and a surface `1 + s` times the written one
/// pulls `1 + s` times harder at the same gap and current, which scales the spring, the
/// mass and the friction read against it alike and which no scatter over the holds or
/// the moves shows. A value whose 99 % interval reaches zero (a tolerance of one or more,
/// a mass or a friction read at or below zero, a fit with no uncertainty) has not been
/// told from none: the file keeps its own value and tolerance, as without a fit (a
/// spring read pushing the wrong way within its interval is written, and refused by the
/// file's check).
///
/// The two-inductance form is `1/L` linear in the gap, `(rho_x g + rho_0) / N^2`, the
/// iron's `rho_0` positive. A real circuit's fringing bends the line (the surface grows
/// with the gap), and through the two inductances its intercept can fall below zero:
/// then both are moved, by the same factor in opposite directions, to the nearest line
/// whose `rho_0` is [`IRON_SHARE`] of the closed gap's reluctance.
///
/// # Errors
/// Measured values no actuator can have (the actuator does not validate).
pub fn measured(
    file: &Actuator,
    report: &Report,
    mechanics: Option<&Mechanics>,
) -> Result<(Actuator, f32), Error> {
    let mut a = *file;
    a.coil.resistance_ohm = report.resistance.ohm;
    let circuit = mechanics.map(|m| m.circuit);
    let mut moved = 1.0;
    match (circuit, a.magnetics) {
        (Some(c), file @ ema::control::actuator::Magnetics::Geometry { .. }) => {
            a.magnetics = c.geometry(a.coil.turns, file);
        }
        (circuit, _) => {
            let (open_h, closed_h) = circuit.map_or(
                (
                    super::open_stop(report, file).0 as f32,
                    report.inductance.closed_h,
                ),
                |c| {
                    (
                        c.inductance_h(0.0) as f32,
                        c.inductance_h(c.stroke_m) as f32,
                    )
                },
            );
            let (g_open, g_closed) = (
                a.mechanics.residual_gap_m + a.mechanics.stroke_m,
                a.mechanics.residual_gap_m,
            );
            let (rho_o, rho_c) = (1.0 / open_h, 1.0 / closed_h);
            let q = g_closed / (g_open - g_closed);
            let intercept = rho_c - (rho_o - rho_c) * q;
            if intercept < IRON_SHARE * rho_c {
                moved = ((1.0 - IRON_SHARE + q) * rho_c / (q * rho_o)).sqrt();
            }
            a.magnetics = ema::control::actuator::Magnetics::Inductance {
                open_h: open_h / moved,
                closed_h: closed_h * moved,
            };
        }
    }
    a.tuning = None;
    a.plant().map_err(Error::Actuator)?;
    #[expect(clippy::cast_possible_truncation)]
    if let Some(m) = mechanics {
        let d = m.form_deviation(&a).unwrap_or(0.0);
        let least_certain = m
            .inductances
            .iter()
            .flatten()
            .map(|h| h.uncertainty_h / h.inductance_h)
            .fold(super::STOP_INDUCTANCE_CLASS, f64::max)
            * super::circuit::interval_per_two_se();
        let fitted = CONVERTER_SCALE + d.max(least_certain);
        a.tolerance.surface = a
            .tolerance
            .surface
            .min(fitted as f32)
            .max((CONVERTER_SCALE + d) as f32);
        // The pull the spring, the mass and the friction are read against comes from the
        // circuit, and carries the uncertainty the file states for it (the surface
        // tolerance just written, less the converters' scale they carry already): a
        // surface `1 + s` times the written one pulls `1 + s` times harder at the same gap
        // and current. (A probe no cycle agreed on, an infinite uncertainty, weighs
        // nothing in the circuit's fit and leaves the surface at the file's.)
        let pull = f64::from(a.tolerance.surface) - CONVERTER_SCALE;
        let holds = crate::simulation::actuator::SEQUENCE.len();
        let spring =
            pull + fitted_tolerance(m.spring.n_per_m, m.spring.uncertainty_n_per_m, holds - 2);
        if spring < 1.0 {
            a.mechanics.spring_n_per_m = m.spring.n_per_m as f32;
            a.mechanics.preload_n = m.spring.preload_n as f32;
            a.tolerance.spring = spring as f32;
        }
        if let Some(arm) = m.armature {
            let dof = arm.moves.saturating_sub(1);
            let mass = pull + fitted_tolerance(arm.mass_kg, arm.mass_uncertainty_kg, dof);
            if let Some((v, t)) = measures(arm.mass_kg, mass) {
                a.mechanics.mass_kg = v;
                a.tolerance.mass = t;
            }
            let friction = pull
                + fitted_tolerance(
                    arm.friction_n_s_per_m,
                    arm.friction_uncertainty_n_s_per_m,
                    dof,
                );
            if let Some((v, t)) = measures(arm.friction_n_s_per_m, friction) {
                a.mechanics.friction_n_s_per_m = v;
                a.tolerance.friction = t;
            }
        }
        a.plant().map_err(Error::Actuator)?;
    }
    Ok((a, moved))
}

/// A measured `value` and its relative `tolerance` as the file carries them, where the
/// measurement tells the quantity from none: its 99 % interval above zero (`value`
/// positive, `tolerance` below one). An interval that reaches zero (or a fit with no
/// uncertainty, NaN) has not measured it: `None`, and the file keeps its own value and
/// tolerance, as without a fit.
#[expect(clippy::cast_possible_truncation)]
fn measures(value: f64, tolerance: f64) -> Option<(f32, f32)> {
    (value > 0.0 && tolerance < 1.0).then_some((value as f32, tolerance as f32))
}
