//! `hil-sim compare`: the paper's law, its boundary-layer variant and the practical law at
//! 10, 20 and 50 kHz on 24, 48 and 150 V supplies, under the product's realistic
//! conditions ([`crate::analysis::compare`]); a table of settling, overshoot, error, ripple, peak
//! current and voltage with pass or fail against the targets, as text, CSV and a figure.

use std::io::Write;
use std::path::PathBuf;

use crate::analysis::compare::{grid, Row, LAWS, RATES_HZ};
use crate::analysis::report::{self, plot::Figure, plot::Panel, plot::Series, sig, Table};
use crate::simulation::targets::Targets;

/// Arguments of `compare`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Args {
    /// Length of each run (the paper's step from 1 to 3 mm) (s).
    #[arg(long, default_value_t = 0.4)]
    pub duration_s: f64,
    /// Output folder [default: out/compare].
    #[command(flatten)]
    pub output: super::Output,
}

impl Default for Args {
    fn default() -> Self {
        Self {
            duration_s: 0.4,
            output: super::Output::default(),
        }
    }
}

/// What `compare` measured and wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// One row per law, rate and supply.
    pub rows: Vec<Row>,
    /// The table printed.
    pub table: Table,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// The comparison table.
#[must_use]
pub fn table(rows: &[Row]) -> Table {
    let mut t = Table::new([
        "law",
        "ISR [kHz]",
        "supply [V]",
        "settling [s]",
        "overshoot [%]",
        "|error| [%]",
        "ripple p-p [A]",
        "peak current [A]",
        "peak |u| [V]",
        "fault",
        "verdict",
    ]);
    for r in rows {
        let w = &r.worst;
        t.push([
            r.law.clone(),
            sig(r.rate_hz / 1e3, 3),
            sig(r.supply_v, 3),
            if w.settling_s.is_finite() {
                sig(w.settling_s, 3)
            } else {
                "never".into()
            },
            sig(w.overshoot_pct, 3),
            sig(w.steady_error_pct, 3),
            sig(w.ripple_pp_a, 3),
            sig(w.current_a, 3),
            sig(w.voltage_v, 3),
            r.fault.clone().unwrap_or_else(|| "-".into()),
            if r.pass() {
                "pass".into()
            } else {
                format!("fail: {}", r.misses.join(", "))
            },
        ]);
    }
    t
}

/// The figure: log10 of error, ripple and peak current against the ISR rate, one line per
/// law on the 24 V supply, the targets dashed.
fn figure(rows: &[Row], t: &Targets) -> Figure {
    let panel = |label: &str, target: f64, f: &dyn Fn(&Row) -> f64| {
        let mut p = Panel::new("ISR rate [kHz]", label);
        for (k, law) in LAWS.iter().enumerate() {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.law == *law && (r.supply_v - 24.0).abs() < 1e-9)
                .map(|r| (r.rate_hz / 1e3, f(r).max(1e-6).log10()))
                .collect();
            p = p.series(Series::line(*law, pts).color(k));
        }
        let lo = RATES_HZ[0] / 1e3;
        let hi = RATES_HZ[RATES_HZ.len() - 1] / 1e3;
        p.series(
            Series::dashed("target", vec![(lo, target.log10()), (hi, target.log10())]).color(3),
        )
    };
    Figure::new("Laws at firmware rates, 24 V, realistic sensors (log10 scale)")
        .panel(panel(
            "log10 |steady error| [%]",
            t.steady_error_pct,
            &|r| r.worst.steady_error_pct,
        ))
        .panel(panel("log10 ripple p-p [A]", t.ripple_pp_a, &|r| {
            r.worst.ripple_pp_a
        }))
        .panel(panel("log10 peak current [A]", t.current_a, &|r| {
            r.worst.current_a
        }))
}

/// Runs the comparison and writes its report.
///
/// # Errors
/// A scenario that does not validate; a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    anyhow::ensure!(
        args.duration_s.is_finite() && args.duration_s > 0.1,
        "--duration-s = {}: a run needs more than 0.1 s (the steady window is the last 50 ms)",
        args.duration_s
    );
    let rows = grid(args.duration_s)?;
    let table = table(&rows);
    let t = Targets::for_scenario(&crate::analysis::compare::scenario(
        "practical",
        20e3,
        24.0,
    )?);
    writeln!(
        out,
        "the product's actuator (physical convention), step 1 -> 3 mm, {} s, nominal plant, \
         converter noise and one sample of delay; targets: settling <= {} s, overshoot <= {} %, \
         |error| <= {} %, ripple <= {} A, current <= {} A, |u| <= supply\n",
        sig(args.duration_s, 3),
        sig(t.settling_max_s(), 3),
        sig(t.overshoot_pct, 3),
        sig(t.steady_error_pct, 3),
        sig(t.ripple_pp_a, 3),
        sig(t.current_a, 3),
    )?;
    write!(out, "{}", table.to_text())?;
    let dir = args.output.dir("compare");
    report::create_dir(&dir)?;
    let mut files = Vec::new();
    let path = dir.join("compare.csv");
    table.write_csv(&path)?;
    files.push(path);
    let path = dir.join("compare.png");
    figure(&rows, &t).write_png(&path)?;
    files.push(path);
    super::list_files(out, &files)?;
    Ok(Outcome { rows, table, files })
}
