//! `hil-sim tune <scenario>`: designs the practical law's gains for the scenario's actuator
//! ([`crate::tune`]): Theorem 1 for every candidate, simulation on the corner plants of
//! the uncertainty set at each ISR rate given, the minimax choice, and a Monte Carlo
//! validation; writes the tuned scenario as TOML and every candidate as CSV.

use std::io::Write;

use crate::report::{self, sig, Table};
use crate::tune::{tune, Grid};
use crate::{catalog, Scenario};

/// Arguments of `tune`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Args {
    /// The actuator and conditions: an embedded scenario's name or a TOML file (its
    /// reference is what candidates are evaluated on).
    #[arg(default_value = "product-sequence")]
    pub scenario: String,
    /// ISR rates to design for at once [Hz].
    #[arg(long, value_delimiter = ',', default_values_t = [10_000.0, 20_000.0, 50_000.0])]
    pub rates_hz: Vec<f64>,
    /// Plants drawn to validate the choice, per rate.
    #[arg(long, default_value_t = 100)]
    pub validate: usize,
    /// RK4 substeps per period for the search (1 is validated for the product's law).
    #[arg(long, default_value_t = 1)]
    pub substeps: u32,
    /// Output folder [default: out/<scenario>-tune].
    #[command(flatten)]
    pub output: super::Output,
}

/// The same scenario at another ISR rate (the converter calibration and the observer
/// bandwidth rule of the controller carry over).
#[allow(clippy::cast_possible_truncation)]
fn at_rate(sc: &Scenario, rate_hz: f64, substeps: u32) -> Scenario {
    let mut s = sc.clone().with_substeps(substeps);
    s.controller.rate_hz = rate_hz as f32;
    s.name = format!("{}-{}khz", sc.name, rate_hz / 1e3);
    s
}

/// Runs the tuning and writes its report; the tuned scenario.
///
/// # Errors
/// A scenario that cannot be loaded; no rate; a failed run or write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Option<Scenario>> {
    anyhow::ensure!(
        !args.rates_hz.is_empty(),
        "--rates-hz: give at least one rate"
    );
    anyhow::ensure!(
        args.substeps > 0,
        "--substeps = 0: at least one RK4 step per period"
    );
    let sc = catalog::load(&args.scenario)?;
    let conditions: Vec<Scenario> = args
        .rates_hz
        .iter()
        .map(|&r| at_rate(&sc, r, args.substeps))
        .collect();
    let grid = Grid::default();
    writeln!(
        out,
        "tuning the practical law for `{}` at {:?} Hz: alpha {:?}, observer {:?} rad/s at \
         20 kHz, shaping margin {:?}; {} corner plants per rate",
        sc.name,
        args.rates_hz,
        grid.alpha,
        grid.observer_rad_s,
        grid.margin,
        crate::tune::corners(&sc.controller.plant).len()
    )?;
    let started = std::time::Instant::now();
    let report = tune(&conditions, &grid, args.validate)?;
    writeln!(
        out,
        "searched in {} s\n",
        sig(started.elapsed().as_secs_f64(), 3)
    )?;

    let mut t = Table::new([
        "alpha [1/s]",
        "observer [rad/s]",
        "margin",
        "Theorem 1",
        "ball radius [m]",
        "worst/target",
        "worst settling [s]",
        "worst overshoot [%]",
        "worst |error| [%]",
        "worst ripple [A]",
    ]);
    let mut sorted = report.evaluations.clone();
    sorted.sort_by(|a, b| a.score.total_cmp(&b.score));
    for e in &sorted {
        let w = e
            .worst
            .iter()
            .fold(crate::targets::Worst::default(), |mut acc, w| {
                acc.settling_s = acc.settling_s.max(w.settling_s);
                acc.overshoot_pct = acc.overshoot_pct.max(w.overshoot_pct);
                acc.steady_error_pct = acc.steady_error_pct.max(w.steady_error_pct);
                acc.ripple_pp_a = acc.ripple_pp_a.max(w.ripple_pp_a);
                acc
            });
        t.push([
            sig(e.candidate.alpha, 3),
            sig(e.candidate.observer_rad_s, 3),
            sig(e.candidate.margin, 2),
            if e.theorem.holds() { "holds" } else { "fails" }.into(),
            e.theorem
                .radius_optimised_m
                .map_or_else(|| "-".into(), |r| sig(r, 3)),
            sig(e.score, 3),
            sig(w.settling_s, 3),
            sig(w.overshoot_pct, 3),
            sig(w.steady_error_pct, 3),
            sig(w.ripple_pp_a, 3),
        ]);
    }
    let best: Vec<_> = t.rows.iter().take(8).cloned().collect();
    let mut head = Table::new(t.header.clone());
    head.rows = best;
    write!(
        out,
        "best candidates (worst over corners and rates / target; <= 1 passes):\n{}",
        head.to_text()
    )?;

    let dir = args.output.dir(&format!("{}-tune", sc.name));
    report::create_dir(&dir)?;
    let mut files = Vec::new();
    let path = dir.join("candidates.csv");
    t.write_csv(&path)?;
    files.push(path);
    let tuned = match (&report.chosen, &report.settings) {
        (Some(c), Some(s)) => {
            let th = &c.theorem;
            writeln!(
                out,
                "\nchosen: alpha1 = alpha2 = {} 1/s, observer {} rad/s at 20 kHz, shaping margin \
                 {} (worst metric at {} of its target)\nTheorem 1 (practical law): the force \
                 gain the loop meets spans {} to {}; a common Lyapunov matrix exists; ball \
                 radius {} m with the optimised P for a {} m/s^2 model error ({})",
                sig(c.candidate.alpha, 3),
                sig(c.candidate.observer_rad_s, 3),
                sig(c.candidate.margin, 2),
                sig(c.score, 3),
                sig(th.gamma_min, 4),
                sig(th.gamma_max, 4),
                th.radius_optimised_m
                    .map_or_else(|| "-".into(), |r| sig(r, 3)),
                sig(th.delta_mps2, 3),
                th.radius_identity_m.map_or_else(
                    || "V = |z|^2/2 alone does not prove it".into(),
                    |r| format!("{} m with P = I", sig(r, 3))
                )
            )?;
            for (w, rate) in report.validation.iter().zip(&args.rates_hz) {
                writeln!(
                    out,
                    "validation at {} kHz, {} drawn plants: settling {} s, overshoot {} %, \
                     |error| {} %, ripple {} A, peak {} A, faults {}",
                    sig(rate / 1e3, 3),
                    w.runs,
                    sig(w.settling_s, 3),
                    sig(w.overshoot_pct, 3),
                    sig(w.steady_error_pct, 3),
                    sig(w.ripple_pp_a, 3),
                    sig(w.current_a, 4),
                    w.faulted_runs
                )?;
            }
            let mut tuned = sc.clone().with_controller(*s);
            tuned.name = format!("{}-tuned", sc.name);
            let path = dir.join("tuned.toml");
            std::fs::write(&path, toml::to_string(&tuned)?)?;
            files.push(path);
            Some(tuned)
        }
        _ => {
            writeln!(
                out,
                "\nno candidate meets every target on every corner plant"
            )?;
            None
        }
    };
    super::list_files(out, &files)?;
    Ok(tuned)
}
