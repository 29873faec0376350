//! The seeds: which draws choose and which judge.
//!
//! A gain, a rule or a constant chosen while looking at a set of draws fits those draws;
//! a figure measured on the same draws says nothing about a plant or an actuator it was not
//! chosen on. So each use of random draws has its own seed, and no figure in
//! `hil-sim/RESULTS.md` is measured on draws that chose anything:
//!
//! | seed | draws | chooses or judges |
//! |---|---|---|
//! | [`TUNE_VALIDATION`] | the plants `tune` validates a candidate on | chooses the gains |
//! | [`DRAWN_DEVELOPMENT`] | the actuators the rules of [`crate::analysis::drawn`], the search of [`crate::analysis::tune`] and the derived thresholds were tried on while they were written | chooses rules |
//! | [`RESULTS`] | the plants of every Monte Carlo and random-instant table of the family in `RESULTS.md` | judges |
//! | [`DRAWN_JUDGE`] | the drawn actuators `RESULTS.md` judges `tune` and the monitors on ([`crate::analysis::outofsample`]) | judges |
//! | [`COMMISSION_DEVELOPMENT`] | the specimens commissioning's fits and the tolerances they write were tried on while they were written (`hil-sim commission`) | chooses rules |
//! | [`COMMISSION_JUDGE`] | the specimens commissioning and its tolerances are judged on (`hil-sim commission --seed`) | judges |
//!
//! A judging seed that was looked at while a rule was changed becomes a development seed:
//! the next judgement then takes a seed nobody has drawn with.

/// Seed of the plants `tune` validates a candidate on (the first
/// [`crate::analysis::tune::DEFAULT_VALIDATE`] of it).
pub const TUNE_VALIDATION: u64 = 1;

/// Seed of the drawn actuators the generator's rules, the tuning search and the thresholds
/// derived from an actuator were developed on.
pub const DRAWN_DEVELOPMENT: u64 = 101;

/// Seed of the plants the family is judged on in `RESULTS.md`: no gain, rule or constant
/// was chosen on it. (It was 3 until two of seed 3's healthy plants, replayed, showed why
/// the electrical residual's margin had to be paid per period: 3 is a development seed
/// now.)
pub const RESULTS: u64 = 707;

/// Seed of the drawn actuators `RESULTS.md` judges on. Its actuator 6 was looked at when
/// the overshoot became the first excursion past the target (and its actuator 16 is the
/// example of a refused actuator): for that rule it is a development seed now, and the
/// next judgement takes a seed nobody has drawn with.
pub const DRAWN_JUDGE: u64 = 202;

/// Seed of the specimens commissioning's fits, and the rule by which a fit's scatter
/// becomes the tolerance it writes, were tried on while they were written.
pub const COMMISSION_DEVELOPMENT: u64 = 303;

/// Seed of the specimens commissioning is judged on: no fit, rule or tolerance was
/// chosen on it.
pub const COMMISSION_JUDGE: u64 = 505;
