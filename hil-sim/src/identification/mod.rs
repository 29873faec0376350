//! The identification library: what the board's commissioning routine measures, fitted
//! ([`commissioning`]): the coil, the magnetic circuit, the spring, the mass and the
//! friction, and the actuator file they make.
//!
//! Uses [`crate::simulation`] (the board's scenario, the plant, the targets) and
//! [`crate::analysis`] (a commissioned actuator is tuned with [`crate::analysis::tune`]);
//! neither uses it. The `bench` tool (its own package) runs it on a board.

pub mod commissioning;
