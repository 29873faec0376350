//! A commissioned actuator on the board: the parameters that carry it, set on the board, and
//! the actuator file written for it.

use std::io::Write;

use anyhow::{bail, ensure};
use ema::control::actuator::{Actuator, Magnetics};
use ema::control::sense::PositionCorrection;
use ema::device::commission::Report;
use ema::device::protocol::{Command, Value};
use hil_sim::analysis::report::sig;
use hil_sim::identification::commissioning::Mechanics;

use super::{save, set_all, value_text};
use crate::link::{Link, Port};

/// The parameters that carry a commissioned actuator `measured` on a board whose file is
/// `board`: the resistance, the spring and its preload, the mass and the friction, the
/// tolerances of these and of the surfaces, and the magnetic circuit in the board's own
/// form (its kind is fixed by the firmware build). A circuit measured in the board's form
/// is carried as it is; one in the two-inductance form (the stops' alone) on a board with
/// a pole geometry without fringing spread, whose `1/L` is linear in the gap as the measured
/// one's, has the pole's sides scaled for the measured airgap reluctance (the fringing
/// coefficient kept) and the iron's reluctance set to the measured one.
///
/// # Errors
/// A two-inductance circuit for a board whose geometry has a fringing spread (its `1/L`
/// is not linear in the gap, so two inductances do not fix it), or a circuit in the
/// geometry form for a board in the two-inductance form.
pub fn commissioned_params(
    board: &Actuator,
    measured: &Actuator,
) -> anyhow::Result<Vec<(&'static str, f32)>> {
    let mut out = vec![
        ("coil.resistance_ohm", measured.coil.resistance_ohm),
        (
            "mechanics.spring_n_per_m",
            measured.mechanics.spring_n_per_m,
        ),
        ("mechanics.preload_n", measured.mechanics.preload_n),
        ("mechanics.mass_kg", measured.mechanics.mass_kg),
        (
            "mechanics.friction_n_s_per_m",
            measured.mechanics.friction_n_s_per_m,
        ),
        ("tolerance.surface", measured.tolerance.surface),
        ("tolerance.spring", measured.tolerance.spring),
        ("tolerance.mass", measured.tolerance.mass),
        ("tolerance.friction", measured.tolerance.friction),
    ];
    match (board.magnetics, measured.magnetics) {
        (Magnetics::Inductance { .. }, Magnetics::Inductance { open_h, closed_h }) => {
            out.push(("magnetics.inductance.open_h", open_h));
            out.push(("magnetics.inductance.closed_h", closed_h));
        }
        (
            Magnetics::Geometry { .. },
            Magnetics::Geometry {
                pole_a_m,
                pole_b_m,
                fringing_spread,
                iron_reluctance_per_h,
                ..
            },
        ) => {
            out.push(("magnetics.geometry.pole_a_m", pole_a_m));
            out.push(("magnetics.geometry.pole_b_m", pole_b_m));
            out.push(("magnetics.geometry.fringing_spread", fringing_spread));
            out.push((
                "magnetics.geometry.iron_reluctance_per_h",
                iron_reluctance_per_h,
            ));
        }
        (
            file @ Magnetics::Geometry {
                fringing_spread, ..
            },
            Magnetics::Inductance { open_h, closed_h },
        ) => {
            ensure!(
                fringing_spread == 0.0,
                "the board's magnetics.geometry.fringing_spread = {fringing_spread}: its 1/L is \
                 not linear in the gap and two inductances do not fix it; commission with the \
                 holds measured (--mechanics), whose fit gives the fringing spread"
            );
            // The measured line in the board's form.
            let line = hil_sim::identification::commissioning::Circuit::line(
                f64::from(open_h),
                f64::from(closed_h),
                measured,
            );
            if let Magnetics::Geometry {
                pole_a_m,
                pole_b_m,
                iron_reluctance_per_h,
                ..
            } = line.geometry(measured.coil.turns, file)
            {
                out.push(("magnetics.geometry.pole_a_m", pole_a_m));
                out.push(("magnetics.geometry.pole_b_m", pole_b_m));
                out.push((
                    "magnetics.geometry.iron_reluctance_per_h",
                    iron_reluctance_per_h,
                ));
            }
        }
        (Magnetics::Inductance { .. }, Magnetics::Geometry { .. }) => bail!(
            "the commissioned circuit is in the geometry form and the board's in the \
             two-inductance form"
        ),
    }
    Ok(out)
}

/// The `set`s that carry a commissioned actuator `measured` ([`commissioned_params`]) and
/// a `tuning` on a board whose file is `board`.
///
/// # Errors
/// As [`commissioned_params`].
pub(super) fn commissioned_sets(
    board: &Actuator,
    measured: &Actuator,
    tuning: &ema::control::actuator::Tuning,
) -> anyhow::Result<Vec<(&'static str, Value)>> {
    let mut sets: Vec<(&str, Value)> = commissioned_params(board, measured)?
        .into_iter()
        .map(|(k, v)| (k, Value::Number(v)))
        .collect();
    sets.extend([
        ("tuning.alpha_per_s", Value::Number(tuning.alpha_per_s)),
        (
            "tuning.observer_rad_s",
            Value::Number(tuning.observer_rad_s),
        ),
        ("tuning.margin", Value::Number(tuning.margin)),
        (
            "tuning.disturbance_follows_force",
            Value::Flag(tuning.disturbance_follows_force),
        ),
    ]);
    Ok(sets)
}

/// The `set`s that carry a position sensor's `correction` from the end stops.
pub(super) fn correction_sets(correction: &PositionCorrection) -> [(&'static str, Value); 2] {
    [
        ("sensor.position_gain", Value::Number(correction.gain)),
        (
            "sensor.position_offset_codes",
            Value::Number(correction.offset_codes),
        ),
    ]
}

/// Sets the commissioned actuator `measured`, its `tuning` and the position sensor's
/// `correction` from the end stops on the board and saves them; on a refusal the stored
/// parameters are loaded back and nothing is saved.
pub(super) fn apply_commissioned<P: Port>(
    link: &mut Link<P>,
    board: &Actuator,
    measured: &Actuator,
    tuning: &ema::control::actuator::Tuning,
    correction: &PositionCorrection,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    let mut sets = commissioned_sets(board, measured, tuning)?;
    sets.extend(correction_sets(correction));
    if let Err(e) = set_all(link, &sets) {
        link.done(Command::Load)?;
        bail!("{e}; the stored parameters are loaded back, nothing saved");
    }
    for (name, value) in sets {
        writeln!(out, "{name} = {}", value_text(name, value))?;
    }
    save(link, out)
}

/// The actuator file a commissioning gives: the measured actuator
/// ([`hil_sim::identification::commissioning::measured`], with the `mechanics` when
/// measured), each measured value and its uncertainty, and the end stops, in comments at
/// its head.
///
/// # Errors
/// The file does not serialise or does not validate (the board measured values no
/// actuator can have).
pub fn actuator_file(
    file: &ema::control::actuator::Actuator,
    report: &Report,
    mechanics: Option<&Mechanics>,
) -> anyhow::Result<String> {
    let r = report.resistance;
    let l = report.inductance;
    let e = report.ends;
    let (a, moved) = hil_sim::identification::commissioning::measured(file, report, mechanics)?;
    let spring_head = mechanics.map_or(String::new(), |m| {
        let s = m.spring;
        let armature = m.armature.map_or(
            "#   mechanics.mass_kg and friction_n_s_per_m: the file's (no move to fit)\n"
                .to_owned(),
            |arm| {
                format!(
                    "#   mass {} kg, friction {} N s/m (the {} moves between the holds);\n\
                     #   mechanics.mass_kg = {}, tolerance.mass = {}, \
                     mechanics.friction_n_s_per_m = {}, tolerance.friction = {}\n\
                     #   (the measurement's; the file's where its 99 % interval reaches zero)\n",
                    sig(arm.mass_kg, 4),
                    sig(arm.friction_n_s_per_m, 3),
                    arm.moves,
                    sig(f64::from(a.mechanics.mass_kg), 4),
                    sig(f64::from(a.tolerance.mass), 3),
                    sig(f64::from(a.mechanics.friction_n_s_per_m), 3),
                    sig(f64::from(a.tolerance.friction), 3)
                )
            },
        );
        let probed: Vec<String> = m
            .inductances
            .iter()
            .flatten()
            .map(|h| {
                format!(
                    "{} +- {} H at {} m",
                    sig(h.inductance_h, 4),
                    sig(h.uncertainty_h, 2),
                    sig(h.x_m, 4)
                )
            })
            .collect();
        let inductances = match m.form_deviation(&a) {
            Some(d) => format!(
                "#   inductance at the holds (probes, loop closed; two standard errors):\n\
                 #     {}\n\
                 #   the circuit below is fitted to them and the stops' (surface growth \
                 q = {} 1/m,\n\
                 #   the surface at the open stop {} % above the closed stop's); within {} % \
                 of the holds'\n\
                 #   (tolerance.surface = {})\n",
                probed.join(", "),
                sig(m.circuit.growth_per_m, 3),
                sig(100.0 * (m.circuit.surface_growth() - 1.0), 3),
                sig(100.0 * d, 2),
                a.tolerance.surface
            ),
            None => "#   inductance at the holds: no probe read one\n".to_owned(),
        };
        format!(
            "#   spring {} +- {} N/m (two standard errors of the fit), preload {} N\n\
             #   (closed-loop holds at four positions);\n\
             #   mechanics.spring_n_per_m = {}, mechanics.preload_n = {}, tolerance.spring = {}\n\
             #   (the measurement's; the file's where its 99 % interval reaches zero)\n\
             {armature}{inductances}",
            sig(s.n_per_m, 4),
            sig(s.uncertainty_n_per_m, 2),
            sig(s.preload_n, 4),
            sig(f64::from(a.mechanics.spring_n_per_m), 4),
            sig(f64::from(a.mechanics.preload_n), 4),
            sig(f64::from(a.tolerance.spring), 3)
        )
    });
    let moved = if moved == 1.0 {
        String::new()
    } else {
        format!(
            "#   in the file's linear form each moved by {:.2} % (positive iron reluctance)\n",
            100.0 * (moved - 1.0).abs()
        )
    };
    let head = format!(
        "# Commissioned on the board (loop open, armature at rest):\n\
         #   coil.resistance_ohm = {} +- {} (two standard errors, converter noise)\n\
         #   inductance at the open stop {} H, at the closed stop {} H (step responses)\n\
         {moved}\
         #   position reading at the open stop {} m, at the closed stop {} m +- {} m\n\
         #   (in the calibration of this file's board.position_span_m)\n\
         {spring_head}\
         # Tune it before use: hil-sim tune <this file>\n",
        r.ohm, r.uncertainty_ohm, l.open_h, l.closed_h, e.open_m, e.closed_m, e.uncertainty_m
    );
    Ok(head + &toml::to_string(&a)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A commissioning without the holds measures two inductances; a board whose file
    /// gives a pole geometry gets them as its sides and iron: the board's circuit then
    /// has the measured inductances at both stops, within 1e-5.
    #[test]
    fn two_measured_inductances_reach_a_geometry_board_as_its_sides_and_iron() {
        let board = Actuator::PRODUCT;
        let nominal = board.plant().unwrap();
        let at = |p: &ema::control::model::Plant, x: f32| p.magnetics.inductance_h(p.gap_m(x));
        let stroke = board.mechanics.stroke_m;
        let measured = Actuator {
            magnetics: Magnetics::Inductance {
                open_h: 1.1 * at(&nominal, 0.0),
                closed_h: 0.95 * at(&nominal, stroke),
            },
            ..board
        };
        let mut got = board;
        for (name, value) in commissioned_params(&board, &measured).unwrap() {
            if let Magnetics::Geometry {
                pole_a_m,
                pole_b_m,
                iron_reluctance_per_h,
                ..
            } = &mut got.magnetics
            {
                match name {
                    "magnetics.geometry.pole_a_m" => *pole_a_m = value,
                    "magnetics.geometry.pole_b_m" => *pole_b_m = value,
                    "magnetics.geometry.iron_reluctance_per_h" => *iron_reluctance_per_h = value,
                    _ => {}
                }
            }
        }
        let (want, have) = (measured.plant().unwrap(), got.plant().unwrap());
        for x in [0.0, stroke] {
            let error = at(&have, x) / at(&want, x) - 1.0;
            assert!(error.abs() < 1e-5, "at {x} m: {error}");
        }
    }
}
