//! The simulation: what is simulated, and what a run is judged against.
//!
//! The true actuator ([`plant`]) behind the mock HAL and converter ([`hal`]), a scenario
//! ([`mod@scenario`]) and the files it comes from ([`actuator`], [`catalog`]), the closed
//! loop ([`sim`]), a run's metrics ([`metrics`]) and targets ([`targets`]), one drawn
//! plant's record ([`draw`]) and the scenario a board runs ([`board`]).
//!
//! The lowest of the three parts: it uses neither [`crate::analysis`] nor
//! [`crate::identification`].

pub mod actuator;
pub mod board;
pub mod catalog;
pub mod draw;
mod error;
pub mod hal;
pub mod metrics;
pub mod plant;
pub mod scenario;
pub mod sim;
pub mod targets;

pub use error::Error;
