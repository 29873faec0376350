//! `hil-sim results [--check]`: the result tables a reader of the repository needs, run and
//! written to `hil-sim/RESULTS.md` so that no figure is copied by hand: the paper's claims
//! beside the measured values, the three laws compared, the family of actuators with the
//! settings derived from each, each member's tuned file re-derived by `tune` (a file it
//! would no longer choose stops the run), the Monte Carlo of every member at its own rate and at
//! 20 kHz, the fault table of every member, the Monte Carlo with converter errors drawn
//! per plant (the sensor's share of the steady error apart), the draws beyond the
//! controller's tolerances sorted into pass, named fault and silent failure, and drawn
//! actuators tuned and judged out of sample. No table is measured on draws that chose a
//! gain, a rule or a constant ([`crate::analysis::seeds`]).
//!
//! `--check` runs the same and compares with the file, failing on the first line that
//! differs: CI runs it, so a change that moves a figure must also regenerate the file.
//! Everything is seeded and the order of the draws is fixed, so the same build gives the
//! same bytes; no wall-clock time is written.

use std::fmt::Write as _;
use std::io::Write;
use std::path::PathBuf;

use super::{compare, drawn, faults, montecarlo, paper, Output};
use crate::analysis::report::{sig, Table};
use crate::simulation::actuator;

/// The file the results are written to, in the `hil-sim` crate.
pub const RESULTS_MD: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/RESULTS.md");

/// The rate every member is also judged at \[Hz\]: the product's firmware rate.
pub const COMMON_RATE_HZ: f64 = 20_000.0;

/// Arguments of `results`.
#[derive(Clone, Debug, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// Compare with the file instead of writing it; fail on the first line that differs.
    #[arg(long)]
    pub check: bool,
    /// Plants drawn per member and rate.
    #[arg(long, default_value_t = 1000)]
    pub n: usize,
    /// Seed of the plants and instants drawn (default: one no gain, rule or constant was
    /// chosen on; see `hil_sim::analysis::seeds`).
    #[arg(long, default_value_t = crate::analysis::seeds::RESULTS)]
    pub seed: u64,
    /// Plants drawn per member and widening factor beyond the controller's tolerances.
    #[arg(long, default_value_t = 200)]
    pub n_beyond: usize,
    /// Random instants (on drawn plants) each fault case is injected at, per member.
    #[arg(long, default_value_t = 200)]
    pub n_random: usize,
    /// Drawn actuators judged out of sample (seed `hil_sim::analysis::seeds::DRAWN_JUDGE`).
    #[arg(long, default_value_t = 20)]
    pub n_drawn: usize,
    /// Plants drawn per drawn actuator once tuned.
    #[arg(long, default_value_t = 50)]
    pub drawn_plants: usize,
    /// The file [default: RESULTS.md in the hil-sim crate].
    #[arg(long, value_name = "FILE")]
    pub file: Option<PathBuf>,
    /// Folder for the files the runs write on the way (figures, CSV) [default:
    /// out/results].
    #[command(flatten)]
    pub output: Output,
}

impl Default for Args {
    fn default() -> Self {
        Self {
            check: false,
            n: 1000,
            seed: crate::analysis::seeds::RESULTS,
            n_beyond: 200,
            n_random: 200,
            n_drawn: 20,
            drawn_plants: 50,
            file: None,
            output: Output::default(),
        }
    }
}

/// What `results` ran.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// The text of the file.
    pub text: String,
}

/// Runs everything, then writes the file or (`--check`) compares with it.
///
/// # Errors
/// A run that fails; with `--check`, a file that differs from the run, naming the first
/// line that does.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    let outcome = render(args, out)?;
    let path = args.file.clone().unwrap_or_else(|| RESULTS_MD.into());
    if args.check {
        let stored = std::fs::read_to_string(&path)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        if let Some((line, theirs, ours)) = first_difference(&stored, &outcome.text) {
            anyhow::bail!(
                "{} differs from the run at line {line}:\n  file: {theirs}\n  run:  {ours}\n\
                 regenerate it with `cargo run -p hil-sim --release -- results` and commit it",
                path.display()
            );
        }
        writeln!(out, "{} matches the run", path.display())?;
    } else {
        std::fs::write(&path, &outcome.text)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        writeln!(out, "wrote {}", path.display())?;
    }
    Ok(outcome)
}

/// The first line (1-based) where `a` and `b` differ, with both lines (`<end>` past the
/// end of one).
#[must_use]
pub fn first_difference(a: &str, b: &str) -> Option<(usize, String, String)> {
    let (mut la, mut lb) = (a.lines(), b.lines());
    for n in 1.. {
        match (la.next(), lb.next()) {
            (None, None) => return None,
            (x, y) if x == y => {}
            (x, y) => {
                let show = |l: Option<&str>| l.unwrap_or("<end>").to_owned();
                return Some((n, show(x), show(y)));
            }
        }
    }
    None
}

/// The text of the file, from the runs.
fn render(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    anyhow::ensure!(args.n > 0, "--n = 0: draw at least one plant");
    anyhow::ensure!(args.n_beyond > 0, "--n-beyond = 0: draw at least one plant");
    anyhow::ensure!(args.n_random > 0, "--n-random = 0: inject at least once");
    anyhow::ensure!(
        args.n_drawn > 0,
        "--n-drawn = 0: draw at least one actuator"
    );
    anyhow::ensure!(
        args.drawn_plants > 0,
        "--drawn-plants = 0: draw at least one plant"
    );
    let sub = |name: &str| scratch(args, name);
    let mut md = String::new();
    let w = &mut md;
    writeln!(
        w,
        "# Results\n\n\
         Generated by `cargo run -p hil-sim --release -- results` from the runs below; CI \
         runs `results --check`, which fails when a figure here no longer matches the code. \
         Do not edit by hand. Definitions of every metric: `hil-sim/src/simulation/metrics.rs`; the \
         product's targets: `hil-sim/src/simulation/targets.rs`; how each setting follows from an \
         actuator's data: the `ema::control::actuator` docs.\n"
    )?;

    writeln!(out, "the paper's example ...")?;
    let p = paper::run(
        &paper::Args {
            output: sub("paper"),
            ..paper::Args::default()
        },
        &mut Vec::new(),
    )?;
    writeln!(
        w,
        "## The paper's example (`hil-sim paper`)\n\n\
         The paper's actuator under the paper's law, in the paper's printed force direction, \
         at a 1 MHz interrupt (near-continuous) and at 20 kHz as firmware runs it. When a \
         claim counts as holding is stated in `hil-sim/src/cli/paper.rs`.\n"
    )?;
    writeln!(w, "{}", p.claims.to_text())?;

    writeln!(out, "the three laws compared ...")?;
    let c = compare::run(
        &compare::Args {
            output: sub("compare"),
            ..compare::Args::default()
        },
        &mut Vec::new(),
    )?;
    writeln!(
        w,
        "## Three laws, three rates, three supplies (`hil-sim compare`)\n\n\
         The product's actuator in the physical convention, step 1 -> 3 mm, nominal plant, \
         converter noise and one sample of delay; each law with its own defaults. Only the \
         practical law (the product's) is expected to pass.\n"
    )?;
    writeln!(w, "{}", c.table.to_text())?;

    writeln!(
        w,
        "## The family (`hil-sim actuators`)\n\n\
         Actuators of different size, stiffness, coil, supply and rate, each described only \
         by its file (`hil-sim/actuators/<name>.toml`); its time scales and every setting \
         are derived from the file, and the gains are the ones `hil-sim tune` chose \
         (`<name>.tuned.toml`).\n"
    )?;
    writeln!(w, "{}", super::actuators::family_table()?.to_text())?;
    rederived(args, w, out)?;

    family_montecarlo(args, w, out)?;
    family_faults(args, w, out)?;
    random_faults(args, w, out)?;

    sensor_errors(args, w, out)?;
    beyond(args, w, out)?;
    drawn_actuators(args, w, out)?;
    Ok(Outcome { text: md })
}

/// The section on the Monte Carlo of every member, at its own rate and at the common one.
fn family_montecarlo(args: &Args, w: &mut String, out: &mut dyn Write) -> anyhow::Result<()> {
    writeln!(
        w,
        "## Monte Carlo of every member (`hil-sim montecarlo <name> --n {n} --seed {seed} \
         [--rate-hz 20000]`)\n\n\
         {n} plants drawn from each member's uncertainty set (seed {seed}), the member's \
         evaluation sequence (rest, then 1/8, 7/8, 3/8 and 3/4 of the stroke), judged \
         against the targets derived from the member's time scales and ratings. Each row \
         gives the worst draw of each metric with its limit in brackets, the settling \
         target of each move of the sequence, and how many draws miss any target.\n",
        n = args.n,
        seed = args.seed
    )?;
    let mut mc = Table::new([
        "member",
        "ISR [kHz]",
        "draws missing a target",
        "settling / its target",
        "settling targets [s]",
        "overshoot [%]",
        "|steady error| [%]",
        "ripple p-p [A]",
        "peak current [A]",
        "peak |u| [V]",
        "draws with a fault",
    ]);
    for e in &actuator::FAMILY {
        let (_, act) = actuator::load(e.name)?;
        let own = f64::from(act.board.rate_hz);
        let mut rates = vec![None];
        if (own - COMMON_RATE_HZ).abs() > 0.5 {
            rates.push(Some(COMMON_RATE_HZ));
        }
        for rate in rates {
            let rate_hz = rate.unwrap_or(own);
            writeln!(
                out,
                "montecarlo {} at {} kHz ...",
                e.name,
                sig(rate_hz / 1e3, 3)
            )?;
            let o = montecarlo::run(
                &montecarlo::Args {
                    scenario: e.name.into(),
                    n: args.n,
                    seed: args.seed,
                    rate_hz: rate,
                    substeps: None,
                    sensor_errors: false,
                    widen: 1.0,
                    quiet: true,
                    output: scratch(args, &format!("{}-{}hz", e.name, rate_hz)),
                },
                &mut Vec::new(),
            )?;
            let cell = |row: &str| -> String {
                o.targets
                    .row(row)
                    .map_or_else(|| "-".into(), |r| format!("{} ({})", r[2], r[1]))
            };
            let faulted = o
                .targets
                .row("no fault")
                .map_or_else(|| "-".into(), |r| r[3].clone());
            mc.push([
                e.name.to_owned(),
                sig(rate_hz / 1e3, 3),
                format!("{} of {}", o.failing, o.draws.len()),
                cell("settling / its target"),
                o.settling_targets_s
                    .iter()
                    .map(|v| sig(*v, 3))
                    .collect::<Vec<_>>()
                    .join(", "),
                cell("overshoot [%]"),
                cell("|steady error| [%]"),
                cell("ripple p-p [A]"),
                cell("peak current [A]"),
                cell("peak |u| [V]"),
                faulted,
            ]);
        }
    }
    writeln!(w, "{}", mc.to_text())?;
    Ok(())
}

/// The section on the faults injected during every member's evaluation sequence.
fn family_faults(args: &Args, w: &mut String, out: &mut dyn Write) -> anyhow::Result<()> {
    writeln!(
        w,
        "## Faults on every member (`hil-sim faults <name>`)\n\n\
         Each fault injected during the member's evaluation sequence, at the member's own \
         rate. A cell gives the fault latched and how long after the injection, in \
         microseconds; a case passes when the expected fault is named within {} us, the \
         current stays at or below the trip level and the bridge coasts from then on \
         (`hil-sim/src/analysis/faults.rs`).\n",
        sig(crate::analysis::faults::DEADLINE_S * 1e6, 4)
    )?;
    let mut cases: Vec<(String, Vec<String>)> = Vec::new();
    let mut header = vec!["fault injected".to_owned(), "expected".to_owned()];
    for e in &actuator::FAMILY {
        writeln!(out, "faults on {} ...", e.name)?;
        header.push(e.name.to_owned());
        let o = faults::run(
            &faults::Args {
                actuator: e.name.into(),
                rate_hz: None,
                supply_v: None,
                random: None,
                seed: 1,
                output: scratch(args, &format!("{}-faults", e.name)),
            },
            &mut Vec::new(),
        )?;
        for (k, case) in o.cases.iter().enumerate() {
            if cases.len() <= k {
                cases.push((case.name.clone(), vec![case.expected.clone()]));
            }
            let latched = case.fault.as_deref().unwrap_or("none");
            let after = case
                .detected_after_s
                .map_or_else(|| "-".into(), |s| sig(s * 1e6, 3));
            let verdict = if case.pass() { "" } else { " FAIL" };
            cases[k].1.push(format!("{latched} {after}{verdict}"));
        }
    }
    let mut ft = Table::new(header);
    for (name, cells) in cases {
        ft.push(std::iter::once(name).chain(cells));
    }
    writeln!(w, "{}", ft.to_text())?;
    Ok(())
}

/// The section that re-derives every member's tuned file with `tune` as a user runs it.
///
/// # Errors
/// A member whose tuned file is not what `tune` chooses now (or for which it chooses
/// nothing), naming the command that re-derives it: the family's figures are only worth
/// what the gains behind them are, so no result is written from a stale file.
fn rederived(args: &Args, w: &mut String, out: &mut dyn Write) -> anyhow::Result<()> {
    writeln!(
        w,
        "## The tuned files re-derived (`hil-sim tune <name>`)\n\n\
         `tune` run again on each member's file as a user runs it (its own validation \
         plants, the default rates); a tuned file in the repository that it would no longer \
         choose stops this run.\n"
    )?;
    let mut t = Table::new([
        "member",
        "tuned file: alpha / observer / margin",
        "tune's choice",
        "worst metric / its target",
        "same",
    ]);
    let gains = |g: &ema::control::actuator::Tuning| {
        format!(
            "{} / {} / {}",
            sig(f64::from(g.alpha_per_s), 3),
            sig(f64::from(g.observer_rad_s), 3),
            sig(f64::from(g.margin), 2)
        )
    };
    let mut stale = Vec::new();
    for e in &actuator::FAMILY {
        writeln!(out, "tune {} ...", e.name)?;
        let (_, act) = actuator::load(e.name)?;
        let file = act
            .tuning
            .ok_or_else(|| anyhow::anyhow!("`{}` has no tuned file", e.name))?;
        let dir = scratch(args, &format!("{}-tune", e.name));
        let o = super::tune::run(
            &super::tune::Args {
                actuator: e.name.into(),
                rates_hz: None,
                validate: super::tune::DEFAULT_VALIDATE,
                substeps: 1,
                tuned: Some(dir.dir("tune").join(format!("{}.tuned.toml", e.name))),
                quiet: true,
                output: dir,
            },
            &mut Vec::new(),
        )?;
        let chosen = o.report.tuned.as_ref().and_then(|a| a.tuning);
        let same = chosen == Some(file);
        if !same {
            stale.push(e.name);
        }
        t.push([
            e.name.to_owned(),
            gains(&file),
            chosen.as_ref().map_or_else(|| "none".into(), gains),
            o.report
                .chosen
                .as_ref()
                .map_or_else(|| "-".into(), |c| sig(c.score, 3)),
            if same { "yes" } else { "no FAIL" }.into(),
        ]);
    }
    writeln!(w, "{}", t.to_text())?;
    anyhow::ensure!(
        stale.is_empty(),
        "tune no longer chooses the tuned file of {}: re-derive each with `cargo run -p \
         hil-sim --release -- tune <name> --tuned hil-sim/actuators/<name>.tuned.toml`",
        stale.join(", ")
    );
    Ok(())
}

/// Widening factors beyond the controller's tolerances the family is drawn at.
pub const BEYOND: [f64; 2] = [1.25, 1.5];

fn mc_args(args: &Args, name: &str, sub: &str) -> montecarlo::Args {
    montecarlo::Args {
        scenario: name.into(),
        n: args.n,
        seed: args.seed,
        rate_hz: None,
        substeps: None,
        sensor_errors: false,
        widen: 1.0,
        quiet: true,
        output: scratch(args, sub),
    }
}

/// The folder `sub` of the runs' scratch folder (`--out`, default `out/results`).
fn scratch(args: &Args, sub: &str) -> Output {
    Output {
        out: Some(args.output.dir("results").join(sub)),
    }
}

/// The section on converter errors.
fn sensor_errors(args: &Args, w: &mut String, out: &mut dyn Write) -> anyhow::Result<()> {
    let class = crate::simulation::hal::CalibrationClass::default();
    writeln!(
        w,
        "## Converter errors (`hil-sim montecarlo <name> --n {n} --seed {seed} \
         --sensor-errors`)\n\n\
         The Monte Carlo above at each member's own rate, each plant also drawn a converter \
         whose position, current and bus channels each carry a gain error uniform within \
         +-{g} % and an offset uniform within +-{o} codes (the calibration class, \
         `hil_sim::simulation::hal::CalibrationClass`), which the controller's calibration does not \
         know. Every target is judged on the true position. The sensor's share is what the \
         position channel's gain and offset alone give at the reference: the armature \
         position at which the mean reading equals the reference, minus the reference \
         (`hil_sim::simulation::hal::sensor_position_error_m`); no controller acting on that reading \
         removes it. The controller's part is the steady error minus that share, and the \
         overshoot past the end the share shifts the armature to. A draw \"misses only by the \
         sensor's share\" when its only misses are the steady error and the overshoot and \
         both controller parts meet their targets. The targets are not changed.\n",
        n = args.n,
        seed = args.seed,
        g = sig(100.0 * class.gain_rel, 3),
        o = sig(class.offset_code, 3),
    )?;
    let mut t = Table::new([
        "member",
        "ISR [kHz]",
        "draws passing every target",
        "missing only by the sensor's share",
        "missing for another reason",
        "|steady error| on the true position [%]",
        "sensor's share [%]",
        "controller's part [%]",
        "overshoot on the true position [%]",
        "controller's overshoot [%]",
        "peak current [A]",
        "draws with a fault",
    ]);
    for e in &actuator::FAMILY {
        writeln!(out, "montecarlo {} with converter errors ...", e.name)?;
        let o = montecarlo::run(
            &montecarlo::Args {
                sensor_errors: true,
                ..mc_args(args, e.name, &format!("{}-sensor-errors", e.name))
            },
            &mut Vec::new(),
        )?;
        let s = o
            .sensor
            .ok_or_else(|| anyhow::anyhow!("{}: no converter errors drawn", e.name))?;
        let cell = |row: &str| -> String {
            o.targets
                .row(row)
                .map_or_else(|| "-".into(), |r| format!("{} ({})", r[2], r[1]))
        };
        let (_, act) = actuator::load(e.name)?;
        let steady = crate::simulation::targets::STEADY_ERROR_PCT;
        let overshoot = crate::simulation::targets::OVERSHOOT_PCT;
        t.push([
            e.name.to_owned(),
            sig(f64::from(act.board.rate_hz) / 1e3, 3),
            format!("{} of {}", o.draws.len() - o.failing, o.draws.len()),
            s.sensor_only.to_string(),
            s.other_misses.to_string(),
            format!("{} ({})", sig(s.worst_true_pct, 4), sig(steady, 3)),
            sig(s.worst_sensor_pct, 4),
            format!("{} ({})", sig(s.worst_controller_pct, 4), sig(steady, 3)),
            cell("overshoot [%]"),
            format!(
                "{} ({})",
                sig(s.worst_controller_overshoot_pct, 4),
                sig(overshoot, 3)
            ),
            cell("peak current [A]"),
            o.targets
                .row("no fault")
                .map_or_else(|| "-".into(), |r| r[3].clone()),
        ]);
    }
    writeln!(w, "{}", t.to_text())?;
    Ok(())
}

/// The section on faults injected at random instants on drawn plants.
fn random_faults(args: &Args, w: &mut String, out: &mut dyn Write) -> anyhow::Result<()> {
    writeln!(
        w,
        "## Faults at random instants (`hil-sim faults <name> --random {n} --seed {seed}`)\n\n\
         Each case of the table above injected {n} times per member, at instants drawn \
         uniformly between the first move and 20 ms before the end of the sequence, each on \
         its own plant drawn from the controller's uncertainty set with its own converter \
         noise (seed {seed}; the same plants and instants for every case). A run passes as \
         in the table above, and only if the fault is latched after the injection; \
         \"latched before\" counts false alarms on the drawn plant before the injection. A \
         frozen reading is what a healthy sensor could read until the true position or \
         current moves by more than the converter's noise allowance \
         (`hil_sim::analysis::faults::observable_after_s`); \"observable in the run\" counts the \
         injections after which it did within the run (every injection of the other \
         cases), and the last column those named as expected within the deadline of that \
         instant. The fault-free control is the Monte Carlo above: its column \"draws with a fault\" at \
         every rate. The plant-outside-the-bounds case is there from power-up and is not \
         drawn. A row passes when at least {named} % of the observable injections are \
         named right within the deadline of becoming observable, at most {misnamed} % are \
         misnamed, none latches before its injection, the bridge coasts after every \
         detection and the current stays at or below the trip \
         (`hil_sim::analysis::faults::RandomCase::misses`).\n",
        named = sig(crate::analysis::faults::NAMED_SHARE * 100.0, 3),
        misnamed = sig(crate::analysis::faults::MISNAMED_SHARE * 100.0, 3),
        n = args.n_random,
        seed = args.seed,
    )?;
    let mut t = Table::new(std::iter::once("member").chain(faults::RANDOM_HEADER));
    for e in &actuator::FAMILY {
        writeln!(out, "faults on {} at random instants ...", e.name)?;
        let o = faults::run(
            &faults::Args {
                actuator: e.name.into(),
                rate_hz: None,
                supply_v: None,
                random: Some(args.n_random),
                seed: args.seed,
                output: scratch(args, &format!("{}-faults-random", e.name)),
            },
            &mut Vec::new(),
        )?;
        for s in &o.random {
            t.push(std::iter::once(e.name.to_owned()).chain(faults::random_row(s)));
        }
    }
    writeln!(w, "{}", t.to_text())?;
    Ok(())
}

/// The section on drawn actuators, judged out of sample.
fn drawn_actuators(args: &Args, w: &mut String, out: &mut dyn Write) -> anyhow::Result<()> {
    let seed = crate::analysis::seeds::DRAWN_JUDGE;
    writeln!(
        w,
        "## Drawn actuators, out of sample (`hil-sim drawn --n {n} --seed {seed} --plants \
         {plants} --plant-seed {plant_seed}`)\n\n\
         {n} actuators drawn over the span the product is for (`hil_sim::analysis::drawn`: 2 g to 2 kg, \
         0.3 to 12 mm, coils of 0.05 to 100 ms, 5 to 60 V, 8 to 50 kHz; every one meets the \
         physical rules), with a seed kept for judging (`hil_sim::analysis::seeds`; one rule, the \
         overshoot's definition, was changed after looking at its actuator 6, so for that \
         rule this sample is no longer out of sample). Each is tuned as a user would \
         (`hil-sim tune <file>`: its own rate, 20 kHz and a neighbour), then run on \
         {plants} plants of its uncertainty set (seed {plant_seed}, apart from the plants \
         `tune` validates on) and through the fault cases of the table above. An actuator \
         passes when `tune` chose gains, at most {share} % of the plants miss a target (a \
         latched fault is a miss) and every fault case passes. `hil-sim drawn --n 100 \
         --plants 1000` runs the full judgement.\n",
        n = args.n_drawn,
        plants = args.drawn_plants,
        plant_seed = args.seed,
        share = sig(crate::analysis::outofsample::MISS_SHARE * 100.0, 2),
    )?;
    writeln!(
        out,
        "{} drawn actuators, tuned and judged ...",
        args.n_drawn
    )?;
    let o = drawn::run(
        &drawn::Args {
            n: args.n_drawn,
            seed,
            plants: args.drawn_plants,
            plant_seed: args.seed,
            quiet: true,
            output: scratch(args, "drawn"),
        },
        &mut Vec::new(),
    )?;
    writeln!(w, "{}\n{}\n", o.table.to_text(), o.summary)?;
    Ok(())
}

/// The section on plants beyond the controller's tolerances.
fn beyond(args: &Args, w: &mut String, out: &mut dyn Write) -> anyhow::Result<()> {
    writeln!(
        w,
        "## Beyond the design set (`hil-sim montecarlo <name> --n {n} --seed {seed} \
         --widen K`)\n\n\
         {n} plants per member (seed {seed}, the member's own rate) drawn with the tolerances \
         of resistance, spring, mass and friction K times the controller's (pole \
         surfaces still within the physical bounds). Every draw is sorted: pass (every \
         target met), a named fault with the bridge coasting from then on, or a silent \
         failure (a target missed with no fault latched). Required: no silent failure; a \
         fault after which the bridge did not coast would be counted apart.\n",
        n = args.n_beyond,
        seed = args.seed,
    )?;
    let mut t = Table::new([
        "member",
        "K",
        "draws",
        "pass",
        "named fault, coasting",
        "faults by name",
        "fault, not coasting",
        "SILENT",
        "silent misses by target",
    ]);
    for e in &actuator::FAMILY {
        for k in BEYOND {
            writeln!(
                out,
                "montecarlo {} at {} times the tolerances ...",
                e.name, k
            )?;
            let o = montecarlo::run(
                &montecarlo::Args {
                    n: args.n_beyond,
                    widen: k,
                    ..mc_args(args, e.name, &format!("{}-widen-{k}", e.name))
                },
                &mut Vec::new(),
            )?;
            let c = &o.classes;
            t.push([
                e.name.to_owned(),
                sig(k, 3),
                c.n.to_string(),
                c.pass.to_string(),
                c.named().to_string(),
                c.mix(),
                c.fault_not_coasting.to_string(),
                if c.silent > 0 {
                    format!("{} FAIL", c.silent)
                } else {
                    "0".into()
                },
                c.silent_mix(),
            ]);
        }
    }
    writeln!(w, "{}", t.to_text())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::first_difference;

    /// The check names the first line that differs, also when one text is shorter.
    #[test]
    fn the_first_differing_line_is_named() {
        assert_eq!(first_difference("a\nb\nc\n", "a\nb\nc\n"), None);
        assert_eq!(
            first_difference("a\nb\nc\n", "a\nB\nc\n"),
            Some((2, "b".into(), "B".into()))
        );
        assert_eq!(
            first_difference("a\nb\n", "a\nb\nc\n"),
            Some((3, "<end>".into(), "c".into()))
        );
    }
}
