//! # hil-sim: the actuator simulator around the `ema` control core
//!
//! Host-side, `std`, `f64`. The true actuator ([`plant`]) with fixed-step RK4.
#![deny(missing_docs)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod error;
pub mod plant;

pub use error::Error;
