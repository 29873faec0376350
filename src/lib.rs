//! # ema: robust position control of an electromagnetic actuator
//!
//! The `no_std`, `f32`-only control core of the EMA controller and the board's
//! application around it. One coil on a magnetic circuit with an airgap, a moving armature
//! held by a spring, a position sensor and a coil-current sensor; the coil is driven by a
//! PWM H-bridge. The method is the one of Deschaux, Gouaisbaut and Ariba, "Nonlinear
//! control for an uncertain electromagnetic actuator" (CDC 2018): flux fringing is
//! modelled as a bounded uncertainty on the airgap surfaces, the mechanical part is
//! controlled by backstepping and the coil current by a sliding-mode law built on the
//! uncertainty bounds.
//!
//! The same [`control::Config::tick`] runs in the firmware interrupt, in the host simulator
//! (`hil-sim`, through mock HAL pins) and on an emulated Cortex-M4F under QEMU.
//!
//! ## Two layers
//!
//! | layer | what it holds | uses |
//! |---|---|---|
//! | [`control`] (`src/control/`) | everything the control tick computes, from converter codes to the bridge, and the settings it is built from | nothing else in the crate |
//! | [`device`] (`src/device/`) | the board's application around the tick: operating states, the bench link, parameters and their store, the analog set point, commissioning, the guard, liveness; the same on the STM32F405 and on `hil-sim`'s virtual board | [`control`] |
//!
//! The build script compiles the control layer on its own (it derives the firmware's
//! settings from the actuator file with it), so the control layer cannot use the device
//! layer. The STM32 glue (timer, ADC, UART, flash, reset) is in the firmware binary
//! (`src/bin/firmware.rs`), not in the library.
//!
//! ## Module map
//!
//! The control layer; its root holds the tick ([`control::Settings`], [`control::Config`],
//! [`control::State`]), its submodules the stages, in the order the tick runs them, then
//! what they share:
//!
//! | module | concept |
//! |---|---|
//! | [`control`] | the settings, the validated configuration, the state and the one tick |
//! | [`control::sense`] | raw ADC codes to SI measurements, plausibility |
//! | [`control::shaping`] | the reference: set points shaped within the actuator's force limits |
//! | [`control::observer`] | velocity (and a force disturbance) from the sampled position |
//! | [`control::law`] | the control laws: the paper's law and the practical variants |
//! | [`control::supervisor`] | limits, fault detectors with history ([`control::supervisor::monitor`]), latched faults, safe state |
//! | [`control::bridge`] | H-bridge over `embedded-hal` 1.0 PWM and pins |
//! | [`control::model`] | reluctance network with flux fringing, `rho`, `L`, `mu` and their bounds |
//! | [`control::actuator`] | an actuator file (datasheet and bench) and every setting derived from it |
//! | [`control::config`] | the validation error every `build`/`try_build` returns: the parameter, its value and why |
//! | [`control::math`] | elementary functions with the same bits on the host and on the Cortex-M4F (correctly rounded square root, clamps, saturation) |
//! | [`control::trace`] | golden traces: ticks recorded on the host, replayed bit for bit on the target |
//!
//! The device layer; its root holds the application (the interrupt's
//! [`device::Controller`], the main loop's [`device::Dispatcher`], the queues between
//! them, [`device::boot`]):
//!
//! | module | concept |
//! |---|---|
//! | [`device`] | states (disarmed, armed, moving, commissioning, fault), the commands' dispatch, telemetry and capture around the tick |
//! | [`device::protocol`] | the bench link's messages (postcard) and frames (COBS and a CRC) |
//! | [`device::params`] | every parameter by name, validated as at build time |
//! | [`device::store`] | parameters in flash, power-fail safe, with a version and a CRC |
//! | [`device::analog`] | the optional analog set point (0-10 V or 4-20 mA, broken wire as a fault) |
//! | [`device::commission`] | measuring the actuator on the board, loop open: the coil's resistance from two voltage steps, its inductance at both end stops from step responses, the position sensor's readings there |
//! | [`device::guard`] | around the tick: deadlines, the hardware trip flag, feeding the watchdog |
//! | [`device::liveness`] | the link's timeout and the main loop's deadline: an armed board never outlives its host |
//!
//! ## Architecture: two data flows
//!
//! ### From the converter frame to the bridge (every tick, in the control interrupt)
//!
//! ```text
//! Frame -> sense -> limits -> set point -> shaping -> observer -> law -> supervisor -> bridge
//!          a fault on the way: latched by the supervisor, the bridge coasts (safe state)
//! ```
//!
//! The firmware's interrupt (the end of the ADC's conversions, once per PWM period) hands
//! the converter codes ([`control::sense::Frame`]) to [`device::Controller::tick`], which,
//! armed, runs [`control::Config::tick`] inside [`device::guard::Config::run`] (a hardware
//! trip or a late start latches a fault before the tick, an overrun after it). The tick,
//! in order:
//!
//! 1. **sense**: [`control::sense::Calibration::convert`] turns the codes into SI
//!    measurements (position, coil current, bus voltage); a code outside its channel's
//!    plausible window is a sensor fault.
//! 2. **limits**: [`control::supervisor::Limits::check`] compares the measurement with the
//!    trip limits (position range, over-current, bus window, non-finite values).
//! 3. **set point**: a non-finite set point is a fault; a finite one is clamped to the
//!    stroke.
//! 4. **shaping**: [`control::shaping::Config::step`] turns the set point into a reference
//!    (position and its derivatives), started from the measured position at the first
//!    tick; without shaping the reference holds the set point.
//! 5. **observer**: [`control::observer::Config::update`] estimates position, velocity
//!    and a force disturbance from the measured position and current.
//! 6. **law**: the configured law ([`control::law::Config`], through
//!    [`control::law::Law::step`]) computes the coil voltage from the estimate, the
//!    measured current and bus voltage, the reference, the previous period's applied
//!    voltage and the inductance probe's step, if one runs.
//! 7. **supervisor**: a non-finite law output or estimate is a fault; then the fault
//!    detectors with history ([`control::supervisor::monitor::Config::check`]: I^2 t,
//!    stuck sensor, the coil's electrical response, tracking) see the measured position
//!    and current, the reference, the set point and the estimated velocity.
//! 8. **bridge**: [`control::bridge::HBridge::apply_clear`] sets the duty and direction
//!    for the voltage on the measured bus (a failing PWM or pin is a fault); the applied
//!    voltage is kept for the next tick and recorded for the detectors.
//!
//! A fault at any step is latched by the supervisor ([`control::supervisor::State::trip`],
//! the first cause is kept) and the tick ends in the safe state: the bridge coasts. A tick
//! that starts with a fault latched goes straight to the safe state, until the fault is
//! cleared ([`control::Config::rearm`]). The tick returns a
//! [`control::Status`] with what each step produced.
//!
//! ### From a host command to a stored parameter (the main loop)
//!
//! ```text
//! bytes -> protocol -> device -> params -> interrupt (installs it, in use, unsaved)
//! Save  -> protocol -> device -> restart -> store (save, load) -> params (build) -> in use
//! ```
//!
//! 1. **protocol**: [`device::Dispatcher::receive`] takes the link's bytes;
//!    [`device::protocol::Framer`] cuts them into frames (COBS, CRC checked) and
//!    [`device::protocol::decode`] reads a [`device::protocol::Request`]. A frame that
//!    does not read is counted and answered with a rejection (at most one per
//!    millisecond).
//! 2. **device**: the dispatcher handles the request's
//!    [`device::protocol::Command`]. For [`device::protocol::Command::Set`], it changes a
//!    copy of the parameters in use by name ([`device::params::Params::set`]).
//! 3. **params**: [`device::params::Params::build`] validates the whole changed set as a
//!    build validates an actuator file and builds what the interrupt runs (the
//!    controller's [`control::Config`], the analog input, the link's timeout); a refusal
//!    is answered with the parameter, its value and why.
//! 4. The built configuration goes to the interrupt as an [`device::Order::Install`]; the
//!    interrupt installs it if the board is not armed, and the dispatcher then takes the
//!    changed set as the one in use, marked unsaved.
//! 5. **store**: [`device::protocol::Command::Save`] asks the interrupt to confirm the
//!    board is disarmed, answers that it is saving and hands the platform an
//!    [`device::Action::Save`] with the set in use. The platform starts again with that set
//!    ([`device::boot`]): [`device::store::Store::save`] writes it to flash (power-fail
//!    safe, with a format version and a CRC), then [`device::store::Store::load`] reads the
//!    stored set back and it is built again before it is used; a stored set that does not
//!    load or build gives way to the defaults.
//!
//! ## Glossary
//!
//! One meaning per word, as the code and its docs use it.
//!
//! | word | meaning |
//! |---|---|
//! | actuator file | the TOML that describes one actuator (mechanics, coil, magnetic circuit, board, tolerances, tuning) and from which every setting is derived ([`control::actuator`]) |
//! | stroke, stops | the armature's travel, measured from the **open stop** (`x = 0`, largest airgap, where the spring holds it with the coil off) to the **closed stop** (`x` = the stroke, the residual gap left) |
//! | practical law | the product's law ([`control::law::practical`]); the **paper's law** is the law as printed, kept to reproduce the paper |
//! | reference | the shaped trajectory (position, velocity, acceleration) the loop follows toward a **set point** |
//! | margin | the share of the force budget a planned move may use ([`control::shaping`]) |
//! | minimum-time move | the fastest move the limits allow: the planner's quintic at the whole force budget plus two **current rises** (the coil's rise from zero to the current limit at full drive, at the closed stop) |
//! | settling target | 1.5 minimum-time moves, at least the paper's 0.2 s ([`control::shaping::Config::settling_target_s`]) |
//! | rated current | the coil's continuous rating (the I^2 t detector's continuous current) |
//! | current limit | what the law may ask for: the rated current less the ripple allowance |
//! | trip | the sampled over-current level, the coil's peak current: seen once a period by the supervisor |
//! | break level | the board's over-current comparator on the timer's break input, 1.2 times the trip: it coasts the bridge between samples, without software |
//! | bounds | the controller's uncertainty set: the tolerances of mass, spring, friction and resistance and the airgap surfaces' interval, from which `mu_lo`, `mu_hi` and the inductance bounds follow ([`control::model`]) |
//! | fault | a cause the supervisor latches (the first is kept) until it is cleared; a **detector** is a fault check with history ([`control::supervisor::monitor`]) |
//! | safe state, coast | all bridge switches open: the current freewheels through the diodes against the bus and decays |
//! | armed, disarmed | the board drives the coil in closed loop, or keeps the bridge coasting; it boots disarmed |
//! | commissioning | measuring an actuator on the board: the coil's resistance and inductance and the position sensor's readings at the stops, loop open ([`device::commission`]), then with the loop closed the **holds**, which the bench tool orders |
//! | hold | during commissioning, the armature held in closed loop at 1/8, 7/8, 3/8 and 3/4 of the stroke, where the spring, its preload and the inductance are measured |
//! | probe | a voltage step during a hold or at a stop, from whose current response the inductance there is read |
//! | uncertainty | of a measured value: two standard errors of its fit (the expanded uncertainty, k = 2), in the value's unit (`uncertainty_ohm`, `uncertainty_m` of a [`device::commission::Report`]); the controller's **uncertainty set** (see bounds) is always named in full |
//! | tolerance | a stated relative half-width about a nominal value, `+-` (the plant's tolerances of mass, spring, friction and resistance; how far commissioning admits a coil off its file, [`device::commission::FILE_TOLERANCE`]) |
//! | allowance | a margin a check adds for what it does not model (the current limit's ripple allowance; the residual's allowance on the back-EMF, [`control::supervisor::monitor::EMF_ALLOWANCE`]) |
//! | peak-to-peak | the largest less the smallest of readings over a window (the current zero's samples, a stop's position window) |
//! | fringing spread | the growth `k` of each pole side per metre of gap, `S(g) = (a + k g)(b + k g)` (`magnetics.geometry.fringing_spread`); the only meaning of "spread" |
//!
//! ## What the paper gets wrong or leaves loose, and what the code does
//!
//! * Force direction: as printed, the magnetic force opens the airgap. A reluctance force
//!   closes it, and its stiffness destabilises the armature near the closed stop. Both
//!   conventions are supported ([`control::model::Convention`]): `Physical` (the stroke
//!   coordinate, the force closes the gap, back-EMF `-x2 x3 mu`) is the product's
//!   everywhere; `Paper`, as printed, only reproduces the paper.
//! * `mu_lo`/`mu_hi` are the exact extremes over the `rho_x` interval (the paper's formula
//!   leaves `rho_x` unspecified); they stay correct where `mu` is not monotone.
//! * `x3d^2 < 0` whenever `z2 > 0`: clipped to `x3d = 0`. Theorem 3's `eps` uses
//!   `|x3| + |x3d|`.
//! * The bound construction ignores how the airgap surface grows with the gap: with an
//!   energy-consistent fringing force the true `mu` can fall below `mu_lo`. The simulator
//!   checks over the stroke whether a controller's bounds bracket the true `mu` and `L`, and
//!   says so when they do not.
//! * Theorem 1's ball radius is a Lyapunov bound of the order of a metre, not a precision
//!   figure; it is computed and reported as such.
//! * Sampled at firmware rates the paper's law chatters tens of amperes. The product's law
//!   ([`control::law::practical`], the "practical law") keeps the paper's structure
//!   (backstepping on position and velocity on the robust design model, a sliding-mode
//!   current law built on the inductance bounds) and redesigns each stage for a sampled,
//!   delayed, noisy loop; the reason for each term is in its module docs.
//!
//! ## Guarantees
//!
//! * `#![no_std]` always (also in test builds of the library itself), no heap.
//! * `f32` only. Every operation the tick uses is IEEE-exact (`+ - * /` and a correctly
//!   rounded square root, [`control::math::sqrt`]), so the host and the Cortex-M4F compute
//!   the same bits for the same inputs.
//! * The tick cannot fail and cannot panic: `unwrap`, `expect`, `panic!`, indexing that can
//!   panic, unchecked casts and integer overflow are denied by lints below. Any non-finite or
//!   implausible value becomes a latched fault and the bridge coasts.
//!
//! ## Example: the paper's actuator under the paper's law
//!
//! ```
//! use ema::control::{law, model};
//!
//! let plant = model::Plant::paper();
//! let paper = law::paper::Gains::paper().build(&plant, 1.0 / 20_000.0).unwrap();
//!
//! // Theorem 1 for the paper's gains: a = -799, b = -40, Q negative definite.
//! let th = paper.theorem1();
//! assert_eq!(th.a, -799.0);
//! assert_eq!(th.b, -40.0);
//! assert!(th.eig_max < 0.0 && (th.eig_max + 2.035).abs() < 1e-3);
//!
//! // alpha2 = 10 fails Theorem 1 and the error says which parameter and why.
//! let bad = law::paper::Gains { alpha2: 10.0, ..law::paper::Gains::paper() };
//! let err = bad.build(&plant, 1.0 / 20_000.0).unwrap_err();
//! assert_eq!(err.param, "alpha2");
//! ```
#![no_std]
#![deny(unsafe_code)]
#![deny(missing_docs)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::todo,
    clippy::unimplemented,
    clippy::unreachable,
    clippy::indexing_slicing,
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap,
    clippy::float_cmp_const
)]
// Tests may unwrap: a failed unwrap is a failed test.
#![cfg_attr(
    test,
    allow(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects
    )
)]

pub mod control;
pub mod device;
