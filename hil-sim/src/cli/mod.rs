//! The `hil-sim` command line (clap derive). One module per subcommand, each with its
//! `Args` and a `run(&Args, &mut dyn Write)` that prints to the writer it is given and
//! returns what it measured, so that tests call it without a subprocess. Files go to
//! `out/<scenario-name>/` under the current directory unless `--out` says otherwise
//! ([`Output`]); tables, traces and figures are written with [`crate::analysis::report`].
//!
//! To add a subcommand: a module here with `Args` and `run`, a variant in [`Command`], an
//! arm in [`dispatch`].
//!
//! The `Args` doc comments are the command line's help text, where `[s]`, `[Hz]` and
//! `[default: out/<name>]` are units and defaults as clap prints them, not links or HTML.
//!
//! | command | what |
//! |---|---|
//! | (none), `paper` | the paper's example at 1 MHz and at 20 kHz: claims vs measured, figures |
//! | `run <scenario>` | one scenario (embedded name or TOML file): metrics per segment, trace, figures |
//! | `scenarios [name]` | lists the embedded scenarios, or prints one's TOML |
//! | `actuators [name]` | lists the family of actuators, or prints one's file; `--draw N --seed S` writes `N` drawn actuators |
//! | `montecarlo <scenario>` | draws plants from the uncertainty set: worst case of each metric, the product's targets, CSV of all draws |
//! | `compare` | the three laws at 10, 20, 50 kHz and 24, 48, 150 V: table, CSV, figure |
//! | `tune [actuator]` | designs the practical law's gains for an actuator, writes its tuned file |
//! | `faults [actuator]` | the fault-injection cases: fault named, detection time, peak current |
//! | `drawn` | drawn actuators tuned and judged out of sample: tune, Monte Carlo, fault cases |
//! | `golden` | records the golden traces the Cortex-M4F replays (`tests/golden/`) |
//! | `results [--check]` | runs every result table and writes (or checks) `hil-sim/RESULTS.md` |

#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub mod actuators;
// Temporary: `commission::run` has 190 lines against the 180 of clippy.toml and is being
// changed elsewhere; this allow goes once it is split (or below the threshold).
#[allow(
    clippy::too_many_lines,
    reason = "temporary: commission::run is being changed elsewhere"
)]
pub mod commission;
pub mod compare;
pub mod drawn;
pub mod faults;
pub mod golden;
pub mod montecarlo;
pub mod paper;
pub mod results;
pub mod run;
pub mod scenarios;
pub mod tune;

/// Host simulator of the electromagnetic actuator around the `ema` control core.
///
/// Without a subcommand, reproduces the paper's example (`paper`).
#[derive(Debug, Parser)]
#[command(name = "hil-sim", version, about, long_about = None)]
pub struct Cli {
    /// What to do (default: `paper`).
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// The paper's example at a 1 MHz ISR (near-continuous) and at 20 kHz: a table of the
    /// paper's claims beside the measured values, CSV traces and the paper's figures.
    Paper(paper::Args),
    /// Runs one scenario (embedded name or TOML file): metrics per reference segment, a
    /// CSV trace, figures.
    Run(run::Args),
    /// Lists the embedded scenarios, or prints the TOML of one.
    Scenarios(scenarios::Args),
    /// Lists the family of actuators kept in the repository, or prints the file of one.
    Actuators(actuators::Args),
    /// Runs a scenario over plants drawn from the uncertainty set, in parallel: the worst
    /// case of each metric, the product's targets, and a CSV of every draw.
    Montecarlo(montecarlo::Args),
    /// Compares the paper's law, the boundary-layer law and the practical law at 10, 20 and
    /// 50 kHz on 24, 48 and 150 V: table, CSV and figure.
    Compare(compare::Args),
    /// Designs the practical law's gains for an actuator: Theorem 1, the corner plants of
    /// the uncertainty set at several rates, a Monte Carlo validation.
    Tune(tune::Args),
    /// Runs the fault-injection cases: the fault named, detection time, peak current.
    Faults(faults::Args),
    /// Draws actuators nobody tuned anything on, tunes each and judges it on drawn plants
    /// and the fault cases: the out-of-sample verdict.
    Drawn(drawn::Args),
    /// The board's commissioning routine against plants drawn wider than an actuator's
    /// file: the identification errors' distribution, its duration and peak current.
    Commission(commission::Args),
    /// Records the golden traces the emulated Cortex-M4F must reproduce bit for bit.
    Golden(golden::Args),
    /// Runs every result table (paper, laws compared, family, Monte Carlo, faults) and
    /// writes hil-sim/RESULTS.md, or with --check fails where it differs from the run.
    Results(results::Args),
}

/// Where a subcommand writes its files.
#[derive(Clone, Debug, Default, PartialEq, Eq, clap::Args)]
pub struct Output {
    /// Folder for the files written [default: out/NAME in the current directory, NAME
    /// being the scenario's name].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

impl Output {
    /// `--out`, or `out/<name>`.
    #[must_use]
    pub fn dir(&self, name: &str) -> PathBuf {
        self.out
            .clone()
            .unwrap_or_else(|| PathBuf::from("out").join(name))
    }
}

/// Runs the command line on the process's arguments; prints errors on standard error.
/// Exit codes: 0 success, 1 refused input or failure (the message names the field and the
/// value), 2 bad command-line usage (clap's).
#[must_use]
pub fn main() -> ExitCode {
    exit(Cli::parse(), dispatch)
}

/// Runs `dispatch` on a parsed command line, printing to standard output; an error goes
/// to standard error after what was printed, and is exit code 1. Shared by both binaries.
pub fn exit<C>(cli: C, dispatch: impl FnOnce(C, &mut dyn Write) -> anyhow::Result<()>) -> ExitCode {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match dispatch(cli, &mut out) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let _ = out.flush();
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Runs one parsed command line, printing to `out`.
///
/// # Errors
/// The subcommand's, with context.
pub fn dispatch(cli: Cli, out: &mut dyn Write) -> anyhow::Result<()> {
    match cli
        .command
        .unwrap_or_else(|| Command::Paper(paper::Args::default()))
    {
        Command::Paper(a) => paper::run(&a, out).map(drop),
        Command::Run(a) => run::run(&a, out).map(drop),
        Command::Scenarios(a) => scenarios::run(&a, out),
        Command::Montecarlo(a) => montecarlo::run(&a, out).map(drop),
        Command::Compare(a) => compare::run(&a, out).map(drop),
        Command::Actuators(a) => actuators::run(&a, out),
        Command::Tune(a) => {
            let o = tune::run(&a, out)?;
            anyhow::ensure!(
                o.tuned.is_some(),
                "no tuning meets every target for `{}`",
                a.actuator
            );
            Ok(())
        }
        Command::Faults(a) => faults::run(&a, out).map(drop),
        Command::Drawn(a) => drawn::run(&a, out).map(drop),
        Command::Commission(a) => commission::run(&a, out),
        Command::Golden(a) => golden::run(&a, out).map(drop),
        Command::Results(a) => results::run(&a, out).map(drop),
    }
}

/// Writes the list of files written, one per line.
fn list_files(out: &mut dyn Write, files: &[PathBuf]) -> anyhow::Result<()> {
    writeln!(out, "\nwrote:")?;
    for f in files {
        writeln!(out, "  {}", f.display())?;
    }
    Ok(())
}
