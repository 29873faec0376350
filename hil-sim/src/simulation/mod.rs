//! The simulation: what is simulated, and what a run is judged against.
//!
//! The true actuator ([`plant`]) behind the mock HAL and converter ([`hal`]), a scenario
//! ([`mod@scenario`]) and the files it comes from ([`actuator`], [`catalog`]), the closed
//! loop ([`sim`]), a run's metrics ([`metrics`]) and targets ([`targets`]), one drawn
//! plant's record ([`draw`]) and the scenario a board runs ([`board`]).
//!
//! The lowest of the three parts: it uses neither [`crate::analysis`] nor
//! [`crate::identification`].
//!
//! Its modules use one another in one direction only, each using only modules before it:
//!
//! ```text
//! error, plant <- hal <- scenario <- files, trace <- metrics <- sim <- draw <- actuator
//!     <- targets <- catalog <- board
//! ```
//!
//! `files` (why a scenario or actuator file could not be loaded, and its summary line; in
//! [`catalog`]'s documentation) and `trace` (a run's samples and impacts; in [`sim`]'s) are
//! private: each holds what a lower module needs of a higher one's public items, which the
//! higher one re-exports. For the same reason the PWM full scale is [`hal`]'s (re-exported
//! by [`actuator`]), the product's scenarios ([`scenario::Scenario::product`]) are defined
//! in [`actuator`], and the metrics' `NaN`-keeping maximum is [`metrics`]'.

pub mod actuator;
pub mod board;
pub mod catalog;
pub mod draw;
mod error;
mod files;
pub mod hal;
pub mod metrics;
pub mod plant;
pub mod scenario;
pub mod sim;
pub mod targets;
mod trace;

pub use error::Error;
