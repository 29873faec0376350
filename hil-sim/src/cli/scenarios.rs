//! `hil-sim scenarios [name]`: the embedded scenarios, or the TOML of one (a starting
//! point for a file of your own).

use std::io::Write;

use crate::simulation::catalog;

/// Arguments of `scenarios`.
#[derive(Clone, Debug, Default, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// Print this embedded scenario's TOML instead of the list.
    pub name: Option<String>,
}

/// Lists the embedded scenarios (name and summary), or prints one's TOML.
///
/// # Errors
/// An unknown name; a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<()> {
    if let Some(name) = &args.name {
        let e = catalog::embedded(name).ok_or_else(|| {
            anyhow::anyhow!("no embedded scenario `{name}` (try `hil-sim scenarios` for the list)")
        })?;
        write!(out, "{}", e.text)?;
        return Ok(());
    }
    let width = catalog::EMBEDDED
        .iter()
        .map(|e| e.name.len())
        .max()
        .unwrap_or(0);
    writeln!(
        out,
        "embedded scenarios (hil-sim run <name>; hil-sim scenarios <name> prints the TOML):"
    )?;
    for e in &catalog::EMBEDDED {
        writeln!(out, "  {:width$}  {}", e.name, e.summary())?;
    }
    Ok(())
}
