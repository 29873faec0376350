//! # hil-sim: the actuator simulator around the `ema` control core
//!
//! Host-side, `std`, `f64`. The true actuator ([`plant`]) is integrated with fixed-step RK4
//! substeps inside each ISR period; at each ISR instant it is sampled (ideal values or raw
//! ADC codes from a converter model, [`hal`]), the core's own `Config::tick` runs exactly
//! as in the firmware, and drives the core's `HBridge` over mock `embedded-hal` PWM and pins
//! whose state sets the coil voltage, period-averaged or pulse by pulse. A [`Scenario`]
//! says what to simulate; [`run`] returns the samples (one per ISR period) and the [`Metrics`]; [`montecarlo()`]
//! repeats a scenario over plants drawn from the uncertainty set.
//!
//! The controller is only ever reached through `ema::control::Settings` ->
//! `Config` -> `tick`, so any law the core offers (`ema::control::law::Settings`) runs
//! unchanged.
//!
//! ## Example: the paper's example at a 100 kHz ISR
//!
//! ```
//! use hil_sim::{run, Scenario};
//!
//! // 150 V, ideal sensors, averaged bridge, step from 1 mm to 3 mm, 1 s.
//! let result = run(&Scenario::paper(100_000.0)).unwrap();
//! let step = result.metrics.first().unwrap();
//!
//! // The law pulls the armature to 3 mm without overshoot...
//! assert_eq!(step.overshoot_pct, 0.0);
//! assert!(step.steady_error_pct.abs() < 2.0);
//! // ...with a start-up current peak of about 23 A and about 6 A to hold it there...
//! assert!(step.i_peak_a > 18.0 && step.i_peak_a < 26.0);
//! assert!((step.steady_current_a - 6.0).abs() < 0.5);
//! // ...but sampled at 100 kHz the sign law makes the current chatter by amperes.
//! assert!(step.ripple_pp_a > 5.0);
//! // The nominal plant lies inside the controller's bounds.
//! assert!(result.metrics.bounds.brackets);
//! ```
//!
//! ## Modules
//!
//! | module | what |
//! |---|---|
//! | [`plant`] | true actuator: conventions, frozen / energy-consistent fringing, end stops, saturation, RK4 |
//! | [`hal`] | mock PWM and pins, supply, converter model, calibrations |
//! | [`scenario`] | scenario, reference, sensors, bridge, integration, uncertainty set |
//! | [`sim`] | the closed loop and its samples |
//! | [`metrics`] | metrics definitions and the bounds check |
//! | [`mod@montecarlo`] | parallel, seeded runs over drawn plants |
//! | [`accuracy`] | how many RK4 substeps per ISR period a scenario needs, measured |
//! | [`actuator`] | actuator files: the family in the repository, loading, tuned files |
//! | [`drawn`] | drawn actuators: plausible actuators for judging the rules out of sample |
//! | [`outofsample`] | drawn actuators tuned, then judged on plants and faults |
//! | [`seeds`] | which seeds choose and which judge |
//! | [`commissioning`] | the identification fits of the board's commissioning routine |
//! | [`catalog`] | scenario files: the embedded defaults, loading by name or from a file |
//! | [`compare`] | the comparison of the laws over ISR rates and supplies |
//! | [`faults`] | fault injection: the fault the supervisor must name, and how fast |
//! | [`golden`] | golden traces for the Cortex-M4F (`ema::control::trace` format) |
//! | [`lyapunov`] | Theorem 1 with a general Lyapunov matrix |
//! | [`targets`] | the product's performance targets and their evaluation |
//! | [`mod@tune`] | the practical law's gains for any actuator |
//! | [`report`] | tables, decimated sample CSV files, PNG plots |
//! | [`cli`] | the `hil-sim` command line, one module per subcommand |
//! | [`mod@bench`] | a board on a bench: the `bench` tool, its link, the virtual board |
//!
//! ## Glossary
//!
//! The core's words are in the `ema` crate docs; these are the simulator's.
//!
//! | word | meaning |
//! |---|---|
//! | family, member | the seven actuators kept in `hil-sim/actuators/`, each with its tuned file ([`actuator::FAMILY`]) |
//! | evaluation sequence | an actuator's scenario: rest at the open stop, then 1/8, 7/8, 3/8 and 3/4 of the stroke, one segment each ([`actuator::scenario`]) |
//! | steady window | the last 50 ms of a segment, where the steady error and the ripple are measured |
//! | targets | the product's limits a run must stay within ([`targets`]) |
//! | draw | one random sample with its own seed: a plant from a controller's uncertainty set ([`mod@montecarlo`]), or an actuator from the generator ([`drawn`]) |
//! | corner plant | a plant at the extremes of the uncertainty set, where `tune` runs its candidates ([`tune::corners`]) |
//! | seed | the start of a reproducible stream of draws; which seed chooses and which judges: [`seeds`] |
//! | class | a stated tolerance band: of a converter's gain and offset ([`hal::CalibrationClass`]), or of a quantity commissioning measures ([`commissioning`]) |
//! | observable | a fault from the first sample at which it can be seen: at once, except a frozen reading, which is what a healthy sensor could read until the true quantity moves ([`faults::observable_after_s`]) |
//! | named right | the expected fault latched within 1 ms, the current at or below the trip, the bridge coasting from then on ([`faults::Outcome::pass`]) |
//! | silent failure | a run that misses a target with no fault latched |
#![deny(missing_docs)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod accuracy;
pub mod actuator;
pub mod bench;
pub mod board;
pub mod catalog;
pub mod cli;
pub mod commissioning;
pub mod compare;
pub mod draw;
pub mod drawn;
mod error;
pub mod faults;
pub mod golden;
pub mod hal;
pub mod lyapunov;
pub mod metrics;
pub mod montecarlo;
pub mod outofsample;
pub mod plant;
pub mod report;
pub mod scenario;
pub mod seeds;
pub mod sim;
pub mod targets;
pub mod tune;

pub use error::Error;
pub use metrics::{BoundsCheck, Metrics, Segment};
pub use montecarlo::{montecarlo, Draw};
pub use scenario::{Reference, Scenario};
pub use sim::{run, Run, Sample};
