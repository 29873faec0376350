//! What scenario and actuator files share, below both loaders ([`crate::simulation::catalog`]
//! and [`crate::simulation::actuator`]): why a file could not be loaded, and its summary line.
//! Both are re-exported by [`crate::simulation::catalog`], where they are documented.

/// The first line of a TOML file's leading comment, trimmed (empty without one): what a
/// scenario or an actuator file describes.
#[must_use]
pub fn summary(text: &str) -> &str {
    text.lines()
        .next()
        .and_then(|l| l.strip_prefix('#'))
        .map_or("", str::trim)
}

/// Why a scenario could not be loaded.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadError {
    /// Neither an embedded name nor a readable file.
    NotFound {
        /// What was asked for.
        what: String,
        /// Why the file could not be read.
        io: String,
    },
    /// The TOML does not parse or does not describe a scenario (unknown field, missing
    /// field, wrong type).
    Toml {
        /// The file (or embedded name).
        origin: String,
        /// toml's message: line, column, the line itself and what is wrong.
        message: String,
    },
    /// A parameter is refused.
    Invalid {
        /// The file (or embedded name).
        origin: String,
        /// The refused parameter, named, with its value.
        error: crate::simulation::Error,
    },
}

impl LoadError {
    /// The refused parameter's dotted name, for [`LoadError::Invalid`].
    #[must_use]
    pub fn field(&self) -> Option<&str> {
        match self {
            LoadError::Invalid { error, .. } => Some(error.name()),
            _ => None,
        }
    }
}
