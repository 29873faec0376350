//! The analysis suite: what is measured over many runs of the simulation.
//!
//! Monte Carlo over drawn plants ([`mod@montecarlo`]), the practical law's gains for any
//! actuator ([`mod@tune`], with Theorem 1 from [`lyapunov`]), fault injection
//! ([`faults`]), the comparison of the laws ([`compare`]), the substeps a scenario needs
//! ([`accuracy`]), golden traces ([`golden`]), drawn actuators and their out-of-sample
//! judgement ([`drawn`], [`outofsample`]), which seeds choose and which judge
//! ([`seeds`]), and tables, CSV files and plots ([`report`]).
//!
//! Uses [`crate::simulation`] only, never [`crate::identification`] (which uses it).

pub mod accuracy;
pub mod compare;
pub mod drawn;
pub mod faults;
pub mod golden;
pub mod lyapunov;
pub mod montecarlo;
pub mod outofsample;
pub mod report;
pub mod seeds;
pub mod tune;
