//! Commissioning: measuring the actuator on the board before the loop is closed on it.
//!
//! A user's coil never has its datasheet's resistance: the winding's tolerance and its
//! temperature move it by tens of per cent, and the law's current loop, the residual
//! detector's bounds and the thermal model all start from it. The first measurement is
//! therefore the coil's resistance, with the loop open; the second, the position sensor's
//! readings at the two end stops. The spring's rate and preload, which no open-loop pull
//! isolates (the magnet's stiffness exceeds the spring's near the closed stop, so the
//! armature jumps to a stop), are measured afterwards with the loop closed, as are the mass
//! and the friction: the host tool moves the armature to four positions over the link and
//! holds it there, and reads the magnet's pull from the captured current and the
//! inductances measured here, the spring's at the holds and the inertia's and the
//! friction's over the moves (`hil-sim bench commission --mechanics`).
//!
//! # The coil's resistance
//!
//! 1. two voltage steps, `u1` then `u2`, each chosen for a fraction of the rated current
//!    ([`LOW_SHARE`], [`HIGH_SHARE`]) at the file's resistance;
//! 2. at each, wait [`SETTLE_TIME_CONSTANTS`] of the slowest coil time constant the
//!    identification admits (the closed gap's inductance over the lowest resistance,
//!    [`FILE_TOLERANCE`] around the file), then average the applied voltage and the measured
//!    current over [`AVERAGE_TIME_CONSTANTS`] of them (at least [`MIN_AVERAGE_S`]);
//! 3. `R = (u2 - u1) / (i2 - i1)`. The difference removes what is constant in both steps:
//!    the current sensor's residual offset and the bridge's voltage drops.
//!
//! These first two steps set every later voltage only. Their pull may leave the armature
//! floating between the stops, and a lightly damped one rings there for seconds (a valve
//! with a damping ratio of 0.02): a window in which the position moves more than its noise
//! is averaged again for at most [`PATIENCE_PERIODS`] of the slowest mechanical period,
//! then taken as it is (the ringing's back-EMF averages out to a fraction of a per cent).
//! The resistance reported is measured the same way at the closed stop (below), where the
//! pull presses the armature against the stop and nothing moves.
//!
//! The uncertainty reported is two standard errors of that quotient from the scatter of the
//! averaged currents. The identification is abandoned, with its reason, when the current
//! exceeds the rating (a coil far below the file's resistance) or the currents of the two
//! steps do not differ (an open coil); a fault, a disarm or any other order also ends it.
//!
//! # The end stops
//!
//! A position sensor carries an offset and a gain error of a few per cent of the stroke,
//! which no controller acting on its reading removes. The readings at the two stops fix
//! both ([`crate::control::sense::PositionCorrection::from_stops`], set on the board as
//! `sensor.position_gain` and `sensor.position_offset_codes`). Still with the loop open, and with the voltages now set from the first two
//! steps' resistance, so that the current stays below the rating whatever the file said:
//!
//! 1. **open stop**: the coil off; once the armature has come back and rests (the wait is
//!    [`RELEASE_PERIODS`] of the slowest mechanical period the identification admits,
//!    `2 pi / w_n` with the spring and the mass [`FILE_TOLERANCE`] off the file), the reading is
//!    averaged over a window in which it stays still: its peak-to-peak within the noise's, and
//!    the means of its two halves within the noise of such a difference
//!    ([`Plan::drift_m`]). An overdamped armature with little preload creeps back onto
//!    the stop, its spring's pull vanishing there, and a creep of ten codes over a
//!    window hides inside the noise's peak-to-peak but not from the halves' means;
//! 2. **approach**: the voltage ramps over [`RAMP_PERIODS`] mechanical periods to the one
//!    that holds [`FULL_SHARE`] of the rated current, slowly against the coil's and the
//!    armature's time constants: the current follows the ramp, the magnet pulls the
//!    armature over to the closed stop, the coil's back-EMF damping the last, unstable
//!    part of the travel (the magnet's stiffness exceeds the spring's near the stop);
//! 3. **closed stop**: the reading is averaged at [`FULL_SHARE`] and again at
//!    [`NEAR_SHARE`] of the rated current. An armature pressed against the stop stays
//!    when the pull falls (the pull grows steeply as the gap closes); one that moved
//!    between the two was held by its spring short of the stop, which the rated current
//!    then cannot reach;
//! 4. **resistance**: from the two holds' voltages and currents, as from the first two
//!    steps, the armature pressed against the stop.
//!
//! The coil's inductance is measured at both stops too, with the armature still: at the
//! open stop from a probe that steps the current between two small levels
//! ([`Plan::probe_a`]: [`PROBE_HIGH_SHARE`] of the rating, or less where the file's
//! spring is soft against its magnet, [`PROBE_PULL_SHARE`]), at the closed stop from the
//! step from [`FULL_SHARE`] down to [`NEAR_SHARE`]. Each step goes to a level `i_end`
//! measured in a hold's window (the closed stop's after the step: the fit's sums are
//! linear in `i_end`, so it enters once known); sampled at the same point of every PWM
//! period whatever the ripple, the current then decays geometrically, `y(k+1) = a y(k)`
//! with `y = i - i_end` and `a = exp(-Ts R / L)`. `a` follows from the ratio of two sums of
//! the readings the converter's delay lets answer the step, weighted by `g^k` and by
//! `g^2k`, `g` falling as the file's coil would ([`Plan::guess_factor`], down to
//! [`FIT_WEIGHT_FLOOR`]): both sums are linear in the readings, so the converter's noise
//! does not bias them (a least squares on `y(k)` itself, whose regressor carries that
//! noise, read a soft-sprung plunger's small probe 6 % high), and both draw on the
//! whole decay, so no single reading's noise sets the result. `L = -Ts R / ln a` with the
//! resistance from the closed stop. A coil whose time constant is about the period has
//! decayed within the converter's delay and a reading or two, and the noise on those few
//! readings is what bounds the result: [`Plan::inductance_uncertainty`] says by how much,
//! for whoever writes the reading down. The probe's pull moves the armature a little
//! off the open stop (the end stops calibrate how far, from its position averaged over
//! the probe's cycle); `1/L` being linear in the gap, the line through the probe's and
//! the closed stop's values gives the open stop's. The two inductances are the magnetic
//! circuit's two-inductance form in the actuator file.
//!
//! The travel between the two readings must be positive (else the sensor is wired
//! backwards) and at least [`MIN_TRAVEL_SHARE`] of the stroke (else the armature is stuck,
//! or no spring brings it back). The end points are means of the file's calibrated reading:
//! the offset and the gain of the sensor follow from them and the stroke.
//!
//! Everything here runs in the control interrupt: no allocation, no panic, `f32` only.

mod decay;
mod identification;
mod plan;
mod report;
mod window;

use decay::Decay;
pub use identification::{Identification, Step};
pub use plan::{Coil, Plan};
pub use report::{Abort, Ends, Inductance, Report, Resistance};
use window::{resistance, Window};

/// Share of the rated current the first step aims at (at the file's resistance).
pub const LOW_SHARE: f32 = 0.3;
/// Share of the rated current the second step aims at.
pub const HIGH_SHARE: f32 = 0.6;
/// The coil may be this far (either way, as a share) from its file's resistance and its
/// inductance: the waits are long enough for the slowest such coil.
pub const FILE_TOLERANCE: f32 = 0.5;
/// Time constants waited at each step before averaging (e^-6: 0.25 % of the step left).
pub const SETTLE_TIME_CONSTANTS: f32 = 6.0;
/// Shortest averaging window \[s\] (many converter samples even for a fast coil).
pub const MIN_AVERAGE_S: f32 = 0.02;
/// Slowest coil time constants averaged at each hold (at least [`MIN_AVERAGE_S`]).
pub const AVERAGE_TIME_CONSTANTS: f32 = 2.0;
/// Slowest mechanical periods a hold may spend restarting its window because the armature
/// was still moving (its motion induces a voltage the steady state must not contain, and
/// its mean position is no stop's) before it gives up; at least one restart, whatever the
/// coil ([`Plan::patience_ticks`]).
pub const PATIENCE_PERIODS: f32 = 4.0;
/// Slowest mechanical periods waited at each hold at the stops (after the coil's
/// settling), before its window: a quarter period is the time the slowest armature
/// admitted, released, takes to swing back to its rest. A window the armature's
/// bounce or creep still moves in starts again ([`PATIENCE_PERIODS`]). Each of the five
/// holds waits it: on a slow armature (a 1 kg plunger on a soft spring, a period near
/// 1.5 s) it is most of the routine's time.
pub const RELEASE_PERIODS: f32 = 0.25;
/// Slowest mechanical periods the approach's voltage ramp lasts.
pub const RAMP_PERIODS: f32 = 0.5;
/// Share of the rated current (at the first two steps' resistance) the approach ends at
/// and the first hold at the closed stop holds.
pub const FULL_SHARE: f32 = 0.95;
/// Share of the rated current of the second hold at the closed stop: the pull falls by
/// `1 - (NEAR / FULL)^2`, 38 %, and an armature pressed against the stop does not move
/// (the magnet's pull grows steeply as the gap closes), while one the spring held short
/// of the stop moves back.
pub const NEAR_SHARE: f32 = 0.75;
/// Largest share of the rated current of the inductance probe's upper level at the open
/// stop: the steps from it and back are fitted, large for many readings above the noise,
/// small for a pull (4 % of the rated one) that leaves the armature near its stop.
pub const PROBE_HIGH_SHARE: f32 = 0.2;
/// The probe's lower level, as a share of its upper one: the coil stays driven, and the
/// step down is three quarters of the upper level.
pub const PROBE_LOW_PER_HIGH: f32 = 0.25;
/// Largest pull of the probe's upper level at the open stop, as a share of the spring's
/// force over the stroke, for the weakest spring and the strongest magnet within
/// [`FILE_TOLERANCE`] of the file: a soft spring would let the rated share pull the armature in.
pub const PROBE_PULL_SHARE: f32 = 0.1;
/// Readings per time constant at the open stop the probe's cycles gather together: a
/// coil faster than the period gives few per step, and the inductance comes from the
/// decay's shape, so the cycles add readings until the fit has this many per time
/// constant.
pub const PROBE_READINGS: f32 = 64.0;
/// Most cycles of the probe (the product's: 53 ms of 1.7 ms levels). More cycles average
/// more noise away, but each pulls the armature a little further off the stop, and a
/// surface growing with the gap bends the line the open stop's value is extrapolated on:
/// the cap trades the noise against that bend.
pub const MAX_PROBE_CYCLES: u32 = 16;
/// A step-response fit ends where the file's coil would have decayed to this share of
/// the step (e^-6: six of its time constants).
pub const FIT_WEIGHT_FLOOR: f32 = 0.0025;
/// Least travel between the stops, as a share of the file's stroke.
pub const MIN_TRAVEL_SHARE: f32 = 0.5;

#[cfg(test)]
mod tests;
