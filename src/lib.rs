//! # ema: robust position control of an electromagnetic actuator
//!
//! The `no_std`, `f32`-only control core of the EMA controller. One coil on a magnetic
//! circuit with an airgap, a moving armature held by a spring, a position sensor and a
//! coil-current sensor; the coil is driven by a PWM H-bridge. The method is the one of
//! Deschaux, Gouaisbaut and Ariba, "Nonlinear control for an uncertain electromagnetic
//! actuator" (CDC 2018): flux fringing is modelled as a bounded uncertainty on the airgap
//! surfaces, the mechanical part is controlled by backstepping and the coil current by a
//! sliding-mode law built on the uncertainty bounds.
//!
//! The same [`control::Config::tick`] runs in the firmware interrupt, in the host simulator
//! (`hil-sim`, through mock HAL pins) and on an emulated Cortex-M4F under QEMU.
//!
//! ## Modules, in the order the tick runs them
//!
//! | module | concept |
//! |---|---|
//! | [`control::actuator`] | an actuator file (datasheet and bench) and every setting derived from it |
//! | [`control::model`] | reluctance network with flux fringing, `rho`, `L`, `mu` and their bounds |
//! | [`control::sense`] | raw ADC codes to SI measurements, plausibility |
//! | [`control::observer`] | velocity (and a force disturbance) from the sampled position |
//! | [`control::shaping`] | the reference: set points shaped within the actuator's force limits |
//! | [`control::law`] | the control laws: the paper's law and the practical variants |
//! | [`control::supervisor`] | limits, latched faults, safe state |
//! | [`control::bridge`] | H-bridge over `embedded-hal` 1.0 PWM and pins |
//! | [`device::commission`] | measuring the actuator on the board, loop open: the coil's resistance from two voltage steps, its inductance at both end stops from step responses, the position sensor's readings there |
//! | [`control`] | the configuration, the state and the one `tick` |
//! | [`device::guard`] | around the tick: deadlines, the hardware trip flag, feeding the watchdog |
//! | [`control::trace`] | golden traces: ticks recorded on the host, replayed bit for bit on the target |
//!
//! Around the tick, the board's application, shared by the firmware and the virtual board:
//!
//! | module | concept |
//! |---|---|
//! | [`device`] | states (disarmed, armed, moving, commissioning, fault), the commands' dispatch, telemetry and capture around the tick |
//! | [`device::protocol`] | the bench link's messages (postcard) and frames (COBS and a CRC) |
//! | [`device::params`] | every parameter by name, validated as at build time |
//! | [`device::store`] | parameters in flash, power-fail safe, with a version and a CRC |
//! | [`device::analog`] | the optional analog set point (0-10 V or 4-20 mA, broken wire as a fault) |
//! | [`device::liveness`] | the link's timeout and the main loop's deadline: an armed board never outlives its host |
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
