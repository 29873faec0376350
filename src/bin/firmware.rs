//! STM32F405 firmware: the control core in a fixed-rate interrupt.
//!
//! TIM1 runs the bridge PWM at 20 kHz, center-aligned; once per period its update event
//! triggers ADC1, which converts coil current, position and bus voltage; the end of that
//! sequence interrupts, and the interrupt runs `ema::control::Config::tick` on the codes
//! and writes the next duty. Pins, clocks and every other hardware constant are in
//! [`board`]; register-level set-up is in `hw`; start-up, the interrupt, the status line
//! and the panic handler are in `app`.
//!
//! Safety measures, in the order they act:
//! * the board pulls the bridge enable low, so the bridge coasts through reset and boot;
//! * start-up drives enable low before configuring the PWM, and measures the
//!   current-sensor zero with the bridge off (an implausible zero latches
//!   `Fault::CurrentOffset`);
//! * the tick cannot panic (link-time proof: `tests/qemu_no_panic.rs`) and latches any
//!   implausible input as a fault with the bridge coasting;
//! * a tick that ends with the next conversion already waiting, or starts more than 1.5
//!   periods after the previous one, latches `Fault::Overrun`;
//! * the independent watchdog (2 ms) is fed only by a tick that ran on time; after a
//!   watchdog reset the controller starts with `Fault::Overrun` latched;
//! * a panic or a hard fault forces coast by register writes before anything else.
//!
//! Logs (defmt over RTT) come from the main loop only: a status line once a second.
//! `defmt-rtt`'s `drop-on-contention` mode never masks interrupts, so logging cannot
//! delay the tick.
//!
//! On the host this binary is a stub; `cargo test` runs the unit tests of [`board`] and
//! [`stats`] there.
#![cfg_attr(target_os = "none", no_std, no_main)]

// The modules live in src/bin/firmware/ (a crate root file resolves modules beside it).
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
#[path = "firmware/board.rs"]
mod board;
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
#[path = "firmware/stats.rs"]
mod stats;

#[cfg(target_os = "none")]
#[path = "firmware/app.rs"]
mod app;
#[cfg(target_os = "none")]
#[path = "firmware/hw.rs"]
mod hw;

/// The firmware only runs on the STM32F405; on the host this binary explains itself.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "the firmware runs on the STM32F405: build it with `cargo fw`, flash and run it with `cargo fw-run`"
    );
}
