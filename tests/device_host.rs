//! The host side of `tests/qemu_device.rs`: the scripted bench session
//! (`tests/common/session.rs`) through the board's application, every answer checked; the
//! bytes the board sent are those whose hash and length the Cortex-M4F must reproduce.

#[path = "common/plant.rs"]
mod plant;
#[path = "common/session.rs"]
mod session;

use std::convert::Infallible;

use ema::control::bridge::HBridge;
use ema::device::Queues;
use session::{Session, CAPTURE, FRAMES_HASH, FRAMES_LEN, LINK_TIMEOUT_TICKS, MAIN_LOOP_TICKS};

struct Pwm;
impl embedded_hal::pwm::ErrorType for Pwm {
    type Error = Infallible;
}
impl embedded_hal::pwm::SetDutyCycle for Pwm {
    fn max_duty_cycle(&self) -> u16 {
        ema::control::bridge::BOARD_MAX_DUTY
    }
    fn set_duty_cycle(&mut self, _: u16) -> Result<(), Infallible> {
        Ok(())
    }
}
struct Pin;
impl embedded_hal::digital::ErrorType for Pin {
    type Error = Infallible;
}
impl embedded_hal::digital::OutputPin for Pin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

#[test]
fn the_session_answers_as_scripted_and_its_frames_are_the_saved_ones() {
    let mut q = Queues::new();
    let (main, isr) = q.split();
    let Ok(bridge) = HBridge::new(Pwm, Pin, Pin);
    let Ok(shadow) = HBridge::new(Pwm, Pin, Pin);
    let s = Session::new(main, isr, bridge, shadow).unwrap();
    let out = s.run(&mut || 0).unwrap();
    println!("{out:?}");
    // The move reached 3 mm; the capture came back whole; telemetry every 20 ticks.
    assert!((out.x_m - 3e-3).abs() < 30e-6, "{}", out.x_m);
    assert_eq!(out.captured, CAPTURE);
    assert!(out.telemetry >= 20, "{}", out.telemetry);
    // The silent host: disarmed one tick after the timeout (counted from the tick that
    // saw the arming request), the tick that carried the order aside.
    assert_eq!(LINK_TIMEOUT_TICKS, 10_000);
    assert!(
        (LINK_TIMEOUT_TICKS + 1..=LINK_TIMEOUT_TICKS + 2).contains(&out.link_lost_after),
        "{}",
        out.link_lost_after
    );
    // The hung main loop: no feed one tick after the deadline.
    assert_eq!(MAIN_LOOP_TICKS, 400);
    assert!(
        (MAIN_LOOP_TICKS + 1..=MAIN_LOOP_TICKS + 2).contains(&out.main_stalled_after),
        "{}",
        out.main_stalled_after
    );
    assert_eq!(
        (out.hash, out.len),
        (FRAMES_HASH, FRAMES_LEN),
        "FRAMES_HASH should be {:#018x} and FRAMES_LEN {}",
        out.hash,
        out.len
    );
}
