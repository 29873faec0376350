//! The actuator file a commissioning writes: the measured values, and the tolerances their
//! measurement leaves.

use ema::control::actuator::Actuator;
use ema::device::commission::Report;

use super::Mechanics;
use crate::simulation::Error;

/// How far the mass [`fit_armature`](super::fit_armature) reads may be off, relative (the
/// `hil-sim commission` table's row of it, whose target this is): above the largest error
/// over the family's drawn plants but for about one drawn positioner in a thousand (a
/// magnet 30 % weaker than its file, a damping ratio below 0.1), which the row counts.
pub const MASS_CLASS: f64 = 0.08;

/// How far the airgap surfaces of the circuit [`Circuit::fit`](super::Circuit::fit) reads
/// may be off, relative: the inductance curve's target (the `hil-sim commission` table's
/// rows of it), above its largest error over the family's drawn plants.
pub const SURFACE_CLASS: f64 = 0.05;

/// How far the spring's rate [`fit_spring`](super::fit_spring) reads may be off, relative
/// (the `hil-sim commission` table's row of it, whose target this is): above the largest
/// error over the family's drawn plants, once the holds' windows are averaged with the
/// armature's inertia taken out.
pub const SPRING_CLASS: f64 = 0.05;

/// How far the friction [`fit_armature`](super::fit_armature) reads may be off, as a share
/// of the critical damping `2 sqrt(K m)`: above the largest error over the family's drawn
/// plants (the `hil-sim commission` table's row of it, whose target this is). Lightly
/// damped actuators read their friction tens of per cent off, but the error is this small
/// against the damping that matters to the loop.
pub const FRICTION_CLASS_DAMPING: f64 = 0.05;

/// The least iron reluctance an actuator measured by a commissioning keeps, as a share of
/// the closed gap's total (see [`measured`], [`Circuit::fit`](super::Circuit::fit)): above
/// none, as the model needs, and far below any real iron's (the paper's actuator's is
/// 4.5e-5), so that the floor bends no line the readings give: a floor near a real
/// iron's share would move the fitted line at the closed stop, where the iron's share of
/// the reluctance is largest.
pub const IRON_SHARE: f32 = 1e-6;

/// The actuator a commissioning measured: `file` (the board's) with the measured resistance
/// and magnetic circuit, the spring, the mass and the friction when measured
/// ([`mechanics`](super::mechanics); a friction fitted below zero, a light one read through
/// the noise, is taken as none), the tuning dropped (it was for another actuator); and the
/// factor the two-inductance form's inductances were moved by (below).
///
/// The magnetic circuit: with the holds measured, the one fitted to their inductances and
/// the stops' ([`Circuit::fit`](super::Circuit::fit)), in the file's form: a pole
/// geometry's sides, growth (`fringing_spread`) and iron reluctance (its gap count,
/// fringing coefficient and aspect kept), or the fitted circuit's inductances at the two
/// stops. Without them, the stops' two inductances.
///
/// A measured spring, mass and friction carry the tolerance their measurement leaves,
/// when it is below the file's: the spring [`SPRING_CLASS`], the mass [`MASS_CLASS`], the
/// friction [`FRICTION_CLASS_DAMPING`] of the critical damping `2 sqrt(K m)` of the
/// measured spring and mass (a datasheet's friction is an estimate, +-50 % by default;
/// the moves read it to a few hundredths of the critical damping). The surfaces, the
/// paper's uncertainty, carry the spread of the circuit's fit: [`SURFACE_CLASS`], or the
/// largest deviation of the written form from the holds' probes where that is larger
/// ([`Mechanics::form_deviation`]), never more than the file's unless the probes ask for
/// it. The resistance keeps the file's: it moves with the coil's temperature.
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
    #[expect(clippy::cast_possible_truncation)]
    if let Some(m) = mechanics {
        a.mechanics.spring_n_per_m = m.spring.n_per_m as f32;
        a.mechanics.preload_n = m.spring.preload_n as f32;
        a.tolerance.spring = a.tolerance.spring.min(SPRING_CLASS as f32);
        if let Some(arm) = m.armature {
            a.mechanics.mass_kg = arm.mass_kg as f32;
            a.mechanics.friction_n_s_per_m = arm.friction_n_s_per_m.max(0.0) as f32;
            a.tolerance.mass = a.tolerance.mass.min(MASS_CLASS as f32);
            let critical = 2.0 * (m.spring.n_per_m * arm.mass_kg).max(0.0).sqrt();
            let class = FRICTION_CLASS_DAMPING * critical / arm.friction_n_s_per_m;
            if arm.friction_n_s_per_m > 0.0 && class < f64::from(a.tolerance.friction) {
                a.tolerance.friction = class as f32;
            }
        }
    }
    let circuit = mechanics.map(|m| m.circuit);
    let mut moved = 1.0;
    match (circuit, a.magnetics) {
        (Some(c), file @ ema::control::actuator::Magnetics::Geometry { .. }) => {
            a.magnetics = c.geometry(a.coil.turns, file);
        }
        (circuit, _) => {
            let (open_h, closed_h) = circuit.map_or(
                (report.inductance.open_h, report.inductance.closed_h),
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
    if let Some(d) = mechanics.and_then(|m| m.form_deviation(&a)) {
        a.tolerance.surface = a.tolerance.surface.min(SURFACE_CLASS as f32).max(d as f32);
    }
    Ok((a, moved))
}
