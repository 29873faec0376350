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

use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, ensure, Context};
use clap::{Parser, Subcommand};
use ema::control::actuator::{Actuator, Magnetics};
use ema::device::commission::{self, Report};
use ema::device::params::{self, Kind, Params};
use ema::device::protocol::{
    Build, CaptureState, Command, Commissioned, LoadError, Message, Mode, Reply, Signal, Source,
    Status, Trigger, Value, CHUNK_SAMPLES,
};
use serialport::SerialPort;

use super::board::{Injection, Options, VirtualBoard};
use super::link::{Link, Port};
use super::{fault_name, Capture};
use crate::commissioning::{Holds, Mechanics};
use crate::report::{self, sig, Figure, Panel, Series, Table};

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
    crate::cli::exit(Cli::parse(), dispatch)
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

/// The board's status.
///
/// # Errors
/// No reply, or an unexpected one.
pub fn status<P: Port>(link: &mut Link<P>) -> anyhow::Result<Status<'static>> {
    let f = link.request(Command::Status)?;
    let mut scratch = Vec::new();
    match f.message(&mut scratch)? {
        Message::Reply {
            reply: Reply::Status(s),
            ..
        } => {
            let leak = |t: &str| -> &'static str { Box::leak(t.to_owned().into_boxed_str()) };
            Ok(Status {
                params: super::owned_source(&s.params),
                build: Build {
                    version: leak(s.build.version),
                    id: leak(s.build.id),
                },
                ..s
            })
        }
        other => Err(anyhow!("unexpected reply: {other:?}")),
    }
}

/// Runs a commissioning and waits for its outcome; prints it, and with `apply` sets the
/// measured resistance (the end stops are reported, not yet applied).
///
/// # Errors
/// Refused, stopped (with the board's reason), no outcome within the timeout, or (with
/// `apply`) the value refused.
pub fn commission<P: Port>(
    link: &mut Link<P>,
    args: &CommissionArgs,
    out: &mut dyn Write,
) -> anyhow::Result<Report> {
    let file = read_params(link)?.actuator;
    let file_r = file.coil.resistance_ohm;
    let stroke_m = file.mechanics.stroke_m;
    let scales = file
        .time_scales()
        .map_err(|e| anyhow!("the board's actuator: {}", e))?;
    link.done(Command::Commission)?;
    let start = Instant::now();
    let r = loop {
        let f = link.request(Command::Commissioned)?;
        let mut scratch = Vec::new();
        match f.message(&mut scratch)? {
            Message::Reply {
                reply: Reply::Commissioned(c),
                ..
            } => match c {
                Commissioned::Done(r) => break r,
                Commissioned::Aborted(commission::Abort::Fault) => {
                    let latched = status(link)?.fault.map_or("none".into(), fault_name);
                    bail!("commissioning stopped: fault {latched} latched, bridge coasting")
                }
                Commissioned::Aborted(a) => bail!("commissioning stopped: {}", a.name()),
                Commissioned::Never => bail!("the board never started the commissioning"),
                Commissioned::Running => {}
            },
            other => bail!("unexpected reply: {other:?}"),
        }
        if start.elapsed().as_secs_f64() > args.timeout_s {
            bail!("no outcome after {} s", args.timeout_s);
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let report = r;
    let r = report.resistance;
    writeln!(
        out,
        "coil resistance {:.4} ohm +- {:.4} (two standard errors); the file says {file_r} ohm ({:+.1} %)",
        r.ohm,
        r.spread_ohm,
        100.0 * (r.ohm / file_r - 1.0)
    )?;
    writeln!(
        out,
        "steps: {:.3} V -> {:.4} A, {:.3} V -> {:.4} A, bus {:.2} V",
        r.u_v[0], r.i_a[0], r.u_v[1], r.i_a[1], r.vbus_v
    )?;
    let l = report.inductance;
    let (file_open_h, file_closed_h) = (scales.coil_open_s * file_r, scales.coil_closed_s * file_r);
    writeln!(
        out,
        "inductance at the open stop {:.1} uH, at the closed stop {:.1} uH; the file says {:.1} and {:.1} uH ({:+.1} %, {:+.1} %)",
        1e6 * l.open_h,
        1e6 * l.closed_h,
        1e6 * file_open_h,
        1e6 * file_closed_h,
        100.0 * (l.open_h / file_open_h - 1.0),
        100.0 * (l.closed_h / file_closed_h - 1.0)
    )?;
    let e = report.ends;
    let travel_m = e.closed_m - e.open_m;
    writeln!(
        out,
        "position at the open stop {:.1} um, at the closed stop {:.1} um (+- {:.2} um, two standard errors, in the file's calibration)",
        1e6 * e.open_m,
        1e6 * e.closed_m,
        1e6 * e.spread_m
    )?;
    writeln!(
        out,
        "sensor: offset {:+.2} % of the stroke, gain {:+.2} % (travel {:.1} um against the file's {:.1} um)",
        100.0 * e.open_m / stroke_m,
        100.0 * (travel_m / stroke_m - 1.0),
        1e6 * travel_m,
        1e6 * stroke_m
    )?;
    let mechanics = if args.mechanics {
        Some(measure_mechanics(link, &file, &report, out)?)
    } else {
        None
    };
    if let Some(path) = &args.out {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            report::create_dir(dir)?;
        }
        std::fs::write(path, actuator_file(&file, &report, mechanics.as_ref())?)
            .map_err(|e| anyhow!("{}: {e}", path.display()))?;
        writeln!(out, "actuator file written: {}", path.display())?;
    }
    if args.tune {
        let Some(path) = &args.out else {
            bail!("--tune needs --out FILE: the commissioned file is what is tuned")
        };
        writeln!(out)?;
        let stem = crate::actuator::stem(path);
        let beside = |name: String| crate::cli::Output {
            out: Some(path.with_file_name(name)),
        };
        let tuned = crate::cli::tune::run(
            &crate::cli::tune::Args {
                actuator: path.display().to_string(),
                rates_hz: Some(vec![f64::from(file.board.rate_hz)]),
                validate: TUNE_VALIDATION_DRAWS,
                substeps: 1,
                tuned: None,
                quiet: true,
                output: beside(format!("{stem}-tune")),
            },
            out,
        )?;
        let Some(tuned_path) = tuned.tuned else {
            bail!("no tuning meets every target for the commissioned actuator (see above); nothing applied")
        };
        writeln!(out, "\npredicted with the tuned file:")?;
        crate::cli::run::run(
            &crate::cli::run::Args {
                scenario: tuned_path.display().to_string(),
                output: beside(stem.clone()),
                max_rows: 20_000,
            },
            out,
        )?;
        if args.apply {
            // The tuned file: the measured actuator with the tuning chosen.
            let tuned = crate::actuator::parse(
                &std::fs::read_to_string(&tuned_path)?,
                &tuned_path.display().to_string(),
            )?;
            let tuning = tuned
                .tuning
                .ok_or_else(|| anyhow!("{}: no tuning in it", tuned_path.display()))?;
            apply_commissioned(link, &file, &tuned, &tuning, out)?;
        }
    } else if args.apply {
        link.done(Command::Set {
            name: "coil.resistance_ohm",
            value: Value::Number(r.ohm),
        })?;
        writeln!(
            out,
            "coil.resistance_ohm = {} (not stored until `save`)",
            r.ohm
        )?;
    }
    Ok(report)
}

/// Measures the magnetic circuit between the stops, the spring, the mass and the friction
/// on the board ([`crate::commissioning::Circuit::fit`],
/// [`crate::commissioning::fit_spring`], [`crate::commissioning::fit_armature`]): sets
/// the actuator `report` measured on the board's `file` with the default tuning (not
/// stored), arms, moves to each position of [`crate::actuator::SEQUENCE`] and holds it as
/// the evaluation sequence does, capturing the move, then the hold's window at the
/// [`crate::commissioning::decimations`], then the hold's inductance probes at every
/// tick; disarms and puts the parameters in use before back (the stored set, or the
/// built-in defaults). A fault during the holds ends the attempt, named: the holds run
/// again, cleared, with a slower loop ([`crate::commissioning::hold_tuning`]), up to
/// [`crate::commissioning::HOLD_ATTEMPTS`] in all.
///
/// # Errors
/// A refusal, no reply, a fault during the last attempt at the holds, a capture that
/// does not finish.
fn measure_mechanics<P: Port>(
    link: &mut Link<P>,
    file: &Actuator,
    report: &Report,
    out: &mut dyn Write,
) -> anyhow::Result<Mechanics> {
    let (m, _) = crate::commissioning::measured(file, report, None)?;
    let settings = m.settings().map_err(|e| anyhow!("{e}"))?;
    let stroke_m = f64::from(m.mechanics.stroke_m);
    let rate_hz = f64::from(m.board.rate_hz);
    let hold_s = crate::actuator::segment_s(&settings, stroke_m);
    let capacity = u16::try_from(ema::device::CAPTURE_CAPACITY).unwrap_or(u16::MAX);
    let (move_decimation, window_decimation) =
        crate::commissioning::decimations(&settings, stroke_m, rate_hz);
    #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let window_samples = ((crate::commissioning::HOLD_WINDOW_SHARE * hold_s * rate_hz
        / f64::from(window_decimation))
    .round()
    .clamp(1.0, f64::from(capacity))) as u16;
    let probe = crate::commissioning::hold_probe(&m);
    let delay = usize::from(settings.delay_ticks);
    let span = u16::try_from(crate::commissioning::probe_capture(probe.ticks(), delay))
        .unwrap_or(u16::MAX)
        .min(capacity);
    writeln!(
        out,
        "spring, mass and friction: the loop closed with the measured coil and circuit, default tuning; holds of {} s at {}",
        sig(hold_s, 3),
        crate::actuator::SEQUENCE.map(|f| format!("{} mm", sig(f * stroke_m * 1e3, 3))).join(", ")
    )?;
    writeln!(
        out,
        "inductance: {} probes at the end of each hold, +-{} A about the hold's current, {} cycles of {} ticks at each level",
        crate::commissioning::HOLD_PROBE_RUNS,
        sig(probe.amplitude_a, 3),
        probe.cycles,
        probe.half_ticks
    )?;
    let mut probes: [Vec<Vec<crate::commissioning::ProbeSample>>; crate::actuator::SEQUENCE.len()];
    let stored = matches!(status(link)?.params, ema::device::protocol::Source::Stored);
    let mut attempt = 0;
    let holds = loop {
        let tuning = crate::commissioning::hold_tuning(&m, attempt)?;
        let sets = commissioned_sets(file, &m, &tuning)?;
        probes = Default::default();
        let mut held = || -> anyhow::Result<Holds> {
            set_all(link, &sets)?;
            // The holds start from the open stop, as the evaluation sequence does: the
            // armature comes back there once the commissioning's last hold lets go.
            let (open_m, still_m) = (
                report.ends.open_m,
                SPRING_START_SHARE * m.mechanics.stroke_m,
            );
            let deadline = Instant::now() + Duration::from_secs(10);
            let mut near = 0;
            while near < 5 {
                ensure!(
                    Instant::now() < deadline,
                    "the armature did not come back to the open stop within 10 s"
                );
                near = if (status(link)?.x_m - open_m).abs() < still_m {
                    near + 1
                } else {
                    0
                };
                std::thread::sleep(Duration::from_millis(20));
            }
            link.done(Command::Arm)?;
            let mut holds = Holds {
                move_dt_s: f64::from(move_decimation) / rate_hz,
                window_dt_s: f64::from(window_decimation) / rate_hz,
                ..Holds::default()
            };
            let readings = |c: &Capture| -> anyhow::Result<Vec<(f64, f64)>> {
                if let Some(s) = c.samples.iter().find(|s| s.fault != 0) {
                    return Err(HoldsFault(fault_name(s.fault)).into());
                }
                Ok(c.samples
                    .iter()
                    .map(|s| (f64::from(s.x_m), f64::from(s.i_a)))
                    .collect())
            };
            for (k, f) in crate::actuator::SEQUENCE.into_iter().enumerate() {
                #[expect(clippy::cast_possible_truncation)]
                let c = capture_move(
                    link,
                    capacity,
                    move_decimation,
                    Some(((f * stroke_m) as f32, None)),
                    rate_hz,
                )?;
                holds.moves[k] = readings(&c)?;
                // The window: the hold's end, once the move has settled.
                let c = capture_move(link, window_samples, window_decimation, None, rate_hz)?;
                holds.windows[k] = readings(&c)?;
                // The inductance at the hold: each probe captured at every tick from its first.
                for _ in 0..crate::commissioning::HOLD_PROBE_RUNS {
                    link.done(Command::Capture {
                        samples: span,
                        decimation: 1,
                        trigger: Trigger::Probe,
                    })?;
                    link.done(probe.command())?;
                    let c = read_capture(link, span, 1, rate_hz)?;
                    // A fault during a probe ends the holds, named, as one during a window.
                    readings(&c)?;
                    probes[k].push(
                        c.samples
                            .iter()
                            .map(|s| crate::commissioning::ProbeSample {
                                y_m: f64::from(s.x_m),
                                u_v: f64::from(s.u_v),
                                i_a: f64::from(s.i_a),
                                vbus_v: f64::from(s.vbus_v),
                            })
                            .collect(),
                    );
                }
            }
            Ok(holds)
        };
        let holds = held();
        // A monitor that ended the holds: again with a slower loop, while attempts are left.
        let ended = holds
            .as_ref()
            .err()
            .and_then(|e| e.downcast_ref::<HoldsFault>())
            .map(|f| f.0.clone());
        match ended {
            Some(fault) if attempt + 1 < crate::commissioning::HOLD_ATTEMPTS => {
                link.done(Command::Clear)?;
                attempt += 1;
                let slower = crate::commissioning::hold_tuning(&m, attempt)?;
                writeln!(
                    out,
                    "  the holds ended by the fault {fault}: again with a slower loop (alpha {} 1/s, observer {} rad/s)",
                    sig(f64::from(slower.alpha_per_s), 3),
                    sig(f64::from(slower.observer_rad_s), 3)
                )?;
            }
            _ => break holds,
        }
    };
    // Whatever happened: the bridge off and the parameters in use before back.
    let disarmed = link.done(Command::Disarm);
    let loaded = link.done(if stored {
        Command::Load
    } else {
        Command::Defaults
    });
    let holds = holds?;
    disarmed?;
    loaded?;
    let line = crate::commissioning::Circuit::through_stops(report, &m);
    let inductances = probes.each_ref().map(|runs| {
        crate::commissioning::hold_inductance(runs, &probe, delay, 1.0 / rate_hz, report, line)
    });
    for (f, l) in crate::actuator::SEQUENCE.iter().zip(&inductances) {
        let line = match l {
            Some((x, l, spread)) => format!(
                "{} uH +- {} at {} mm",
                sig(l * 1e6, 4),
                sig(spread * 1e6, 2),
                sig(x * 1e3, 4)
            ),
            None => format!(
                "not read at the hold at {} mm (the current did not step, or the probes \
                 spread above {} %)",
                sig(f * stroke_m * 1e3, 3),
                100.0 * crate::commissioning::HOLD_PROBE_MAX_SPREAD
            ),
        };
        writeln!(out, "  inductance {line}")?;
    }
    let mechanics = Mechanics::fit(report, file, &holds, inductances);
    let c = mechanics.circuit;
    let n2 = f64::from(file.coil.turns).powi(2);
    let growth = if c.growth_per_m == 0.0 {
        "constant over the stroke (no growth beyond the readings' noise)".to_owned()
    } else {
        format!(
            "growing {} % from the closed stop to the open one",
            sig(100.0 * (c.surface_growth() - 1.0), 3)
        )
    };
    writeln!(
        out,
        "circuit fitted to the six inductances: rho_0 {} 1/H, rho_x {} 1/(H m) at a closed gap \
         ({} turns), the airgap's surface {growth}; within {} % of the holds' inductances",
        sig(c.iron_per_h * n2, 4),
        sig(c.gap_per_h_m * n2, 4),
        file.coil.turns,
        sig(100.0 * c.deviation(&inductances).unwrap_or(f64::NAN), 2)
    )?;
    let Mechanics {
        spring: s,
        armature,
        ..
    } = mechanics;
    for (x, f) in s.holds {
        writeln!(
            out,
            "  hold at {} mm: magnet's pull {} N",
            sig(x * 1e3, 4),
            sig(f, 4)
        )?;
    }
    writeln!(
        out,
        "spring rate {} N/m +- {} (two standard errors), preload {} N; the file says {} N/m, {} N",
        sig(s.n_per_m, 4),
        sig(s.spread_n_per_m, 2),
        sig(s.preload_n, 4),
        file.mechanics.spring_n_per_m,
        file.mechanics.preload_n
    )?;
    match armature {
        Some(arm) => writeln!(
            out,
            "mass {} kg, friction {} N s/m (the moves between the holds, {} fitted); the file says {} kg, {} N s/m",
            sig(arm.mass_kg, 4),
            sig(arm.friction_n_s_per_m, 3),
            arm.moves,
            file.mechanics.mass_kg,
            file.mechanics.friction_n_s_per_m
        )?,
        None => writeln!(
            out,
            "mass and friction not measured: every move came near a stop; the file's kept"
        )?,
    }
    Ok(mechanics)
}

/// How near the open stop's reading, as a share of the stroke, the armature must read on
/// five status polls in a row before [`measure_mechanics`]'s holds start.
const SPRING_START_SHARE: f32 = 0.01;

/// Drawn plants `commission --tune` validates the tuning on.
const TUNE_VALIDATION_DRAWS: usize = 100;

/// The parameters that carry a commissioned actuator `measured` on a board whose file is
/// `board`: the resistance, the spring and its preload, the mass and the friction, the
/// tolerances of these and of the surfaces, and the magnetic circuit in the board's own
/// form (its kind is fixed by the firmware build). A circuit measured in the board's form
/// is carried as it is; one in the two-inductance form (the stops' alone) on a board with
/// a pole geometry without spread, whose `1/L` is linear in the gap as the measured
/// one's, has the pole's sides scaled for the measured airgap reluctance (the fringing
/// coefficient kept) and the iron's reluctance set to the measured one.
///
/// # Errors
/// A two-inductance circuit for a board whose geometry has a fringing spread (its `1/L`
/// is not linear in the gap, so two inductances do not fix it), or a circuit in the
/// geometry form for a board in the two-inductance form.
pub fn commissioned_params(
    board: &Actuator,
    measured: &Actuator,
) -> anyhow::Result<Vec<(&'static str, f32)>> {
    let mut out = vec![
        ("coil.resistance_ohm", measured.coil.resistance_ohm),
        (
            "mechanics.spring_n_per_m",
            measured.mechanics.spring_n_per_m,
        ),
        ("mechanics.preload_n", measured.mechanics.preload_n),
        ("mechanics.mass_kg", measured.mechanics.mass_kg),
        (
            "mechanics.friction_n_s_per_m",
            measured.mechanics.friction_n_s_per_m,
        ),
        ("tolerance.surface", measured.tolerance.surface),
        ("tolerance.spring", measured.tolerance.spring),
        ("tolerance.mass", measured.tolerance.mass),
        ("tolerance.friction", measured.tolerance.friction),
    ];
    match (board.magnetics, measured.magnetics) {
        (Magnetics::Inductance { .. }, Magnetics::Inductance { open_h, closed_h }) => {
            out.push(("magnetics.inductance.open_h", open_h));
            out.push(("magnetics.inductance.closed_h", closed_h));
        }
        (
            Magnetics::Geometry { .. },
            Magnetics::Geometry {
                pole_a_m,
                pole_b_m,
                fringing_spread,
                iron_reluctance_per_h,
                ..
            },
        ) => {
            out.push(("magnetics.geometry.pole_a_m", pole_a_m));
            out.push(("magnetics.geometry.pole_b_m", pole_b_m));
            out.push(("magnetics.geometry.fringing_spread", fringing_spread));
            out.push((
                "magnetics.geometry.iron_reluctance_per_h",
                iron_reluctance_per_h,
            ));
        }
        (
            file @ Magnetics::Geometry {
                fringing_spread, ..
            },
            Magnetics::Inductance { open_h, closed_h },
        ) => {
            ensure!(
                fringing_spread == 0.0,
                "the board's magnetics.geometry.fringing_spread = {fringing_spread}: its 1/L is \
                 not linear in the gap and two inductances do not fix it; commission with the \
                 holds measured (--mechanics), whose fit gives the spread"
            );
            // The measured line in the board's form.
            let line = crate::commissioning::Circuit::line(
                f64::from(open_h),
                f64::from(closed_h),
                measured,
            );
            if let Magnetics::Geometry {
                pole_a_m,
                pole_b_m,
                iron_reluctance_per_h,
                ..
            } = line.geometry(measured.coil.turns, file)
            {
                out.push(("magnetics.geometry.pole_a_m", pole_a_m));
                out.push(("magnetics.geometry.pole_b_m", pole_b_m));
                out.push((
                    "magnetics.geometry.iron_reluctance_per_h",
                    iron_reluctance_per_h,
                ));
            }
        }
        (Magnetics::Inductance { .. }, Magnetics::Geometry { .. }) => bail!(
            "the commissioned circuit is in the geometry form and the board's in the \
             two-inductance form"
        ),
    }
    Ok(out)
}

/// The `set`s that carry a commissioned actuator `measured` ([`commissioned_params`]) and
/// a `tuning` on a board whose file is `board`.
///
/// # Errors
/// As [`commissioned_params`].
fn commissioned_sets(
    board: &Actuator,
    measured: &Actuator,
    tuning: &ema::control::actuator::Tuning,
) -> anyhow::Result<Vec<(&'static str, Value)>> {
    let mut sets: Vec<(&str, Value)> = commissioned_params(board, measured)?
        .into_iter()
        .map(|(k, v)| (k, Value::Number(v)))
        .collect();
    sets.extend([
        ("tuning.alpha_per_s", Value::Number(tuning.alpha_per_s)),
        (
            "tuning.observer_rad_s",
            Value::Number(tuning.observer_rad_s),
        ),
        ("tuning.margin", Value::Number(tuning.margin)),
        (
            "tuning.disturbance_follows_force",
            Value::Flag(tuning.disturbance_follows_force),
        ),
    ]);
    Ok(sets)
}

/// A fault the board latched during the holds of [`measure_mechanics`], by name.
#[derive(Debug)]
struct HoldsFault(String);

impl core::fmt::Display for HoldsFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "fault {} latched during the holds", self.0)
    }
}

impl std::error::Error for HoldsFault {}

/// Sets the commissioned actuator `measured` and its `tuning` on the board and saves
/// them; on a refusal the stored parameters are loaded back and nothing is saved.
fn apply_commissioned<P: Port>(
    link: &mut Link<P>,
    board: &Actuator,
    measured: &Actuator,
    tuning: &ema::control::actuator::Tuning,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    let sets = commissioned_sets(board, measured, tuning)?;
    if let Err(e) = set_all(link, &sets) {
        link.done(Command::Load)?;
        bail!("{e}; the stored parameters are loaded back, nothing saved");
    }
    for (name, value) in sets {
        writeln!(out, "{name} = {}", value_text(name, value))?;
    }
    save(link, out)
}

/// Sets every `(name, value)` on the board. The board validates each set with the rest
/// as they stand, so a valid whole can be refused halfway (a stiffer spring before the
/// stronger circuit that carries it): the refused ones are set again after the others,
/// pass after pass, for as long as a pass sets one.
///
/// # Errors
/// A pass that sets none (the board's refusal of the last one), or the link failing.
pub fn set_all<P: Port>(link: &mut Link<P>, sets: &[(&'static str, Value)]) -> anyhow::Result<()> {
    let mut pending = sets.to_vec();
    while !pending.is_empty() {
        let mut refused = Vec::new();
        let mut last = None;
        for (name, value) in &pending {
            match link.done(Command::Set {
                name,
                value: *value,
            }) {
                Ok(()) => {}
                Err(e) if e.downcast_ref::<super::link::Refused>().is_some() => {
                    refused.push((*name, *value));
                    last = Some(e);
                }
                Err(e) => return Err(e),
            }
        }
        if refused.len() == pending.len() {
            return Err(last.unwrap_or_else(|| anyhow!("nothing to set")));
        }
        pending = refused;
    }
    Ok(())
}

/// Stores the parameters in use; the board restarts with them.
///
/// # Errors
/// No restart, or the board's store failed (named).
fn save<P: Port>(link: &mut Link<P>, out: &mut dyn Write) -> anyhow::Result<()> {
    link.forget_started();
    link.done(Command::Save)?;
    let started = link.wait_started(Duration::from_secs(10))?;
    match started.saved {
        Some(Ok(())) => writeln!(
            out,
            "saved; the board restarted with the {}",
            super::source(&started.params)
        )?,
        Some(Err(e)) => bail!(
            "the save failed: {}; the board restarted with the {}",
            super::board::store_error(e),
            super::source(&started.params)
        ),
        None => bail!("the board restarted without saving"),
    }
    Ok(())
}

/// Why a save would destroy a stored set, if it would: the board fell back to its defaults
/// because its stored set is of a format this firmware cannot read (a later one), which a
/// save replaces.
#[must_use]
pub fn save_would_replace(source: &Source<'_>) -> Option<String> {
    match source {
        Source::Fallback(LoadError::Version { found, expected }) => Some(format!(
            "the board's stored set is of format {found}, which this firmware (format \
             {expected}) cannot read: saving replaces it. Back it up with the firmware that \
             wrote it (bench backup FILE), then `save --replace` or `restore FILE`"
        )),
        _ => None,
    }
}

/// The board's parameters `p` as a file: the actuator file, then the board's own tables
/// (`[setpoint]`, `[link]`), choices by name.
///
/// # Errors
/// The actuator does not serialise.
pub fn backup_text(p: &Params) -> anyhow::Result<String> {
    let mut text = format!(
        "# Every parameter of a board (bench backup): the actuator file, then the board's\n\
         # own [setpoint] and [link]. `bench restore` sets them all and saves.\n\n{}",
        toml::to_string(&p.actuator)?
    );
    for table in crate::actuator::BOARD_TABLES {
        text.push_str(&format!("\n[{table}]\n"));
        for info in params::all().filter(|i| i.name.starts_with(table)) {
            let key = &info.name[table.len() + 1..];
            let v = p
                .get(info.name)
                .map_err(|e| anyhow!("{}: {e:?}", info.name))?;
            let value = match v {
                Value::Choice(_) => format!("\"{}\"", value_text(info.name, v)),
                Value::Flag(b) => b.to_string(),
                Value::Number(x) => format!("{x:?}"),
            };
            text.push_str(&format!("{key} = {value}\n"));
        }
    }
    Ok(text)
}

/// The parameters in a file `backup_text` wrote (or a plain actuator file: the board's
/// tables then at their defaults), validated as the board validates them; `origin` names
/// it in errors.
///
/// # Errors
/// TOML that does not parse, an unknown or mistyped field (named), a value refused.
pub fn parse_backup(text: &str, origin: &str) -> anyhow::Result<Params> {
    let mut table: toml::Table = toml::from_str(text).with_context(|| origin.to_owned())?;
    let actuator = crate::actuator::parse(text, origin)?;
    let board_tables: Vec<(&str, Option<toml::Value>)> = crate::actuator::BOARD_TABLES
        .into_iter()
        .map(|t| (t, table.remove(t)))
        .collect();
    let mut p = Params::new(actuator);
    for (name, value) in board_tables {
        let Some(value) = value else { continue };
        let toml::Value::Table(fields) = value else {
            bail!("{origin}: [{name}] is not a table");
        };
        for (key, v) in fields {
            let full = format!("{name}.{key}");
            let text = match v {
                toml::Value::String(s) => s,
                other => other.to_string(),
            };
            let value = parse_value(&full, &text).with_context(|| origin.to_owned())?;
            p.set(&full, value)
                .map_err(|e| anyhow!("{origin}: {full}: {e:?}"))?;
        }
    }
    Ok(p)
}

/// Sets every parameter of `p` the link can change on the board ([`set_all`]); the
/// firmware's fixed ones (`board.rate_hz`, `magnetics.kind`) must already agree.
///
/// # Errors
/// A fixed parameter that differs, a refusal, the link failing.
pub fn restore<P: Port>(link: &mut Link<P>, p: &Params) -> anyhow::Result<()> {
    let mut sets = Vec::new();
    for info in params::all() {
        let Ok(v) = p.get(info.name) else { continue };
        if let Some(why) = info.fixed {
            let board = get(link, info.name)?;
            if board != v {
                bail!(
                    "{} is {} in the file and {} on the board, which cannot change it ({why})",
                    info.name,
                    value_text(info.name, v),
                    value_text(info.name, board)
                );
            }
            continue;
        }
        sets.push((info.name, v));
    }
    set_all(link, &sets)
}

/// Runs the commands of `input`, one per line, over `link` (see [`Verb::Console`]); a
/// line that does not parse or fails is reported and the next one runs. At the end of the
/// input an armed board is disarmed.
///
/// # Errors
/// The link failing at the end.
pub fn console<P: Port>(
    link: &mut Link<P>,
    input: impl std::io::BufRead,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    /// One line of the console.
    #[derive(Debug, Parser)]
    #[command(name = "", no_binary_name = true)]
    struct Line {
        #[command(subcommand)]
        verb: Verb,
    }
    for line in input.lines() {
        let line = line?;
        let words: Vec<&str> = line.split_whitespace().collect();
        if words.is_empty() || words[0].starts_with('#') {
            continue;
        }
        match Line::try_parse_from(&words) {
            Err(e) => writeln!(out, "{}", e.to_string().trim_end())?,
            Ok(Line {
                verb: Verb::Console | Verb::Virtual(_),
            }) => writeln!(out, "`{}` does not run inside a console", words[0])?,
            Ok(Line { verb }) => {
                if let Err(e) = run(link, verb, out) {
                    writeln!(out, "{}: {e:#}", words[0])?;
                }
            }
        }
    }
    if status(link)?.mode.armed() {
        link.done(Command::Disarm)?;
        writeln!(out, "end of input: disarmed")?;
    }
    Ok(())
}

/// The actuator file a commissioning gives: the measured actuator
/// ([`crate::commissioning::measured`], with the `mechanics` when measured), each measured
/// value and its uncertainty, and the end stops, in comments at its head.
///
/// # Errors
/// The file does not serialise or does not validate (the board measured values no
/// actuator can have).
pub fn actuator_file(
    file: &ema::control::actuator::Actuator,
    report: &Report,
    mechanics: Option<&Mechanics>,
) -> anyhow::Result<String> {
    let r = report.resistance;
    let l = report.inductance;
    let e = report.ends;
    let (a, moved) = crate::commissioning::measured(file, report, mechanics)?;
    let spring_head = mechanics.map_or(String::new(), |m| {
        let s = m.spring;
        let armature = m.armature.map_or(
            "#   mechanics.mass_kg and friction_n_s_per_m: the file's (no move to fit)\n"
                .to_owned(),
            |arm| {
                format!(
                    "#   mechanics.mass_kg = {}, mechanics.friction_n_s_per_m = {} (the {} moves \
                     between the holds),\n\
                     #   tolerance.mass = {}, tolerance.friction = {} (the measurement's, \
                     where below the file's)\n",
                    sig(arm.mass_kg, 4),
                    sig(arm.friction_n_s_per_m, 3),
                    arm.moves,
                    sig(f64::from(a.tolerance.mass), 3),
                    sig(f64::from(a.tolerance.friction), 3)
                )
            },
        );
        let probed: Vec<String> = m
            .inductances
            .iter()
            .flatten()
            .map(|(x, l, spread)| {
                format!(
                    "{} +- {} H at {} m",
                    sig(*l, 4),
                    sig(*spread, 2),
                    sig(*x, 4)
                )
            })
            .collect();
        let inductances = match m.form_deviation(&a) {
            Some(d) => format!(
                "#   inductance at the holds (probes, loop closed; two standard errors):\n\
                 #     {}\n\
                 #   the circuit below is fitted to them and the stops' (surface growth \
                 q = {} 1/m,\n\
                 #   the surface at the open stop {} % above the closed stop's); within {} % \
                 of the holds'\n\
                 #   (tolerance.surface = {})\n",
                probed.join(", "),
                sig(m.circuit.growth_per_m, 3),
                sig(100.0 * (m.circuit.surface_growth() - 1.0), 3),
                sig(100.0 * d, 2),
                a.tolerance.surface
            ),
            None => "#   inductance at the holds: no probe read one\n".to_owned(),
        };
        format!(
            "#   mechanics.spring_n_per_m = {} +- {} (two standard errors of the fit),\n\
             #   mechanics.preload_n = {} (closed-loop holds at four positions),\n\
             #   tolerance.spring = {} (the measurement's, where below the file's)\n\
             {armature}{inductances}",
            sig(s.n_per_m, 4),
            sig(s.spread_n_per_m, 2),
            sig(s.preload_n, 4),
            sig(f64::from(a.tolerance.spring), 3)
        )
    });
    let moved = if moved == 1.0 {
        String::new()
    } else {
        format!(
            "#   in the file's linear form each moved by {:.2} % (positive iron reluctance)\n",
            100.0 * (moved - 1.0).abs()
        )
    };
    let head = format!(
        "# Commissioned on the board (loop open, armature at rest):\n\
         #   coil.resistance_ohm = {} +- {} (two standard errors, converter noise)\n\
         #   inductance at the open stop {} H, at the closed stop {} H (step responses)\n\
         {moved}\
         #   position reading at the open stop {} m, at the closed stop {} m +- {} m\n\
         #   (in the calibration of this file's board.position_span_m)\n\
         {spring_head}\
         # Tune it before use: hil-sim tune <this file>\n",
        r.ohm, r.spread_ohm, l.open_h, l.closed_h, e.open_m, e.closed_m, e.spread_m
    );
    Ok(head + &toml::to_string(&a)?)
}

/// A status as the `status` command prints it.
#[must_use]
pub fn status_text(s: &Status<'_>) -> String {
    let mut t = Table::new(["", ""]);
    let row = |t: &mut Table, k: &str, v: String| t.push([k.to_owned(), v]);
    row(
        &mut t,
        "firmware",
        format!("ema {} ({})", s.build.version, s.build.id),
    );
    row(&mut t, "state", s.mode.name().into());
    row(
        &mut t,
        "latched fault",
        s.fault.map_or("none".into(), fault_name),
    );
    row(
        &mut t,
        "arming",
        s.not_ready
            .map_or("possible".into(), |f| format!("refused: {}", fault_name(f))),
    );
    let counts: Vec<String> = s
        .fault_counts
        .iter()
        .enumerate()
        .filter(|(_, &n)| n > 0)
        .map(|(k, n)| format!("{} x{n}", fault_name(u8::try_from(k + 1).unwrap_or(0))))
        .collect();
    row(
        &mut t,
        "faults since start",
        if counts.is_empty() {
            "none".into()
        } else {
            counts.join(", ")
        },
    );
    row(
        &mut t,
        "position",
        format!("{} mm", sig(f64::from(s.x_m) * 1e3, 4)),
    );
    row(
        &mut t,
        "set point",
        format!("{} mm", sig(f64::from(s.setpoint_m) * 1e3, 4)),
    );
    row(
        &mut t,
        "coil current",
        format!("{} A", sig(f64::from(s.i_a), 3)),
    );
    row(
        &mut t,
        "bus voltage",
        format!("{} V", sig(f64::from(s.vbus_v), 4)),
    );
    row(
        &mut t,
        "cycles per tick",
        if s.isr_cycles_max == 0 {
            "not measured (virtual board)".into()
        } else {
            format!("mean {} max {}", s.isr_cycles_mean, s.isr_cycles_max)
        },
    );
    row(&mut t, "overruns", s.overruns.to_string());
    row(&mut t, "ticks", s.ticks.to_string());
    row(
        &mut t,
        "parameters",
        format!(
            "{}{}",
            super::source(&s.params),
            if s.unsaved {
                ", changed since (unsaved)"
            } else {
                ""
            }
        ),
    );
    row(
        &mut t,
        "capture",
        match s.capture {
            CaptureState::Idle => "none".into(),
            CaptureState::Waiting => "waiting for a move".into(),
            CaptureState::Running(n) => format!("recording ({n} samples)"),
            CaptureState::Done(n) => format!("{n} samples ready"),
        },
    );
    row(
        &mut t,
        "link",
        format!(
            "{} frames rejected, {} telemetry samples dropped",
            s.frames_rejected, s.telemetry_dropped
        ),
    );
    t.to_text()
}

/// A parameter's value.
///
/// # Errors
/// A refusal (described), or no reply.
pub fn get<P: Port>(link: &mut Link<P>, name: &str) -> anyhow::Result<Value> {
    let f = link.request(Command::Get { name })?;
    let mut scratch = Vec::new();
    match f.message(&mut scratch)? {
        Message::Reply {
            reply: Reply::Value(v),
            ..
        } => Ok(v),
        Message::Reply {
            reply: Reply::Refused(r),
            ..
        } => Err(anyhow!("{}", super::refusal(&r))),
        other => Err(anyhow!("unexpected reply: {other:?}")),
    }
}

/// Every parameter of the board, read one by one.
///
/// # Errors
/// As [`get`].
pub fn read_params<P: Port>(link: &mut Link<P>) -> anyhow::Result<Params> {
    let kind = get(link, "magnetics.kind")?;
    let mut a = Actuator::PRODUCT;
    if kind == Value::Choice(1) {
        a.magnetics = Magnetics::Inductance {
            open_h: 1.0,
            closed_h: 2.0,
        };
    }
    let mut p = Params::new(a);
    for info in params::all() {
        if info.fixed.is_some() || matches!(p.get(info.name), Err(params::Refused::Unused)) {
            continue;
        }
        let v = get(link, info.name)?;
        p.set(info.name, v)
            .map_err(|e| anyhow!("{}: {e:?}", info.name))?;
    }
    if let Value::Number(r) = get(link, "board.rate_hz")? {
        p.actuator.board.rate_hz = r;
    }
    Ok(p)
}

/// A value as text, choices by name.
#[must_use]
pub fn value_text(name: &str, v: Value) -> String {
    match (params::info(name).map(|i| i.kind), v) {
        (Some(Kind::Choice(names)), Value::Choice(c)) => names
            .get(usize::from(c))
            .map_or_else(|| format!("choice {c}"), |s| (*s).to_owned()),
        (_, v) => v.to_string(),
    }
}

/// Parses a value for the parameter `name`.
///
/// # Errors
/// An unknown name, or text that is not a value of its kind.
pub fn parse_value(name: &str, text: &str) -> anyhow::Result<Value> {
    let info = params::info(name).ok_or_else(|| anyhow!("no parameter is called `{name}`"))?;
    Ok(match info.kind {
        Kind::Number => Value::Number(
            text.parse::<f32>()
                .map_err(|_| anyhow!("{name}: `{text}` is not a number"))?,
        ),
        Kind::Flag => Value::Flag(
            text.parse::<bool>()
                .map_err(|_| anyhow!("{name}: `{text}` is not true or false"))?,
        ),
        Kind::Choice(names) => {
            let k = names
                .iter()
                .position(|n| *n == text)
                .ok_or_else(|| anyhow!("{name}: `{text}` is none of {}", names.join(", ")))?;
            Value::Choice(u8::try_from(k)?)
        }
    })
}

fn signal_mask(names: &[String]) -> anyhow::Result<(u16, Vec<Signal>)> {
    let mut mask = 0;
    let mut chosen = Vec::new();
    for n in names {
        let s = Signal::ALL
            .into_iter()
            .find(|s| s.name() == n)
            .ok_or_else(|| anyhow!("no signal is called `{n}`"))?;
        mask |= s.bit();
    }
    for s in Signal::ALL {
        if mask & s.bit() != 0 {
            chosen.push(s);
        }
    }
    Ok((mask, chosen))
}

fn watch<P: Port>(link: &mut Link<P>, a: &WatchArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let (mask, chosen) = signal_mask(&a.signals)?;
    link.done(Command::Stream {
        signals: mask,
        decimation: a.decimation,
    })?;
    let bar = indicatif::ProgressBar::new((a.seconds * 1000.0) as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {elapsed:>4} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let mut frames = 0u64;
    let mut last = String::new();
    while start.elapsed().as_secs_f64() < a.seconds {
        link.pump()?;
        for t in link.telemetry() {
            frames += 1;
            let values: Vec<String> = chosen
                .iter()
                .zip(t.values.iter())
                .map(|(s, v)| format!("{} {}", s.name(), sig(f64::from(*v), 4)))
                .collect();
            last = format!(
                "{} {}{}",
                Mode::from_code(t.mode).map_or("?", Mode::name),
                values.join("  "),
                if t.fault == 0 {
                    String::new()
                } else {
                    format!("  fault {}", fault_name(t.fault))
                }
            );
            bar.set_message(last.clone());
        }
        bar.set_position(start.elapsed().as_millis() as u64);
    }
    bar.finish_and_clear();
    link.done(Command::Stream {
        signals: 0,
        decimation: 0,
    })?;
    writeln!(out, "{frames} telemetry frames; last: {last}")?;
    Ok(())
}

/// What `capture` measured and wrote.
#[derive(Clone, Debug)]
pub struct CaptureOutcome {
    /// The capture.
    pub capture: Capture,
    /// The simulator's metrics of the capture.
    pub board: crate::Metrics,
    /// The simulator's metrics of its prediction, on the same samples.
    pub simulator: crate::Metrics,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Captures `samples` readings, one every `decimation` ticks, of a move to `position_m`
/// (the board armed; `time_s` the move's duration, the board's shaping if `None`), or
/// from now without a move (`to` is `None`), and reads the capture back.
///
/// # Errors
/// A refusal, no reply, a capture that does not finish.
fn capture_move<P: Port>(
    link: &mut Link<P>,
    samples: u16,
    decimation: u16,
    to: Option<(f32, Option<f32>)>,
    rate_hz: f64,
) -> anyhow::Result<Capture> {
    link.done(Command::Capture {
        samples,
        decimation,
        trigger: if to.is_some() {
            Trigger::Move
        } else {
            Trigger::Now
        },
    })?;
    if let Some((position_m, time_s)) = to {
        link.done(Command::Move { position_m, time_s })?;
    }
    read_capture(link, samples, decimation, rate_hz)
}

/// Waits for the capture started (`samples` every `decimation` ticks) to finish and reads
/// it back.
///
/// # Errors
/// A refusal, no reply, a capture that does not finish.
fn read_capture<P: Port>(
    link: &mut Link<P>,
    samples: u16,
    decimation: u16,
    rate_hz: f64,
) -> anyhow::Result<Capture> {
    let span_s = f64::from(samples) * f64::from(decimation) / rate_hz;
    let deadline = Instant::now() + Duration::from_secs_f64(10.0 * span_s + 5.0);
    let total = loop {
        match status(link)?.capture {
            CaptureState::Done(n) => break n,
            _ if Instant::now() > deadline => bail!("the capture did not finish"),
            _ => std::thread::sleep(Duration::from_millis(20)),
        }
    };
    let mut chunks = Vec::new();
    let mut offset = 0u16;
    while offset < total {
        let f = link.request(Command::ReadCapture { offset })?;
        let mut scratch = Vec::new();
        match f.message(&mut scratch)? {
            Message::Reply {
                reply: Reply::Capture(c),
                ..
            } => chunks.push(c),
            Message::Reply {
                reply: Reply::Refused(r),
                ..
            } => bail!("refused: {}", super::refusal(&r)),
            other => bail!("unexpected reply: {other:?}"),
        }
        offset = offset.saturating_add(CHUNK_SAMPLES as u16);
    }
    Capture::from_chunks(&chunks).ok_or_else(|| anyhow!("empty capture"))
}

/// Captures a move (the board must be armed) and compares it with the prediction.
///
/// # Errors
/// A refusal, no reply, a capture that does not finish, files that cannot be written.
pub fn capture<P: Port>(
    link: &mut Link<P>,
    a: &CaptureArgs,
    out: &mut dyn Write,
) -> anyhow::Result<CaptureOutcome> {
    let s = status(link)?;
    if !s.mode.armed() {
        bail!("the board is {}: arm it first", s.mode.name());
    }
    let params = read_params(link)?;
    let rate = f64::from(params.actuator.board.rate_hz);
    let span_s = f64::from(a.samples) * f64::from(a.decimation) / rate;
    let capture = capture_move(
        link,
        a.samples,
        a.decimation,
        Some(((a.position_mm * 1e-3) as f32, a.time_s.map(|t| t as f32))),
        rate,
    )?;
    let (sc, run) = super::prediction(&params, &capture, a.noise)?;
    let board = super::capture_metrics(&sc, &capture);
    let simulator = super::prediction_metrics(&sc, &run, &capture);
    let at_s = match sc.reference {
        crate::scenario::Reference::Step { at_s, .. } => at_s,
        _ => 0.0,
    };
    let predicted = super::prediction_samples(&run, &capture, at_s, rate);

    report::create_dir(&a.out)?;
    let csv = a.out.join("capture.csv");
    let mut t = Table::new([
        "t_s", "r_m", "x_m", "v_mps", "i_a", "u_v", "duty", "fault", "sim_x_m", "sim_i_a",
        "sim_u_v",
    ]);
    for (k, s) in capture.samples.iter().enumerate() {
        let p = predicted.get(k).copied().unwrap_or_default();
        t.push([
            format!("{}", capture.t_s(k, rate)),
            s.r_m.to_string(),
            s.x_m.to_string(),
            s.v_mps.to_string(),
            s.i_a.to_string(),
            s.u_v.to_string(),
            s.duty.to_string(),
            s.fault.to_string(),
            p.x_m.to_string(),
            p.i_a.to_string(),
            p.u_v.to_string(),
        ]);
    }
    t.write_csv(&csv)?;
    // The board does not measure the supply's current: the energy is not reported.
    let metrics = report::metrics_table(&[("board", &board), ("simulator", &simulator)])
        .without("energy [J]");
    let metrics_csv = a.out.join("metrics.csv");
    metrics.write_csv(&metrics_csv)?;
    let pts = |f: &dyn Fn(&ema::device::protocol::Sample) -> f64,
               v: &[ema::device::protocol::Sample]| {
        v.iter()
            .enumerate()
            .map(|(k, s)| (capture.t_s(k, rate), f(s)))
            .collect::<Vec<_>>()
    };
    let png = a.out.join("capture.png");
    Figure::new(format!(
        "step response {} -> {} mm: board and simulator",
        sig(f64::from(capture.from_m) * 1e3, 4),
        sig(f64::from(capture.to_m) * 1e3, 4)
    ))
    .panel(
        Panel::new("time from the move [s]", "position [mm]")
            .series(
                Series::line(
                    "x, board",
                    pts(&|s| f64::from(s.x_m) * 1e3, &capture.samples),
                )
                .color(0),
            )
            .series(
                Series::dashed("x, simulator", pts(&|s| f64::from(s.x_m) * 1e3, &predicted))
                    .color(1),
            )
            .series(
                Series::dashed(
                    "reference",
                    pts(&|s| f64::from(s.r_m) * 1e3, &capture.samples),
                )
                .color(7),
            ),
    )
    .panel(
        Panel::new("time from the move [s]", "coil current [A]")
            .series(Series::line("i, board", pts(&|s| f64::from(s.i_a), &capture.samples)).color(0))
            .series(
                Series::dashed("i, simulator", pts(&|s| f64::from(s.i_a), &predicted)).color(1),
            ),
    )
    .panel(
        Panel::new("time from the move [s]", "coil voltage [V]")
            .series(Series::line("u, board", pts(&|s| f64::from(s.u_v), &capture.samples)).color(0))
            .series(
                Series::dashed("u, simulator", pts(&|s| f64::from(s.u_v), &predicted)).color(1),
            ),
    )
    .write_png(&png)?;
    writeln!(
        out,
        "captured {} samples, one every {} ticks ({} s), move {} -> {} mm planned over {} s",
        capture.samples.len(),
        capture.decimation,
        sig(span_s, 4),
        sig(f64::from(capture.from_m) * 1e3, 4),
        sig(f64::from(capture.to_m) * 1e3, 4),
        sig(f64::from(capture.move_s), 4)
    )?;
    write!(out, "{}", metrics.transposed().to_text())?;
    let files = vec![csv, metrics_csv, png];
    writeln!(out, "\nwrote:")?;
    for f in &files {
        writeln!(out, "  {}", f.display())?;
    }
    Ok(CaptureOutcome {
        capture,
        board,
        simulator,
        files,
    })
}

/// What the virtual board's standard input takes.
const INJECTIONS: &str = "supply V, position-open, position-ok, analog-v V, analog-ma MA, \
                          cut-save STEP, resistance OHM, surfaces SCALE, \
                          spring N_PER_M PRELOAD_N, \
                          mechanics MASS_KG N_PER_M PRELOAD_N FRICTION_N_S_PER_M, \
                          hang-main, run-main";

/// A line of the virtual board's standard input, as an injection on a board whose
/// actuator's file is `file` (a spring keeps its mass and friction).
fn injection(line: &str, file: &Actuator) -> Option<Result<Injection, String>> {
    let mut words = line.split_whitespace();
    let verb = words.next()?;
    if verb == "mechanics" {
        let v: Vec<f64> = words.map_while(|w| w.parse().ok()).collect();
        return Some(match v[..] {
            [mass_kg, spring_n_per_m, preload_n, friction_n_s_per_m]
                if mass_kg > 0.0 && spring_n_per_m >= 0.0 && friction_n_s_per_m >= 0.0 =>
            {
                Ok(Injection::Mechanics {
                    mass_kg,
                    spring_n_per_m,
                    preload_n,
                    friction_n_s_per_m,
                })
            }
            _ => Err(format!(
                "`{line}`: mechanics takes four numbers, the mass above zero, the spring and \
                 the friction not below ({INJECTIONS})"
            )),
        });
    }
    let arg = words.next().map(str::parse::<f64>);
    let second = words.next().map(str::parse::<f64>);
    if let ("spring", Some(Ok(k)), Some(Ok(f0))) = (verb, &arg, &second) {
        return Some(Ok(Injection::Mechanics {
            mass_kg: f64::from(file.mechanics.mass_kg),
            spring_n_per_m: *k,
            preload_n: *f0,
            friction_n_s_per_m: f64::from(file.mechanics.friction_n_s_per_m),
        }));
    }
    Some(match (verb, arg) {
        ("supply", Some(Ok(v))) => Ok(Injection::Supply(v)),
        ("position-open", None) => Ok(Injection::PositionOpen(true)),
        ("position-ok", None) => Ok(Injection::PositionOpen(false)),
        ("analog-v", Some(Ok(v))) => Ok(Injection::Analog {
            value: v,
            current: false,
        }),
        ("analog-ma", Some(Ok(v))) => Ok(Injection::Analog {
            value: v * 1e-3,
            current: true,
        }),
        ("cut-save", Some(Ok(v))) => Ok(Injection::CutSave(v as u64)),
        ("resistance", Some(Ok(v))) => Ok(Injection::Resistance(v)),
        ("surfaces", Some(Ok(v))) => Ok(Injection::Surfaces(v)),
        ("hang-main", None) => Ok(Injection::HangMainLoop(true)),
        ("run-main", None) => Ok(Injection::HangMainLoop(false)),
        _ => Err(format!("unknown: `{line}` ({INJECTIONS})")),
    })
}

fn run_virtual(a: &VirtualArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let actuator = match &a.actuator {
        Some(name) => crate::actuator::load(name)?.1,
        None => Actuator::PRODUCT,
    };
    // As fast as it can, the board's ticks outrun a host's heartbeat paced in real time:
    // its link timeout is off then (see `Options::link`).
    let link = if a.speed > 0.0 {
        ema::device::liveness::Settings::default()
    } else {
        ema::device::liveness::Settings {
            timeout_s: 0.0,
            ..ema::device::liveness::Settings::default()
        }
    };
    let mut board = VirtualBoard::new(Options {
        actuator,
        noise: a.noise,
        link,
        ..Options::default()
    })?;
    let (mut master, slave) =
        serialport::TTYPort::pair().context("cannot open a pseudo-terminal")?;
    master.set_timeout(Duration::from_millis(1))?;
    let path = slave
        .name()
        .ok_or_else(|| anyhow!("the pseudo-terminal has no name"))?;
    if let Some(link) = &a.link {
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(&path, link)
            .with_context(|| format!("cannot link {}", link.display()))?;
    }
    writeln!(
        out,
        "virtual board on {path}: {} at {} Hz, {}; injections on standard input ({INJECTIONS})",
        a.actuator.as_deref().unwrap_or("the product's actuator"),
        board.scenario().rate_hz(),
        if a.speed > 0.0 {
            format!(
                "{} x real time, link.timeout_s {} s",
                a.speed, link.timeout_s
            )
        } else {
            "as fast as it can, link.timeout_s off".into()
        }
    )?;
    out.flush()?;
    let (tx, rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let stop = AtomicBool::new(false);
    let speed = (a.speed > 0.0).then_some(a.speed);
    board.serve(&mut master, speed, &stop, |b| {
        while let Ok(line) = rx.try_recv() {
            match injection(&line, &actuator) {
                Some(Ok(i)) => {
                    eprintln!("virtual board: {i:?}");
                    b.inject(i);
                }
                Some(Err(e)) => eprintln!("virtual board: {e}"),
                None => {}
            }
        }
    })?;
    drop(slave);
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

    /// A commissioning without the holds measures two inductances; a board whose file
    /// gives a pole geometry gets them as its sides and iron: the board's circuit then
    /// has the measured inductances at both stops, within 1e-5.
    #[test]
    fn two_measured_inductances_reach_a_geometry_board_as_its_sides_and_iron() {
        let board = Actuator::PRODUCT;
        let nominal = board.plant().unwrap();
        let at = |p: &ema::control::model::Plant, x: f32| p.magnetics.inductance_h(p.gap_m(x));
        let stroke = board.mechanics.stroke_m;
        let measured = Actuator {
            magnetics: Magnetics::Inductance {
                open_h: 1.1 * at(&nominal, 0.0),
                closed_h: 0.95 * at(&nominal, stroke),
            },
            ..board
        };
        let mut got = board;
        for (name, value) in commissioned_params(&board, &measured).unwrap() {
            if let Magnetics::Geometry {
                pole_a_m,
                pole_b_m,
                iron_reluctance_per_h,
                ..
            } = &mut got.magnetics
            {
                match name {
                    "magnetics.geometry.pole_a_m" => *pole_a_m = value,
                    "magnetics.geometry.pole_b_m" => *pole_b_m = value,
                    "magnetics.geometry.iron_reluctance_per_h" => *iron_reluctance_per_h = value,
                    _ => {}
                }
            }
        }
        let (want, have) = (measured.plant().unwrap(), got.plant().unwrap());
        for x in [0.0, stroke] {
            let error = at(&have, x) / at(&want, x) - 1.0;
            assert!(error.abs() < 1e-5, "at {x} m: {error}");
        }
    }

    #[test]
    fn the_virtual_boards_mechanics_injection_takes_four_numbers_and_refuses_a_massless_one() {
        let got = injection("mechanics 0.085 150 0.06 6", &Actuator::PRODUCT);
        assert_eq!(
            got,
            Some(Ok(Injection::Mechanics {
                mass_kg: 0.085,
                spring_n_per_m: 150.0,
                preload_n: 0.06,
                friction_n_s_per_m: 6.0,
            }))
        );
        for bad in [
            "mechanics 0.085 150 0.06",
            "mechanics 0 150 0.06 6",
            "mechanics 0.085 x 150 0.06 6",
        ] {
            let Some(Err(e)) = injection(bad, &Actuator::PRODUCT) else {
                panic!("`{bad}` accepted");
            };
            assert!(e.contains("mechanics takes four numbers"), "{e}");
        }
        // `spring` keeps the file's mass and friction.
        let Some(Ok(Injection::Mechanics { mass_kg, .. })) =
            injection("spring 150 0.06", &Actuator::PRODUCT)
        else {
            panic!("spring refused");
        };
        assert_eq!(mass_kg, f64::from(Actuator::PRODUCT.mechanics.mass_kg));
    }
}
