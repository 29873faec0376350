//! `commission --mechanics`: the holds on the board that measure the magnetic circuit between
//! the stops, the spring, the mass and the friction.

use std::io::Write;
use std::time::{Duration, Instant};

use anyhow::{anyhow, ensure};
use ema::control::actuator::Actuator;
use ema::device::commission::Report;
use ema::device::protocol::{Command, Trigger};
use hil_sim::analysis::report::sig;
use hil_sim::identification::commissioning::{HoldInductance, Holds, Mechanics};

use super::{capture_move, commissioned_sets, read_capture, set_all, status};
use crate::link::{Link, Port};
use crate::{fault_name, Capture};

/// Measures the magnetic circuit between the stops, the spring, the mass and the friction
/// on the board ([`hil_sim::identification::commissioning::Circuit::fit`],
/// [`hil_sim::identification::commissioning::fit_spring`],
/// [`hil_sim::identification::commissioning::fit_armature`]): sets the actuator `report`
/// measured on the board's `file` with the default tuning (not stored), arms, moves to each
/// position of [`hil_sim::simulation::actuator::SEQUENCE`] and holds it as the evaluation
/// sequence does, capturing the move, then the hold's window at the
/// [`hil_sim::identification::commissioning::decimations`], then the hold's inductance
/// probes at every tick; disarms and puts the parameters in use before back (the stored
/// set, or the built-in defaults). A fault during the holds ends the attempt, named: the
/// holds run again, cleared, with a slower loop
/// ([`hil_sim::identification::commissioning::hold_tuning`]), up to
/// [`hil_sim::identification::commissioning::HOLD_ATTEMPTS`] in all.
///
/// # Errors
/// A refusal, no reply, a fault during the last attempt at the holds, a capture that
/// does not finish.
pub(super) fn measure_mechanics<P: Port>(
    link: &mut Link<P>,
    file: &Actuator,
    report: &Report,
    out: &mut dyn Write,
) -> anyhow::Result<Mechanics> {
    let plan = HoldPlan::new(file, report)?;
    plan.print(out)?;
    let stored = matches!(status(link)?.params, ema::device::protocol::Source::Stored);
    let held = hold_with_retries(link, file, &plan, report, out)?;
    // Whatever happened: the bridge off and the parameters in use before back.
    let disarmed = link.done(Command::Disarm);
    let loaded = link.done(if stored {
        Command::Load
    } else {
        Command::Defaults
    });
    let (holds, probes) = held?;
    disarmed?;
    loaded?;
    let line = hil_sim::identification::commissioning::Circuit::through_stops(report, &plan.m);
    let inductances = probes.each_ref().map(|runs| {
        hil_sim::identification::commissioning::hold_inductance(
            runs,
            &plan.probe,
            plan.delay,
            1.0 / plan.rate_hz,
            report,
            line,
            hil_sim::identification::commissioning::ChannelNoise::of(file),
        )
    });
    print_inductances(out, plan.stroke_m, &inductances)?;
    let mechanics = Mechanics::fit(report, file, &holds, inductances);
    print_mechanics(out, file, &mechanics, &inductances)?;
    Ok(mechanics)
}

/// Each hold's inductance probes: per position of [`hil_sim::simulation::actuator::SEQUENCE`], the
/// samples of each probe.
type Probes = [Vec<Vec<hil_sim::identification::commissioning::ProbeSample>>;
    hil_sim::simulation::actuator::SEQUENCE.len()];

/// How [`measure_mechanics`] captures the holds: the measured actuator with the default
/// tuning and what follows from it.
struct HoldPlan {
    /// The actuator measured on the board, with the default tuning.
    m: Actuator,
    /// Its stroke \[m\].
    stroke_m: f64,
    /// Its loop rate \[Hz\].
    rate_hz: f64,
    /// Each hold's duration \[s\].
    hold_s: f64,
    /// The board's capture capacity \[samples\].
    capacity: u16,
    /// Ticks between a move's captured samples.
    move_decimation: u16,
    /// Ticks between a window's captured samples.
    window_decimation: u16,
    /// A window's captured samples.
    window_samples: u16,
    /// The inductance probe at each hold.
    probe: hil_sim::simulation::scenario::InductanceProbe,
    /// The loop's delay \[ticks\].
    delay: usize,
    /// A probe's captured samples, one a tick.
    span: u16,
}

impl HoldPlan {
    /// The plan for the actuator `report` measured on the board's `file`.
    ///
    /// # Errors
    /// The measured actuator does not make settings.
    fn new(file: &Actuator, report: &Report) -> anyhow::Result<Self> {
        let (m, _) = hil_sim::identification::commissioning::measured(file, report, None)?;
        let settings = m.settings().map_err(|e| anyhow!("{e}"))?;
        let stroke_m = f64::from(m.mechanics.stroke_m);
        let rate_hz = f64::from(m.board.rate_hz);
        let hold_s = hil_sim::simulation::actuator::segment_s(&settings, stroke_m);
        let capacity = u16::try_from(ema::device::CAPTURE_CAPACITY).unwrap_or(u16::MAX);
        let (move_decimation, window_decimation) =
            hil_sim::identification::commissioning::decimations(&settings, stroke_m, rate_hz);
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let window_samples =
            ((hil_sim::identification::commissioning::HOLD_WINDOW_SHARE * hold_s * rate_hz
                / f64::from(window_decimation))
            .round()
            .clamp(1.0, f64::from(capacity))) as u16;
        let probe = hil_sim::identification::commissioning::hold_probe(&m);
        let delay = usize::from(settings.delay_ticks);
        let span = u16::try_from(hil_sim::identification::commissioning::probe_capture(
            probe.ticks(),
            delay,
        ))
        .unwrap_or(u16::MAX)
        .min(capacity);
        Ok(Self {
            m,
            stroke_m,
            rate_hz,
            hold_s,
            capacity,
            move_decimation,
            window_decimation,
            window_samples,
            probe,
            delay,
            span,
        })
    }

    /// Prints the holds and the probes the plan runs.
    ///
    /// # Errors
    /// `out` failing.
    fn print(&self, out: &mut dyn Write) -> anyhow::Result<()> {
        writeln!(
            out,
            "spring, mass and friction: the loop closed with the measured coil and circuit, default tuning; holds of {} s at {}",
            sig(self.hold_s, 3),
            hil_sim::simulation::actuator::SEQUENCE.map(|f| format!("{} mm", sig(f * self.stroke_m * 1e3, 3))).join(", ")
        )?;
        writeln!(
            out,
            "inductance: {} probes at the end of each hold, +-{} A about the hold's current, {} cycles of {} ticks at each level",
            hil_sim::identification::commissioning::HOLD_PROBE_RUNS,
            sig(self.probe.amplitude_a, 3),
            self.probe.cycles,
            self.probe.half_ticks
        )?;
        Ok(())
    }
}

/// Runs the holds of `plan` until they end without a monitor's fault or
/// [`hil_sim::identification::commissioning::HOLD_ATTEMPTS`] have run: after a fault,
/// cleared, again with a slower loop
/// ([`hil_sim::identification::commissioning::hold_tuning`]). The inner result is the last
/// attempt's; the board is left armed or not as it ended.
///
/// # Errors
/// (Outer) no tuning or parameters for an attempt, a refusal of `Clear`, `out` failing.
fn hold_with_retries<P: Port>(
    link: &mut Link<P>,
    file: &Actuator,
    plan: &HoldPlan,
    report: &Report,
    out: &mut dyn Write,
) -> anyhow::Result<anyhow::Result<(Holds, Probes)>> {
    let mut attempt = 0;
    loop {
        let tuning = hil_sim::identification::commissioning::hold_tuning(&plan.m, attempt)?;
        let sets = commissioned_sets(file, &plan.m, &tuning)?;
        let held = run_holds(link, plan, &sets, report);
        // A monitor that ended the holds: again with a slower loop, while attempts are left.
        let ended = held
            .as_ref()
            .err()
            .and_then(|e| e.downcast_ref::<HoldsFault>())
            .map(|f| f.0.clone());
        match ended {
            Some(fault) if attempt + 1 < hil_sim::identification::commissioning::HOLD_ATTEMPTS => {
                link.done(Command::Clear)?;
                attempt += 1;
                let slower = hil_sim::identification::commissioning::hold_tuning(&plan.m, attempt)?;
                writeln!(
                    out,
                    "  the holds ended by the fault {fault}: again with a slower loop (alpha {} 1/s, observer {} rad/s)",
                    sig(f64::from(slower.alpha_per_s), 3),
                    sig(f64::from(slower.observer_rad_s), 3)
                )?;
            }
            _ => return Ok(held),
        }
    }
}

/// One attempt at the holds: sets `sets`, waits for the armature at the open stop, arms,
/// and at each position of [`hil_sim::simulation::actuator::SEQUENCE`] captures the move,
/// the hold's window and its inductance probes.
///
/// # Errors
/// A refusal, no reply, the armature not back at the open stop, a fault in a capture
/// ([`HoldsFault`]).
fn run_holds<P: Port>(
    link: &mut Link<P>,
    plan: &HoldPlan,
    sets: &[(&'static str, ema::device::protocol::Value)],
    report: &Report,
) -> anyhow::Result<(Holds, Probes)> {
    set_all(link, sets)?;
    // The holds start from the open stop, as the evaluation sequence does: the
    // armature comes back there once the commissioning's last hold lets go.
    wait_at_open_stop(
        link,
        report.ends.open_m,
        SPRING_START_SHARE * plan.m.mechanics.stroke_m,
    )?;
    link.done(Command::Arm)?;
    let mut holds = Holds {
        move_dt_s: f64::from(plan.move_decimation) / plan.rate_hz,
        window_dt_s: f64::from(plan.window_decimation) / plan.rate_hz,
        ..Holds::default()
    };
    let mut probes = Probes::default();
    for (k, f) in hil_sim::simulation::actuator::SEQUENCE
        .into_iter()
        .enumerate()
    {
        #[expect(clippy::cast_possible_truncation)]
        let c = capture_move(
            link,
            plan.capacity,
            plan.move_decimation,
            Some(((f * plan.stroke_m) as f32, None)),
            plan.rate_hz,
        )?;
        holds.moves[k] = readings(&c)?;
        // The window: the hold's end, once the move has settled.
        let c = capture_move(
            link,
            plan.window_samples,
            plan.window_decimation,
            None,
            plan.rate_hz,
        )?;
        holds.windows[k] = readings(&c)?;
        // The inductance at the hold: each probe captured at every tick from its first.
        for _ in 0..hil_sim::identification::commissioning::HOLD_PROBE_RUNS {
            link.done(Command::Capture {
                samples: plan.span,
                decimation: 1,
                trigger: Trigger::Probe,
            })?;
            link.done(plan.probe.command())?;
            let c = read_capture(link, plan.span, 1, plan.rate_hz)?;
            // A fault during a probe ends the holds, named, as one during a window.
            readings(&c)?;
            probes[k].push(
                c.samples
                    .iter()
                    .map(|s| hil_sim::identification::commissioning::ProbeSample {
                        y_m: f64::from(s.x_m),
                        u_v: f64::from(s.u_v),
                        i_a: f64::from(s.i_a),
                        vbus_v: f64::from(s.vbus_v),
                    })
                    .collect(),
            );
        }
    }
    Ok((holds, probes))
}

/// Waits until the armature reads within `still_m` of `open_m` on five status polls in a
/// row.
///
/// # Errors
/// A refusal, no reply, or not so within 10 s.
fn wait_at_open_stop<P: Port>(link: &mut Link<P>, open_m: f32, still_m: f32) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut near = 0;
    while near < 5 {
        ensure!(
            Instant::now() < deadline,
            "the armature did not come back to the open stop within 10 s"
        );
        near = if (status(link)?.x_m - open_m).abs() < still_m {
            near + 1
        } else {
            0
        };
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(())
}

/// A capture's positions and currents, `(x_m, i_a)` per sample.
///
/// # Errors
/// A sample with a fault ([`HoldsFault`], naming it).
fn readings(c: &Capture) -> anyhow::Result<Vec<(f64, f64)>> {
    if let Some(s) = c.samples.iter().find(|s| s.fault != 0) {
        return Err(HoldsFault(fault_name(s.fault)).into());
    }
    Ok(c.samples
        .iter()
        .map(|s| (f64::from(s.x_m), f64::from(s.i_a)))
        .collect())
}

/// Prints each hold's inductance, or why it was not read; `stroke_m` places the holds.
///
/// # Errors
/// `out` failing.
fn print_inductances(
    out: &mut dyn Write,
    stroke_m: f64,
    inductances: &[Option<HoldInductance>],
) -> anyhow::Result<()> {
    for (f, l) in hil_sim::simulation::actuator::SEQUENCE
        .iter()
        .zip(inductances)
    {
        let line = match l {
            Some(h) => format!(
                "{} uH +- {} at {} mm",
                sig(h.inductance_h * 1e6, 4),
                sig(h.uncertainty_h * 1e6, 2),
                sig(h.x_m * 1e3, 4)
            ),
            None => format!(
                "not read at the hold at {} mm (the current did not step, or the noise carries the \
                 reading out of its domain)",
                sig(f * stroke_m * 1e3, 3),
            ),
        };
        writeln!(out, "  inductance {line}")?;
    }
    Ok(())
}

/// Prints the circuit, the spring and the armature fitted (`mechanics`) against the
/// board's `file`, the circuit's deviation from the holds' `inductances`.
///
/// # Errors
/// `out` failing.
fn print_mechanics(
    out: &mut dyn Write,
    file: &Actuator,
    mechanics: &Mechanics,
    inductances: &[Option<HoldInductance>],
) -> anyhow::Result<()> {
    let c = mechanics.circuit;
    let n2 = f64::from(file.coil.turns).powi(2);
    let growth = if c.growth_per_m == 0.0 {
        "constant over the stroke (no growth beyond the readings' noise)".to_owned()
    } else {
        format!(
            "growing {} % from the closed stop to the open one",
            sig(100.0 * (c.surface_growth() - 1.0), 3)
        )
    };
    writeln!(
        out,
        "circuit fitted to the six inductances: rho_0 {} 1/H, rho_x {} 1/(H m) at a closed gap \
         ({} turns), the airgap's surface {growth}; within {} % of the holds' inductances",
        sig(c.iron_per_h * n2, 4),
        sig(c.gap_per_h_m * n2, 4),
        file.coil.turns,
        sig(100.0 * c.deviation(inductances).unwrap_or(f64::NAN), 2)
    )?;
    let Mechanics {
        spring: s,
        armature,
        ..
    } = mechanics;
    for (x, f) in &s.holds {
        writeln!(
            out,
            "  hold at {} mm: magnet's pull {} N",
            sig(x * 1e3, 4),
            sig(*f, 4)
        )?;
    }
    writeln!(
        out,
        "spring rate {} N/m +- {} (two standard errors), preload {} N; the file says {} N/m, {} N",
        sig(s.n_per_m, 4),
        sig(s.uncertainty_n_per_m, 2),
        sig(s.preload_n, 4),
        file.mechanics.spring_n_per_m,
        file.mechanics.preload_n
    )?;
    match armature {
        Some(arm) => writeln!(
            out,
            "mass {} kg, friction {} N s/m (the moves between the holds, {} fitted); the file says {} kg, {} N s/m",
            sig(arm.mass_kg, 4),
            sig(arm.friction_n_s_per_m, 3),
            arm.moves,
            file.mechanics.mass_kg,
            file.mechanics.friction_n_s_per_m
        )?,
        None => writeln!(
            out,
            "mass and friction not measured: every move came near a stop; the file's kept"
        )?,
    }
    Ok(())
}

/// How near the open stop's reading, as a share of the stroke, the armature must read on
/// five status polls in a row before [`measure_mechanics`]'s holds start.
pub(super) const SPRING_START_SHARE: f32 = 0.01;

/// A fault the board latched during the holds of [`measure_mechanics`], by name.
#[derive(Debug)]
pub(super) struct HoldsFault(String);

impl core::fmt::Display for HoldsFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "fault {} latched during the holds", self.0)
    }
}

impl std::error::Error for HoldsFault {}
