//! The simulated side of a board: the scenario the virtual board (the `bench` tool's)
//! runs and commissioning is simulated on. The plant, the sensors and the supply are the
//! actuator's judging scenario ([`crate::simulation::actuator::scenario`]: nominal plant, supply
//! resistance `R/8`, averaged bridge) with a deterministic converter by default (12 bits,
//! one sample of delay, no noise), so that a capture on the virtual board equals, bit for
//! bit, the simulator's run of the same scenario; `noise` adds the typical converter noise.

use ema::control::actuator::Actuator;

use crate::simulation::hal::Adc;
use crate::simulation::scenario::{Initial, Scenario, Sensors};
use crate::simulation::Error;

/// The scenario the virtual board runs (see the module documentation): at rest at the
/// open stop; the reference is the board's, not the scenario's.
///
/// # Errors
/// An actuator whose settings do not derive.
pub fn scenario(actuator: &Actuator, noise: bool) -> Result<Scenario, Error> {
    let mut sc = crate::simulation::actuator::scenario("virtual-board", actuator)?;
    sc.sensors = Sensors::Adc(if noise {
        Adc::typical()
    } else {
        Adc {
            delay_samples: 1,
            ..Adc::default()
        }
    });
    sc.initial = Initial::default();
    Ok(sc)
}
