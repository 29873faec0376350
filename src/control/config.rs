//! Validation of configurations: the error that names the bad parameter and why.
//!
//! Every configuration is built once, outside the interrupt, by a `build`/`try_build` that
//! returns [`Error`]; the tick only ever sees validated, immutable configurations.

use core::fmt;

/// A refused configuration: which parameter, its value and the reason.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Error {
    /// Dotted name of the parameter, as in the configuration files (`law.alpha2`).
    pub param: &'static str,
    /// The refused value (the first one of the pair for ordering errors).
    pub value: f32,
    /// Why it was refused.
    pub reason: Reason,
}

/// Why a parameter was refused. `S` is how another parameter's or a derived quantity's
/// name is held: `&'static str` here, a borrowed `&str` in the bench link's messages
/// ([`crate::device::protocol::Invalid`]), one definition and one text for both.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub enum Reason<S = &'static str> {
    /// `NaN` or infinite.
    NotFinite,
    /// Zero or negative where only a positive value is physical.
    NotPositive,
    /// Below the smallest admissible value.
    BelowMin {
        /// Smallest admissible value.
        min: f32,
    },
    /// Above the largest admissible value.
    AboveMax {
        /// Largest admissible value.
        max: f32,
    },
    /// Must be strictly below another parameter (inverted bounds).
    NotBelow {
        /// The other parameter.
        other: S,
        /// Its value.
        limit: f32,
    },
    /// Must be strictly above another parameter.
    NotAbove {
        /// The other parameter.
        other: S,
        /// Its value.
        limit: f32,
    },
    /// Theorem 1 of the paper fails: `alpha2 > |b|` is required and `Q` must be negative
    /// definite, which needs `alpha2 > alpha2_min = b + a^2 / (4 alpha1)`.
    Theorem1 {
        /// `a = 1 - alpha1^2 + (lambda/m) alpha1 - K/m`.
        a: f32,
        /// `b = alpha1 - lambda/m`.
        b: f32,
        /// `det Q`; negative or zero means `Q` is not negative definite.
        det_q: f32,
        /// Smallest `alpha2` that satisfies both conditions for this `alpha1`.
        alpha2_min: f32,
    },
    /// A derived quantity is out of its admissible range (for example a discrete pole
    /// outside the unit circle); `what` says which.
    Derived {
        /// The derived quantity.
        what: S,
        /// Its value.
        derived: f32,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} = {}: {}", self.param, self.value, self.reason)
    }
}

impl<S: fmt::Display> fmt::Display for Reason<S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Reason::NotFinite => write!(f, "must be finite"),
            Reason::NotPositive => write!(f, "must be positive"),
            Reason::BelowMin { min } => write!(f, "must be at least {min}"),
            Reason::AboveMax { max } => write!(f, "must be at most {max}"),
            Reason::NotBelow { other, limit } => {
                write!(f, "must be below {other} = {limit}")
            }
            Reason::NotAbove { other, limit } => {
                write!(f, "must be above {other} = {limit}")
            }
            Reason::Theorem1 {
                a,
                b,
                det_q,
                alpha2_min,
            } => write!(
                f,
                "fails Theorem 1 (a = {a}, b = {b}, det Q = {det_q}): Q is negative definite \
                 and alpha2 > |b| only for alpha2 > {alpha2_min}"
            ),
            Reason::Derived { what, derived } => {
                write!(f, "gives {what} = {derived}, outside its admissible range")
            }
        }
    }
}

impl core::error::Error for Error {}

/// `Ok` when `value` is finite.
///
/// # Errors
/// [`Reason::NotFinite`] for `param`.
pub fn finite(param: &'static str, value: f32) -> Result<f32, Error> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Error {
            param,
            value,
            reason: Reason::NotFinite,
        })
    }
}

/// `Ok` when `value` is finite and strictly positive.
///
/// # Errors
/// [`Reason::NotFinite`] or [`Reason::NotPositive`] for `param`.
#[inline(never)]
pub fn positive(param: &'static str, value: f32) -> Result<f32, Error> {
    finite(param, value)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err(Error {
            param,
            value,
            reason: Reason::NotPositive,
        })
    }
}

/// `Ok` when `value` is finite and `>= min`.
///
/// # Errors
/// [`Reason::NotFinite`] or [`Reason::BelowMin`] for `param`.
pub fn at_least(param: &'static str, value: f32, min: f32) -> Result<f32, Error> {
    finite(param, value)?;
    if value >= min {
        Ok(value)
    } else {
        Err(Error {
            param,
            value,
            reason: Reason::BelowMin { min },
        })
    }
}

/// `Ok` when `value` is finite and within `[min, max]`.
///
/// # Errors
/// [`Reason::NotFinite`], [`Reason::BelowMin`] or [`Reason::AboveMax`] for `param`.
#[inline(never)]
pub fn within(param: &'static str, value: f32, min: f32, max: f32) -> Result<f32, Error> {
    at_least(param, value, min)?;
    if value <= max {
        Ok(value)
    } else {
        Err(Error {
            param,
            value,
            reason: Reason::AboveMax { max },
        })
    }
}

/// `Ok` when the measurement delay `delay_ticks` (the age of the measurements when the tick
/// runs) is one the stages predict across: 0 or 1 sample. Every stage built with a delay
/// checks it here.
///
/// # Errors
/// [`Reason::AboveMax`] for `delay_ticks`.
pub fn delay_ticks(delay_ticks: u8) -> Result<u8, Error> {
    within("delay_ticks", f32::from(delay_ticks), 0.0, 1.0)?;
    Ok(delay_ticks)
}

/// `Ok` when the sample period `ts_s` is finite and positive. Settings files give the
/// control rate, not the period: a refusal names `rate_hz`, with the rate's value
/// (`1 / ts_s`).
///
/// # Errors
/// [`Reason::NotFinite`] or [`Reason::NotPositive`] for `rate_hz`.
pub fn sample_period(ts_s: f32) -> Result<f32, Error> {
    positive("rate_hz", 1.0 / ts_s)?;
    Ok(ts_s)
}

/// `Ok` when `lo < hi` (both already checked finite by the caller).
///
/// # Errors
/// [`Reason::NotBelow`] naming `lo_param` and `hi_param`.
pub fn ordered(
    lo_param: &'static str,
    lo: f32,
    hi_param: &'static str,
    hi: f32,
) -> Result<(), Error> {
    if lo < hi {
        Ok(())
    } else {
        Err(Error {
            param: lo_param,
            value: lo,
            reason: Reason::NotBelow {
                other: hi_param,
                limit: hi,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    #[test]
    fn messages_name_parameter_value_and_reason() {
        let e = positive("plant.mass_kg", -1.0).unwrap_err();
        assert_eq!(e.to_string(), "plant.mass_kg = -1: must be positive");
        let e = finite("law.alpha1", f32::INFINITY).unwrap_err();
        assert_eq!(e.to_string(), "law.alpha1 = inf: must be finite");
        let e = ordered("lo", 2.0, "hi", 1.0).unwrap_err();
        assert_eq!(e.to_string(), "lo = 2: must be below hi = 1");
        assert!(within("x", 5.0, 0.0, 4.0).is_err());
        assert_eq!(within("x", 4.0, 0.0, 4.0), Ok(4.0));
    }
}
