//! `hil-sim montecarlo <scenario> --n N --seed S`: the scenario over `N` plants drawn from
//! the uncertainty set (the scenario's own when its plant is `kind = "drawn"`, else the
//! default set), in parallel with a progress bar ([`crate::montecarlo()`]); prints the
//! worst case of each metric and the product's targets ([`crate::simulation::targets`]: how many
//! draws miss each) and writes every draw (plant parameters and metrics) as CSV.
//!
//! RK4 substeps: unless `--substeps` is given, the fewest per period (at most the
//! scenario's own) whose every period, replayed from draw 0's recorded states, stays
//! within [`TOLERANCE_REL`] of a 1 us RK4 solution
//! ([`crate::analysis::accuracy::fewest_substeps`]). After the draws, the draws that hold a
//! worst case ([`worst_draws`]) are checked the same way; when one needs more substeps, the
//! draws run again with that many, and the output says so.
//!
//! `--sensor-errors` draws each plant's converter gain and offset errors from the
//! calibration class ([`crate::simulation::hal::CalibrationClass`], +-0.5 % and +-2 codes
//! per channel); the targets stay judged on the true position, and the output gives apart
//! the sensor's share of the steady error
//! ([`crate::simulation::hal::sensor_position_error_m`]) and the draws that miss only
//! because of it. `--widen K` draws the plant beyond the controller's tolerances (each
//! tolerance times `K`) and sorts every draw into pass, named fault with the bridge coasting, or
//! silent failure ([`Class`]).

use std::io::Write;
use std::path::PathBuf;

use crate::analysis::accuracy::{self, TOLERANCE_REL};
use crate::analysis::montecarlo::{montecarlo_opts, Options};
use crate::analysis::report::{self, sig, Table, METRICS_COLUMNS};
use crate::simulation::catalog;
use crate::simulation::hal::CalibrationClass;
use crate::simulation::plant::{ForceModel, Surface};
use crate::simulation::scenario::Scenario;
use crate::simulation::targets::{Targets, Worst};
use crate::{Draw, Segment};

/// Arguments of `montecarlo`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Args {
    /// An embedded scenario's name (see `hil-sim scenarios`) or a TOML file.
    pub scenario: String,
    /// Number of plants drawn.
    #[arg(long, default_value_t = 100)]
    pub n: usize,
    /// Seed of the draws (draw k uses a seed derived from it and k).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Interrupt rate [Hz], for an actuator (a family member or an actuator file): every
    /// setting derived again at this rate, the tuned gains kept [default: the actuator's
    /// own].
    #[arg(long)]
    pub rate_hz: Option<f64>,
    /// RK4 substeps per ISR period [default: the fewest validated on draw 0 and on the
    /// draws holding a worst case].
    #[arg(long)]
    pub substeps: Option<u32>,
    /// Draw each plant's converter gain and offset errors from the calibration class
    /// (+-0.5 % gain, +-2 codes offset on the position, current and bus channels).
    #[arg(long)]
    pub sensor_errors: bool,
    /// Factor that widens the plant's tolerances (resistance, spring, mass, friction)
    /// beyond the controller's; 1 is the design set.
    #[arg(long, default_value_t = 1.0)]
    pub widen: f64,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Output folder.
    #[command(flatten)]
    pub output: super::Output,
}

/// What `montecarlo` measured and wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// RK4 substeps per period used.
    pub substeps: u32,
    /// The draws holding a worst case, with the fewest substeps each needs and that
    /// count's accuracy (empty with `--substeps`).
    pub checked: Vec<(usize, accuracy::Accuracy)>,
    /// The draws, in draw order.
    pub draws: Vec<Draw>,
    /// Worst case of each metric.
    pub worst: Table,
    /// The product's targets: draws missing each.
    pub targets: Table,
    /// The settling target of each step segment \[s\].
    pub settling_targets_s: Vec<f64>,
    /// Draws that miss at least one target.
    pub failing: usize,
    /// With `--sensor-errors`: the sensor's share apart.
    pub sensor: Option<SensorSummary>,
    /// Every draw sorted into pass, named fault or silent failure.
    pub classes: Classes,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Worst value of `f` over every segment of every draw (largest, NaN skipped), with the
/// draw and segment where it occurs.
fn worst(draws: &[Draw], f: impl Fn(&Segment) -> f64) -> Option<(f64, usize, usize)> {
    let mut best: Option<(f64, usize, usize)> = None;
    for d in draws {
        for (k, s) in d.metrics.segments.iter().enumerate() {
            let v = f(s);
            if !v.is_nan() && best.is_none_or(|b| v > b.0) {
                best = Some((v, d.index, k));
            }
        }
    }
    best
}

/// The draws holding the worst of each judged metric (settling, overshoot, steady error,
/// ripple, peak current and voltage), each once, in draw order.
#[must_use]
pub fn worst_draws(draws: &[Draw]) -> Vec<usize> {
    let fs: [fn(&Segment) -> f64; 6] = [
        |s| s.settling_time_s.unwrap_or(f64::INFINITY),
        |s| s.overshoot_pct,
        |s| s.steady_error_pct.abs(),
        |s| s.ripple_pp_a,
        |s| s.i_peak_a,
        |s| s.u_peak_v,
    ];
    let mut ks: Vec<usize> = fs
        .iter()
        .filter_map(|f| worst(draws, f).map(|(_, d, _)| d))
        .collect();
    ks.sort_unstable();
    ks.dedup();
    ks
}

/// The worst-case table.
#[must_use]
pub fn worst_table(draws: &[Draw]) -> Table {
    let mut t = Table::new(["metric", "worst", "draw", "segment"]);
    let mut row = |name: &str, w: Option<(f64, usize, usize)>, digits: usize| {
        let (v, d, s) = w.map_or(("-".into(), "-".into(), "-".into()), |(v, d, s)| {
            (sig(v, digits), d.to_string(), s.to_string())
        });
        t.push([name.to_owned(), v, d, s]);
    };
    let unsettled = draws
        .iter()
        .flat_map(|d| d.metrics.segments.iter().map(move |s| (d.index, s)))
        .filter(|(_, s)| s.settling_time_s.is_none())
        .map(|(d, _)| d)
        .collect::<Vec<_>>();
    row(
        "settling 2 % [s]",
        worst(draws, |s| s.settling_time_s.unwrap_or(f64::NAN)),
        4,
    );
    row("overshoot [%]", worst(draws, |s| s.overshoot_pct), 3);
    row(
        "|steady error| [um]",
        worst(draws, |s| s.steady_error_um.abs()),
        4,
    );
    row(
        "|steady error| [%]",
        worst(draws, |s| s.steady_error_pct.abs()),
        3,
    );
    row("ripple p-p [A]", worst(draws, |s| s.ripple_pp_a), 3);
    row("ripple rms [A]", worst(draws, |s| s.ripple_rms_a), 3);
    row("peak current [A]", worst(draws, |s| s.i_peak_a), 4);
    row("peak |u| [V]", worst(draws, |s| s.u_peak_v), 4);
    row("peak |u command| [V]", worst(draws, |s| s.u_cmd_peak_v), 4);
    #[expect(clippy::cast_precision_loss)]
    row(
        "saturated samples",
        worst(draws, |s| s.saturated_samples as f64),
        6,
    );
    row(
        "landing speed [m/s]",
        worst(draws, |s| s.landing_speed_mps.unwrap_or(f64::NAN)),
        3,
    );
    let faulted: Vec<usize> = draws
        .iter()
        .filter(|d| d.metrics.first_fault.is_some())
        .map(|d| d.index)
        .collect();
    let outside: Vec<usize> = draws
        .iter()
        .filter(|d| !d.metrics.bounds.brackets)
        .map(|d| d.index)
        .collect();
    for (name, list) in [
        ("segments not settled", unsettled),
        ("draws with a fault", faulted),
        ("plants outside the controller's bounds", outside),
    ] {
        t.push([
            name.to_owned(),
            list.len().to_string(),
            list.first().map_or_else(|| "-".into(), ToString::to_string),
            "-".into(),
        ]);
    }
    t
}

/// The product's targets over the draws: worst value, target, draws missing it; and the
/// number of draws that miss any.
#[must_use]
pub fn targets_table(draws: &[Draw], t: &Targets) -> (Table, usize) {
    let misses: Vec<Vec<&'static str>> = draws
        .iter()
        .map(|d| Worst::of([&d.metrics], t).misses(t))
        .collect();
    let all = Worst::of_draws(draws, t);
    let count = |name: &str| misses.iter().filter(|m| m.contains(&name)).count();
    let mut table = Table::new(["target", "limit", "worst", "draws missing it"]);
    #[expect(clippy::cast_precision_loss)]
    for (label, key, limit, worst) in [
        ("settling / its target", "settling", 1.0, all.settling_ratio),
        (
            "overshoot [%]",
            "overshoot",
            t.overshoot_pct,
            all.overshoot_pct,
        ),
        (
            "|steady error| [%]",
            "steady error",
            t.steady_error_pct,
            all.steady_error_pct,
        ),
        ("ripple p-p [A]", "ripple", t.ripple_pp_a, all.ripple_pp_a),
        ("peak current [A]", "current", t.current_a, all.current_a),
        ("peak |u| [V]", "voltage", t.voltage_v, all.voltage_v),
        ("no fault", "fault", 0.0, all.faulted_runs as f64),
    ] {
        table.push([
            label.to_owned(),
            sig(limit, 3),
            sig(worst, 4),
            count(key).to_string(),
        ]);
    }
    let failing = misses.iter().filter(|m| !m.is_empty()).count();
    (table, failing)
}

/// Every draw: one row per draw and segment, plant parameters then metrics.
#[must_use]
pub fn draws_table(draws: &[Draw]) -> Table {
    let gaps = draws.iter().map(|d| d.plant.gaps.len()).max().unwrap_or(0);
    let mut header: Vec<String> = [
        "draw",
        "seed",
        "mass_kg",
        "spring_n_per_m",
        "friction_n_s_per_m",
        "resistance_ohm",
        "force",
    ]
    .map(String::from)
    .to_vec();
    for k in 0..gaps {
        header.push(format!("gap{k}_kind"));
        header.push(format!("gap{k}_s_at_min_gap_m2"));
        header.push(format!("gap{k}_s_at_max_gap_m2"));
    }
    header.extend(["mu_over_mu_lo_min", "brackets", "first_fault"].map(String::from));
    header.extend(METRICS_COLUMNS.iter().skip(1).map(|s| (*s).to_owned()));
    let mut t = Table::new(header);
    for d in draws {
        let p = &d.plant;
        let mut plant = vec![
            d.index.to_string(),
            d.seed.to_string(),
            p.mass_kg.to_string(),
            p.spring_n_per_m.to_string(),
            p.friction_n_s_per_m.to_string(),
            p.resistance_ohm.to_string(),
            match p.force {
                ForceModel::Frozen => "frozen",
                ForceModel::EnergyConsistent => "energy_consistent",
            }
            .into(),
        ];
        let (g0, g1) = p.gap_range_m();
        for k in 0..gaps {
            match p.gaps.get(k) {
                Some(s) => {
                    plant.push(
                        match s {
                            Surface::Constant { .. } => "constant",
                            Surface::Rectangular { .. } => "rectangular",
                        }
                        .into(),
                    );
                    plant.push(s.area_m2(g0).to_string());
                    plant.push(s.area_m2(g1).to_string());
                }
                None => plant.extend([String::new(), String::new(), String::new()]),
            }
        }
        let m = &d.metrics;
        plant.push(m.bounds.mu_lo_ratio_min.to_string());
        plant.push(m.bounds.brackets.to_string());
        plant.push(
            m.first_fault
                .and_then(|f| f.fault)
                .map_or("", ema::control::supervisor::Fault::name)
                .into(),
        );
        let seg = report::metrics_table(&[("", m)]);
        for row in seg.rows {
            let mut r = plant.clone();
            r.extend(row.into_iter().skip(1));
            t.rows.push(r);
        }
    }
    t
}

/// With converter errors, the steady error on the true position split into the sensor's
/// share and the rest, over the step segments of every draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorSummary {
    /// Worst `|steady error|` on the true position \[% of the reference\].
    pub worst_true_pct: f64,
    /// Worst `|sensor's share|` \[% of the reference\].
    pub worst_sensor_pct: f64,
    /// Worst `|steady error - sensor's share|`: the controller's part \[%\].
    pub worst_controller_pct: f64,
    /// Worst overshoot past the end the sensor's share shifts the armature to (the
    /// controller's part of the overshoot) \[% of the step\].
    pub worst_controller_overshoot_pct: f64,
    /// Draws missing the steady-error target.
    pub steady_misses: usize,
    /// Draws whose only misses are the steady error and the overshoot, each met by its
    /// controller part: they miss only because of the sensor's share.
    pub sensor_only: usize,
    /// Draws missing a target for another reason.
    pub other_misses: usize,
}

/// The [`SensorSummary`] of draws run with converter errors (draws without are skipped).
/// A NaN metric counts as the worst.
#[must_use]
pub fn sensor_summary(draws: &[Draw], t: &Targets) -> SensorSummary {
    let worse = |a: f64, b: f64| {
        if a.is_nan() || b.is_nan() {
            f64::NAN
        } else {
            a.max(b)
        }
    };
    let mut s = SensorSummary {
        worst_true_pct: 0.0,
        worst_sensor_pct: 0.0,
        worst_controller_pct: 0.0,
        worst_controller_overshoot_pct: 0.0,
        steady_misses: 0,
        sensor_only: 0,
        other_misses: 0,
    };
    for d in draws {
        let Some(sensor) = &d.sensor else { continue };
        let (mut controller, mut overshoot) = (0.0_f64, 0.0_f64);
        for (k, seg) in d.metrics.segments.iter().enumerate() {
            let step = seg.spec.to_m - seg.spec.from_m;
            if step == 0.0 {
                continue;
            }
            let share = sensor.steady_error_pct.get(k).copied().unwrap_or(f64::NAN);
            s.worst_true_pct = worse(s.worst_true_pct, seg.steady_error_pct.abs());
            s.worst_sensor_pct = worse(s.worst_sensor_pct, share.abs());
            controller = worse(controller, (seg.steady_error_pct - share).abs());
            // The sensor's share moves the end the armature settles at; past that end is
            // the controller's overshoot.
            let past = sensor
                .controller_overshoot_pct
                .get(k)
                .copied()
                .unwrap_or(f64::NAN);
            overshoot = worse(overshoot, past);
        }
        s.worst_controller_pct = worse(s.worst_controller_pct, controller);
        s.worst_controller_overshoot_pct = worse(s.worst_controller_overshoot_pct, overshoot);
        let misses = Worst::of([&d.metrics], t).misses(t);
        let steady = misses.contains(&"steady error");
        s.steady_misses += usize::from(steady);
        let only_sensor_kinds = misses
            .iter()
            .all(|m| *m == "steady error" || *m == "overshoot");
        if !misses.is_empty()
            && only_sensor_kinds
            && controller <= t.steady_error_pct
            && overshoot <= t.overshoot_pct
        {
            s.sensor_only += 1;
        } else if !misses.is_empty() {
            s.other_misses += 1;
        }
    }
    s
}

/// What became of one draw.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Class {
    /// Every target met, no fault.
    Pass,
    /// A fault latched (named), the bridge coasting from then on when `coasting`.
    Fault {
        /// The fault's name.
        name: &'static str,
        /// The bridge coasted at every sample from the fault on.
        coasting: bool,
    },
    /// A target missed (steady error, overshoot, peak current...) with no fault latched.
    Silent(Vec<&'static str>),
}

/// Sorts a draw.
#[must_use]
pub fn classify(d: &Draw, t: &Targets) -> Class {
    if let Some(f) = d.metrics.first_fault {
        return Class::Fault {
            name: f
                .fault
                .map_or("unnamed", ema::control::supervisor::Fault::name),
            coasting: d.coasting_after_fault,
        };
    }
    let misses = Worst::of([&d.metrics], t).misses(t);
    if misses.is_empty() {
        Class::Pass
    } else {
        Class::Silent(misses)
    }
}

/// The draws sorted ([`classify`]).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Classes {
    /// Draws.
    pub n: usize,
    /// Draws that meet every target.
    pub pass: usize,
    /// Named faults with the bridge coasting, by fault name (sorted by name).
    pub faults: Vec<(&'static str, usize)>,
    /// Faults after which the bridge did not coast at every sample.
    pub fault_not_coasting: usize,
    /// Silent failures.
    pub silent: usize,
    /// The silent failures' misses, by target name (sorted by name).
    pub silent_misses: Vec<(&'static str, usize)>,
}

impl Classes {
    /// Draws ending in a named fault with the bridge coasting.
    #[must_use]
    pub fn named(&self) -> usize {
        self.faults.iter().map(|(_, n)| n).sum()
    }

    /// The named faults as `name n, name n` (`-` when none).
    #[must_use]
    pub fn mix(&self) -> String {
        list(&self.faults)
    }

    /// The silent failures' misses as `target n, ...` (`-` when none).
    #[must_use]
    pub fn silent_mix(&self) -> String {
        list(&self.silent_misses)
    }
}

fn list(v: &[(&'static str, usize)]) -> String {
    if v.is_empty() {
        "-".into()
    } else {
        v.iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

fn bump(v: &mut Vec<(&'static str, usize)>, key: &'static str) {
    crate::analysis::report::tally(v, key);
    v.sort_unstable();
}

/// Every draw sorted.
#[must_use]
pub fn classify_all(draws: &[Draw], t: &Targets) -> Classes {
    let mut c = Classes {
        n: draws.len(),
        ..Classes::default()
    };
    for d in draws {
        match classify(d, t) {
            Class::Pass => c.pass += 1,
            Class::Fault {
                name,
                coasting: true,
            } => bump(&mut c.faults, name),
            Class::Fault { .. } => c.fault_not_coasting += 1,
            Class::Silent(misses) => {
                c.silent += 1;
                for m in misses {
                    bump(&mut c.silent_misses, m);
                }
            }
        }
    }
    c
}

/// Runs the Monte Carlo and writes its report.
///
/// # Errors
/// A scenario that cannot be loaded (nothing is written then), a failed draw or write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    anyhow::ensure!(args.n > 0, "--n = 0: draw at least one plant");
    let mut sc = match args.rate_hz {
        None => catalog::load(&args.scenario)?,
        Some(r) => catalog::load_at_rate(&args.scenario, r)?,
    };
    let dir = args.output.dir(&match args.rate_hz {
        None => format!("{}-montecarlo", sc.name),
        Some(r) => format!("{}-{}khz-montecarlo", sc.name, sig(r / 1e3, 3)),
    });
    anyhow::ensure!(
        args.widen.is_finite() && args.widen > 0.0,
        "--widen = {}: a positive factor",
        args.widen
    );
    let options = Options {
        sensor_errors: args.sensor_errors.then(CalibrationClass::default),
        widen: args.widen,
    };
    let substeps = if let Some(n) = args.substeps {
        anyhow::ensure!(n > 0, "--substeps = 0: at least one RK4 step per period");
        writeln!(out, "RK4 substeps per period: {n} (--substeps)")?;
        n
    } else {
        let (first, _) = options.scenario(&sc, args.seed, 0)?;
        let a = accuracy::fewest_substeps(&first, sc.integration.substeps, TOLERANCE_REL)?;
        writeln!(
            out,
            "RK4 substeps per period: {} (the scenario has {}; draw 0 replayed with {} stays \
             within {} of the stroke and {} of the peak current of a 1 us RK4 solution, \
             tolerance {})",
            a.substeps,
            sc.integration.substeps,
            a.substeps,
            sig(a.position_rel, 2),
            sig(a.current_rel, 2),
            sig(TOLERANCE_REL, 1)
        )?;
        a.substeps
    };
    sc.integration.substeps = substeps;
    describe_draws(args, &options, &sc, out)?;
    let started = std::time::Instant::now();
    let mut draws = montecarlo_opts(&sc, args.n, args.seed, !args.quiet, &options)?;
    writeln!(
        out,
        "{} draws in {} s",
        draws.len(),
        sig(started.elapsed().as_secs_f64(), 3)
    )?;
    let checked = if args.substeps.is_none() {
        check_worst_draws(args, &options, &mut sc, substeps, &mut draws, out)?
    } else {
        Vec::new()
    };
    let substeps = sc.integration.substeps;
    let worst = worst_table(&draws);
    write!(out, "\nworst case over the draws:\n{}", worst.to_text())?;
    let t = Targets::for_scenario(&sc);
    let (targets, failing) = targets_table(&draws, &t);
    write!(
        out,
        "\nthe targets on every step segment (settling target per segment: {} s):\n{}{} of \
         {} draws pass every target\n",
        t.settling_s
            .iter()
            .map(|v| sig(*v, 3))
            .collect::<Vec<_>>()
            .join(", "),
        targets.to_text(),
        draws.len() - failing,
        draws.len()
    )?;
    let sensor = draws
        .iter()
        .any(|d| d.sensor.is_some())
        .then(|| sensor_summary(&draws, &t));
    if let Some(s) = &sensor {
        write_sensor_summary(s, out)?;
    }
    let classes = classify_all(&draws, &t);
    writeln!(
        out,
        "\n{} pass, {} end in a named fault with the bridge coasting ({}), {} fail silently \
         (a target missed, no fault latched), {} latch a fault without coasting",
        classes.pass,
        classes.named(),
        classes.mix(),
        classes.silent,
        classes.fault_not_coasting
    )?;

    report::create_dir(&dir)?;
    let mut files = Vec::new();
    let path = dir.join("draws.csv");
    draws_table(&draws).write_csv(&path)?;
    files.push(path);
    let path = dir.join("worst.csv");
    worst.write_csv(&path)?;
    files.push(path);
    let path = dir.join("targets.csv");
    targets.write_csv(&path)?;
    files.push(path);
    super::list_files(out, &files)?;
    Ok(Outcome {
        substeps,
        checked,
        draws,
        worst,
        targets,
        settling_targets_s: t.settling_s,
        failing,
        sensor,
        classes,
        files,
    })
}

/// Writes what is drawn: the scenario, the plants' tolerances when widened, the converter
/// errors when drawn.
fn describe_draws(
    args: &Args,
    options: &Options,
    sc: &Scenario,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    writeln!(
        out,
        "scenario `{}`: {}; {} plants, seed {}",
        sc.name,
        super::run::describe(sc),
        args.n,
        args.seed
    )?;
    if args.widen != 1.0 {
        let u = options.uncertainty(sc);
        writeln!(
            out,
            "plant tolerances {} times the controller's: R +-{} %, K +-{} %, m +-{} %, lambda \
             +-{} % (pole surfaces within the physical bounds)",
            sig(args.widen, 3),
            sig(100.0 * u.resistance_rel, 3),
            sig(100.0 * u.spring_rel, 3),
            sig(100.0 * u.mass_rel, 3),
            sig(100.0 * u.friction_rel, 3)
        )?;
    }
    if let Some(c) = options.sensor_errors {
        writeln!(
            out,
            "converter errors drawn per plant: gain +-{} %, offset +-{} codes on each channel",
            sig(100.0 * c.gain_rel, 3),
            sig(c.offset_code, 3)
        )?;
    }
    Ok(())
}

/// Replays the draws that hold a worst case against a 1 us RK4 solution: the substep count
/// was validated on draw 0 only. A count too small for one of them is raised in `sc` and
/// the `draws` are run again. Returns each checked draw with its accuracy.
fn check_worst_draws(
    args: &Args,
    options: &Options,
    sc: &mut Scenario,
    substeps: u32,
    draws: &mut Vec<Draw>,
    out: &mut dyn Write,
) -> anyhow::Result<Vec<(usize, accuracy::Accuracy)>> {
    let mut checked = Vec::new();
    for k in worst_draws(draws) {
        let (drawn, _) = options.scenario(sc, args.seed, k)?;
        let reference = accuracy::Reference::new(&drawn)?;
        let mut a = reference.accuracy(sc.integration.substeps)?;
        while !a.within(TOLERANCE_REL) && a.substeps < 10 * substeps.max(10) {
            a = reference.accuracy(a.substeps + 1)?;
        }
        checked.push((k, a));
    }
    let needed = checked.iter().map(|(_, a)| a.substeps).max().unwrap_or(0);
    let list = checked
        .iter()
        .map(|(k, a)| {
            format!(
                "{k} ({} substeps: {} of the stroke, {} of the peak current)",
                a.substeps,
                sig(a.position_rel, 2),
                sig(a.current_rel, 2)
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    if needed > sc.integration.substeps {
        writeln!(
            out,
            "the worst draws need {needed} substeps per period to stay within {} of a 1 us \
             RK4 solution: {list}; running the draws again with {needed}",
            sig(TOLERANCE_REL, 1)
        )?;
        sc.integration.substeps = needed;
        *draws = montecarlo_opts(sc, args.n, args.seed, !args.quiet, options)?;
    } else {
        writeln!(
            out,
            "the draws holding a worst case, replayed with {} substeps, stay within {} of \
             a 1 us RK4 solution: draws {list}",
            sc.integration.substeps,
            sig(TOLERANCE_REL, 1)
        )?;
    }
    Ok(checked)
}

/// Writes the sensor's share of the steady error against the controller's.
fn write_sensor_summary(s: &SensorSummary, out: &mut dyn Write) -> anyhow::Result<()> {
    writeln!(
        out,
        "\non the true position, with converter errors: worst |steady error| {} % of the \
             reference, of which the sensor's share (what the gain and offset errors alone \
             give at the reference; no controller removes it) up to {} %; the controller's \
             part (|error - sensor's share|) at most {} %, its overshoot past the end the \
             share shifts to at most {} % of the step; {} draws miss the steady-error target; \
             {} draws miss targets only because of the sensor's share, {} for another reason",
        sig(s.worst_true_pct, 3),
        sig(s.worst_sensor_pct, 3),
        sig(s.worst_controller_pct, 3),
        sig(s.worst_controller_overshoot_pct, 3),
        s.steady_misses,
        s.sensor_only,
        s.other_misses
    )?;
    Ok(())
}
