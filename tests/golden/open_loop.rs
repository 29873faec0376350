//! TEMPORARY golden-trace generator: runs the core in OPEN LOOP on synthetic converter
//! codes and writes `tests/golden/<case>.emat` for every case of `ema::trace::CASES`.
//!
//! It exists so that the trace format, the host check (`tests/golden_host.rs`) and the
//! Cortex-M4F check (`tests/qemu_golden.rs`) work before the simulator does. The product's
//! traces come from `hil-sim` in closed loop (same format, same `ema::trace::tick_record`
//! hook); when they do, this program goes.
//!
//! ```sh
//! cargo run --example golden_open_loop
//! ```
//!
//! Inputs, per tick `k` at the case's rate: position 2 mm + 1.5 mm sin(2 pi t / 0.2 s),
//! current 6 A + 8 A sin(2 pi t / 50 ms), bus 24 V + 0.5 V sin(2 pi t / 10 ms), each with
//! +-3 codes of deterministic noise; the set point steps every 1700 ticks through 3, 1,
//! 2.5, 4.5 (beyond the stroke: clamped), -1 (clamped) and 3 mm; the last 40 ticks put the
//! current sensor on its rail, so the trace ends in a latched fault.

use std::error::Error;
use std::f64::consts::TAU;
use std::fs;
use std::path::Path;

use core::convert::Infallible;
use ema::bridge::HBridge;
use ema::sense::{Frame, Measurement};
use ema::trace::{self, Header, CASES};
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};

/// Ticks per trace.
const TICKS: u32 = 10_240;
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

fn main() -> Result<(), Box<dyn Error>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    for case in CASES {
        let cfg = (case.settings)().build()?;
        let cal = *cfg.sense();
        let ts = f64::from(cfg.ts_s());
        let mut state = cfg.initial_state();
        let Ok(mut bridge) = HBridge::new(Pwm, Pin, Pin);
        let mut out = Vec::from(Header::new(case, &cfg, MAX_DUTY, TICKS).encode());
        let mut noise = 0x9e37_79b9_u32;
        let mut jitter = move || {
            noise ^= noise << 13;
            noise ^= noise >> 17;
            noise ^= noise << 5;
            i32::try_from(noise % 7).unwrap_or(0) - 3
        };
        let mut faults = 0;
        for k in 0..TICKS {
            let t = f64::from(k) * ts;
            let m = Measurement {
                x_m: (2e-3 + 1.5e-3 * (TAU * t / 0.2).sin()) as f32,
                i_a: (6.0 + 8.0 * (TAU * t / 0.05).sin()) as f32,
                vbus_v: (24.0 + 0.5 * (TAU * t / 0.01).sin()) as f32,
            };
            let ideal = cal.frame(&m);
            let mut noisy = |c: u16| u16::try_from((i32::from(c) + jitter()).clamp(0, 4095));
            let mut frame = Frame {
                position: noisy(ideal.position)?,
                current: noisy(ideal.current)?,
                vbus: noisy(ideal.vbus)?,
            };
            if k + 40 >= TICKS {
                frame.current = ema::sense::ADC_MAX_CODE;
            }
            let setpoint_m = [3e-3, 1e-3, 2.5e-3, 4.5e-3, -1e-3, 3e-3]
                .get(usize::try_from(k / 1700)?)
                .copied()
                .unwrap_or(3e-3);
            let (status, record) =
                trace::tick_record(&cfg, &mut state, &mut bridge, &frame, setpoint_m);
            faults += u32::from(status.fault.is_some());
            out.extend_from_slice(&record.encode());
        }
        let path = dir.join(format!("{}.emat", case.name));
        fs::write(&path, &out)?;
        println!(
            "{}: {} ticks ({} with a latched fault), {} bytes -> {}",
            case.name,
            TICKS,
            faults,
            out.len(),
            path.display()
        );
    }
    Ok(())
}
