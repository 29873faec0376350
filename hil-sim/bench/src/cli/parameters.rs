//! Parameters over the link: one read or set, all of them read or set, saved, backed up and
//! restored, their values as text.

use std::io::Write;
use std::time::Duration;

use anyhow::{anyhow, bail, Context};
use ema::control::actuator::{Actuator, Magnetics};
use ema::device::params::{self, Kind, Params};
use ema::device::protocol::{Command, LoadError, Message, Reply, Source, Value};

use crate::link::{Link, Port};

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
                Err(e) if e.downcast_ref::<crate::link::Refused>().is_some() => {
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
pub(super) fn save<P: Port>(link: &mut Link<P>, out: &mut dyn Write) -> anyhow::Result<()> {
    link.forget_started();
    link.done(Command::Save)?;
    let started = link.wait_started(Duration::from_secs(10))?;
    match started.saved {
        Some(Ok(())) => writeln!(
            out,
            "saved; the board restarted with the {}",
            crate::source(&started.params)
        )?,
        Some(Err(e)) => bail!(
            "the save failed: {}; the board restarted with the {}",
            crate::board::store_error(e),
            crate::source(&started.params)
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
    for table in hil_sim::simulation::actuator::BOARD_TABLES {
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
    let actuator = hil_sim::simulation::actuator::parse(text, origin)?;
    let board_tables: Vec<(&str, Option<toml::Value>)> =
        hil_sim::simulation::actuator::BOARD_TABLES
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
        } => Err(anyhow!("{}", crate::refusal(&r))),
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
