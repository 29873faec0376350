//! Faults injected into a run: what, when, and what the simulator changes.

use serde::{Deserialize, Serialize};

use crate::simulation::plant::{non_negative, positive};
use crate::simulation::Error;

/// A fault injected into a run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Injection {
    /// When it starts \[s\] (it lasts to the end of the run).
    pub at_s: f64,
    /// What goes wrong.
    pub fault: Injected,
}

/// What an [`Injection`] does.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Injected {
    /// The position sensor's output falls to 0 V (open wire): the converter reads its low
    /// rail.
    PositionOpen,
    /// The position sensor's output is shorted to its supply: the converter reads its high
    /// rail.
    PositionShorted,
    /// The position sensor's output freezes at its value at the injection.
    PositionStuck,
    /// The current sensor's output freezes at its value at the injection.
    CurrentStuck,
    /// The current sensor's zero steps by `offset_a`.
    CurrentOffset {
        /// Offset \[A\].
        offset_a: f64,
    },
    /// The coil circuit opens: no current can flow.
    CoilOpen,
    /// Shorted turns: the coil resistance drops to `resistance_ohm`.
    CoilShort {
        /// New resistance \[ohm\].
        resistance_ohm: f64,
    },
    /// The supply's source voltage changes to `voltage_v` (sag or over-voltage).
    Supply {
        /// New source voltage \[V\].
        voltage_v: f64,
    },
    /// The control interrupt misses `ticks` deadlines in a row: no tick runs and the
    /// bridge keeps its last state; when the interrupt runs again the firmware's guard
    /// (`ema::device::guard`) sees the gap and latches the overrun, and a stall longer than
    /// the window watchdog's early wake-up is ended by the watchdog, which coasts the
    /// bridge.
    MissedDeadlines {
        /// Missed periods.
        ticks: u32,
    },
}

impl Injection {
    /// Checks the parameters.
    ///
    /// # Errors
    /// A time that is negative or not finite, a resistance or voltage that is not
    /// positive, zero missed ticks.
    pub fn validate(&self) -> Result<(), Error> {
        non_negative("faults.at_s", self.at_s)?;
        match self.fault {
            Injected::CurrentOffset { offset_a } if !offset_a.is_finite() => {
                return Err(Error::param(
                    "faults.fault.offset_a",
                    offset_a,
                    "must be finite",
                ));
            }
            Injected::CoilShort { resistance_ohm } => {
                positive("faults.fault.resistance_ohm", resistance_ohm)?;
            }
            Injected::Supply { voltage_v } => positive("faults.fault.voltage_v", voltage_v)?,
            Injected::MissedDeadlines { ticks: 0 } => {
                return Err(Error::param(
                    "faults.fault.ticks",
                    0.0,
                    "must be at least 1",
                ));
            }
            _ => {}
        }
        Ok(())
    }
}
