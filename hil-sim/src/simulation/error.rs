//! The simulator's error: a refused parameter (named, with its value and why) or a refused
//! controller configuration from the core.

use std::fmt;

/// Why a scenario, a plant or a sensor model was refused.
#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    /// A simulator parameter.
    Param {
        /// Dotted name as in a scenario file (`plant.mass_kg`, `sensors.delay_samples`).
        name: String,
        /// The refused value (`NaN` when the value is not a number).
        value: f64,
        /// Why.
        reason: String,
    },
    /// The controller settings, refused by `ema::control::Settings::build`.
    Controller(ema::control::config::Error),
    /// An actuator file, refused by `ema::control::actuator::Actuator::settings` (the name
    /// is the field's in the file).
    Actuator(ema::control::config::Error),
}

impl Error {
    /// A refused simulator parameter.
    pub fn param(name: impl Into<String>, value: f64, reason: impl Into<String>) -> Self {
        Error::Param {
            name: name.into(),
            value,
            reason: reason.into(),
        }
    }

    /// Name of the refused parameter (the core's dotted name for controller errors).
    #[must_use]
    pub fn name(&self) -> &str {
        match self {
            Error::Param { name, .. } => name,
            Error::Controller(e) | Error::Actuator(e) => e.param,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Param {
                name,
                value,
                reason,
            } => write!(f, "{name} = {value}: {reason}"),
            Error::Controller(e) => write!(f, "controller: {e}"),
            Error::Actuator(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for Error {}

impl From<ema::control::config::Error> for Error {
    fn from(e: ema::control::config::Error) -> Self {
        Error::Controller(e)
    }
}
