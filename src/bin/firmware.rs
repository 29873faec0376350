//! STM32F405 firmware: the control core in a fixed-rate interrupt, the bench application
//! around it.
//!
//! TIM1 runs the bridge PWM at 20 kHz, center-aligned, and drives all three bridge lines
//! (PWM, enable, direction) as timer outputs; once per period its compare channel 4
//! triggers ADC1, which converts position, coil current, bus voltage and the analog set
//! point around the top of the count; the end of that sequence interrupts, and the
//! interrupt runs the application's `ema::device::Controller::tick` (the operating state,
//! one order from the main loop, `ema::control::Config::tick` through `ema::device::guard`,
//! telemetry and capture) and writes the next duty, direction and enable, which the timer
//! applies together at the next period boundary. The board boots disarmed, with the
//! bridge coasting. The main loop serves the bench link (USART2 by DMA, `link`) with
//! `ema::device::Dispatcher`, and the parameters live in flash sectors 1 and 2 through
//! `ema::device::store`, loaded at start (an earlier format migrated; a damaged or unknown
//! set falls back to the built-in defaults and says so) and saved at the next start, before
//! the control runs. Pins, clocks and every other hardware fact are in [`board`]; the
//! register values in [`regs`]; register-level set-up in `hw`; start-up, the interrupts,
//! the status line and the panic and fault handlers in `app`; what survives a reset in
//! [`reset`].
//!
//! Safety measures, in the order they act:
//! * the board pulls the bridge lines low, so the bridge coasts through reset and boot;
//! * the independent watchdog runs from the first line of start-up with a boot timeout
//!   (`board::IWDG_BOOT`, 2.7 s at least) longer than everything start-up does, each of
//!   its waits bounded (the crystal 100 ms, the PLL 2 ms, a deferred flash save): a good
//!   board never starts with a watchdog reset, a crystal that does not start is named
//!   (`StartError::ClockSetup`), and a start refused three times in a row stays refused,
//!   logging why, instead of cycling through resets; start-up tightens it to 2 ms
//!   (`board::IWDG_RUN`) just before the control interrupt starts;
//! * start-up keeps the timer's main output off (all three lines driven low) until the
//!   end, measures the current-sensor zero with the bridge off (an implausible zero
//!   latches `Fault::CurrentOffset`), and refuses to run unless the update event falls at
//!   the top of the count and the conversions end where the trigger places them;
//! * the driver's fault output and a comparator on the current shunt stop the timer's
//!   outputs through its break input, without software, and the next tick latches
//!   `Fault::HardwareTrip`; a failing crystal does the same (clock security system), and
//!   its interrupt coasts the bridge;
//! * the tick cannot panic (link-time proof: `tests/qemu_no_panic.rs`) and latches any
//!   implausible input as a fault with the bridge coasting;
//! * the guard (`ema::device::guard`) latches `Fault::Overrun` for a tick that starts more
//!   than 1.5 periods after the previous one, ends with the next conversion waiting, or
//!   ends after the period boundary its writes were for; only on-time ticks feed the
//!   watchdogs, and only while the main loop checks in (`ema::device::liveness`: a main
//!   loop silent for 20 ms latches `Fault::MainLoopStalled`, the bridge coasts and the
//!   watchdogs end the run; the next start keeps the fault);
//! * armed for the link, a host silent for `link.timeout_s` disarms the board with
//!   `Fault::LinkTimeout` latched (`ema::device::liveness`);
//! * the window watchdog's early wake-up (at most 292.6 us after the last feed) coasts the
//!   bridge, its reset follows one count later; the independent watchdog (2 ms) is the
//!   last resort; after a watchdog reset the controller starts with `Fault::Overrun`
//!   latched unless the stop was a refused start ([`reset`]);
//! * a panic, a hard fault or an unexpected interrupt coasts the bridge by register writes
//!   before anything else;
//! * under a debugger halt, TIM1 stops with its outputs at their idle level (low: the
//!   bridge coasts) and both watchdogs pause.
//!
//! Logs (defmt over RTT) come from the main loop only: a status line once a second.
//! `defmt-rtt`'s `drop-on-contention` mode never masks interrupts, so logging cannot
//! delay the tick.
//!
//! On the host this binary is a stub; `cargo test` runs the unit tests of [`board`],
//! [`regs`], [`reset`] and [`stats`] there.
#![cfg_attr(target_os = "none", no_std, no_main)]

// The modules live in src/bin/firmware/ (a crate root file resolves modules beside it).
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
#[path = "firmware/board.rs"]
mod board;
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
#[path = "firmware/regs.rs"]
mod regs;
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
#[path = "firmware/reset.rs"]
mod reset;
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
#[path = "firmware/stats.rs"]
mod stats;

#[cfg(target_os = "none")]
#[path = "firmware/app.rs"]
mod app;
#[cfg(target_os = "none")]
#[path = "firmware/hw.rs"]
mod hw;
#[cfg(target_os = "none")]
#[path = "firmware/link.rs"]
mod link;

/// The firmware only runs on the STM32F405; on the host this binary explains itself.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "the firmware runs on the STM32F405: build it with `cargo fw`, flash and run it with `cargo fw-run`"
    );
}
