//! The `commission` verb: the commissioning on the board, its report shown, and on request
//! the tuning of the commissioned file.

use std::io::Write;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail};
use ema::device::commission::Report;
use ema::device::protocol::{Command, Commissioned, Message, Reply, Value};
use hil_sim::analysis::report::{self};

use super::{
    actuator_file, apply_commissioned, correction_sets, measure_mechanics, read_params, set_all,
    status, value_text, CommissionArgs,
};
use crate::fault_name;
use crate::link::{Link, Port};

/// Runs a commissioning and waits for its outcome; prints it, and with `apply` sets the
/// measured resistance and the position sensor's correction from the end stops
/// (`sensor.position_gain`, `sensor.position_offset_codes`).
///
/// # Errors
/// Refused, stopped (with the board's reason), no outcome within the timeout, or (with
/// `apply`) the value refused.
pub fn commission<P: Port>(
    link: &mut Link<P>,
    args: &CommissionArgs,
    out: &mut dyn Write,
) -> anyhow::Result<Report> {
    let file = read_params(link)?.actuator;
    let file_r = file.coil.resistance_ohm;
    let stroke_m = file.mechanics.stroke_m;
    let scales = file
        .time_scales()
        .map_err(|e| anyhow!("the board's actuator: {}", e))?;
    link.done(Command::Commission)?;
    let start = Instant::now();
    let r = loop {
        let f = link.request(Command::Commissioned)?;
        let mut scratch = Vec::new();
        match f.message(&mut scratch)? {
            Message::Reply {
                reply: Reply::Commissioned(c),
                ..
            } => match c {
                Commissioned::Done(r) => break r,
                Commissioned::Aborted(ema::device::commission::Abort::Fault) => {
                    let latched = status(link)?.fault.map_or("none".into(), fault_name);
                    bail!("commissioning stopped: fault {latched} latched, bridge coasting")
                }
                Commissioned::Aborted(a) => bail!("commissioning stopped: {}", a.name()),
                Commissioned::Never => bail!("the board never started the commissioning"),
                Commissioned::Running => {}
            },
            other => bail!("unexpected reply: {other:?}"),
        }
        if start.elapsed().as_secs_f64() > args.timeout_s {
            bail!("no outcome after {} s", args.timeout_s);
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let report = r;
    let r = report.resistance;
    writeln!(
        out,
        "coil resistance {:.4} ohm +- {:.4} (two standard errors); the file says {file_r} ohm ({:+.1} %)",
        r.ohm,
        r.uncertainty_ohm,
        100.0 * (r.ohm / file_r - 1.0)
    )?;
    writeln!(
        out,
        "steps: {:.3} V -> {:.4} A, {:.3} V -> {:.4} A, bus {:.2} V",
        r.u_v[0], r.i_a[0], r.u_v[1], r.i_a[1], r.vbus_v
    )?;
    let l = report.inductance;
    let (file_open_h, file_closed_h) = (scales.coil_open_s * file_r, scales.coil_closed_s * file_r);
    writeln!(
        out,
        "inductance at the open stop {:.1} uH, at the closed stop {:.1} uH; the file says {:.1} and {:.1} uH ({:+.1} %, {:+.1} %)",
        1e6 * l.open_h,
        1e6 * l.closed_h,
        1e6 * file_open_h,
        1e6 * file_closed_h,
        100.0 * (l.open_h / file_open_h - 1.0),
        100.0 * (l.closed_h / file_closed_h - 1.0)
    )?;
    let e = report.ends;
    let travel_m = e.closed_m - e.open_m;
    writeln!(
        out,
        "position at the open stop {:.1} um, at the closed stop {:.1} um (+- {:.2} um, two standard errors, in the file's calibration)",
        1e6 * e.open_m,
        1e6 * e.closed_m,
        1e6 * e.uncertainty_m
    )?;
    writeln!(
        out,
        "sensor: offset {:+.2} % of the stroke, gain {:+.2} % (travel {:.1} um against the file's {:.1} um)",
        100.0 * e.open_m / stroke_m,
        100.0 * (travel_m / stroke_m - 1.0),
        1e6 * travel_m,
        1e6 * stroke_m
    )?;
    let correction = hil_sim::identification::commissioning::stops_correction(&file, &report);
    let mechanics = if args.mechanics {
        Some(measure_mechanics(link, &file, &report, out)?)
    } else {
        None
    };
    if let Some(path) = &args.out {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            report::create_dir(dir)?;
        }
        std::fs::write(path, actuator_file(&file, &report, mechanics.as_ref())?)
            .map_err(|e| anyhow!("{}: {e}", path.display()))?;
        writeln!(out, "actuator file written: {}", path.display())?;
    }
    if args.tune {
        let Some(path) = &args.out else {
            bail!("--tune needs --out FILE: the commissioned file is what is tuned")
        };
        writeln!(out)?;
        let stem = hil_sim::simulation::actuator::stem(path);
        let beside = |name: String| hil_sim::cli::Output {
            out: Some(path.with_file_name(name)),
        };
        let tuned = hil_sim::cli::tune::run(
            &hil_sim::cli::tune::Args {
                actuator: path.display().to_string(),
                rates_hz: Some(vec![f64::from(file.board.rate_hz)]),
                validate: TUNE_VALIDATION_DRAWS,
                substeps: 1,
                tuned: None,
                quiet: true,
                output: beside(format!("{stem}-tune")),
            },
            out,
        )?;
        let Some(tuned_path) = tuned.tuned else {
            bail!("no tuning meets every target for the commissioned actuator (see above); nothing applied")
        };
        writeln!(out, "\npredicted with the tuned file:")?;
        hil_sim::cli::run::run(
            &hil_sim::cli::run::Args {
                scenario: tuned_path.display().to_string(),
                output: beside(stem.clone()),
                max_rows: 20_000,
            },
            out,
        )?;
        if args.apply {
            // The tuned file: the measured actuator with the tuning chosen.
            let tuned = hil_sim::simulation::actuator::parse(
                &std::fs::read_to_string(&tuned_path)?,
                &tuned_path.display().to_string(),
            )?;
            let tuning = tuned
                .tuning
                .ok_or_else(|| anyhow!("{}: no tuning in it", tuned_path.display()))?;
            apply_commissioned(link, &file, &tuned, &tuning, &correction, out)?;
        }
    } else if args.apply {
        let mut sets = vec![("coil.resistance_ohm", Value::Number(r.ohm))];
        sets.extend(correction_sets(&correction));
        if let Err(e) = set_all(link, &sets) {
            link.done(Command::Load)?;
            bail!("{e}; the stored parameters are loaded back");
        }
        for (name, value) in sets {
            writeln!(
                out,
                "{name} = {} (not stored until `save`)",
                value_text(name, value)
            )?;
        }
    }
    Ok(report)
}

/// Drawn plants `commission --tune` validates the tuning on.
pub(super) const TUNE_VALIDATION_DRAWS: usize = 100;
