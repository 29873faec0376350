//! # hil-sim: the actuator simulator around the `ema` control core
//!
//! Host-side, `std`, `f64`. The true actuator ([`simulation::plant`]) is integrated with
//! fixed-step RK4 substeps inside each ISR period; at each ISR instant it is sampled (ideal
//! values or raw ADC codes from a converter model, [`simulation::hal`]), the core's own
//! `Config::tick` runs exactly as in the firmware, and drives the core's `HBridge` over mock
//! `embedded-hal` PWM and pins whose state sets the coil voltage, period-averaged or pulse by
//! pulse. A [`Scenario`] says what to simulate; [`run`] returns the samples (one per ISR
//! period) and the [`Metrics`]; [`montecarlo()`] repeats a scenario over plants drawn from
//! the uncertainty set.
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
//! ## Parts
//!
//! Three parts, each a module of modules, with a one-way dependency and no circle between
//! them; the command line uses all three:
//!
//! | part | what | uses |
//! |---|---|---|
//! | [`simulation`] | the plant, the mock HAL, the closed loop, scenarios, metrics, targets, actuator and scenario files | none |
//! | [`analysis`] | what is measured over many runs: Monte Carlo, tune, faults, Lyapunov, compare, accuracy, golden traces, drawn actuators, seeds, reports | [`simulation`] |
//! | [`identification`] | the identification fits of the board's commissioning routine | [`simulation`], [`analysis`] |
//! | [`cli`] | the `hil-sim` command line, one module per subcommand | all three |
//!
//! The host tool for a board on a bench and the virtual board are their own package,
//! `bench` (`hil-sim/bench/`, `cargo run -p bench -- --help`), which uses this crate; no
//! part of this crate uses it.
//!
//! ## Modules
//!
//! | module | what |
//! |---|---|
//! | [`simulation::plant`] | true actuator: conventions, frozen / energy-consistent fringing, end stops, saturation, RK4 |
//! | [`simulation::hal`] | mock PWM and pins, supply, converter model, calibrations |
//! | [`simulation::scenario`] | scenario, reference, sensors, bridge, integration, uncertainty set |
//! | [`simulation::sim`] | the closed loop and its samples |
//! | [`simulation::metrics`] | metrics definitions and the bounds check |
//! | [`simulation::targets`] | the product's performance targets and their evaluation |
//! | [`simulation::draw`] | one Monte Carlo draw: the plant, its metrics, its converter errors |
//! | [`simulation::actuator`] | actuator files: the family in the repository, loading, tuned files |
//! | [`simulation::catalog`] | scenario files: the embedded defaults, loading by name or from a file |
//! | [`simulation::board`] | the scenario a board runs: the virtual board's, commissioning's |
//! | [`mod@analysis::montecarlo`] | parallel, seeded runs over drawn plants |
//! | [`mod@analysis::tune`] | the practical law's gains for any actuator |
//! | [`analysis::lyapunov`] | Theorem 1 with a general Lyapunov matrix |
//! | [`analysis::faults`] | fault injection: the fault the supervisor must name, and how fast |
//! | [`analysis::compare`] | the comparison of the laws over ISR rates and supplies |
//! | [`analysis::accuracy`] | how many RK4 substeps per ISR period a scenario needs, measured |
//! | [`analysis::golden`] | golden traces for the Cortex-M4F (`ema::control::trace` format) |
//! | [`analysis::drawn`] | drawn actuators: plausible actuators for judging the rules out of sample |
//! | [`analysis::outofsample`] | drawn actuators tuned, then judged on plants and faults |
//! | [`analysis::seeds`] | which seeds choose and which judge |
//! | [`analysis::report`] | tables, decimated sample CSV files, PNG plots |
//! | [`identification::commissioning`] | the identification fits of the board's commissioning routine |
//! | [`cli`] | the `hil-sim` command line, one module per subcommand |
//!
//! ## Glossary
//!
//! The core's words are in the `ema` crate docs; these are the simulator's.
//!
//! | word | meaning |
//! |---|---|
//! | family, member | the seven actuators kept in `hil-sim/actuators/`, each with its tuned file ([`simulation::actuator::FAMILY`]) |
//! | evaluation sequence | an actuator's scenario: rest at the open stop, then 1/8, 7/8, 3/8 and 3/4 of the stroke, one segment each ([`simulation::actuator::scenario`]) |
//! | steady window | the last 50 ms of a segment, where the steady error and the ripple are measured |
//! | targets | the product's limits a run must stay within ([`simulation::targets`]) |
//! | draw | one random sample with its own seed: a plant from a controller's uncertainty set ([`mod@analysis::montecarlo`], [`simulation::draw`]), or an actuator from the generator ([`analysis::drawn`]) |
//! | specimen | an actuator as a user's is, drawn off its file for a commissioning: its plant, its position sensor's and converter's errors, its noise ([`identification::commissioning::Specimen`]) |
//! | injection | a fault a scenario injects at an instant ([`simulation::scenario::Injection`]); what the bench's test rig does to the virtual board is a stimulus (the `bench` crate) |
//! | corner plant | a plant at the extremes of the uncertainty set, where `tune` runs its candidates ([`analysis::tune::corners`]) |
//! | seed | the start of a reproducible stream of draws; which seed chooses and which judges: [`analysis::seeds`] |
//! | uncertainty | of a measured value: two standard errors of its fit (k = 2), in the value's unit (`uncertainty_h` of a [`identification::commissioning::HoldInductance`], `uncertainty_n_per_m` of a [`identification::commissioning::Spring`]); the **uncertainty set** a plant is drawn from ([`simulation::scenario::Uncertainty`]) is always named in full |
//! | tolerance | a relative half-width about a nominal value, `+-`: the uncertainty set's `resistance_rel`, `spring_rel`, `mass_rel`, `friction_rel`; an actuator file's, which a commissioning writes from what its fits leave ([`identification::commissioning::fitted_tolerance`]) |
//! | widen | the Monte Carlo's factor `K` on the plant's tolerances beyond the controller's (`hil-sim montecarlo --widen K`, [`analysis::montecarlo::Options::widen`]) |
//! | random case | one fault case injected at random instants on drawn plants, and how it was found ([`analysis::faults::RandomCase`]) |
//! | class | a stated tolerance band of a kind of part, not of one measured value: a converter's gain and offset ([`simulation::hal::CalibrationClass`]), the stops' inductance readings ([`identification::commissioning::STOP_INDUCTANCE_CLASS`]) |
//! | observable | a fault from the first sample at which it can be seen: at once, except a frozen reading, which is what a healthy sensor could read until the true quantity moves ([`analysis::faults::observable_after_s`]) |
//! | named right | the expected fault latched within 1 ms, the current at or below the trip, the bridge coasting from then on ([`analysis::faults::Outcome::pass`]) |
//! | silent failure | a run that misses a target with no fault latched |
#![deny(missing_docs)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod analysis;
pub mod cli;
pub mod identification;
pub mod simulation;

pub use analysis::montecarlo::montecarlo;
pub use simulation::draw::Draw;
pub use simulation::metrics::{BoundsCheck, Metrics, Segment};
pub use simulation::scenario::{Reference, Scenario};
pub use simulation::sim::{run, Run, Sample};
pub use simulation::Error;
