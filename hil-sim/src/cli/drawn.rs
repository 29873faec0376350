//! `hil-sim drawn --n N --seed S --plants P`: `N` drawn actuators
//! ([`crate::analysis::drawn`]), each tuned as a user would and judged out of sample
//! ([`crate::analysis::outofsample`]): whether `tune` chose gains (or why not), the Monte
//! Carlo of `P` plants on each tuned one, the fault cases on each. Prints the table, what
//! passed, and the distribution of the tuning time; writes the table as CSV and Markdown.
//! `hil-sim actuators --draw N --seed S` writes the same actuators as files, to tune or run
//! one by hand.

use std::fmt::Write as _;
use std::io::Write;

use crate::analysis::outofsample::{self, Verdict};
use crate::analysis::report::{self, sig, Table};

/// Arguments of `drawn`.
#[derive(Clone, Debug, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// Actuators drawn.
    #[arg(long, default_value_t = 20)]
    pub n: usize,
    /// Seed of the actuators (default: the judging seed, apart from every seed used to
    /// write the rules).
    #[arg(long, default_value_t = crate::analysis::seeds::DRAWN_JUDGE)]
    pub seed: u64,
    /// Plants drawn per tuned actuator.
    #[arg(long, default_value_t = 1000)]
    pub plants: usize,
    /// Seed of the plants (default: the results' seed, apart from tune's validation).
    #[arg(long, default_value_t = crate::analysis::seeds::RESULTS)]
    pub plant_seed: u64,
    /// Hide the progress messages.
    #[arg(long)]
    pub quiet: bool,
    /// Output folder (default: `out/drawn-<seed>`).
    #[command(flatten)]
    pub output: super::Output,
}

impl Default for Args {
    fn default() -> Self {
        Self {
            n: 20,
            seed: crate::analysis::seeds::DRAWN_JUDGE,
            plants: 1000,
            plant_seed: crate::analysis::seeds::RESULTS,
            quiet: false,
            output: super::Output::default(),
        }
    }
}

/// What `drawn` measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// One verdict per actuator, in the order drawn.
    pub verdicts: Vec<Verdict>,
    /// The table.
    pub table: Table,
    /// What passed, in sentences.
    pub summary: String,
}

/// Draws, tunes and judges; prints and writes the table.
///
/// # Errors
/// `--n` or `--plants` 0; a draw or run that fails; a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    anyhow::ensure!(args.n > 0, "--n = 0: draw at least one actuator");
    anyhow::ensure!(args.plants > 0, "--plants = 0: draw at least one plant");
    let mut verdicts = Vec::with_capacity(args.n);
    for index in 0..args.n {
        let d = crate::analysis::drawn::draw_one(args.seed, index)?;
        if !args.quiet {
            writeln!(out, "{} ({}) ...", d.name(), d.circuit)?;
        }
        let v = outofsample::judge(&d, args.plants, args.plant_seed)?;
        if !args.quiet {
            writeln!(
                out,
                "  {} in {} s",
                if v.pass() { "pass" } else { "FAIL" },
                sig(v.tune_s, 3)
            )?;
        }
        verdicts.push(v);
    }
    let table = table(&verdicts);
    let summary = summary(&verdicts);
    writeln!(
        out,
        "{} drawn actuators of seed {}, {} plants of seed {} each:\n{}\n{summary}",
        args.n,
        args.seed,
        args.plants,
        args.plant_seed,
        table.to_text()
    )?;
    let mut times: Vec<f64> = verdicts.iter().map(|v| v.tune_s).collect();
    times.sort_by(f64::total_cmp);
    writeln!(
        out,
        "tune took {} s median, {} s at most ({} of {} over 60 s)",
        sig(times.get(times.len() / 2).copied().unwrap_or(f64::NAN), 3),
        sig(times.last().copied().unwrap_or(f64::NAN), 3),
        times.iter().filter(|&&t| t > 60.0).count(),
        times.len()
    )?;
    let dir = args.output.dir(&format!("drawn-{}", args.seed));
    report::create_dir(&dir)?;
    let csv = dir.join("verdicts.csv");
    table.write_csv(&csv)?;
    let md = dir.join("verdicts.md");
    std::fs::write(&md, format!("{}\n{summary}\n", table.to_text()))?;
    super::list_files(out, &[csv, md])?;
    Ok(Outcome {
        verdicts,
        table,
        summary,
    })
}

/// The verdicts as a table: the actuator, the tuning, the Monte Carlo, the fault cases.
#[must_use]
pub fn table(verdicts: &[Verdict]) -> Table {
    let mut t = Table::new([
        "actuator",
        "circuit",
        "mass [g]",
        "stroke [mm]",
        "coil L/R [ms]",
        "rate [kHz]",
        "tune: alpha / observer / margin",
        "draws missing a target",
        "fault cases failed",
        "verdict",
    ]);
    for v in verdicts {
        t.push([
            v.name.clone(),
            v.circuit.clone(),
            sig(v.mass_kg * 1e3, 3),
            sig(v.stroke_m * 1e3, 3),
            sig(v.coil_s * 1e3, 3),
            sig(v.rate_hz / 1e3, 3),
            match &v.tune {
                Ok(g) => format!(
                    "{} / {} / {}",
                    sig(g.alpha, 3),
                    sig(g.observer_rad_s, 3),
                    sig(g.margin, 2)
                ),
                Err(r) => format!("FAIL: {}", r.short()),
            },
            v.montecarlo.as_ref().map_or_else(
                || "-".into(),
                |m| {
                    let what = m
                        .misses
                        .iter()
                        .map(|(w, k)| format!("{w} {k}"))
                        .collect::<Vec<_>>()
                        .join(", ");
                    format!(
                        "{} of {}{}{}",
                        m.missing,
                        m.draws,
                        if what.is_empty() {
                            String::new()
                        } else {
                            format!(" ({what})")
                        },
                        if m.pass() { "" } else { " FAIL" }
                    )
                },
            ),
            v.faults.as_ref().map_or_else(
                || "-".into(),
                |f| {
                    if f.failed.is_empty() {
                        format!("none of {}", f.cases)
                    } else {
                        format!(
                            "{} of {} FAIL ({})",
                            f.failed.len(),
                            f.cases,
                            f.failed.join("; ")
                        )
                    }
                },
            ),
            if v.pass() { "pass" } else { "FAIL" }.into(),
        ]);
    }
    t
}

/// What passed, in sentences: tuned, Monte Carlo, fault cases, overall; the refusals by
/// the target missed.
#[must_use]
pub fn summary(verdicts: &[Verdict]) -> String {
    let n = verdicts.len();
    let tuned: Vec<&Verdict> = verdicts.iter().filter(|v| v.tune.is_ok()).collect();
    let mc = tuned
        .iter()
        .filter(|v| {
            v.montecarlo
                .as_ref()
                .is_some_and(outofsample::MonteCarlo::pass)
        })
        .count();
    let faults = tuned
        .iter()
        .filter(|v| v.faults.as_ref().is_some_and(|f| f.failed.is_empty()))
        .count();
    let pass = verdicts.iter().filter(|v| v.pass()).count();
    let mut refused: Vec<(String, usize)> = Vec::new();
    for v in verdicts {
        if let Err(r) = &v.tune {
            crate::analysis::report::tally(&mut refused, r.what.clone());
        }
    }
    refused.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut s = format!(
        "`tune` chose gains for {} of {n}{}; of those, the Monte Carlo passes (at most {} % \
         of the draws missing a target) on {mc} and every fault case on {faults}. Pass \
         overall: {pass} of {n}.",
        tuned.len(),
        if refused.is_empty() {
            String::new()
        } else {
            format!(
                " (refused for {})",
                refused
                    .iter()
                    .map(|(w, k)| format!("{w}: {k}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        },
        sig(outofsample::MISS_SHARE * 100.0, 2)
    );
    if pass < n {
        let _ = write!(s, " FAIL: the target is every actuator.");
    }
    s
}
