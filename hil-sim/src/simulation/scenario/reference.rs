//! The position reference a scenario hands to the tick: steps, sequences and their
//! segments.

use serde::{Deserialize, Serialize};

use crate::simulation::plant::{non_negative, positive};
use crate::simulation::Error;

/// The position reference `y_r(t)` handed to the tick as its set point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Reference {
    /// `from_m` before `at_s`, `to_m` from `at_s` on.
    Step {
        /// Reference before the step \[m\] (the position the armature starts from).
        from_m: f64,
        /// Reference after the step \[m\].
        to_m: f64,
        /// Time of the step \[s\].
        #[serde(default)]
        at_s: f64,
    },
    /// Linear ramp from `from_m` to `to_m` over `[start_s, start_s + duration_s]`.
    Ramp {
        /// Start value \[m\].
        from_m: f64,
        /// End value \[m\].
        to_m: f64,
        /// Start time \[s\].
        start_s: f64,
        /// Ramp duration \[s\].
        duration_s: f64,
    },
    /// Minimum-jerk (quintic, `10 s^3 - 15 s^4 + 6 s^5`) move from `from_m` to `to_m`
    /// over `[start_s, start_s + duration_s]`: zero velocity and acceleration at both ends.
    Smooth {
        /// Start value \[m\].
        from_m: f64,
        /// End value \[m\].
        to_m: f64,
        /// Start time \[s\].
        start_s: f64,
        /// Move duration \[s\].
        duration_s: f64,
    },
    /// A sequence of steps at increasing times.
    Sequence {
        /// Reference before the first step \[m\].
        initial_m: f64,
        /// The steps, in increasing time.
        steps: Vec<StepAt>,
    },
}

/// One step of a [`Reference::Sequence`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepAt {
    /// Time of the step \[s\].
    pub at_s: f64,
    /// Reference from then on \[m\].
    pub to_m: f64,
}

/// A part of the run over which metrics are taken: one move of the reference and the time
/// until the next one (or the end).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentSpec {
    /// Start of the move \[s\].
    pub start_s: f64,
    /// End of the segment \[s\].
    pub end_s: f64,
    /// Reference before the move \[m\].
    pub from_m: f64,
    /// Final reference of the segment \[m\].
    pub to_m: f64,
}

impl Reference {
    /// The reference at time `t_s` \[m\].
    #[must_use]
    pub fn position_m(&self, t_s: f64) -> f64 {
        match self {
            Reference::Step { from_m, to_m, at_s } => {
                if t_s >= *at_s {
                    *to_m
                } else {
                    *from_m
                }
            }
            Reference::Ramp {
                from_m,
                to_m,
                start_s,
                duration_s,
            } => {
                let s = ((t_s - start_s) / duration_s).clamp(0.0, 1.0);
                from_m + (to_m - from_m) * s
            }
            Reference::Smooth {
                from_m,
                to_m,
                start_s,
                duration_s,
            } => {
                let s = ((t_s - start_s) / duration_s).clamp(0.0, 1.0);
                let shape = s * s * s * (10.0 + s * (-15.0 + 6.0 * s));
                from_m + (to_m - from_m) * shape
            }
            Reference::Sequence { initial_m, steps } => steps
                .iter()
                .take_while(|s| s.at_s <= t_s)
                .last()
                .map_or(*initial_m, |s| s.to_m),
        }
    }

    /// The reference's value before it first moves \[m\]: `from_m` of a step, ramp or
    /// smooth move, `initial_m` of a sequence.
    #[must_use]
    pub fn start_m(&self) -> f64 {
        match self {
            Reference::Step { from_m, .. }
            | Reference::Ramp { from_m, .. }
            | Reference::Smooth { from_m, .. } => *from_m,
            Reference::Sequence { initial_m, .. } => *initial_m,
        }
    }

    /// The segments of a run of `duration_s`.
    #[must_use]
    pub fn segments(&self, duration_s: f64) -> Vec<SegmentSpec> {
        match self {
            Reference::Step { from_m, to_m, at_s } => vec![SegmentSpec {
                start_s: *at_s,
                end_s: duration_s,
                from_m: *from_m,
                to_m: *to_m,
            }],
            Reference::Ramp {
                from_m,
                to_m,
                start_s,
                ..
            }
            | Reference::Smooth {
                from_m,
                to_m,
                start_s,
                ..
            } => vec![SegmentSpec {
                start_s: *start_s,
                end_s: duration_s,
                from_m: *from_m,
                to_m: *to_m,
            }],
            Reference::Sequence { initial_m, steps } => {
                let mut from = *initial_m;
                let mut out = Vec::with_capacity(steps.len());
                for (k, s) in steps.iter().enumerate() {
                    let end = steps.get(k + 1).map_or(duration_s, |n| n.at_s);
                    out.push(SegmentSpec {
                        start_s: s.at_s,
                        end_s: end.min(duration_s),
                        from_m: from,
                        to_m: s.to_m,
                    });
                    from = s.to_m;
                }
                out
            }
        }
    }

    pub(super) fn validate(&self, duration_s: f64) -> Result<(), Error> {
        let finite = |name: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(Error::param(
                    format!("reference.{name}"),
                    v,
                    "must be finite",
                ))
            }
        };
        match self {
            Reference::Step { from_m, to_m, at_s } => {
                finite("from_m", *from_m)?;
                finite("to_m", *to_m)?;
                non_negative("reference.at_s", *at_s)
            }
            Reference::Ramp {
                from_m,
                to_m,
                start_s,
                duration_s,
            }
            | Reference::Smooth {
                from_m,
                to_m,
                start_s,
                duration_s,
            } => {
                finite("from_m", *from_m)?;
                finite("to_m", *to_m)?;
                non_negative("reference.start_s", *start_s)?;
                positive("reference.duration_s", *duration_s)
            }
            Reference::Sequence { initial_m, steps } => {
                finite("initial_m", *initial_m)?;
                let mut last = -1.0;
                for (k, s) in steps.iter().enumerate() {
                    finite(&format!("steps[{k}].to_m"), s.to_m)?;
                    if !(s.at_s.is_finite() && s.at_s > last && s.at_s < duration_s) {
                        return Err(Error::param(
                            format!("reference.steps[{k}].at_s"),
                            s.at_s,
                            "must increase and lie inside the run",
                        ));
                    }
                    last = s.at_s;
                }
                Ok(())
            }
        }
    }
}
