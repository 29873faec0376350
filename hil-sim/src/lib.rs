//! Host simulator of the electromagnetic actuator (in progress: see the README).
pub mod lyapunov;
