//! `hil-sim actuators [name]`: the family of actuators kept in the repository, with the
//! time scales their settings come from, or the file of one (a starting point for a file
//! of your own).

use std::io::Write;

use crate::actuator;
use crate::report::{sig, Table};

/// Arguments of `actuators`.
#[derive(Clone, Debug, Default, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// Print this actuator's file instead of the list.
    pub name: Option<String>,
    /// With a name: print its tuned file.
    #[arg(long)]
    pub tuned: bool,
}

/// Lists the family (name, what it is, time scales, tuned gains), or prints one's file.
///
/// # Errors
/// An unknown name; a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<()> {
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
            format!(
                "{}-{}",
                sig(f64::from(s.coil_open_s) * 1e3, 2),
                sig(f64::from(s.coil_closed_s) * 1e3, 2)
            ),
            sig(f64::from(tuning.alpha_per_s), 3),
            sig(f64::from(tuning.observer_rad_s), 3),
            sig(f64::from(tuning.margin), 2),
            e.summary().to_owned(),
        ]);
    }
    Ok(t)
}
