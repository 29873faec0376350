//! Fault detectors that need history: I^2 t, stuck position sensor, the coil's electrical
//! response, tracking error. Each is optional and runs inside the tick.
//!
//! ## Stuck position sensor
//!
//! See [`Stuck`]: a reading that stops within its noise band mid-move, while the reference
//! runs on toward a target the reading has not reached.
//!
//! ## Electrical residual
//!
//! Between two current samples the bridge applied a known average voltage `u` (the drive
//! of the tick that lies `delay` ticks before the older sample). Every admissible coil,
//! inductance `L` in `[L_lo(g), L_hi(g)]` and resistance `R (1 +- tol)`, moves the current
//! by (Tustin, as the law predicts it)
//!
//! ```text
//! di = (Ts / L) (u - R i) / (1 + R Ts / (2 L))
//! ```
//!
//! **The corner bank.** From an anchor (a reading), the four corner coils (`L_lo` or
//! `L_hi`, `R_lo` or `R_hi`) are advanced tick by tick under the applied voltage. Their
//! envelope, widened by `noise_codes` steps of the current converter (the allowance
//! follows the calibration: the same board noise is 8 mA per code on a +-16.5 A channel
//! and 20 mA on a +-40 A one) and, summed over the periods since the anchor, by the
//! back-EMF allowance and a relative `margin` of each period's largest admissible change,
//! holds every admissible coil's current. The margin is paid per period, not on the net
//! excursion: a law that chatters about the holding voltage swings the coil back and
//! forth by far more than it moves it, and what the model leaves out adds up over the
//! swings. A reading outside it for
//! `confirm_ticks` ticks in a row on the same side is evidence against the coil or the
//! sensor. The anchor is renewed every `window` ticks, but not while the reading is
//! outside: evidence that starts late in a window is not thrown away. Summed over
//! several ticks, the bank sees drives far too weak to show in a single step (a slow
//! ramp, a coil slightly faster than its bounds), against a noise allowance paid once.
//!
//! **The learned resistance.** The bounds `R (1 +- tol)` cover every coil the
//! actuator's file admits, and a coil that is one of them sits somewhere in them: a
//! frozen reading on it stays within the bank until the law has driven the real current
//! by the tolerance away from it. So the bank learns the coil's own resistance, in the
//! channel's units (a gain error of the converter is in it, as it is in the readings),
//! over blocks of `learn_ticks` steps on which it found nothing: with Tustin's step,
//! `u - di / k = R (i0 + i1) / 2` for the true `k = Ts / L`, so over a block
//! `R = (sum (u + e) - sum di / k) / sum i_mid`. The inductive sum telescopes to the
//! block's end readings less its first, so on a hold it carries two readings' noise over
//! some hundred steps. A block counts when what it cannot know, the inductance anywhere
//! in its bounds (a relative `(k_fast - k_slow) / (k_fast + k_slow)` of the inductive
//! sum) and the back-EMF's allowance, stays within half of `learn_tol` of the resistive
//! sum, and the resistance is within the bounds (a coil outside them is the bank's to
//! name). The corners then take `R_learned (1 +- (learn_tol + o / i_l))`, within the
//! bounds: `o / i_l` is what the channel's offset class `o` makes of a block learned at
//! the mean current `i_l` once the current is half of it, and the learned interval holds
//! only for currents within a factor 2 of `i_l` and for `learn_age_ticks` after the
//! block (a coil warms). A short or an open coil moves the resistance by far more than
//! `learn_tol`, and the one-step check and the bank see them sooner against it.
//!
//! Which fault it is follows from where the reading went, relative to the direction the
//! admissible coils were driven (all corners above the anchor: driven up; all below:
//! driven down; otherwise holding):
//!
//! | reading outside the envelope | fault |
//! |---|---|
//! | within `open_a` of zero while every admissible coil carries current | [`Fault::CoilOpen`] |
//! | behind the drive, moved less than `1/gross` of the least admissible change | [`Fault::CurrentStuck`] |
//! | behind the drive, but moved along it | [`Fault::ModelBounds`] (a coil slower than its bounds) |
//! | ahead of the drive, against it, or away while holding: resistance fitted below `R_lo / gross` | [`Fault::CoilShort`] |
//! | the same, resistance fitted above | [`Fault::ModelBounds`] (a coil faster than its bounds) |
//!
//! A frozen reading and a shorted coil that the law has already brought back to holding
//! look alike (the current stays put on a voltage below what holds it in any admissible
//! coil); they differ in what came first: a short makes the current run ahead of every
//! admissible coil (or against the drive that the law then applies), a frozen reading
//! never moves. So the verdict takes the reading's move since the anchor, and the anchor
//! is kept while the evidence builds.
//!
//! **The fit.** Over the excursion, the steps from the one that carried the reading out of
//! the envelope to the confirmation, the deviation `e` of each measured change from the
//! nominal prediction `p = k (u - R i)/(1 + R k/2)` (`k = Ts/L_nom`) is fitted by least
//! squares as `e = a p + b k i`: `a` is an inductance error, `b` a resistance deficit; the
//! resistance fitted is `R - b`. When `p` and `k i` are proportional (the law holding on a
//! constant voltage) the two cannot be separated and all of it is taken as resistance,
//! which is what a short that the law holds looks like. The healthy steps before the
//! excursion are left out: a fit over the whole window would dilute a short that began
//! late in it by the share of the window before it, and read a resistance within the
//! bounds.
//!
//! **One step.** A single measured change beyond the one-step interval of the corners by
//! more than `jump_a` plus `gross - 1` times the largest admissible change (no coil even
//! `gross` times faster than the fastest admissible one makes it) is a jump. What the next
//! step does tells a step in the reading from a step in the coil:
//!
//! * If the reading stepped by `o` (the jump's excess over the interval's middle, known
//!   within the interval's half-width), the coil's current is the reading less `o`, and
//!   each corner `(f, R)` moves it by `f (u - R i) + f R o`: the next step lies in the
//!   one-step interval shifted by `f R o`, a shift of `o` times the period over the coil's
//!   time constant. Found there: [`Fault::CurrentOffset`], one tick after the jump. A
//!   step that lands within `open_a` of zero is left to the bank: a coil that opens drops
//!   its current to zero within a period.
//! * A second jump the same way, away from zero: the coil runs on ahead of every
//!   admissible coil by as much as on the first step, which a dropped resistance does
//!   and a reading that stepped does not: [`Fault::CoilShort`], one tick after the jump.
//!   On a coil whose time constant is a few periods this is what keeps the current under
//!   the trip: each period a short adds `Ts / L (R - R') i`, and the bank's confirmation
//!   would take two periods more. Between the jump and the verdict the tick applies zero
//!   volts ([`Config::drive_v`]): with the conversion's period of delay the verdict's
//!   evidence was driven before the jump was seen, so the hold costs it nothing, and the
//!   short's current stays where the jump found it instead of running on by one more
//!   jump.
//!
//! The motional back-EMF `e = s_emf v i mu(g)` (the armature's velocity `v` from the
//! observer) adds to the applied voltage: `di = k (u + e - R i) / (1 + R k / 2)`. It is
//! taken with the nominal `mu` and an allowance of [`EMF_ALLOWANCE`] of itself either way
//! (the surfaces' bounds and the velocity estimate's error): on a fast, small valve it is
//! as large as the resistive drop, and left out it reads as a coil outside its bounds.
//! The allowance holds while the observer follows the armature. A loop that limit-cycles
//! faster than the observer's bandwidth (a file run with gains far from its own, bang-bang
//! on the supply) leaves the estimate a quarter of a cycle behind, of either sign; on an
//! armature whose `i dL/dx` is large (a short airgap, many turns) the back-EMF at a few
//! centimetres per second is then as large as the supply, the estimate misses most of it,
//! and the bank names [`Fault::ModelBounds`] on a coil inside its bounds. The cure is a
//! residual in the flux, `L(x) i` at the window's two ends against the integral of
//! `u - R i`, which carries the motion in `L(x)` with no velocity at all; it is not built.
//!
//! What this cannot see: a reading frozen while the coil is driven no harder than the
//! resistance's interval explains (`|u - R i| <= tol R |i|`, holding or a slow move, with
//! `tol` the learned one's half-width, or the bounds' before a block has taught it)
//! agrees with an admissible coil; the bank names it only once the law, acting on the
//! frozen reading, has driven the real current that far from it. A current that drifts
//! slowly (the position loop re-balancing a held armature) takes milliseconds to get
//! there after it has left the converter's noise.
//!
//! ## What each fault moves, and what cannot be told apart
//!
//! Each fault moves one of three kinds of evidence first: a reading outside its
//! converter's plausible window ([`crate::control::sense::Calibration::convert`]), the
//! electrical residual above (the current reading against every admissible coil under the
//! voltage applied), or the position reading against the observer's motion ([`Stuck`]).
//!
//! | fault | what moves first | named by |
//! |---|---|---|
//! | position sensor open or shorted | the position code on a rail | the window |
//! | position sensor stuck | the reading stays in its noise band while the observer's velocity carries the armature on | [`Stuck`] |
//! | current sensor stuck | the reading stays put while every admissible coil is driven away from it (behind the drive) | the bank |
//! | current sensor offset | one step beyond any coil, then a step admissible for the current under the reading | the one-step check |
//! | coil open | the reading falls to zero while every admissible coil carries current | the bank |
//! | coil short | the reading runs ahead of every admissible coil on the same voltage | two jumps in a row, or the bank and its fit |
//! | coil outside its bounds | the reading outside the envelope, by less than `gross` | the bank |
//! | supply sag or over-voltage | the bus reading | the limits |
//!
//! Three pairs are not isolable from the electrical residual alone, and the bank names
//! them by what came first, which holds only while that first evidence is seen:
//!
//! * **a frozen current reading and a short the loop already holds**: both keep the
//!   reading still on a voltage below what holds any admissible coil (the short's `u = R'
//!   i` with `R'` below the bounds; the frozen reading's law winding its voltage down).
//!   With a constant voltage the two are the same data. A short ran ahead of every coil
//!   before the loop caught it; a frozen reading never moved. When the run-ahead was
//!   within the noise (a slow coil, a small holding current), the short is named
//!   [`Fault::CurrentStuck`].
//! * **a short and a coil below its inductance bound, while the coil is driven hard**:
//!   the current then rises by `Ts / L (u - R i)` per period, and a lower `R` and a lower
//!   `L` raise it alike. They part where the drive is small: holding (`u = R i`), no
//!   inductance moves the current and a lower resistance does. The fit over the
//!   excursion separates them when its steps carry both; a short during a move at full
//!   voltage, where the drive term dominates every step, can read as a coil faster than
//!   its bounds: [`Fault::ModelBounds`].
//! * **a current offset and a resistance change, once the step is past**: a reading
//!   `i + o` on a coil held at `u = R i` looks like a coil of resistance `u / (i + o)`.
//!   The one-step check names the offset on the step itself; one that steps in over
//!   several periods (a drifting amplifier) is read as a resistance.
//!
//! What separates them, and is not used yet: the armature. A frozen current reading lets
//! the real current, hence the pull, drift while the reading says it is right; the
//! position then leaves the reference with no force the observer can account for. A
//! short the loop holds keeps the pull right, and the armature where it was.
//! `hil-sim faults NAME --random N` measures how often each case is named right at random
//! instants; the results' random-instant table judges each row.

mod residual;
mod stuck;
#[cfg(test)]
mod tests;
mod thermal;
mod tracking;

pub use residual::{Residual, EMF_ALLOWANCE};
pub use stuck::{Stuck, MOVING_RATIO};
pub use thermal::Thermal;
pub use tracking::Tracking;

use super::Fault;
use crate::control::config::{self, Error};
use crate::control::math;
use crate::control::model::{Envelope, Plant};
use crate::control::sense::Calibration;

/// The optional detectors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct Monitors {
    /// I^2 t.
    pub thermal: Option<Thermal>,
    /// Stuck position sensor.
    pub stuck: Option<Stuck>,
    /// Electrical residual.
    pub residual: Option<Residual>,
    /// Tracking error.
    pub tracking: Option<Tracking>,
}

impl Monitors {
    /// Validates and builds the detectors for `plant`, the converters' calibration
    /// `sense`, the sample period `ts_s` and `delay_ticks` of measurement delay.
    ///
    /// # Errors
    /// The first bad parameter, by name.
    pub fn build(
        &self,
        plant: &Plant,
        sense: &Calibration,
        ts_s: f32,
        delay_ticks: u8,
    ) -> Result<Config, Error> {
        let envelope = plant.envelope()?;
        config::delay_ticks(delay_ticks)?;
        if let Some(t) = &self.thermal {
            config::positive("monitors.thermal.continuous_a", t.continuous_a)?;
            config::positive("monitors.thermal.allowance_a2s", t.allowance_a2s)?;
        }
        if let Some(s) = &self.stuck {
            config::positive("monitors.stuck.band_codes", s.band_codes)?;
            config::positive("monitors.stuck.reference_m", s.reference_m)?;
        }
        if let Some(residual) = &self.residual {
            config::positive("monitors.residual.noise_codes", residual.noise_codes)?;
            config::at_least("monitors.residual.margin", residual.margin, 0.0)?;
            config::at_least(
                "monitors.residual.confirm_ticks",
                f32::from(residual.confirm_ticks),
                2.0,
            )?;
            config::positive("monitors.residual.jump_a", residual.jump_a)?;
            config::at_least("monitors.residual.open_a", residual.open_a, 0.0)?;
            config::at_least("monitors.residual.gross", residual.gross, 1.0)?;
            config::at_least("monitors.residual.window", f32::from(residual.window), 2.0)?;
            config::within("monitors.residual.learn_tol", residual.learn_tol, 0.0, 0.5)?;
            config::positive("monitors.residual.offset_a", residual.offset_a)?;
        }
        let tracking_ticks = match &self.tracking {
            Some(t) => {
                config::positive("monitors.tracking.error_m", t.error_m)?;
                // Checked in the file's unit, seconds: from one period to 1e9 periods.
                config::within("monitors.tracking.time_s", t.time_s, ts_s, 1e9 * ts_s)?;
                let ticks = math::clamp(t.time_s / ts_s, 1.0, 1e9);
                // In [1, 1e9]: the truncation is the intended rounding down.
                #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let n = ticks as u32;
                n
            }
            None => 0,
        };
        // The deadline in whole periods; positive, and far below u16::MAX at any rate the
        // tick runs at.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let moving_ticks = math::clamp(
            libm::roundf(super::DEADLINE_S / ts_s),
            1.0,
            f32::from(u16::MAX),
        ) as u16;
        let r_ohm = plant.resistance_ohm;
        let tol = plant.tolerance.resistance;
        let noise_a = self.residual.as_ref().map_or(0.0, |residual| {
            residual.noise_codes * sense.current.scale.abs()
        });
        let band_m = self
            .stuck
            .as_ref()
            .map_or(0.0, |s| s.band_codes * sense.position.scale.abs());
        Ok(Config {
            monitors: *self,
            ts_over_n2: ts_s / plant.magnetics.turns_sq(),
            noise_a,
            band_m,
            nominal: envelope.nominal(),
            envelope,
            convention: plant.convention,
            ts_s,
            r_nom: r_ohm,
            r_lo: r_ohm * (1.0 - tol),
            r_hi: r_ohm * (1.0 + tol),
            emf_sign: plant.convention.emf_sign(),
            tracking_ticks,
            moving_ticks,
            delayed: delay_ticks > 0,
        })
    }
}

/// The detectors, validated.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    monitors: Monitors,
    /// `Ts / N^2`, so that `Ts / L(g) = rho(g) Ts / N^2` needs no division.
    ts_over_n2: f32,
    noise_a: f32,
    band_m: f32,
    envelope: Envelope,
    nominal: crate::control::model::Nominal,
    convention: crate::control::model::Convention,
    ts_s: f32,
    r_nom: f32,
    r_lo: f32,
    r_hi: f32,
    emf_sign: f32,
    tracking_ticks: u32,
    /// The detection deadline in interrupt periods (see [`Stuck`]).
    moving_ticks: u16,
    delayed: bool,
}

/// History the detectors keep.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    /// `integral of (i^2 - I_c^2) dt`, floored at 0 \[A^2 s\].
    pub i2t_a2s: f32,
    /// Anchor of the band the reading must leave: the reading at its last exit \[m\].
    x_last: f32,
    /// The reading at the exit before \[m\].
    x_prev: f32,
    /// The reading left its last two bands the same way, the reference travelling at most
    /// [`MOVING_RATIO`] times as far as the reading across them.
    x_moving: bool,
    /// Direction of the reading's last exit from its band (0 before the first).
    x_dir: i8,
    /// Reference at the reading's last exit \[m\].
    r_at_change: f32,
    /// Reference at the exit before \[m\].
    r_prev: f32,
    /// Ticks since the reading's last exit.
    x_ticks: u16,
    /// Ticks the reading's last crossing took.
    x_prev_ticks: u16,
    /// Travel of the velocity estimate since the reading's last exit, the way it went
    /// \[m\].
    x_travel: f32,
    i_prev: f32,
    /// Average voltage applied by the last two drives, newest first, and whether the
    /// bridge was driving (not coasting) then.
    u_hist: [(f32, bool); 2],
    /// The previous step was beyond the one-step interval by a jump.
    jumped: bool,
    /// That jump's excess over the middle of the interval: the offset the reading
    /// stepped by, if it did \[A\].
    step_a: f32,
    /// Half the width the excess is known within (the interval's half-width and its
    /// widening) \[A\].
    step_tol_a: f32,
    /// Corner bank: the four corner coils' currents since the anchor \[A\].
    bank: [f32; 4],
    /// Measured current at the bank's anchor \[A\].
    bank_anchor: f32,
    /// Ticks since the anchor (0: anchor at the next step).
    bank_ticks: u16,
    /// Consecutive steps with the reading outside the bank on the side `bank_side`.
    bank_out: u16,
    /// Side of the envelope the reading was last outside on: `1` above, `-1` below.
    bank_side: i8,
    /// The allowances accumulated by the bank since its anchor: the back-EMF's and the
    /// margin on each period's largest admissible change \[A\].
    bank_allow: f32,
    /// Least-squares sums over the bank's window: `p p`, `p q`, `q q`, `p e`, `q e`.
    fit: [f32; 5],
    /// Sums over the resistance's learning block: voltage with the back-EMF \[V\], the
    /// inductive voltage `di / k` \[V\], the back-EMF's allowance \[V\], mid-step
    /// current \[A\].
    learn: [f32; 4],
    /// Steps in the learning block.
    learn_ticks: u16,
    /// The learned resistance's interval \[ohm\].
    r_learned: (f32, f32),
    /// The mean current it was learned at \[A\].
    i_learned: f32,
    /// Ticks since it was learned (`u16::MAX`: never).
    learned_age: u16,
    off_track: u32,
    primed: bool,
}

impl State {
    /// Forgets the history except the coil's I^2 t (the coil is still warm).
    pub fn rearm(&mut self) {
        *self = Self {
            i2t_a2s: self.i2t_a2s,
            ..Self::default()
        };
    }
}

/// What the detectors look at, once per tick.
#[derive(Clone, Copy, Debug)]
pub struct Inputs {
    /// Measured position \[m\].
    pub x_m: f32,
    /// Measured current \[A\].
    pub i_a: f32,
    /// Reference position \[m\].
    pub r_m: f32,
    /// Set point the reference is heading to \[m\].
    pub target_m: f32,
    /// Estimated velocity \[m/s\] (for the motional back-EMF).
    pub v_mps: f32,
}

impl Config {
    /// Runs every enabled detector; the first fault found, if any.
    #[inline]
    pub fn check(&self, st: &mut State, inp: &Inputs) -> Option<Fault> {
        if !st.primed {
            *st = State {
                x_last: inp.x_m,
                x_prev: inp.x_m,
                r_at_change: inp.r_m,
                r_prev: inp.r_m,
                i_prev: inp.i_a,
                learned_age: u16::MAX,
                primed: true,
                ..State::default()
            };
            return None;
        }
        let fault = self
            .thermal(st, inp)
            .or_else(|| self.stuck(st, inp))
            .or_else(|| self.residual(st, inp))
            .or_else(|| self.tracking(st, inp));
        st.i_prev = inp.i_a;
        fault
    }

    /// The voltage the bridge may apply for the law's `u_v`: zero while the last current
    /// step jumped beyond every admissible coil with no verdict yet (the next step names
    /// a short or a stepped reading, see the module documentation), `u_v` otherwise.
    #[inline]
    pub fn drive_v(&self, st: &State, u_v: f32) -> f32 {
        if st.jumped {
            0.0
        } else {
            u_v
        }
    }

    /// Records the average voltage the bridge applied this tick (`driving = false` when
    /// it coasts, where the coil voltage is set by the freewheeling current).
    #[inline]
    pub fn record_drive(&self, st: &mut State, u_v: f32, driving: bool) {
        st.u_hist = [(u_v, driving), st.u_hist[0]];
    }
}
