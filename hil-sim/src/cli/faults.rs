//! `hil-sim faults`: the fault-injection scenarios ([`crate::faults`]): for each injected
//! fault, the fault the supervisor latched, how long after the injection, the peak coil
//! current against the trip level, and whether the bridge coasted from then on.

use std::io::Write;
use std::path::PathBuf;

use crate::faults::{table as run_cases, Outcome as Case, DEADLINE_S};
use crate::report::{self, sig, Table};

/// Arguments of `faults`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Args {
    /// ISR rate [Hz].
    #[arg(long, default_value_t = 20_000.0)]
    pub rate_hz: f64,
    /// Supply [V].
    #[arg(long, default_value_t = 24.0)]
    pub supply_v: f64,
    /// Output folder [default: out/faults].
    #[command(flatten)]
    pub output: super::Output,
}

/// What `faults` measured and wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// One entry per case.
    pub cases: Vec<Case>,
    /// The table printed.
    pub table: Table,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// The fault table.
#[must_use]
pub fn table(cases: &[Case]) -> Table {
    let mut t = Table::new([
        "fault injected",
        "what",
        "expected",
        "latched",
        "detected after [us]",
        "peak current [A]",
        "trip [A]",
        "verdict",
    ]);
    for c in cases {
        t.push([
            c.name.clone(),
            c.what.clone(),
            c.expected.clone(),
            c.fault.clone().unwrap_or_else(|| "none".into()),
            c.detected_after_s
                .map_or_else(|| "-".into(), |s| sig(s * 1e6, 4)),
            sig(c.peak_current_a, 4),
            sig(c.trip_a, 4),
            if c.pass() { "pass" } else { "FAIL" }.into(),
        ]);
    }
    t
}

/// Runs the cases and writes the table.
///
/// # Errors
/// A scenario that does not validate; a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    let cases = run_cases(args.rate_hz, args.supply_v)?;
    let table = table(&cases);
    writeln!(
        out,
        "fault injection at {} kHz on {} V: each must be named within {} us, the current stay \
         at or below the trip level, the bridge coast from then on\n",
        sig(args.rate_hz / 1e3, 3),
        sig(args.supply_v, 3),
        sig(DEADLINE_S * 1e6, 4)
    )?;
    write!(out, "{}", table.to_text())?;
    let dir = args.output.dir("faults");
    report::create_dir(&dir)?;
    let path = dir.join("faults.csv");
    table.write_csv(&path)?;
    let files = vec![path];
    super::list_files(out, &files)?;
    Ok(Outcome {
        cases,
        table,
        files,
    })
}
