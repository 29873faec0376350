//! `hil-sim faults [ACTUATOR]`: the fault-injection scenarios ([`crate::analysis::faults`]) on an
//! actuator (a family member or a file; the product's by default): for each injected
//! fault, the fault the supervisor latched, how long after the injection, the peak coil
//! current against the trip level, and whether the bridge coasted from then on.

use std::io::Write;
use std::path::PathBuf;

use crate::analysis::faults::{
    random, table as run_cases, Outcome as Case, RandomCase, DEADLINE_S,
};
use crate::analysis::report::{self, sig, Table};

/// Arguments of `faults`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Args {
    /// A family member's name (see `hil-sim actuators`) or an actuator file.
    #[arg(default_value = "product")]
    pub actuator: String,
    /// ISR rate (Hz; default: the actuator's).
    #[arg(long)]
    pub rate_hz: Option<f64>,
    /// Supply (V; default: the actuator's).
    #[arg(long)]
    pub supply_v: Option<f64>,
    /// Inject each case this many times at random instants on drawn plants.
    #[arg(long)]
    pub random: Option<usize>,
    /// Seed of the random injections (plants and instants).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
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
    /// With `--random`: one entry per case.
    pub random: Vec<RandomCase>,
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

/// Column names of the random-injection table.
pub const RANDOM_HEADER: [&str; 14] = [
    "fault injected",
    "expected",
    "n",
    "pass",
    "named within deadline [%]",
    "detection median / p99 / max [us]",
    "misnamed",
    "not named",
    "observable in the run",
    "named within deadline once observable",
    "latched before",
    "not coasting",
    "peak current [A] (trip)",
    "verdict",
];

/// One case's row of the random-injection table.
#[must_use]
pub fn random_row(s: &RandomCase) -> [String; 14] {
    let us = |v: Option<f64>| v.map_or_else(|| "-".into(), |s| sig(s * 1e6, 3));
    #[expect(clippy::cast_precision_loss)]
    let share = 100.0 * s.within_deadline as f64 / s.n.max(1) as f64;
    [
        s.name.clone(),
        s.expected.clone(),
        s.n.to_string(),
        s.pass.to_string(),
        sig(share, 4),
        format!(
            "{} / {} / {}",
            us(s.quantile_s(0.5)),
            us(s.quantile_s(0.99)),
            us(s.quantile_s(1.0))
        ),
        if s.misnamed.is_empty() {
            "0".into()
        } else {
            s.misnamed
                .iter()
                .map(|(k, n)| format!("{k} {n}"))
                .collect::<Vec<_>>()
                .join(", ")
        },
        s.unnamed.to_string(),
        s.observable.to_string(),
        s.named_once_observable.to_string(),
        s.before.to_string(),
        s.not_coasting.to_string(),
        format!("{} ({})", sig(s.peak_current_a, 4), sig(s.trip_a, 4)),
        if s.pass() {
            "pass".into()
        } else {
            format!("FAIL ({})", s.misses().join(", "))
        },
    ]
}

/// The random-injection table.
#[must_use]
pub fn random_table(cases: &[RandomCase]) -> Table {
    let mut t = Table::new(RANDOM_HEADER);
    for s in cases {
        t.push(random_row(s));
    }
    t
}

/// Runs the cases and writes the table.
///
/// # Errors
/// A scenario that does not validate; a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    let (name, mut act) = crate::simulation::actuator::load(&args.actuator)?;
    #[expect(clippy::cast_possible_truncation)]
    if let Some(r) = args.rate_hz {
        act = act.with_rate_hz(r as f32);
    }
    #[expect(clippy::cast_possible_truncation)]
    if let Some(v) = args.supply_v {
        act = act.with_supply_v(v as f32);
    }
    let base = crate::simulation::actuator::scenario(&name, &act)?;
    if let Some(n) = args.random {
        anyhow::ensure!(n > 0, "--random 0: inject at least once");
        let at_random = random(&base, n, args.seed)?;
        let table = random_table(&at_random);
        writeln!(
            out,
            "fault injection on `{name}` at {} kHz on {} V: each case {n} times at random \
             instants between the first move and 20 ms before the end of the sequence, on \
             plants drawn from the controller's uncertainty set, seed {}; deadline {} us\n",
            sig(base.rate_hz() / 1e3, 3),
            sig(base.supply.voltage_v, 3),
            args.seed,
            sig(DEADLINE_S * 1e6, 4)
        )?;
        write!(out, "{}", table.to_text())?;
        let dir = args.output.dir(&format!("{name}-faults-random"));
        report::create_dir(&dir)?;
        let path = dir.join("faults-random.csv");
        table.write_csv(&path)?;
        let files = vec![path];
        super::list_files(out, &files)?;
        return Ok(Outcome {
            cases: Vec::new(),
            table,
            random: at_random,
            files,
        });
    }
    let cases = run_cases(&base)?;
    let table = table(&cases);
    writeln!(
        out,
        "fault injection on `{name}` at {} kHz on {} V: each must be named within {} us of \
         its injection, the current stay at or below the trip level, the bridge coast from \
         then on\n",
        sig(base.rate_hz() / 1e3, 3),
        sig(base.supply.voltage_v, 3),
        sig(DEADLINE_S * 1e6, 4)
    )?;
    write!(out, "{}", table.to_text())?;
    let dir = args.output.dir(&format!("{name}-faults"));
    report::create_dir(&dir)?;
    let path = dir.join("faults.csv");
    table.write_csv(&path)?;
    let files = vec![path];
    super::list_files(out, &files)?;
    Ok(Outcome {
        cases,
        table,
        random: Vec::new(),
        files,
    })
}
