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
//!    [`SPREAD`] around the file), then average the applied voltage and the measured
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
//! The uncertainty reported is two standard errors of that quotient from the spread of the
//! averaged currents. The identification is abandoned, with its reason, when the current
//! exceeds the rating (a coil far below the file's resistance) or the currents of the two
//! steps do not differ (an open coil); a fault, a disarm or any other order also ends it.
//!
//! # The end stops
//!
//! A position sensor carries an offset and a gain error of a few per cent of the stroke,
//! which no controller acting on its reading removes. The readings at the two stops fix
//! both. Still with the loop open, and with the voltages now set from the first two
//! steps' resistance, so that the current stays below the rating whatever the file said:
//!
//! 1. **open stop**: the coil off; once the armature has come back and rests (the wait is
//!    [`RELEASE_PERIODS`] of the slowest mechanical period the identification admits,
//!    `2 pi / w_n` with the spring and the mass [`SPREAD`] off the file), the reading is
//!    averaged over a window in which it stays still: its spread within the noise's, and
//!    the means of its two halves within the noise of such a difference
//!    ([`Plan::drift_m`]). An overdamped armature with little preload creeps back onto
//!    the stop, its spring's pull vanishing there, and a creep of ten codes over a
//!    window hides inside the noise's spread but not from the halves' means;
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
//! noise, read a soft-sprung plunger's small probe 6 % high), and both spread over the
//! whole decay, so no single reading's noise sets the result. `L = -Ts R / ln a` with the
//! resistance from the closed stop. The probe's pull moves the armature a little
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

use serde::{Deserialize, Serialize};

use crate::control::math;
use crate::control::sense::Measurement;

/// Share of the rated current the first step aims at (at the file's resistance).
pub const LOW_SHARE: f32 = 0.3;
/// Share of the rated current the second step aims at.
pub const HIGH_SHARE: f32 = 0.6;
/// The coil may be this far (either way, as a share) from its file's resistance and its
/// inductance: the waits are long enough for the slowest such coil.
pub const SPREAD: f32 = 0.5;
/// Time constants waited at each step before averaging (e^-6: 0.25 % of the step left).
pub const SETTLE_TIME_CONSTANTS: f32 = 6.0;
/// Shortest averaging window \[s\] (many converter samples even for a fast coil).
pub const MIN_AVERAGE_S: f32 = 0.02;
/// Slowest coil time constants averaged at each hold (at least [`MIN_AVERAGE_S`]).
pub const AVERAGE_TIME_CONSTANTS: f32 = 2.0;
/// Slowest mechanical periods a hold may spend restarting its window because the armature
/// was still moving (its motion induces a voltage the steady state must not contain, and
/// its mean position is no stop's) before it gives up.
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
/// [`SPREAD`] of the file: a soft spring would let the rated share pull the armature in.
pub const PROBE_PULL_SHARE: f32 = 0.1;
/// Readings per time constant at the open stop the probe's cycles gather together (a
/// coil faster than the period gives few per step). Half as many read one of 1000 drawn
/// micro-valves' open stops 5 % off (its 16 cycles take 50 ms, its 10 then 30 ms).
pub const PROBE_READINGS: f32 = 64.0;
/// Most cycles of the probe (the product's: 53 ms of 1.7 ms levels). Each cycle pulls the
/// armature a little further off the stop, and a surface growing with the gap bends the
/// line the open stop's value is extrapolated on: twice as many read 1000 drawn products'
/// open stops with a 99th percentile of 2.2 % instead of 3.2 %, but a product whose pole
/// grows by 0.3 of the gap with its curve 0.54 % off instead of 0.15 %.
pub const MAX_PROBE_CYCLES: u32 = 16;
/// A step-response fit ends where the file's coil would have decayed to this share of
/// the step (e^-6: six of its time constants).
pub const FIT_WEIGHT_FLOOR: f32 = 0.0025;
/// Least travel between the stops, as a share of the file's stroke.
pub const MIN_TRAVEL_SHARE: f32 = 0.5;

/// What the identification does, computed by the main loop from the parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// Voltages of the two steps \[V\].
    pub u_v: [f32; 2],
    /// Ticks waited at each step before averaging.
    pub settle_ticks: u32,
    /// Ticks averaged at each step.
    pub average_ticks: u32,
    /// Current above which the identification stops \[A\] (the coil's rating).
    pub abort_a: f32,
    /// Interrupt period \[s\].
    pub period_s: f32,
    /// Readings after a voltage step that may still be conversions from before it (the
    /// converter's delay).
    pub skip_readings: u32,
    /// The file's coil's current decay factor per period, `exp(-Ts R / L)`, at the open
    /// and at the closed stop: the step-response fits' weights.
    pub guess_factor: [f32; 2],
    /// Largest spread of the position readings over a window with the armature at rest
    /// \[m\] (the sensor's noise): a wider one restarts the window.
    pub still_m: f32,
    /// Largest difference between the mean positions of a window's two halves with the
    /// armature at rest \[m\]: four deviations of that difference, as [`Plan::still_m`]
    /// is twice four deviations of the difference of two readings. A larger one is a slow
    /// creep (an overdamped armature coming back to a stop with little preload, well
    /// inside the noise's spread) and restarts the window.
    pub drift_m: f32,
    /// Ticks waited after the coil is switched off before the open stop's window (and at
    /// each hold at the closed stop).
    pub release_ticks: u32,
    /// Ticks of the approach's voltage ramp.
    pub ramp_ticks: u32,
    /// Ticks a hold may spend restarting its window (each restart with the wait for the
    /// coil to settle before it).
    pub patience_ticks: u32,
    /// Ticks at each level of the inductance probe's cycle ([`SETTLE_TIME_CONSTANTS`] of
    /// the slowest coil at the open stop).
    pub probe_half_ticks: u32,
    /// Cycles of the probe: enough for [`PROBE_READINGS`] readings per time constant at
    /// the open stop, at most [`MAX_PROBE_CYCLES`].
    pub probe_cycles: u32,
    /// The probe's two currents, lower and upper \[A\]: [`PROBE_HIGH_SHARE`] of the
    /// rating, or less where [`PROBE_PULL_SHARE`] asks it; the lower
    /// [`PROBE_LOW_PER_HIGH`] of the upper.
    pub probe_a: [f32; 2],
    /// The file's stroke \[m\].
    pub stroke_m: f32,
}

/// What the plan is made from: the file's actuator, the board's rate and its noise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coil {
    /// Coil resistance \[ohm\].
    pub resistance_ohm: f32,
    /// Smallest inductance, at the open stop \[H\].
    pub open_inductance_h: f32,
    /// Largest inductance, at the closed stop \[H\].
    pub closed_inductance_h: f32,
    /// Rated current \[A\].
    pub rated_a: f32,
    /// Mechanical natural frequency `sqrt(K / m)` \[rad/s\].
    pub natural_rad_s: f32,
    /// Stroke \[m\].
    pub stroke_m: f32,
    /// Spring rate \[N/m\].
    pub spring_n_per_m: f32,
    /// The magnet's force coefficient at the open stop, `F = mu i^2 / 2` \[H/m\].
    pub open_force_h_per_m: f32,
}

impl Plan {
    /// The plan for actuator `a` on a board ticking at `rate_hz`: its coil and armature
    /// from the file, the readings' delay and noise from the board's converter.
    ///
    /// # Errors
    /// The actuator's time scales do not derive, or the plan's inputs are not positive
    /// (named by the coil's resistance).
    pub fn for_actuator(
        a: &crate::control::actuator::Actuator,
        rate_hz: f32,
    ) -> Result<Self, crate::control::config::Error> {
        let r = a.coil.resistance_ohm;
        let t = a.time_scales()?;
        let plant = a.plant()?;
        let open_force_h_per_m = plant
            .envelope()?
            .nominal()
            .force_coefficient_h_per_m(plant.gap_m(0.0));
        // The position's noise at rest: the allowance the detectors use for the
        // difference of two readings, twice (a window's extremes, not two readings).
        let still_m =
            2.0 * crate::control::actuator::NOISE_ALLOWANCE_CODES * t.position_code_m.abs();
        let coil = Coil {
            resistance_ohm: r,
            open_inductance_h: t.coil_open_s * r,
            closed_inductance_h: t.coil_closed_s * r,
            rated_a: a.coil.rated_current_a,
            natural_rad_s: t.natural_rad_s,
            stroke_m: a.mechanics.stroke_m,
            spring_n_per_m: a.mechanics.spring_n_per_m,
            open_force_h_per_m,
        };
        Self::new(
            &coil,
            rate_hz,
            crate::control::actuator::DELAY_TICKS,
            still_m,
        )
        .ok_or(crate::control::config::Error {
            param: "coil.resistance_ohm",
            value: r,
            reason: crate::control::config::Reason::NotPositive,
        })
    }

    /// The plan for the file's `coil`, at `rate_hz`, with readings `delay_ticks` periods
    /// old and a position reading whose noise spans `still_m` at rest. `None` for values
    /// that are not positive and finite.
    #[must_use]
    pub fn new(coil: &Coil, rate_hz: f32, delay_ticks: u8, still_m: f32) -> Option<Self> {
        let Coil {
            resistance_ohm,
            open_inductance_h,
            closed_inductance_h,
            rated_a,
            natural_rad_s,
            stroke_m,
            spring_n_per_m,
            open_force_h_per_m,
        } = *coil;
        let positive = |v: f32| v.is_finite() && v > 0.0;
        if !(positive(resistance_ohm)
            && positive(open_inductance_h)
            && positive(closed_inductance_h)
            && positive(rated_a)
            && positive(natural_rad_s)
            && positive(stroke_m)
            && positive(spring_n_per_m)
            && positive(open_force_h_per_m)
            && positive(rate_hz)
            && positive(still_m))
        {
            return None;
        }
        // The slowest armature admitted: spring SPREAD softer, mass SPREAD heavier.
        let slowest_w = natural_rad_s * math::sqrt((1.0 - SPREAD) / (1.0 + SPREAD));
        let period_s = 2.0 * core::f32::consts::PI / slowest_w;
        let slowest_s = closed_inductance_h * (1.0 + SPREAD) / (resistance_ohm * (1.0 - SPREAD));
        let slowest_open_s = open_inductance_h * (1.0 + SPREAD) / (resistance_ohm * (1.0 - SPREAD));
        let settle_s = SETTLE_TIME_CONSTANTS * slowest_s;
        // The weakest spring's force over the stroke against the strongest magnet's pull.
        let pull_a = math::sqrt(
            2.0 * PROBE_PULL_SHARE * spring_n_per_m * (1.0 - SPREAD) * stroke_m
                / (open_force_h_per_m * (1.0 + SPREAD)),
        );
        let probe_high_a = math::min(PROBE_HIGH_SHARE * rated_a, pull_a);
        let ticks = |s: f32| {
            let t = libm::ceilf(s * rate_hz);
            if (1.0..1e9).contains(&t) {
                // A whole number (ceil) within u32's range.
                #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                Some(t as u32)
            } else {
                None
            }
        };
        let average_ticks = ticks(math::max(AVERAGE_TIME_CONSTANTS * slowest_s, MIN_AVERAGE_S))?;
        Some(Self {
            u_v: [
                LOW_SHARE * rated_a * resistance_ohm,
                HIGH_SHARE * rated_a * resistance_ohm,
            ],
            settle_ticks: ticks(settle_s)?,
            average_ticks,
            abort_a: rated_a,
            period_s: 1.0 / rate_hz,
            skip_readings: u32::from(delay_ticks) + 1,
            guess_factor: [open_inductance_h, closed_inductance_h]
                .map(|h| libm::expf(-resistance_ohm / (h * rate_hz))),
            still_m,
            // still_m is 8 deviations of a two-reading difference (sqrt 2 of a reading's);
            // two half-window means of n/2 readings differ with sqrt(4/n) of a reading's:
            // four of those are still_m / sqrt(2 n).
            drift_m: still_m / math::sqrt(2.0 * average_ticks as f32),
            release_ticks: ticks(RELEASE_PERIODS * period_s + settle_s)?,
            ramp_ticks: ticks(RAMP_PERIODS * period_s)?,
            patience_ticks: ticks(PATIENCE_PERIODS * period_s)?,
            probe_half_ticks: ticks(SETTLE_TIME_CONSTANTS * slowest_open_s)?,
            probe_cycles: {
                let per_constant = open_inductance_h / resistance_ohm * rate_hz;
                let c = libm::ceilf(PROBE_READINGS / per_constant);
                // At least one, at most the cap: within u32.
                #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let c = math::min(math::max(c, 1.0), MAX_PROBE_CYCLES as f32) as u32;
                c
            },
            probe_a: [PROBE_LOW_PER_HIGH * probe_high_a, probe_high_a],
            stroke_m,
        })
    }

    /// Levels the probe's cycle holds: up and down `probe_cycles` times, ending down.
    #[must_use]
    pub const fn probe_halves(&self) -> u32 {
        self.probe_cycles.saturating_mul(2).saturating_sub(1)
    }

    /// Ticks the whole identification takes when no window restarts: the first two
    /// steps, the probe's cycles; the open stop, the probe's two levels, the approach and
    /// the two holds at the closed stop.
    #[must_use]
    pub const fn ticks(&self) -> u64 {
        let window = self.average_ticks as u64;
        let step = (self.settle_ticks as u64).saturating_add(window);
        let hold = (self.release_ticks as u64).saturating_add(window);
        let cycle = (self.probe_half_ticks as u64)
            .saturating_mul(self.probe_halves() as u64)
            .saturating_add(window);
        step.saturating_mul(2)
            .saturating_add(cycle)
            .saturating_add(hold.saturating_mul(5))
            .saturating_add(self.ramp_ticks as u64)
    }
}

/// Why an identification stopped without a result.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Abort {
    /// The current exceeded the rating (the coil is far below its file's resistance, or
    /// shorted).
    OverRated,
    /// The two steps gave the same current: no coil, or an open one.
    NoResponse,
    /// The armature never came to rest (see [`PATIENCE_PERIODS`]).
    NotAtRest,
    /// The armature moved between the two holds at the closed stop: its spring held it
    /// short of the stop, which the rated current cannot reach.
    NoStop,
    /// The reading fell from the open stop to the closed one: the sensor reads backwards.
    Backwards,
    /// Less than [`MIN_TRAVEL_SHARE`] of the stroke between the stops: the armature is
    /// stuck, or no spring brings it back.
    NoTravel,
    /// A current step did not decay geometrically: the armature moved, or something
    /// other than a coil answers.
    NoDecay,
    /// The probe's pull took the armature more than half its stroke off the open stop:
    /// the open stop's inductance cannot be extrapolated from there.
    PulledIn,
    /// A fault latched during the identification.
    Fault,
    /// Ended by an order (disarm, or another command).
    Stopped,
}

impl Abort {
    /// Lower-case name.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Abort::OverRated => "current_above_rating",
            Abort::NoResponse => "no_response",
            Abort::NotAtRest => "not_at_rest",
            Abort::NoStop => "closed_stop_not_reached",
            Abort::Backwards => "position_backwards",
            Abort::NoTravel => "no_travel",
            Abort::NoDecay => "step_response_not_a_coil",
            Abort::PulledIn => "probe_pulled_the_armature_in",
            Abort::Fault => "fault",
            Abort::Stopped => "stopped",
        }
    }
}

/// The coil's resistance as measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Resistance {
    /// Resistance \[ohm\].
    pub ohm: f32,
    /// Two standard errors of it from the converter's noise \[ohm\].
    pub spread_ohm: f32,
    /// Mean currents of the two steps \[A\].
    pub i_a: [f32; 2],
    /// Mean applied voltages of the two steps \[V\].
    pub u_v: [f32; 2],
    /// Mean bus voltage over both steps \[V\].
    pub vbus_v: f32,
}

/// The position readings at the two end stops, in the file's calibration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Ends {
    /// Mean reading at the open stop, the coil off \[m\].
    pub open_m: f32,
    /// Mean reading at the closed stop, at [`FULL_SHARE`] of the rated current \[m\].
    pub closed_m: f32,
    /// Two standard errors of the noisier of the two means \[m\].
    pub spread_m: f32,
}

/// The coil's inductance at the two end stops.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Inductance {
    /// At the open stop (the largest gap) \[H\].
    pub open_h: f32,
    /// At the closed stop (the residual gap) \[H\].
    pub closed_h: f32,
}

/// Everything a commissioning measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// The coil's resistance.
    pub resistance: Resistance,
    /// The position sensor's readings at the end stops.
    pub ends: Ends,
    /// The coil's inductance at the end stops.
    pub inductance: Inductance,
}

/// A current's response to a voltage step towards a level `i_end` (measured before the
/// step, or by the hold after it: the sums are linear in it), the armature still:
/// `y(k) = i(k) - i_end` obeys `y(k) = A a^k` from the first reading the converter's
/// delay lets answer the step. Two weighted sums of the readings,
/// `S1 = sum w(k) y(k)` and `S2 = sum w(k) |w(k)| y(k)`, the weight `w(k) = +-g^k` (the
/// sign of the step's deviation, `+` for a step down) falling as the file's coil would
/// (`g`, its factor per period), are `A / (1 - g a)` and `A / (1 - g^2 a)`: their ratio
/// `r = S1 / S2` does not depend on the step's size, and `a = (r - 1) / (g (r - g))`.
/// Several steps add to both sums alike.
///
/// Both sums are linear in the readings, so their noise (zero mean) does not bias them,
/// as it biases a least squares on `y(k)` itself (whose regressor's noise variance a small
/// probe's readings are comparable with); and each spreads its weight over the whole
/// decay, so no single reading sets the estimate. (The instrument
/// `sum w(k) y(k+1) / sum w(k) y(k)` is unbiased too, but its two sums differ by the
/// first reading alone: one reading's noise on a 50-code step read a soft-sprung
/// plunger's inductance up to 20 % off, ten times what the two sums give.) The weight's
/// guess only costs efficiency, not accuracy.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Decay {
    /// The level the current settles at \[A\] (`NaN`: no fit in this phase).
    end_a: f32,
    /// Readings since the step (`u32::MAX`: the step has not come yet).
    since: u32,
    /// The weight of the next reading (0: this step's fit has ended).
    weight: f32,
    /// The file's coil's factor per period, the weight's decay.
    guess: f32,
    /// `S1` and `S2` of the deviations from `end_a`.
    s1: f32,
    s2: f32,
    /// Sums of the weights and of `w |w|`: the sums for an end other than `end_a`.
    sw1: f32,
    sw2: f32,
}

impl Decay {
    const NONE: Self = Self::towards(f32::NAN, 1.0, 0.0);

    const fn towards(end_a: f32, sign: f32, guess: f32) -> Self {
        Self {
            end_a,
            since: u32::MAX,
            weight: sign,
            guess,
            s1: 0.0,
            s2: 0.0,
            sw1: 0.0,
            sw2: 0.0,
        }
    }

    /// The next step goes to `end_a`, down for `sign` `+1`, up for `-1`; the sums so far
    /// are kept.
    fn retarget(&mut self, end_a: f32, sign: f32) {
        self.end_a = end_a;
        self.since = u32::MAX;
        self.weight = sign;
    }

    /// A reading `i_a`; `stepped`: the voltage over the period it ends differs from the
    /// one before; `skip`: readings after the step that may still be the converter's
    /// earlier conversions.
    fn add(&mut self, i_a: f32, stepped: bool, skip: u32) {
        if self.end_a.is_nan() || self.weight == 0.0 {
            return;
        }
        if self.since == u32::MAX {
            if !stepped {
                return;
            }
            self.since = 0;
        } else {
            self.since = self.since.saturating_add(1);
        }
        if self.since < skip {
            return;
        }
        let w = self.weight;
        let w2 = w * w.abs();
        let y = i_a - self.end_a;
        self.s1 += w * y;
        self.s2 += w2 * y;
        self.sw1 += w;
        self.sw2 += w2;
        self.weight *= self.guess;
        if self.weight.abs() < FIT_WEIGHT_FLOOR {
            // The file's coil would have settled: the rest is noise.
            self.weight = 0.0;
        }
    }

    /// The factor per period `a`, the current's end `shift_a` from `end_a` (the sums are
    /// linear in it); `None` unless `0 < a < 1`.
    fn factor(&self, shift_a: f32) -> Option<f32> {
        let r = (self.s1 - shift_a * self.sw1) / (self.s2 - shift_a * self.sw2);
        let g = self.guess;
        let a = (r - 1.0) / (g * (r - g));
        (a > 0.0 && a < 1.0).then_some(a)
    }
}

/// One hold's averaging window: sums of deviations from its first reading (which keeps
/// the sums of squares well conditioned).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Window {
    n: u32,
    u: f32,
    vbus: f32,
    i: Moments,
    x: Moments,
    x_min: f32,
    x_max: f32,
    /// `x_min` and `x_max` hold a reading.
    spanned: bool,
    /// The position's sum of deviations and the count at the window's half.
    x_half: f32,
    n_half: u32,
}

/// Running sums of one reading's deviations from the window's first.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Moments {
    first: f32,
    sum: f32,
    squares: f32,
}

impl Moments {
    const EMPTY: Self = Self {
        first: 0.0,
        sum: 0.0,
        squares: 0.0,
    };

    fn add(&mut self, first: bool, v: f32) {
        if first {
            self.first = v;
        }
        let d = v - self.first;
        self.sum += d;
        self.squares += d * d;
    }

    /// Mean and the variance of the mean over `n` readings.
    fn mean(&self, n: f32) -> (f32, f32) {
        let mean_d = self.sum / n;
        let var = math::max(self.squares / n - mean_d * mean_d, 0.0);
        (self.first + mean_d, var / n)
    }
}

impl Window {
    const EMPTY: Self = Self {
        n: 0,
        u: 0.0,
        vbus: 0.0,
        i: Moments::EMPTY,
        x: Moments::EMPTY,
        x_min: 0.0,
        x_max: 0.0,
        spanned: false,
        x_half: 0.0,
        n_half: 0,
    };

    /// Widens the span of positions by `x_m` (a reading of the window, or one just
    /// before it).
    fn span(&mut self, x_m: f32) {
        if !self.spanned {
            self.spanned = true;
            self.x_min = x_m;
            self.x_max = x_m;
        }
        self.x_min = math::min(self.x_min, x_m);
        self.x_max = math::max(self.x_max, x_m);
    }

    fn add(&mut self, u_v: f32, m: &Measurement) {
        let first = self.n == 0;
        self.span(m.x_m);
        self.n = self.n.saturating_add(1);
        self.u += u_v;
        self.vbus += m.vbus_v;
        self.i.add(first, m.i_a);
        self.x.add(first, m.x_m);
    }

    fn n(&self) -> f32 {
        self.n.max(1) as f32
    }

    /// Mean voltage, mean current, variance of the mean current.
    fn current(&self) -> (f32, f32, f32) {
        let (i, var) = self.i.mean(self.n());
        (self.u / self.n(), i, var)
    }

    /// Mean position and the variance of that mean.
    fn position(&self) -> (f32, f32) {
        self.x.mean(self.n())
    }

    /// Marks the window's half.
    fn halve(&mut self) {
        self.x_half = self.x.sum;
        self.n_half = self.n;
    }

    /// The second half's mean position less the first's \[m\] (zero before the half).
    fn drift(&self) -> f32 {
        let second_n = self.n.saturating_sub(self.n_half);
        if self.n_half == 0 || second_n == 0 {
            return 0.0;
        }
        let second = (self.x.sum - self.x_half) / second_n as f32;
        second - self.x_half / self.n_half as f32
    }
}

/// The resistance from two holds' windows, `expected_a` the difference of their currents
/// the plan aims at; [`Abort::NoResponse`] when less than a tenth of it answers.
fn resistance(first: &Window, second: &Window, expected_a: f32) -> Result<Resistance, Abort> {
    let (u1, i1, var1) = first.current();
    let (u2, i2, var2) = second.current();
    let di = i2 - i1;
    if di.is_nan() || di <= 0.1 * expected_a {
        return Err(Abort::NoResponse);
    }
    let ohm = (u2 - u1) / di;
    let spread_ohm = 2.0 * ohm * math::sqrt(var1 + var2) / di;
    let n = first.n.saturating_add(second.n).max(1) as f32;
    Ok(Resistance {
        ohm,
        spread_ohm,
        i_a: [i1, i2],
        u_v: [u1, u2],
        vbus_v: (first.vbus + second.vbus) / n,
    })
}

/// What the identification asks of the bridge at one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Apply this voltage \[V\].
    Drive(f32),
    /// Finished: coast; the result.
    Done(Result<Report, Abort>),
}

/// Where an identification stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// The resistance's first step.
    Low,
    /// Its second step.
    High,
    /// The coil off, the armature at the open stop.
    Open,
    /// The inductance probe's lower level at the open stop.
    ProbeLow,
    /// Its upper level.
    ProbeHigh,
    /// Between the two levels, [`Plan::probe_cycles`] times, ending at the lower: every
    /// step's response fitted.
    ProbeCycle,
    /// The voltage ramp towards the closed stop.
    Ramp,
    /// The first hold at the closed stop.
    Full,
    /// The second, a step down from the first: its response fitted.
    Near,
}

/// How much a hold's window needs the armature at rest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Rest {
    /// Its mean position is a stop's: a window in which the armature moved is averaged
    /// again, for at most [`Plan::patience_ticks`], then the identification gives up.
    Required,
    /// At rest if it comes within the patience, else the window is taken as it is: the
    /// first two steps' resistance only sets the later voltages, and a lightly damped
    /// armature ringing about the pull's equilibrium leaves a back-EMF that averages out.
    Preferred,
    /// The window measures the current's level only; the probe's position is averaged
    /// over its cycle, where its inductance is fitted.
    Any,
}

impl Phase {
    const fn rest(self) -> Rest {
        match self {
            Phase::Open | Phase::Near | Phase::Full => Rest::Required,
            Phase::Low | Phase::High => Rest::Preferred,
            Phase::ProbeLow | Phase::ProbeHigh | Phase::ProbeCycle | Phase::Ramp => Rest::Any,
        }
    }
}

/// Indices of the windows an identification keeps.
const OPEN: usize = 0;
const PROBE: usize = 1;
const NEAR: usize = 2;
const FULL: usize = 3;

/// An identification in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identification {
    plan: Plan,
    phase: Phase,
    /// Ticks into the phase.
    tick: u32,
    /// Ticks of windows restarted in this phase, with the waits that preceded them.
    restarts: u32,
    window: Window,
    /// The windows the result is made from (the resistance's first step in the first).
    kept: [Window; 4],
    /// The resistance the first two steps measured, which every later voltage is set
    /// from \[ohm\] (the one reported comes from the closed stop).
    drive_ohm: f32,
    /// The step response being fitted.
    decay: Decay,
    /// The coil's time constant at the probe's position near the open stop \[s\].
    probe_s: f32,
    /// The current at the probe's lower level \[A\].
    probe_end_a: f32,
    /// The voltage over the period the last reading ended \[V\].
    previous_v: f32,
    /// The readings over the probe's cycle, where its inductance is fitted.
    cycle: Window,
}

impl Identification {
    /// Starts `plan`.
    #[must_use]
    pub const fn new(plan: Plan) -> Self {
        Self {
            plan,
            phase: Phase::Low,
            tick: 0,
            restarts: 0,
            window: Window::EMPTY,
            kept: [Window::EMPTY; 4],
            drive_ohm: 0.0,
            decay: Decay::NONE,
            probe_s: 0.0,
            probe_end_a: 0.0,
            previous_v: 0.0,
            cycle: Window::EMPTY,
        }
    }

    /// The plan.
    #[must_use]
    pub const fn plan(&self) -> &Plan {
        &self.plan
    }

    /// The voltage of a share of the rated current at the resistance the first two steps
    /// measured \[V\].
    fn share_v(&self, share: f32) -> f32 {
        self.current_v(share * self.plan.abort_a)
    }

    /// The voltage of current `i_a` at the resistance the first two steps measured \[V\].
    fn current_v(&self, i_a: f32) -> f32 {
        i_a * self.drive_ohm
    }

    /// The phase's drive \[V\] and the ticks it waits before its window.
    fn phase_drive(&self) -> (f32, u32) {
        let p = &self.plan;
        match self.phase {
            Phase::Low => (p.u_v[0], p.settle_ticks),
            Phase::High => (p.u_v[1], p.settle_ticks),
            Phase::Open => (0.0, p.release_ticks),
            // The probe's pull moves the armature: its levels wait as the open stop does.
            Phase::ProbeLow => (self.current_v(p.probe_a[0]), p.release_ticks),
            Phase::ProbeHigh => (self.current_v(p.probe_a[1]), p.release_ticks),
            Phase::ProbeCycle => {
                let wait = p.probe_half_ticks.saturating_mul(p.probe_halves());
                let high = self.tick < wait && self.probe_high(self.tick);
                let [low_a, high_a] = p.probe_a;
                (self.current_v(if high { high_a } else { low_a }), wait)
            }
            Phase::Ramp => {
                let done = self.tick as f32 / p.ramp_ticks.max(1) as f32;
                (self.share_v(FULL_SHARE) * done, p.ramp_ticks)
            }
            Phase::Full => (self.share_v(FULL_SHARE), p.release_ticks),
            Phase::Near => (self.share_v(NEAR_SHARE), p.release_ticks),
        }
    }

    /// Whether the probe's cycle is at its upper level at tick `t`.
    fn probe_high(&self, t: u32) -> bool {
        t.checked_div(self.plan.probe_half_ticks)
            .is_some_and(|half| half & 1 == 1)
    }

    fn enter(&mut self, phase: Phase) {
        self.phase = phase;
        self.tick = 0;
        self.restarts = 0;
        self.window = Window::EMPTY;
        self.decay = match phase {
            // The probe's steps go to levels measured before.
            Phase::ProbeCycle => Decay::towards(self.probe_end_a, 1.0, self.plan.guess_factor[0]),
            // This step's end is the hold's own window, measured after it: the fit takes
            // deviations from the level before and shifts them once it is known.
            Phase::Near => {
                Decay::towards(self.kept[FULL].current().1, 1.0, self.plan.guess_factor[1])
            }
            _ => Decay::NONE,
        };
    }

    /// One tick: `m` is this tick's measurement, `applied_v` the voltage the bridge has
    /// applied over the period `m` ends (the last tick's drive).
    pub fn step(&mut self, m: &Measurement, applied_v: f32) -> Step {
        if !(m.i_a.is_finite()
            && m.vbus_v.is_finite()
            && m.x_m.is_finite()
            && applied_v.is_finite())
        {
            return Step::Done(Err(Abort::Fault));
        }
        if m.i_a.abs() > self.plan.abort_a {
            return Step::Done(Err(Abort::OverRated));
        }
        let (_, wait) = self.phase_drive();
        self.tick = self.tick.saturating_add(1);
        let stepped = applied_v != core::mem::replace(&mut self.previous_v, applied_v);
        if self.tick <= wait {
            if self.phase == Phase::ProbeCycle {
                self.cycle.add(applied_v, m);
            }
            if self.tick.saturating_add(self.plan.settle_ticks) > wait {
                // The coil's current settles over the wait's last part: an armature that
                // moves then (one that snaps onto a stop at the end of a slow creep) is
                // a window whose current still recovers from its back-EMF.
                self.window.span(m.x_m);
            }
            // A step's response, over the wait (as long as the slowest coil needs).
            let p = &self.plan;
            self.decay.add(m.i_a, stepped, p.skip_readings);
            if self.phase == Phase::ProbeCycle
                && self.tick < wait
                && self.tick.is_multiple_of(p.probe_half_ticks)
            {
                // The drive changes level now: the next step goes to the other one.
                let (low_a, high_a) = (self.probe_end_a, self.kept[PROBE].current().1);
                let high = self.probe_high(self.tick);
                if high {
                    self.decay.retarget(high_a, -1.0);
                } else {
                    self.decay.retarget(low_a, 1.0);
                }
            }
        }
        if self.phase == Phase::Ramp {
            if self.tick >= wait {
                self.enter(Phase::Full);
            }
        } else {
            if self.tick > wait {
                // The averaging window starts after the wait, so that every reading in
                // it ends a whole period of the hold's own voltage (a drive takes effect
                // one period after it is set).
                self.window.add(applied_v, m);
                if self.tick == wait.saturating_add(self.plan.average_ticks / 2) {
                    self.window.halve();
                }
            }
            if self.tick > wait.saturating_add(self.plan.average_ticks) {
                let moved = self.window.x_max - self.window.x_min > self.plan.still_m
                    || self.window.drift().abs() > self.plan.drift_m;
                let rest = self.phase.rest();
                let patient = self.restarts.saturating_add(self.plan.average_ticks)
                    <= self.plan.patience_ticks;
                if moved && rest != Rest::Any && patient {
                    // The armature moved during the window or the wait's last part:
                    // its motion induced a voltage, and its mean is no stop's. Average
                    // again once the coil's current has settled from the motion (its
                    // inductance changed, its back-EMF kicked the current); the step
                    // `Near` fits in its wait is not repeated.
                    let settle = if self.phase == Phase::Near {
                        0
                    } else {
                        self.plan.settle_ticks
                    };
                    self.restarts = self
                        .restarts
                        .saturating_add(self.plan.average_ticks.saturating_add(settle));
                    self.window = Window::EMPTY;
                    self.tick = wait.saturating_sub(settle);
                } else if moved && rest == Rest::Required {
                    return Step::Done(Err(Abort::NotAtRest));
                } else if let Some(done) = self.finish() {
                    return Step::Done(done);
                }
            }
        }
        Step::Drive(self.phase_drive().0)
    }

    /// A hold's window is complete: keep it and go on, or end.
    fn finish(&mut self) -> Option<Result<Report, Abort>> {
        let window = self.window;
        let next = match self.phase {
            Phase::Low => {
                self.kept[0] = window;
                Phase::High
            }
            Phase::High => {
                match resistance(
                    &self.kept[0],
                    &window,
                    (HIGH_SHARE - LOW_SHARE) * self.plan.abort_a,
                ) {
                    Ok(r) => self.drive_ohm = r.ohm,
                    Err(a) => return Some(Err(a)),
                }
                Phase::Open
            }
            Phase::Open => {
                self.kept[OPEN] = window;
                Phase::ProbeLow
            }
            Phase::ProbeLow => {
                self.probe_end_a = window.current().1;
                Phase::ProbeHigh
            }
            Phase::ProbeHigh => {
                self.kept[PROBE] = window;
                Phase::ProbeCycle
            }
            Phase::ProbeCycle => match self.time_constant(0.0) {
                Some(s) => {
                    self.probe_s = s;
                    Phase::Ramp
                }
                None => return Some(Err(Abort::NoDecay)),
            },
            Phase::Full => {
                self.kept[FULL] = window;
                Phase::Near
            }
            Phase::Near => {
                self.kept[NEAR] = window;
                return Some(self.report());
            }
            // The ramp ends by its own count (see `step`), never by a window.
            Phase::Ramp => Phase::Full,
        };
        self.enter(next);
        None
    }

    /// The coil's time constant `L / R` from the phase's step response, its end `shift_a`
    /// from the level the fit took its deviations from.
    fn time_constant(&self, shift_a: f32) -> Option<f32> {
        let a = self.decay.factor(shift_a)?;
        Some(-self.plan.period_s / libm::logf(a))
    }

    /// Everything, once the last hold's window is complete.
    fn report(&self) -> Result<Report, Abort> {
        let (open_m, var_open) = self.kept[OPEN].position();
        let (probe_m, _) = self.cycle.position();
        let (near_m, _) = self.kept[NEAR].position();
        let (closed_m, var_closed) = self.kept[FULL].position();
        let travel = closed_m - open_m;
        let stroke = self.plan.stroke_m;
        // A NaN travel (none can come from finite readings) is no travel either.
        if travel.is_nan() || travel.abs() < MIN_TRAVEL_SHARE * stroke {
            return Err(Abort::NoTravel);
        }
        if travel < 0.0 {
            return Err(Abort::Backwards);
        }
        if (closed_m - near_m).abs() > self.plan.still_m {
            return Err(Abort::NoStop);
        }
        // At the closed stop the armature is pressed against it: the two holds give the
        // resistance free of any motion.
        let resistance = resistance(
            &self.kept[NEAR],
            &self.kept[FULL],
            (FULL_SHARE - NEAR_SHARE) * self.plan.abort_a,
        )?;
        let shift = self.kept[NEAR].current().1 - self.kept[FULL].current().1;
        let closed_h = resistance.ohm * self.time_constant(shift).ok_or(Abort::NoDecay)?;
        // The probe's pull moved the armature `x` off the open stop (the ends calibrate
        // the reading): `1/L` is linear in the gap, so the line through the probe's and
        // the closed stop's gives the open stop's.
        let x = (probe_m - open_m) * stroke / travel;
        if x.is_nan() || x >= MIN_TRAVEL_SHARE * stroke {
            return Err(Abort::PulledIn);
        }
        let (inv_p, inv_c) = (1.0 / (resistance.ohm * self.probe_s), 1.0 / closed_h);
        let open_h = 1.0 / (inv_p + (inv_p - inv_c) * x / (stroke - x));
        Ok(Report {
            resistance,
            inductance: Inductance { open_h, closed_h },
            ends: Ends {
                open_m,
                closed_m,
                spread_m: 2.0 * math::sqrt(math::max(var_open, var_closed)),
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: f32 = 20_000.0;
    const STROKE: f32 = 2e-3;

    /// The file the plans are made from: 2 ohm, 20 mH, 4 A, a 1 kg armature on 4000 N/m
    /// (63 rad/s), 2 mm of stroke.
    const FILE: Coil = Coil {
        resistance_ohm: 2.0,
        open_inductance_h: 0.02,
        closed_inductance_h: 0.02,
        rated_a: 4.0,
        natural_rad_s: 63.2,
        stroke_m: STROKE,
        spring_n_per_m: 4000.0,
        // The test magnet's pull at the open stop, 1.5 N/A^2.
        open_force_h_per_m: 3.0,
    };

    /// A test actuator: the coil `L i' = u - R i` (exact exponential per tick) with a
    /// constant sensor offset `offset_a` and a bridge drop `drop_v` while it drives, the
    /// drive applied one period late; an armature of 1 kg on a spring `k` with `friction` between
    /// stops at 0 and [`STROKE`], pulled by `pull(i, x)`; the reading `read(x)`.
    struct Rig {
        r: f32,
        l: f32,
        offset_a: f32,
        drop_v: f32,
        k: f32,
        friction: f32,
        pull: fn(f32, f32) -> f32,
        read: fn(f32) -> f32,
        stuck: bool,
    }

    /// A magnet whose pull grows as the gap (0.5 mm residual) closes: 4 A at the open
    /// stop pulls 24 N, 3.8 times what the spring asks at the closed one.
    fn magnet(i: f32, x: f32) -> f32 {
        let g = 0.5e-3 + STROKE - x;
        1.5 * i * i * (0.5e-3 + STROKE) * (0.5e-3 + STROKE) / (g * g)
    }

    impl Rig {
        fn coil(r: f32) -> Self {
            Self {
                r,
                l: 0.02,
                offset_a: 0.05,
                drop_v: 0.3,
                k: 4000.0,
                friction: 40.0,
                pull: magnet,
                read: |x| x,
                stuck: false,
            }
        }

        /// Runs a whole identification; its result and the highest current.
        fn run(&self) -> (Result<Report, Abort>, f32) {
            let plan = Plan::new(&FILE, RATE, 0, 1e-5).unwrap();
            let mut id = Identification::new(plan);
            let (mut i, mut pending, mut applied) = (0.0_f32, 0.0_f32, 0.0_f32);
            let (mut x, mut v, mut peak) = (0.0_f32, 0.0_f32, 0.0_f32);
            let decay = libm::expf(-self.r / (self.l * RATE));
            let h = 1.0 / RATE;
            for _ in 0..10 * plan.ticks() {
                // The bridge's drop while it drives; coasting, nothing.
                let u = if applied > 0.0 {
                    applied - self.drop_v
                } else {
                    applied
                };
                i = u / self.r + (i - u / self.r) * decay;
                peak = peak.max(i);
                if !self.stuck {
                    let a = (self.pull)(i, x) - self.k * x - self.friction * v;
                    v += a * h;
                    x += v * h;
                    if x <= 0.0 || x >= STROKE {
                        x = x.clamp(0.0, STROKE);
                        v = 0.0;
                    }
                }
                let m = Measurement {
                    x_m: (self.read)(x),
                    i_a: i + self.offset_a,
                    vbus_v: 24.0,
                };
                match id.step(&m, applied) {
                    Step::Drive(v) => {
                        applied = pending;
                        pending = v;
                    }
                    Step::Done(r) => return (r, peak),
                }
            }
            (Err(Abort::Stopped), peak)
        }
    }

    #[test]
    fn the_plan_follows_the_coil_and_the_armature() {
        let p = Plan::new(&FILE, RATE, 0, 1e-5).unwrap();
        // Slowest coil: 0.02 * 1.5 / (2 * 0.5) = 30 ms; six of them, 180 ms = 3600 ticks;
        // two averaged, 1200.
        assert_eq!(p.settle_ticks, 3600);
        assert_eq!(p.average_ticks, 1200);
        assert_eq!(p.u_v, [0.3 * 4.0 * 2.0, 0.6 * 4.0 * 2.0]);
        assert_eq!(p.abort_a, 4.0);
        // Slowest armature: 63.2 * sqrt(0.5 / 1.5) = 36.49 rad/s, a period of 172.2 ms;
        // half of it, 1722 ticks; the release a quarter of it, 861, after the coil's 180 ms.
        assert_eq!(p.ramp_ticks, 1722);
        assert_eq!(p.release_ticks, 4461);
        // The probe's pull at the open stop: a tenth of the weakest spring's 4 N over the
        // stroke (2000 N/m, 2 mm) against the strongest magnet (4.5 N/A^2) is 0.42 A,
        // under a fifth of the rating (0.8 A).
        let pull_a = (2.0_f32 * 0.1 * 2000.0 * STROKE / 4.5).sqrt();
        assert!((p.probe_a[1] / pull_a - 1.0).abs() < 1e-6, "{p:?}");
        assert!((p.probe_a[0] / (0.25 * pull_a) - 1.0).abs() < 1e-6, "{p:?}");
        // A stiff spring leaves the rating's fifth.
        let stiff = Plan::new(
            &Coil {
                spring_n_per_m: 40_000.0,
                ..FILE
            },
            RATE,
            0,
            1e-5,
        )
        .unwrap();
        assert_eq!(stiff.probe_a, [0.2, 0.8]);
        // A fast coil averages at least 20 ms.
        let fast = Plan::new(
            &Coil {
                resistance_ohm: 20.0,
                open_inductance_h: 0.002,
                closed_inductance_h: 0.002,
                rated_a: 0.3,
                ..FILE
            },
            50_000.0,
            0,
            1e-5,
        )
        .unwrap();
        assert_eq!(fast.average_ticks, 1000);
        for bad in [
            Coil {
                resistance_ohm: 0.0,
                ..FILE
            },
            Coil {
                closed_inductance_h: f32::NAN,
                ..FILE
            },
            Coil {
                natural_rad_s: 0.0,
                ..FILE
            },
            Coil {
                stroke_m: -1.0,
                ..FILE
            },
            Coil {
                open_force_h_per_m: 0.0,
                ..FILE
            },
        ] {
            assert!(Plan::new(&bad, RATE, 0, 1e-5).is_none(), "{bad:?}");
        }
    }

    #[test]
    fn the_resistance_and_the_stops_are_found_through_offsets_and_a_drop() {
        for r in [1.4_f32, 2.0, 2.6] {
            let mut rig = Rig::coil(r);
            // A sensor 3 % of the stroke off and 3 % steep.
            rig.read = |x| 0.03 * STROKE + 1.03 * x;
            let (got, peak) = rig.run();
            let got = got.unwrap();
            assert!((got.resistance.ohm / r - 1.0).abs() < 1e-3, "{r}: {got:?}");
            assert!((got.ends.open_m - 0.03 * STROKE).abs() < 1e-9, "{got:?}");
            assert!((got.ends.closed_m - 1.06 * STROKE).abs() < 1e-9, "{got:?}");
            // The test coil's inductance does not depend on the gap. Its time constant
            // spans 200 to 290 periods: the fit's sums over as many readings in f32
            // leave a few parts in ten thousand.
            for h in [got.inductance.open_h, got.inductance.closed_h] {
                assert!((h / 0.02 - 1.0).abs() < 3e-3, "{r}: {got:?}");
            }
            // The holds at the closed stop stay below the rating, whatever the file said.
            assert!(peak < 0.96 * 4.0, "{r}: {peak} A");
        }
    }

    #[test]
    fn a_ringing_armature_is_measured_at_the_stops() {
        // 1 N s/m: a damping ratio of 0.008; the armature floating about the first two
        // steps' equilibria rings for seconds. The resistance comes from the closed stop.
        let mut ringing = Rig::coil(2.0);
        ringing.friction = 1.0;
        // A pull that grows gently as the gap closes: at the first step (1.2 A) the
        // armature floats about 0.24 mm, at the second (2.4 A) about 1.3 mm; from 3 A on
        // it is pressed against the closed stop.
        ringing.pull = |i, x| 0.6 * i * i * (1.0 + 400.0 * x);
        let (got, peak) = ringing.run();
        let got = got.unwrap();
        assert!((got.resistance.ohm / 2.0 - 1.0).abs() < 1e-3, "{got:?}");
        for h in [got.inductance.open_h, got.inductance.closed_h] {
            assert!((h / 0.02 - 1.0).abs() < 3e-3, "{got:?}");
        }
        assert!(peak < 0.96 * 4.0, "{peak} A");
    }

    #[test]
    fn an_armature_creeping_back_onto_the_open_stop_is_read_once_there() {
        // 200 to 400 N s/m: damping ratios of 1.6 to 3.2, the slow mode creeping back with
        // a time constant of 44 to 98 ms onto a stop where the spring no longer pulls.
        // Released from the first two steps' pull, the armature is still 5 to 11 um off
        // the stop when the reading's spread first stays within the noise's (10 um here).
        let open_m = [200.0, 300.0, 400.0, 600.0].map(|friction| {
            let mut creeping = Rig::coil(2.0);
            creeping.friction = friction;
            creeping.run().0.map(|got| got.ends.open_m)
        });
        let [a, b, c, slowest] = open_m;
        assert!(
            [a, b, c].iter().all(|x| x.is_ok_and(|x| x.abs() < 1e-6)),
            "{open_m:?}"
        );
        // A creep slower than the patience is named, not read short of the stop.
        assert_eq!(slowest, Err(Abort::NotAtRest), "{open_m:?}");
    }

    #[test]
    fn a_low_resistance_stops_above_the_rating_and_an_open_coil_is_named() {
        // 2 ohm in the file, 1.1 ohm in the coil: the second step drives 4.8 V, 4.4 A.
        assert_eq!(Rig::coil(1.1).run().0, Err(Abort::OverRated));
        assert_eq!(Rig::coil(1e6).run().0, Err(Abort::NoResponse));
    }

    #[test]
    fn a_backwards_sensor_a_stuck_armature_and_a_short_pull_are_named() {
        let mut backwards = Rig::coil(2.0);
        backwards.read = |x| STROKE - x;
        assert_eq!(backwards.run().0, Err(Abort::Backwards));
        let mut stuck = Rig::coil(2.0);
        stuck.stuck = true;
        assert_eq!(stuck.run().0, Err(Abort::NoTravel));
        // A pull that does not grow as the gap closes (14.4 N at 4 A): the spring holds
        // the armature at 2.0 mm * 0.56 at 75 % of the rating and 0.9 at 95 %.
        let mut short = Rig::coil(2.0);
        short.pull = |i, _| 0.9 * i * i;
        assert_eq!(short.run().0, Err(Abort::NoStop));
    }
}
