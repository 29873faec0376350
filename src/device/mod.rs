//! The board's application, the same on the STM32F405 and on `hil-sim`'s virtual board:
//! the operating states, the commands of the link, the parameters and their store,
//! telemetry and captures. Everything target-specific (the timer, the ADC, the UART, the
//! flash, the reset) stays in the firmware; `hil-sim` gives the same two halves a
//! simulated plant, a pseudo-terminal and a simulated flash.
//!
//! This module's root is the application: its two halves ([`Controller`], [`Dispatcher`]), the
//! queues between them ([`Queues`]) and the start-up's [`boot`], each kept in a private file of
//! its own and named here. Its public submodules are what only the application uses: the link's
//! messages and frames ([`protocol`]), the parameters ([`params`]) and their store ([`store`]),
//! the analog set point ([`analog`]), the commissioning routine ([`commission`]), the checks
//! around each tick ([`guard`]) and the link's and main loop's liveness ([`liveness`]). It runs
//! the control layer ([`crate::control`]), which does not know it.
//!
//! **Where it runs.** The firmware's control interrupt runs [`Controller::tick`] and its
//! main loop the [`Dispatcher`], over USART2 and the chip's flash; `hil-sim`'s virtual
//! board runs the same two halves (the host tool is tested against it), and
//! `tests/qemu_device.rs` runs a scripted session of it on the Cortex-M4F.
//!
//! ## Two halves and three queues
//!
//! | half | runs in | owns |
//! |---|---|---|
//! | [`Controller`] | the control interrupt, every tick | the controller's configuration and state, the operating state, the set point, the capture buffer |
//! | [`Dispatcher`] | the main loop | the link (frames in and out), the parameters, the store |
//!
//! They share nothing but three single-producer single-consumer queues from `heapless`
//! ([`Queues`]): orders from the main loop to the interrupt ([`Ticket`], one at a time),
//! answers back ([`Answer`]), and telemetry samples ([`Telemetered`]). The interrupt
//! takes at most one order per tick and never waits; a full telemetry queue drops the
//! sample and counts it. Every decision that needs the present measurement (arming,
//! clearing) is taken by the interrupt, at the tick the order arrives; everything that
//! takes time (validating and building a configuration, reading the store, encoding
//! frames) is done by the main loop.
//!
//! ## Operating states
//!
//! ```text
//!            arm (no fault, sensors plausible, bus in window, 4-20 mA loop closed)
//! Disarmed ---------------------------> Armed <----> Moving   (a move in progress)
//!    ^  <------------- disarm ------------|             |
//!    |                                    +---- fault --+--> Fault (latched, coasting)
//!    +------------ clear (disarmed, cause gone) ---------------------+
//! ```
//!
//! * **Disarmed** (after every start): the bridge coasts, the sensors are read and
//!   checked every tick; nothing is driven.
//! * **Armed**: closed loop, holding the position measured when armed (with the link as
//!   the set point's source) or following the analog set point.
//! * **Moving**: armed, a move in progress (the reference shaping's).
//! * **Commissioning** (entered from Disarmed by
//!   [`Command::Commission`](protocol::Command::Commission), nothing latched, sensors and
//!   bus ready): the loop open, the bridge driven by the actuator's
//!   identification ([`commission`]); it returns to Disarmed when the result is in,
//!   when any order other than a status, stream or capture arrives (the bridge coasts at
//!   once), or to Fault when a fault latches (every tick still converts and checks the
//!   codes and the limits).
//! * **Fault**: a fault latched (by the tick, the guard, or the analog input's wire
//!   check); the bridge coasts until the fault is cleared, which leaves the board
//!   disarmed. Clearing is refused while the cause is still measured (a sensor
//!   implausible, the bus outside its window, the bridge's break input active, the
//!   4-20 mA loop open).
//!
//! ## Cost in the interrupt
//!
//! Disarmed, a tick converts and checks the codes and coasts the bridge. Armed, it is
//! `Config::tick` through the guard, plus: one queue poll, the analog input when chosen,
//! the operating state, and when due, one telemetry sample and one capture sample (a copy
//! of eight values). `tests/qemu_device.rs` counts the instructions on the Cortex-M4F.

pub mod analog;
pub mod commission;
pub mod guard;
pub mod liveness;
pub mod params;
pub mod protocol;
pub mod store;

mod boot;
mod controller;
mod dispatcher;
mod queues;

pub use boot::{boot, Action, Boot, Storage};
pub use controller::{Controller, CycleSummary, Cycles, Inputs, Ticked};
pub use dispatcher::{Counts, Dispatcher};
pub use queues::{Answer, Install, IsrEnds, MainEnds, Order, Outcome, Queues, Telemetered, Ticket};

/// Samples the firmware's capture buffer holds (at 20 kHz with a decimation of 20: 0.256 s).
pub const CAPTURE_CAPACITY: usize = 256;
/// Slots of the order queue (one order in flight, plus the queue's empty slot).
pub const ORDER_SLOTS: usize = 2;
/// Slots of the answer queue.
pub const ANSWER_SLOTS: usize = 2;
/// Slots of the telemetry queue.
pub const SAMPLE_SLOTS: usize = 16;
/// Bytes the dispatcher buffers for the link.
pub const TX_CAPACITY: usize = 1024;
/// Longest move a [`Command::Move`](protocol::Command::Move) may ask for \[s\].
pub const MAX_MOVE_S: f32 = 10.0;
/// Rejections ([`Message::Rejected`](protocol::Message::Rejected)) the board sends at most
/// per second: one per millisecond, about 10 bytes each, a fifth of the link's 46 bytes per
/// millisecond at most, however noisy the line; the rest are counted, not answered.
pub const REJECTIONS_PER_S: f32 = 1000.0;
/// Largest amplitude a [`Command::Probe`](protocol::Command::Probe) may ask for, as a share
/// of the rated current: a probe measures about a hold, it does not move the armature.
pub const PROBE_MAX_SHARE: f32 = 0.1;
