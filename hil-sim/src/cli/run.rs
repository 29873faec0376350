//! `hil-sim run <scenario>`: one scenario, its metrics per reference segment, a decimated
//! CSV trace and the standard figures.

use std::io::Write;
use std::path::PathBuf;

use crate::analysis::report::{self, decimated, figures, figures::Case, sig, Table};
use crate::simulation::catalog;
use crate::{Metrics, Scenario};

/// Arguments of `run`.
#[derive(Clone, Debug, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// An embedded scenario's name (see `hil-sim scenarios`) or a TOML file.
    pub scenario: String,
    /// Output folder.
    #[command(flatten)]
    pub output: super::Output,
    /// Largest number of rows in the trace CSV: the trace keeps every n-th ISR sample,
    /// with the current and voltage extremes of the samples in between.
    #[arg(long, default_value_t = 20_000, value_name = "ROWS")]
    pub max_rows: usize,
}

/// What `run` measured and wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The scenario run.
    pub scenario: Scenario,
    /// Its metrics.
    pub metrics: Metrics,
    /// The metrics table (one row per segment).
    pub table: Table,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// A one-line description of a scenario: rate, supply, law, duration, substeps.
#[must_use]
pub fn describe(sc: &Scenario) -> String {
    let rate = sc.rate_hz();
    let rate = if rate >= 1e6 {
        format!("{} MHz", sig(rate / 1e6, 4))
    } else {
        format!("{} kHz", sig(rate / 1e3, 4))
    };
    format!(
        "{rate} ISR, {} V supply, `{}` law, {} sensors, {:?} bridge, {} s, {} RK4 substeps per period",
        sig(sc.supply.voltage_v, 4),
        sc.controller.law.name(),
        match sc.sensors {
            crate::simulation::scenario::Sensors::Ideal => "ideal",
            crate::simulation::scenario::Sensors::Adc(_) => "converter-model",
        },
        sc.bridge.mode,
        sig(sc.duration_s, 4),
        sc.integration.substeps
    )
    .replace("Averaged", "averaged")
    .replace("Switching", "switching-level")
}

/// Writes what every run reports besides the table: bounds check, first fault, probes.
pub(crate) fn write_notes(out: &mut dyn Write, m: &Metrics) -> anyhow::Result<()> {
    match &m.bounds.warning {
        None => writeln!(
            out,
            "bounds: the controller's mu and L bounds bracket the true plant over the stroke \
             (min mu/mu_lo {}, max mu/mu_hi {})",
            sig(m.bounds.mu_lo_ratio_min, 4),
            sig(m.bounds.mu_hi_ratio_max, 4)
        )?,
        Some(w) => writeln!(out, "WARNING: {w}")?,
    }
    match &m.first_fault {
        None => writeln!(out, "faults: none")?,
        Some(f) => writeln!(
            out,
            "first fault: {} at {} s (the bridge coasts from then on)",
            f.fault.map_or("?", ema::control::supervisor::Fault::name),
            sig(f.t_s, 4)
        )?,
    }
    for e in &m.errors_at {
        writeln!(
            out,
            "error at {} s: {} um ({} %)",
            sig(e.t_s, 4),
            sig(e.error_um, 4),
            sig(e.error_pct, 3)
        )?;
    }
    Ok(())
}

/// Loads, runs and reports one scenario.
///
/// # Errors
/// A scenario that cannot be loaded (named field and value; nothing is written then), a
/// failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    let sc = catalog::load(&args.scenario)?;
    let dir = args.output.dir(&sc.name);
    writeln!(out, "scenario `{}`: {}", sc.name, describe(&sc))?;
    let r = crate::run(&sc)?;
    report::create_dir(&dir)?;
    let mut files = Vec::new();

    let table = report::metrics_table(&[(sc.name.as_str(), &r.metrics)]);
    let mut shown = table.transposed();
    shown.header[0] = "metric".into();
    for (k, h) in shown.header.iter_mut().enumerate().skip(1) {
        *h = format!("segment {}", k - 1);
    }
    shown
        .rows
        .retain(|row| row[0] != "case" && row[0] != "segment");
    write!(out, "\n{}\n", shown.to_text())?;
    write_notes(out, &r.metrics)?;

    let path = dir.join("metrics.csv");
    table.write_csv(&path)?;
    files.push(path);
    let every = decimated::every_for(r.samples.len(), args.max_rows);
    let path = dir.join("trace.csv");
    decimated::write_csv(&path, &r.samples, every)?;
    files.push(path);

    let rows = decimated::decimate(&r.samples, decimated::every_for(r.samples.len(), 4000));
    let case = [Case {
        label: &sc.name,
        rows: &rows,
    }];
    let name = &sc.name;
    for (file, fig) in [
        (
            "x1-x2.png",
            figures::position_velocity(&format!("{name}: position and velocity"), &case),
        ),
        (
            "x3.png",
            figures::current(&format!("{name}: coil current"), &case),
        ),
        (
            "u.png",
            figures::voltage(&format!("{name}: coil voltage"), &case, sc.supply.voltage_v),
        ),
    ] {
        let path = dir.join(file);
        fig.write_png(&path)?;
        files.push(path);
    }
    super::list_files(out, &files)?;
    Ok(Outcome {
        scenario: sc,
        metrics: r.metrics,
        table,
        files,
    })
}
