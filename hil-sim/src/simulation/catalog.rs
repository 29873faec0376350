//! Scenario files: the embedded defaults (`hil-sim/scenarios/*.toml`, compiled in), and
//! loading a scenario by name or from a TOML file with every check done up front.
//!
//! A scenario file is a [`Scenario`] in TOML, units in the field names, the optional
//! sections listed in [`Scenario`]'s documentation. [`load`] refuses, before anything
//! runs or is written:
//!
//! * TOML that does not parse, an unknown field, a missing field or a wrong type (toml's
//!   message, with the line and the field);
//! * a parameter the simulator or the core refuses ([`preflight`]): named with its dotted
//!   path and its value, e.g. `plant.mass_kg = -0.1: must be finite and positive`, or
//!   `controller: alpha2 = 10: Theorem 1 ...` for the core's checks (the core names its
//!   fields relative to `controller`).
//!
//! ```
//! let sc = hil_sim::simulation::catalog::load("paper-20khz").unwrap();
//! assert_eq!(sc.rate_hz(), 20_000.0);
//! let bad = hil_sim::simulation::catalog::parse("duration_s = -1.0", "inline");
//! assert!(bad.is_err());
//! ```

use std::fmt;
use std::path::Path;

pub use crate::simulation::files::{summary, LoadError};
use crate::simulation::hal;
use crate::simulation::scenario::Scenario;

/// An embedded scenario file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Entry {
    /// Name, as given on the command line (the file's stem).
    pub name: &'static str,
    /// The file's text.
    pub text: &'static str,
}

impl Entry {
    /// The first line of the file's leading comment: what the scenario is.
    #[must_use]
    pub fn summary(&self) -> &'static str {
        summary(self.text)
    }
}

/// The embedded scenarios, in the order `hil-sim scenarios` lists them.
pub const EMBEDDED: [Entry; 4] = [
    Entry {
        name: "paper",
        text: include_str!("../../scenarios/paper.toml"),
    },
    Entry {
        name: "paper-20khz",
        text: include_str!("../../scenarios/paper-20khz.toml"),
    },
    Entry {
        name: "product",
        text: include_str!("../../scenarios/product.toml"),
    },
    Entry {
        name: "product-sequence",
        text: include_str!("../../scenarios/product-sequence.toml"),
    },
];

/// The embedded scenario called `name`.
#[must_use]
pub fn embedded(name: &str) -> Option<&'static Entry> {
    EMBEDDED.iter().find(|e| e.name == name)
}

// (`LoadError` is defined in `files`, below the actuator files; its message names the
// embedded scenarios.)
impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoadError::NotFound { what, io } => {
                let names: Vec<&str> = EMBEDDED.iter().map(|e| e.name).collect();
                write!(
                    f,
                    "no scenario `{what}`: not an embedded one ({}) and not a readable file \
                     ({io})",
                    names.join(", ")
                )
            }
            LoadError::Toml { origin, message } => {
                write!(f, "scenario {origin}: {}", message.trim_end())
            }
            LoadError::Invalid { origin, error } => write!(f, "scenario {origin}: {error}"),
        }
    }
}

impl std::error::Error for LoadError {}

/// Loads a scenario by embedded name (see [`EMBEDDED`]), an actuator of the family by
/// name (its evaluation scenario, [`crate::simulation::actuator::scenario`], with its tuned
/// gains), or a TOML file, scenario or actuator (an actuator file has a `[mechanics]`
/// table), and checks it ([`preflight`]). A scenario file without a `name` is named after
/// its stem.
///
/// # Errors
/// See [`LoadError`].
pub fn load(name_or_path: &str) -> Result<Scenario, LoadError> {
    if let Some(e) = embedded(name_or_path) {
        return parse_named(e.text, e.name, e.name);
    }
    if let Some(e) = crate::simulation::actuator::member(name_or_path) {
        return from_actuator(e.tuned, e.name, e.name);
    }
    let path = Path::new(name_or_path);
    let text = std::fs::read_to_string(path).map_err(|e| LoadError::NotFound {
        what: name_or_path.to_owned(),
        io: e.to_string(),
    })?;
    let origin = path.display().to_string();
    if crate::simulation::actuator::is_actuator_text(&text) {
        return from_actuator(&text, &origin, &crate::simulation::actuator::stem(path));
    }
    let stem = path
        .file_stem()
        .map_or_else(|| "scenario".into(), |s| s.to_string_lossy().into_owned());
    parse_named(&text, &origin, &stem)
}

/// An actuator (a family member's tuned file or an actuator file) judged at another
/// interrupt rate: its evaluation scenario with every setting derived again at `rate_hz`
/// (the tuned gains kept). A scenario file is refused: its settings are its own.
///
/// # Errors
/// See [`LoadError`]; a scenario file is [`LoadError::Invalid`] naming `rate_hz`.
pub fn load_at_rate(name_or_path: &str, rate_hz: f64) -> Result<Scenario, LoadError> {
    let path = Path::new(name_or_path);
    let is_member = crate::simulation::actuator::member(name_or_path).is_some();
    if !is_member {
        let is_scenario = match embedded(name_or_path) {
            Some(_) => true,
            None => {
                let text = std::fs::read_to_string(path).map_err(|e| LoadError::NotFound {
                    what: name_or_path.to_owned(),
                    io: e.to_string(),
                })?;
                !crate::simulation::actuator::is_actuator_text(&text)
            }
        };
        if is_scenario {
            return Err(LoadError::Invalid {
                origin: path.display().to_string(),
                error: crate::simulation::Error::param(
                    "rate_hz",
                    rate_hz,
                    "another rate applies to an actuator (a family member or an actuator \
                     file); a scenario's settings are its own",
                ),
            });
        }
    }
    let (name, act) = crate::simulation::actuator::load(name_or_path)?;
    #[expect(clippy::cast_possible_truncation)]
    let act = act.with_rate_hz(rate_hz as f32);
    checked(&act, name_or_path, &name)
}

/// An actuator file's evaluation scenario ([`crate::simulation::actuator::scenario`]), checked.
fn from_actuator(text: &str, origin: &str, name: &str) -> Result<Scenario, LoadError> {
    let act = crate::simulation::actuator::parse(text, origin)?;
    checked(&act, origin, name)
}

/// An actuator's evaluation scenario, checked.
fn checked(
    act: &ema::control::actuator::Actuator,
    origin: &str,
    name: &str,
) -> Result<Scenario, LoadError> {
    let invalid = |error| LoadError::Invalid {
        origin: origin.to_owned(),
        error,
    };
    let sc = crate::simulation::actuator::scenario(name, act).map_err(invalid)?;
    preflight(&sc).map_err(invalid)?;
    Ok(sc)
}

/// Parses and checks scenario TOML; `origin` names it in errors.
///
/// # Errors
/// See [`LoadError`].
pub fn parse(text: &str, origin: &str) -> Result<Scenario, LoadError> {
    parse_named(text, origin, "scenario")
}

fn parse_named(text: &str, origin: &str, default_name: &str) -> Result<Scenario, LoadError> {
    let mut sc: Scenario = toml::from_str(text).map_err(|e| LoadError::Toml {
        origin: origin.to_owned(),
        message: with_field(text, &e),
    })?;
    if sc.name.is_empty() {
        default_name.clone_into(&mut sc.name);
    }
    preflight(&sc).map_err(|error| LoadError::Invalid {
        origin: origin.to_owned(),
        error,
    })?;
    Ok(sc)
}

/// toml's message, plus the offending line when toml could only point at its table (a
/// wrong type inside a tagged section such as `[plant]` is reported at the table's
/// header): the first line of that table whose value is the one refused.
fn with_field(text: &str, e: &toml::de::Error) -> String {
    let message = e.to_string();
    let Some(found) = e
        .message()
        .strip_prefix("invalid type: ")
        .and_then(|m| m.split_once(", expected"))
        .map(|(found, _)| found)
    else {
        return message;
    };
    // `string "heavy"`, `integer `5``, `floating point `1.5``, `boolean `true``.
    let value = found
        .split_once(' ')
        .map_or(found, |(_, v)| v)
        .trim_start_matches("point ")
        .trim_matches('`');
    // 1-based line of the span's start.
    let start = e.span().map_or(0, |span| {
        text.get(..span.start)
            .map_or(0, |t| t.matches('\n').count() + 1)
    });
    let hit = text
        .lines()
        .enumerate()
        .skip(start.saturating_sub(1))
        .take_while(|(k, l)| *k + 1 == start || !l.trim_start().starts_with('['))
        .find(|(_, l)| {
            l.split_once('=')
                .is_some_and(|(_, v)| v.split('#').next().is_some_and(|v| v.trim() == value))
        });
    match hit {
        Some((k, line)) if k + 1 != start => {
            format!(
                "{}\nthe value is at line {}: {}",
                message.trim_end(),
                k + 1,
                line.trim()
            )
        }
        _ => message,
    }
}

/// Everything that can be checked without running: the supply against the controller's
/// bus channel and bus window (a supply outside either makes the first tick read a
/// broken sensor or trip), [`Scenario::validate`], the controller settings
/// (`ema::control::Settings::build`, Theorem 1 included), the true plant and the
/// controller's envelope. [`crate::simulation::sim::run`] repeats the last three; a loader
/// calls this first so that nothing is written for a scenario that cannot run.
///
/// # Errors
/// The first refused parameter, by name, with its value.
pub fn preflight(sc: &Scenario) -> Result<(), crate::simulation::Error> {
    sc.supply.validate()?;
    let v = sc.supply.voltage_v;
    let (_, channel_max) = hal::channel_span(&sc.controller.sense.vbus);
    if v >= channel_max {
        return Err(crate::simulation::Error::param(
            "supply.voltage_v",
            v,
            format!(
                "above the {channel_max:.1} V the controller's bus channel reads \
                 (controller.sense.vbus); raise its scale or lower the supply"
            ),
        ));
    }
    let limits = &sc.controller.limits;
    let (lo, hi) = (f64::from(limits.vbus_min_v), f64::from(limits.vbus_max_v));
    if !(lo..=hi).contains(&v) {
        return Err(crate::simulation::Error::param(
            "supply.voltage_v",
            v,
            format!(
                "outside the controller's bus window {lo} to {hi} V \
                 (controller.limits.vbus_min_v, vbus_max_v): the supervisor would trip at \
                 the first tick"
            ),
        ));
    }
    sc.validate()?;
    sc.controller.build()?;
    let plant = sc.plant.resolve(&sc.controller.plant);
    plant.validate()?;
    crate::simulation::metrics::bounds_check(&sc.controller.plant, &plant)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_entries_have_a_summary_and_unique_names() {
        for (k, e) in EMBEDDED.iter().enumerate() {
            assert!(e.summary().len() > 20, "{}", e.name);
            assert!(EMBEDDED[k + 1..].iter().all(|o| o.name != e.name));
        }
        assert!(embedded("paper").is_some() && embedded("nope").is_none());
        assert!(EMBEDDED[0].summary().starts_with("The paper's example"));
    }

    #[test]
    fn a_missing_file_lists_the_embedded_names() {
        let e = load("no/such/file.toml").unwrap_err();
        let text = e.to_string();
        assert!(text.contains("paper-20khz") && text.contains("no/such/file.toml"));
    }
}
