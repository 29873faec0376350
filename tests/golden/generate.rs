//! TEMPORARY golden-trace generator: runs the core in closed loop with the small actuator
//! model of the tests (`tests/common/plant.rs`) and writes `tests/golden/<case>.emat` for
//! every case of `ema::trace::CASES`.
//!
//! It exists so that the trace format, the host check (`tests/golden_host.rs`) and the
//! Cortex-M4F check (`tests/qemu_golden.rs`) work before the simulator does. The product's
//! traces come from `hil-sim` (uncertain plant, ADC model, scenarios; same format, same
//! `ema::trace::tick_record` hook); when they do, this program goes.
//!
//! ```sh
//! cargo run --example golden_generate
//! ```
//!
//! Scenario: at rest at 1 mm on a 24 V bus; set point 3 mm, then 2 mm at tick 3000, 3.5 mm
//! at 6000, 1.5 mm at 8500; a tick after a latched fault re-arms (the paper's law trips
//! the current checks every few ticks at 20 kHz); the last 40 ticks put the current sensor
//! on its rail, so the trace ends in a latched fault.
//!
//! Synthetic open-loop codes (the first version of this program) no longer work: the
//! supervisor's electrical-residual monitor rightly refuses a current that does not follow
//! the applied voltage.

#[path = "../common/plant.rs"]
mod plant;

use std::error::Error;
use std::fs;
use std::path::Path;

use core::convert::Infallible;
use ema::bridge::HBridge;
use ema::trace::{self, Header, CASES, MIN_GOLDEN_TICKS};
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};

/// Ticks per trace.
const TICKS: u32 = MIN_GOLDEN_TICKS;
/// Ticks at the end with the current sensor on its rail.
const RAIL_TICKS: u32 = 40;
/// PWM resolution of the firmware's TIM1 (ARR + 1).
const MAX_DUTY: u16 = 4201;

struct Pwm;
impl PwmErrorType for Pwm {
    type Error = Infallible;
}
impl SetDutyCycle for Pwm {
    fn max_duty_cycle(&self) -> u16 {
        MAX_DUTY
    }
    fn set_duty_cycle(&mut self, _: u16) -> Result<(), Infallible> {
        Ok(())
    }
}
struct Pin;
impl PinErrorType for Pin {
    type Error = Infallible;
}
impl OutputPin for Pin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

fn setpoint_m(k: u32) -> f32 {
    match k {
        0..3000 => 3e-3,
        3000..6000 => 2e-3,
        6000..8500 => 3.5e-3,
        _ => 1.5e-3,
    }
}

fn main() -> Result<(), Box<dyn Error>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    for case in CASES {
        let settings = (case.settings)();
        let cfg = settings.build()?;
        let mut state = cfg.initial_state();
        let Ok(mut bridge) = HBridge::new(Pwm, Pin, Pin);
        let mut actuator = plant::Plant::new(&settings, 1e-3, 24.0);
        let mut out = Vec::from(Header::new(case, &cfg, MAX_DUTY, TICKS).encode());
        let (mut tripped, mut rearms, mut running) = (false, 0, 0);
        for k in 0..TICKS {
            let rail = k + RAIL_TICKS >= TICKS;
            let mut frame = actuator.frame();
            if rail {
                frame.current = ema::sense::ADC_MAX_CODE;
            }
            let rearm = tripped && !rail;
            let (status, record) =
                trace::tick_record(&cfg, &mut state, &mut bridge, &frame, setpoint_m(k), rearm);
            actuator.advance(&status.drive);
            tripped = status.fault.is_some();
            rearms += u32::from(rearm);
            running += u32::from(!tripped);
            out.extend_from_slice(&record.encode());
        }
        let path = dir.join(format!("{}.emat", case.name));
        fs::write(&path, &out)?;
        println!(
            "{}: {TICKS} ticks, {running} ran the whole path, {rearms} re-arms, x = {:.3} mm at the end, {} bytes -> {}",
            case.name,
            actuator.x_m * 1e3,
            out.len(),
            path.display()
        );
    }
    Ok(())
}
