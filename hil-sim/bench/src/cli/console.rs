//! The `console` verb: commands read one per line and run over one link.

use std::io::Write;

use clap::Parser;
use ema::device::protocol::Command;

use super::{run, status, Verb};
use crate::link::{Link, Port};

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
