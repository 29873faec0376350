//! `bench`: the host tool for a board on a bench, over a serial port (the board's UART,
//! through a USB-serial adapter) or the virtual board's pseudo-terminal.
//!
//! | command | what |
//! |---|---|
//! | `status` | state, latched fault, fault counters, measurements, interrupt cycles, parameters' source |
//! | `arm`, `disarm`, `clear` | operating state |
//! | `move MM [--time-s S]` | a move of the set point |
//! | `get [NAME]`, `set NAME VALUE` | parameters (all of them without a name) |
//! | `save`, `load`, `defaults`, `restart` | parameters in flash, the board |
//! | `watch` | live values with a progress display |
//! | `capture MM` | a step response: CSV and PNG, the simulator's metrics and its prediction overlaid |
//! | `virtual` | runs the virtual board on a pseudo-terminal and prints its path |
//!
//! Exit codes: 0 done, 1 refused or failed (the message says why), 2 bad usage.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::{Parser, Subcommand};
use ema::device::params::{self};
use ema::device::protocol::Command;
use hil_sim::analysis::report::Table;
use serialport::SerialPort;

use super::link::{Link, Port};

mod capture;
mod commission;
mod commissioned;
mod console;
mod mechanics;
mod parameters;
mod status;
mod virtual_board;
mod watch;

pub use capture::{capture, CaptureOutcome};
use capture::{capture_move, read_capture};
pub use commission::commission;
pub use commissioned::{actuator_file, commissioned_params};
use commissioned::{apply_commissioned, commissioned_sets, correction_sets};
pub use console::console;
use mechanics::measure_mechanics;
use parameters::save;
pub use parameters::{
    backup_text, get, parse_backup, parse_value, read_params, restore, save_would_replace, set_all,
    value_text,
};
pub use status::{status, status_text};
use virtual_board::run_virtual;
use watch::watch;

/// The link's speed \[baud\]: one definition, the core's, which the firmware's UART uses.
pub use ema::device::protocol::BAUD;

/// Host tool for a board on a bench (or the virtual board).
#[derive(Debug, Parser)]
#[command(name = "bench", version, long_about = None)]
pub struct Cli {
    /// Serial port of the board (or the virtual board's pseudo-terminal).
    #[arg(long, global = true, env = "EMA_PORT", value_name = "PATH")]
    pub port: Option<PathBuf>,
    /// How long to wait for a reply (s).
    #[arg(long, global = true, default_value_t = 2.0, value_name = "S")]
    pub timeout_s: f64,
    /// What to do.
    #[command(subcommand)]
    pub command: Verb,
}

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Verb {
    /// State, fault, counters, measurements, cycles per tick, parameters' source.
    Status,
    /// Closed loop, holding the present position.
    Arm,
    /// Bridge off.
    Disarm,
    /// Clears a latched fault (disarmed, cause gone).
    Clear,
    /// Moves to a position (mm).
    Move {
        /// Target (mm).
        position_mm: f64,
        /// Duration of the move (s) (default: as fast as the actuator allows).
        #[arg(long)]
        time_s: Option<f64>,
    },
    /// A parameter's value, or all of them.
    Get {
        /// Dotted name (`coil.rated_current_a`).
        name: Option<String>,
    },
    /// Changes a parameter (disarmed; not stored until `save`).
    Set {
        /// Dotted name.
        name: String,
        /// Value: a number, true/false, or a choice's name.
        value: String,
    },
    /// Stores the parameters in flash (the board restarts to write them).
    Save {
        /// Also when the board's stored set is one this firmware cannot read (a set of a
        /// later format): saving replaces it (back it up with the firmware that wrote it
        /// first).
        #[arg(long)]
        replace: bool,
    },
    /// Reloads the stored parameters.
    Load,
    /// Back to the built-in parameters (not stored until `save`).
    Defaults,
    /// Restarts the board.
    Restart,
    /// Live values.
    Watch(WatchArgs),
    /// Captures a move's response and compares it with the simulator's prediction.
    Capture(CaptureArgs),
    /// Measures the actuator on the board, loop open (disarmed, nothing latched): the
    /// coil's resistance, its inductance and the position sensor's readings at both end
    /// stops; with `--mechanics`, loop closed, the spring, the mass and the friction.
    Commission(CommissionArgs),
    /// Writes every parameter of the board to FILE: the actuator file, with the board's
    /// `[setpoint]` and `[link]` tables (before a firmware update; `hil-sim` reads it as
    /// an actuator file).
    Backup {
        /// The file to write.
        file: PathBuf,
    },
    /// Sets every parameter FILE holds (a `backup`, or an actuator file) on the board,
    /// each validated as a `set`, and saves them (disarmed).
    Restore {
        /// The file to read.
        file: PathBuf,
    },
    /// Commands from standard input, one per line as on the command line (`arm`, `move 3
    /// --time-s 0.05`, `capture 2`, ...), over one link: the heartbeat keeps the board
    /// armed between them; at the end of the input an armed board is disarmed.
    Console,
    /// Runs the virtual board on a pseudo-terminal.
    Virtual(VirtualArgs),
}

/// Arguments of `commission`.
#[derive(Clone, Debug, clap::Args)]
pub struct CommissionArgs {
    /// Also set `coil.resistance_ohm` to the measured value (validated as any `set`; not
    /// stored until `save`). With `--tune`: the resistance, the magnetic circuit (in the
    /// board's form) and the tuning, then saved.
    #[arg(long)]
    pub apply: bool,
    /// Tunes the commissioned actuator (the file `--out` writes): `hil-sim tune` at the
    /// board's rate, then the tuned file's evaluation run, the predicted step responses
    /// with their metrics and figures; all beside the file (`<stem>.tuned.toml`,
    /// `<stem>-tune/`, `<stem>/`).
    #[arg(long, requires = "out")]
    pub tune: bool,
    /// Then measures the spring's rate and preload, the mass and the friction: the loop
    /// closed with the measured coil and circuit and the default tuning (for the holds
    /// only, then put back; holds a monitor ends run again with a slower loop), the armature moved to and held at 1/8, 7/8, 3/8 and 3/4 of
    /// the stroke, the magnet's pull read from the captured current (the board drives the
    /// coil and the armature moves): the spring from the holds, the mass and the friction
    /// from the moves. `--out` writes them, `--tune` tunes for them and `--apply` sets
    /// them.
    #[arg(long)]
    pub mechanics: bool,
    /// Longest wait for the result (s).
    #[arg(long, default_value_t = 60.0)]
    pub timeout_s: f64,
    /// Writes the board's actuator file with the measured resistance and magnetic circuit
    /// in it (the stops' two inductances, or with `--mechanics` the circuit fitted to them
    /// and the holds', in the board's form), each value's uncertainty and the end stops in
    /// its head: the file `hil-sim tune` takes.
    #[arg(long)]
    pub out: Option<std::path::PathBuf>,
}

/// Arguments of `watch`.
#[derive(Clone, Debug, clap::Args)]
pub struct WatchArgs {
    /// Signals, comma separated (reference_m, x_m, v_mps, i_a, u_v, duty, vbus_v, analog_m).
    #[arg(long, default_value = "x_m,i_a,u_v", value_delimiter = ',')]
    pub signals: Vec<String>,
    /// Ticks per sample.
    #[arg(long, default_value_t = 200)]
    pub decimation: u16,
    /// How long (s).
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
}

/// Arguments of `capture`.
#[derive(Clone, Debug, clap::Args)]
pub struct CaptureArgs {
    /// Target of the move (mm).
    pub position_mm: f64,
    /// Duration of the move (s) (default: as fast as the actuator allows).
    #[arg(long)]
    pub time_s: Option<f64>,
    /// Samples.
    #[arg(long, default_value_t = 256)]
    pub samples: u16,
    /// Ticks per sample.
    #[arg(long, default_value_t = 20)]
    pub decimation: u16,
    /// The prediction's converter has the typical noise (as `virtual --noise`).
    #[arg(long)]
    pub noise: bool,
    /// Folder for the files.
    #[arg(long, default_value = "out/capture")]
    pub out: PathBuf,
}

/// Arguments of `virtual`.
#[derive(Clone, Debug, clap::Args)]
pub struct VirtualArgs {
    /// The actuator file the virtual firmware is built for (default: the product's).
    #[arg(long)]
    pub actuator: Option<String>,
    /// Times real time (default 1); 0: as fast as it can.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Typical converter noise.
    #[arg(long)]
    pub noise: bool,
    /// Also make this path a link to the pseudo-terminal.
    #[arg(long)]
    pub link: Option<PathBuf>,
}

/// Runs the tool on the process's arguments.
#[must_use]
pub fn main() -> ExitCode {
    hil_sim::cli::exit(Cli::parse(), dispatch)
}

/// Opens the serial port at `path`, its input flushed (see [`Link::new`]).
///
/// # Errors
/// The port cannot be opened.
pub fn open(
    path: &std::path::Path,
    timeout: Duration,
) -> anyhow::Result<Link<serialport::TTYPort>> {
    let port = serialport::new(path.to_string_lossy(), BAUD)
        .timeout(Duration::from_millis(20))
        .open_native()
        .with_context(|| format!("cannot open {}", path.display()))?;
    // Whatever arrived before this process (replies to an earlier one, telemetry, line
    // noise) is not for it.
    port.clear(serialport::ClearBuffer::Input)
        .with_context(|| format!("cannot flush {}", path.display()))?;
    Ok(Link::new(port, timeout))
}

/// Runs one parsed command line.
///
/// # Errors
/// A refusal or failure, described.
pub fn dispatch(cli: Cli, out: &mut dyn Write) -> anyhow::Result<()> {
    if let Verb::Virtual(a) = &cli.command {
        return run_virtual(a, out);
    }
    let Some(port) = &cli.port else {
        bail!("give the board's serial port: --port PATH (or EMA_PORT)");
    };
    let mut link = open(port, Duration::from_secs_f64(cli.timeout_s))?;
    run(&mut link, cli.command, out)
}

/// Runs one command over `link`.
///
/// # Errors
/// A refusal or failure, described.
pub fn run<P: Port>(link: &mut Link<P>, verb: Verb, out: &mut dyn Write) -> anyhow::Result<()> {
    match verb {
        Verb::Status => {
            let s = status(link)?;
            write!(out, "{}", status_text(&s))?;
        }
        Verb::Arm => {
            link.done(Command::Arm)?;
            writeln!(
                out,
                "armed: holding the present position (the board disarms link.timeout_s \
                 after this tool stops talking to it: `bench console` keeps it armed)"
            )?;
        }
        Verb::Disarm => {
            link.done(Command::Disarm)?;
            writeln!(out, "disarmed: bridge off")?;
        }
        Verb::Clear => {
            link.done(Command::Clear)?;
            writeln!(out, "cleared: disarmed")?;
        }
        Verb::Move {
            position_mm,
            time_s,
        } => {
            link.done(Command::Move {
                position_m: (position_mm * 1e-3) as f32,
                time_s: time_s.map(|t| t as f32),
            })?;
            writeln!(out, "moving to {position_mm} mm")?;
        }
        Verb::Get { name: Some(name) } => {
            let v = get(link, &name)?;
            writeln!(out, "{name} = {}", value_text(&name, v))?;
        }
        Verb::Get { name: None } => {
            let mut t = Table::new(["parameter", "value", "note"]);
            for info in params::all() {
                match get(link, info.name) {
                    Ok(v) => t.push([
                        info.name.to_owned(),
                        value_text(info.name, v),
                        info.fixed.map_or(String::new(), |w| format!("fixed: {w}")),
                    ]),
                    Err(e) => t.push([info.name.to_owned(), "-".into(), format!("{e}")]),
                }
            }
            write!(out, "{}", t.to_text())?;
        }
        Verb::Set { name, value } => {
            let v = parse_value(&name, &value)?;
            link.done(Command::Set {
                name: &name,
                value: v,
            })?;
            writeln!(
                out,
                "{name} = {} (not stored until `save`)",
                value_text(&name, v)
            )?;
        }
        Verb::Save { replace } => {
            if !replace {
                if let Some(why) = save_would_replace(&status(link)?.params) {
                    bail!("{why}");
                }
            }
            save(link, out)?;
        }
        Verb::Backup { file } => {
            let p = read_params(link)?;
            std::fs::write(&file, backup_text(&p)?)
                .with_context(|| format!("cannot write {}", file.display()))?;
            writeln!(out, "every parameter written to {}", file.display())?;
        }
        Verb::Restore { file } => {
            let text = std::fs::read_to_string(&file)
                .with_context(|| format!("cannot read {}", file.display()))?;
            let p = parse_backup(&text, &file.display().to_string())?;
            restore(link, &p)?;
            save(link, out)?;
        }
        Verb::Console => {
            let stdin = std::io::stdin();
            console(link, stdin.lock(), out)?;
        }
        Verb::Load => {
            link.done(Command::Load)?;
            writeln!(out, "loaded the stored parameters")?;
        }
        Verb::Defaults => {
            link.done(Command::Defaults)?;
            writeln!(out, "built-in parameters in use (not stored until `save`)")?;
        }
        Verb::Restart => {
            link.forget_started();
            link.done(Command::Restart)?;
            let started = link.wait_started(Duration::from_secs(10))?;
            writeln!(out, "restarted with the {}", super::source(&started.params))?;
        }
        Verb::Watch(a) => watch(link, &a, out)?,
        Verb::Capture(a) => {
            capture(link, &a, out)?;
        }
        Verb::Commission(a) => {
            commission(link, &a, out)?;
        }
        Verb::Virtual(_) => bail!("`virtual` runs on its own"),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `bench --help` says it is the bench tool, not the simulator (whose description
    /// the package carries).
    #[test]
    fn the_help_names_the_bench_tool() {
        use clap::CommandFactory;
        let about = Cli::command().get_about().map(ToString::to_string);
        assert_eq!(
            about.as_deref(),
            Some("Host tool for a board on a bench (or the virtual board)")
        );
    }
}
