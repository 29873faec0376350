//! `hil-sim actuators [name]`: the family of actuators kept in the repository, with the
//! time scales their settings come from, or the file of one (a starting point for a file
//! of your own); `hil-sim actuators --draw N --seed S`: `N` drawn actuators
//! ([`crate::analysis::drawn`]), each written as a file.

use std::io::Write;

use crate::analysis::report::{sig, Table};
use crate::simulation::actuator;

/// Arguments of `actuators`.
#[derive(Clone, Debug, Default, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// Print this actuator's file instead of the list.
    pub name: Option<String>,
    /// With a name: print its tuned file.
    #[arg(long)]
    pub tuned: bool,
    /// Draw this many plausible actuators instead (each redrawn until the physical rules
    /// accept it), and write each as a file.
    #[arg(long, value_name = "N", conflicts_with_all = ["name", "tuned"])]
    pub draw: Option<usize>,
    /// Seed of the draw (actuator k uses a seed derived from it and k).
    #[arg(long, default_value_t = 1, requires = "draw")]
    pub seed: u64,
    /// Directory the drawn files go to.
    #[arg(long, default_value = "out/drawn", requires = "draw")]
    pub out: std::path::PathBuf,
}

/// Lists the family (name, what it is, time scales, tuned gains), or prints one's file.
///
/// # Errors
/// An unknown name; a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<()> {
    if let Some(n) = args.draw {
        return draw(n, args.seed, &args.out, out);
    }
    if let Some(name) = &args.name {
        let e = actuator::member(name).ok_or_else(|| {
            anyhow::anyhow!("no actuator `{name}` in the family (try `hil-sim actuators`)")
        })?;
        write!(out, "{}", if args.tuned { e.tuned } else { e.text })?;
        return Ok(());
    }
    let t = family_table()?;
    writeln!(
        out,
        "the family (hil-sim actuators <name> prints the file, --tuned the tuned one; every \
         command takes a name or a file):"
    )?;
    write!(out, "{}", t.to_text())?;
    Ok(())
}

/// The family: name, rate, time scales, tuned gains, what it is.
///
/// # Errors
/// A member whose file does not load (a defect of the repository).
pub fn family_table() -> anyhow::Result<Table> {
    let mut t = Table::new([
        "name",
        "rate [kHz]",
        "natural [rad/s]",
        "authority [rad/s]",
        "coil L/R [ms]",
        "alpha [1/s]",
        "observer [rad/s]",
        "margin",
        "what",
    ]);
    for e in &actuator::FAMILY {
        let (_, act) = actuator::load(e.name)?;
        let s = act.time_scales().map_err(crate::Error::Actuator)?;
        let tuning = act.tuning_or_default().map_err(crate::Error::Actuator)?;
        t.push([
            e.name.to_owned(),
            sig(f64::from(act.board.rate_hz) / 1e3, 3),
            sig(f64::from(s.natural_rad_s), 3),
            sig(f64::from(s.authority_rad_s), 3),
            coil_ms(&s),
            sig(f64::from(tuning.alpha_per_s), 3),
            sig(f64::from(tuning.observer_rad_s), 3),
            sig(f64::from(tuning.margin), 2),
            e.summary().to_owned(),
        ]);
    }
    Ok(t)
}

/// Draws `n` actuators with `seed`, writes each to `dir` and lists them.
///
/// # Errors
/// A draw the rules never accept; a failed write.
pub fn draw(n: usize, seed: u64, dir: &std::path::Path, out: &mut dyn Write) -> anyhow::Result<()> {
    let drawn = crate::analysis::drawn::draw(n, seed)?;
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let t = drawn_table(&drawn)?;
    for d in &drawn {
        let path = dir.join(format!("{}.toml", d.name()));
        std::fs::write(&path, d.text()?)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
    }
    writeln!(
        out,
        "{n} actuators drawn with seed {seed}, written to {} (the ranges and rules: \
         hil_sim::analysis::drawn):",
        dir.display()
    )?;
    write!(out, "{}", t.to_text())?;
    Ok(())
}

/// The drawn actuators: what each is, its time scales and how many draws the rules refused
/// before it.
///
/// # Errors
/// A drawn actuator whose time scales do not derive (a defect: the rules accepted it).
pub fn drawn_table(drawn: &[crate::analysis::drawn::Drawn]) -> anyhow::Result<Table> {
    let mut t = Table::new([
        "name",
        "circuit",
        "mass [g]",
        "stroke [mm]",
        "spring [N/m]",
        "supply [V]",
        "rate [kHz]",
        "natural [rad/s]",
        "authority [rad/s]",
        "coil L/R [ms]",
        "redrawn",
    ]);
    for d in drawn {
        let a = &d.actuator;
        let s = a.time_scales().map_err(crate::Error::Actuator)?;
        t.push([
            d.name(),
            d.circuit.to_owned(),
            sig(f64::from(a.mechanics.mass_kg) * 1e3, 3),
            sig(f64::from(a.mechanics.stroke_m) * 1e3, 3),
            sig(f64::from(a.mechanics.spring_n_per_m), 3),
            sig(f64::from(a.board.supply_v), 3),
            sig(f64::from(a.board.rate_hz) / 1e3, 3),
            sig(f64::from(s.natural_rad_s), 3),
            sig(f64::from(s.authority_rad_s), 3),
            coil_ms(&s),
            d.redrawn.values().sum::<usize>().to_string(),
        ]);
    }
    Ok(t)
}

/// The coil's time constants at the two stops, `open-closed` \[ms\].
fn coil_ms(s: &ema::control::actuator::TimeScales) -> String {
    format!(
        "{}-{}",
        sig(f64::from(s.coil_open_s) * 1e3, 2),
        sig(f64::from(s.coil_closed_s) * 1e3, 2)
    )
}
