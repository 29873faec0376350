//! `hil-sim tune <actuator>`: designs the practical law's gains for an actuator
//! ([`crate::analysis::tune`]): a search space from its time scales, Theorem 1 for every candidate,
//! screening on the nominal plant, the corner plants of the uncertainty set at three
//! interrupt rates, the minimax choice and a Monte Carlo validation. Writes the tuned
//! actuator file (the input with a `[tuning]` section) and every candidate as CSV; when no
//! candidate passes, says which target is out of reach, where and why, and exits with a
//! failure.

use std::io::Write;
use std::path::PathBuf;

use crate::analysis::report::{self, sig, Table};
use crate::analysis::tune::{self, Space};
use crate::simulation::actuator;

pub use crate::analysis::tune::{default_rates, BOARD_RATES_HZ, DEFAULT_VALIDATE};

/// Arguments of `tune`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Args {
    /// A family member's name (see `hil-sim actuators`) or an actuator file.
    #[arg(default_value = "product")]
    pub actuator: String,
    /// Interrupt rates to design for at once (Hz; default: the actuator's own, 20 kHz and
    /// the one of 10, 20, 25, 40 and 50 kHz nearest to the actuator's).
    #[arg(long, value_delimiter = ',')]
    pub rates_hz: Option<Vec<f64>>,
    /// Plants drawn to validate a candidate, per rate.
    #[arg(long, default_value_t = DEFAULT_VALIDATE)]
    pub validate: usize,
    /// RK4 substeps per period for the search.
    #[arg(long, default_value_t = 1)]
    pub substeps: u32,
    /// Where to write the tuned file (default: beside an input file as
    /// `<stem>.tuned.toml`; for a family member, in the output folder).
    #[arg(long)]
    pub tuned: Option<PathBuf>,
    /// Hide the progress messages.
    #[arg(long)]
    pub quiet: bool,
    /// Output folder (default: `out/<actuator>-tune`).
    #[command(flatten)]
    pub output: super::Output,
}

/// What `tune` chose and wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The report.
    pub report: tune::Report,
    /// The tuned file's path, when a candidate passed.
    pub tuned: Option<PathBuf>,
    /// Seconds the search took.
    pub seconds: f64,
}

/// Runs the tuning and writes its report.
///
/// # Errors
/// An actuator that cannot be loaded; a failed run or write. Finding no candidate is not
/// an error here (the outcome says so); the command line exits with a failure then.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    anyhow::ensure!(
        args.substeps > 0,
        "--substeps = 0: at least one RK4 step per period"
    );
    anyhow::ensure!(
        args.validate > 0,
        "--validate = 0: a candidate is validated on at least one drawn plant"
    );
    let (name, act, source) = actuator::load_untuned(&args.actuator)?;
    act.check_consistency()
        .map_err(|e| anyhow::anyhow!("`{source}` is not an actuator a user could have: {e}"))?;
    let own = f64::from(act.board.rate_hz);
    let mut rates = args.rates_hz.clone().unwrap_or_else(|| default_rates(own));
    anyhow::ensure!(!rates.is_empty(), "--rates-hz: give at least one rate");
    // Screening happens at the actuator's own rate, first.
    if let Some(k) = rates.iter().position(|r| (r - own).abs() < 0.5) {
        rates.swap(0, k);
    } else {
        rates.insert(0, own);
    }
    let rate_min = rates.iter().copied().fold(f64::INFINITY, f64::min);
    let space = Space::for_actuator(&act, rate_min)?;
    let scales = act.time_scales().map_err(crate::Error::Actuator)?;
    writeln!(
        out,
        "tuning `{name}` at {} kHz: mechanical frequency {} rad/s (natural {}, authority {}), \
         coil L/R {}-{} ms",
        rates
            .iter()
            .map(|r| sig(r / 1e3, 3))
            .collect::<Vec<_>>()
            .join(", "),
        sig(f64::from(scales.mechanical_rad_s()), 3),
        sig(f64::from(scales.natural_rad_s), 3),
        sig(f64::from(scales.authority_rad_s), 3),
        sig(f64::from(scales.coil_open_s) * 1e3, 3),
        sig(f64::from(scales.coil_closed_s) * 1e3, 3),
    )?;
    writeln!(
        out,
        "search space: alpha {:?} 1/s, observer {:?} x alpha, margin {:?}; {} candidates, {} \
         corner plants per rate",
        space.alpha,
        space.observer_per_alpha,
        space.margin,
        space.candidates(own).len(),
        tune::corners(&act.plant()?).len()
    )?;
    let started = std::time::Instant::now();
    let report = tune::tune(&name, &act, &rates, &space, args.substeps, args.validate)?;
    let seconds = started.elapsed().as_secs_f64();
    writeln!(out, "searched and validated in {} s\n", sig(seconds, 3))?;

    let stroke_m = f64::from(act.mechanics.stroke_m);
    let t = candidates_table(&report, stroke_m);
    let mut head = Table::new(t.header.clone());
    head.rows = t.rows.iter().take(8).cloned().collect();
    write!(
        out,
        "best candidates (worst over the corners and rates / target; <= 1 passes):\n{}",
        head.to_text()
    )?;

    let dir = args.output.dir(&format!("{name}-tune"));
    report::create_dir(&dir)?;
    let mut files = Vec::new();
    let path = dir.join("candidates.csv");
    t.write_csv(&path)?;
    files.push(path);
    let mut tuned_path = None;
    if let (Some(c), Some(tuned)) = (&report.chosen, &report.tuned) {
        write_chosen(out, c, &report, &rates, own, stroke_m)?;
        let path = args.tuned.clone().unwrap_or_else(|| {
            if actuator::member(&args.actuator).is_some() {
                dir.join(format!("{name}.tuned.toml"))
            } else {
                PathBuf::from(&args.actuator).with_file_name(format!("{name}.tuned.toml"))
            }
        });
        let note = format!(
            "written by `hil-sim tune` at {} kHz: worst metric at {} of its target",
            rates
                .iter()
                .map(|r| sig(r / 1e3, 3))
                .collect::<Vec<_>>()
                .join(", "),
            sig(c.score, 3)
        );
        let text = actuator::tuned_text(
            &source,
            &tuned.tuning.unwrap_or(c.candidate.tuning()),
            &note,
        );
        // The file written must load and derive exactly the tuning chosen.
        let back = actuator::parse(&text, &path.display().to_string())?;
        anyhow::ensure!(
            back == *tuned,
            "the tuned file does not read back as written"
        );
        std::fs::write(&path, text)?;
        files.push(path.clone());
        tuned_path = Some(path);
    } else if let Some(d) = &report.refusal {
        writeln!(out, "\n{d}")?;
    }
    super::list_files(out, &files)?;
    Ok(Outcome {
        report,
        tuned: tuned_path,
        seconds,
    })
}

/// The table of every candidate evaluated, best first.
fn candidates_table(report: &tune::Report, stroke_m: f64) -> Table {
    let mut t = Table::new([
        "alpha [1/s]",
        "observer [rad/s]",
        "margin",
        "d follows force",
        "Theorem 1",
        "ball radius / stroke",
        "nominal/target",
        "worst/target",
        "complete",
        "validated",
        "limiting",
    ]);
    for e in &report.evaluations {
        t.push([
            sig(e.candidate.alpha, 3),
            sig(e.candidate.observer_rad_s, 3),
            sig(e.candidate.margin, 2),
            if e.candidate.follows_force {
                "yes"
            } else {
                "no"
            }
            .into(),
            if e.theorem.holds() { "holds" } else { "fails" }.into(),
            e.theorem
                .radius_optimised_m
                .map_or_else(|| "-".into(), |r| sig(r / stroke_m, 3)),
            // A screening run stops at a certain settling miss (`Until::Miss`): its
            // size is not known, only that it is above 1, and the limiting metric is the
            // one it stopped at.
            if e.screen.is_infinite() && e.limiting.as_ref().is_some_and(|l| l.0 == "settling") {
                "> 1 (stopped)".into()
            } else {
                sig(e.screen, 3)
            },
            if e.worst.is_empty() {
                "-".into()
            } else {
                sig(e.score, 3)
            },
            if e.complete { "yes" } else { "stopped" }.into(),
            match e.validated {
                Some(true) => "yes",
                Some(false) => "no",
                None => "-",
            }
            .into(),
            e.limiting.as_ref().map_or_else(
                || "-".into(),
                |(what, rate)| {
                    let plants = if e.validated == Some(false) {
                        " on drawn plants"
                    } else {
                        ""
                    };
                    format!("{what}{plants} at {} kHz", sig(rate / 1e3, 3))
                },
            ),
        ]);
    }
    t
}

/// Writes the chosen candidate, what Theorem 1 says of it and its validation at each rate.
fn write_chosen(
    out: &mut dyn Write,
    c: &tune::Evaluation,
    report: &tune::Report,
    rates: &[f64],
    own: f64,
    stroke_m: f64,
) -> anyhow::Result<()> {
    let th = &c.theorem;
    writeln!(
        out,
        "\nchosen: alpha1 = alpha2 = {} 1/s, observer {} rad/s at {} kHz, shaping margin {} \
         (worst metric at {} of its target)\nTheorem 1 (practical law): the force gain the \
         loop meets spans {} to {}; a common Lyapunov matrix exists, so the error stays \
         bounded on every plant of the uncertainty set; the bound (a ball of radius {} m with \
         the optimised P for a {} m/s^2 model error, {} strokes) says nothing at the \
         stroke's scale: the precision is what the corner runs and the validation measure",
        sig(c.candidate.alpha, 3),
        sig(c.candidate.observer_rad_s, 3),
        sig(own / 1e3, 3),
        sig(c.candidate.margin, 2),
        sig(c.score, 3),
        sig(th.gamma_min, 4),
        sig(th.gamma_max, 4),
        th.radius_optimised_m
            .map_or_else(|| "-".into(), |r| sig(r, 3)),
        sig(th.delta_mps2, 3),
        th.radius_optimised_m
            .map_or_else(|| "-".into(), |r| sig(r / stroke_m, 3)),
    )?;
    for ((w, targets), rate) in report.validation.iter().zip(rates) {
        writeln!(
            out,
            "validation at {} kHz, {} drawn plants: settling {} s ({} of its target), \
             overshoot {} %, |error| {} %, ripple {} A (target {} A), peak {} A (rated {} A), \
             faults {}",
            sig(rate / 1e3, 3),
            w.runs,
            sig(w.settling_s, 3),
            sig(w.settling_ratio, 3),
            sig(w.overshoot_pct, 3),
            sig(w.steady_error_pct, 3),
            sig(w.ripple_pp_a, 3),
            sig(targets.ripple_pp_a, 3),
            sig(w.current_a, 4),
            sig(targets.current_a, 4),
            w.faulted_runs
        )?;
    }
    Ok(())
}
