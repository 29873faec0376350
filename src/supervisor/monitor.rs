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
//! envelope, widened by a relative `margin` of its own extent, by `noise_codes` steps of
//! the current converter (the allowance follows the calibration: the same board noise is
//! 8 mA per code on a +-16.5 A channel and 20 mA on a +-40 A one) and by the back-EMF
//! allowance, holds every admissible coil's current. A reading outside it for
//! `confirm_ticks` ticks in a row on the same side is evidence against the coil or the
//! sensor. The anchor is renewed every `window` ticks, but not while the reading is
//! outside: evidence that starts late in a window is not thrown away. Summed over
//! several ticks, the bank sees drives far too weak to show in a single step (a slow
//! ramp, a coil slightly faster than its bounds), against a noise allowance paid once.
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
//! **The fit.** Over the bank's window, the deviation `e` of each measured change from
//! the nominal prediction `p = k (u - R i)/(1 + R k/2)` (`k = Ts/L_nom`) is fitted by
//! least squares as `e = a p + b k i`: `a` is an inductance error, `b` a resistance
//! deficit; the resistance fitted is `R - b`. When `p` and `k i` are proportional (the
//! law holding on a constant voltage) the two cannot be separated and all of it is
//! taken as resistance, which is what a short that the law holds looks like.
//!
//! **One step.** A single measured change beyond the one-step interval of the corners by
//! more than `jump_a` plus `gross - 1` times the largest admissible change (no coil even
//! `gross` times faster than the fastest admissible one makes it), followed by an
//! admissible step, is a step in the reading, not in the coil: [`Fault::CurrentOffset`],
//! found one tick later. A step that lands within `open_a` of zero is left to the bank: a
//! coil that opens drops its current to zero within a period.
//!
//! The motional back-EMF `e = s_emf v i mu(g)` (the armature's velocity `v` from the
//! observer) adds to the applied voltage: `di = k (u + e - R i) / (1 + R k / 2)`. It is
//! taken with the nominal `mu` and an allowance of [`EMF_SPREAD`] of itself either way
//! (the surfaces' bounds and the velocity estimate's error): on a fast, small valve it is
//! as large as the resistive drop, and left out it reads as a coil outside its bounds.
//!
//! What this cannot see: a reading frozen while the coil is driven no harder than the
//! resistance tolerance explains (`|u - R i| <= tol R |i|`, holding or a slow move)
//! agrees with an admissible coil; it becomes observable only once the law, acting on the
//! frozen reading, has driven the real current away from it.

use super::Fault;
use crate::config::{self, Error};
use crate::math;
use crate::model::{Envelope, Plant};
use crate::sense::Calibration;

/// Relative allowance on the motional back-EMF in the residual: the force coefficient
/// anywhere in its bounds (at most +-25 % of nominal for +-20 % surfaces) and the
/// velocity estimate's error during a move \[-\].
pub const EMF_SPREAD: f32 = 0.5;

/// How much farther the reference may travel than the reading while the reading crosses
/// its last two bands, for the reading to count as moving with it \[-\] (see [`Stuck`]).
pub const MOVING_RATIO: f32 = 1.5;

/// I^2 t protection of the coil.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Thermal {
    /// Continuous current rating \[A\].
    pub continuous_a: f32,
    /// Allowance above the continuous rating, `integral of (i^2 - I_c^2) dt` \[A^2 s\].
    pub allowance_a2s: f32,
}

/// Stuck position sensor: the reading stops within its noise band mid-move while the
/// reference runs on.
///
/// A frozen sensor output still reaches the tick through the converter, with the
/// converter's noise: the evidence is a reading that stays within `band_codes` of where
/// it last left its band (an anchor, renewed at every exit) while the armature, by the
/// observer's velocity estimate (which runs on the coil current and the force model as
/// much as on the reading), has travelled `reference_m` the way the reading was going.
/// A healthy reading leaves the band before: `reference_m` is the band plus the
/// converter's worst noise excursions of the anchor and of the newest reading. (Counting
/// the reading's own crossing times instead, "in one band longer than the last crossings
/// took", names a healthy armature that slows down while its noise stretches one
/// crossing and shortens the one before.)
///
/// Four conditions keep healthy motion out:
///
/// * **the reading was moving with the reference**: it left its last two bands the same
///   way, and while it crossed the last one the reference travelled at most
///   [`MOVING_RATIO`] times as far as the reading. An armature at rest that a move sets
///   off lags its reference by the time the coil needs to build the current that
///   overcomes the spring and its preload (milliseconds on a valve): during that lag the
///   reference runs away from a static reading, and its first band crossings are slow
///   beside the reference: it is healthy, and not yet moving;
/// * **the reading crossed its last two bands within the deadline**
///   ([`crate::supervisor::DEADLINE_S`], in interrupt periods), at least two bands per
///   deadline: a slower reading could not be named within the deadline anyway, and a
///   creep that slow (an armature that the start-up left ahead of a slow reference, at a
///   fraction of a code per period) crosses its bands as much by the converter's noise as
///   by its motion, which can make it look as if it moved with the reference;
/// * **the reference runs on the same way**, by `reference_m` since the anchor: a reading
///   that waits while the reference comes back toward it is healthy;
/// * **the reading is short of the target** (the set point the move goes to) by more
///   than `reference_m`: a healthy armature that leads its reference stops at the target
///   and waits there for the reference to arrive; it does not stop halfway.
///
/// A sensor that freezes mid-move, with the armature at speed `v`, is found once the
/// estimate and the reference have both run `reference_m` past the last exit: about
/// `reference_m / v`, under the deadline whenever the reading moved at least two bands
/// per deadline (`reference_m` is `1 + sqrt 2` bands). One that
/// freezes at rest, or within `reference_m` of the target, looks exactly like an armature
/// that is where it should be, and is left to the tracking detector.
///
/// "No change while the current changes" is not usable as evidence: in closed loop the
/// controller changes the current precisely to hold the position against a changing
/// disturbance, and over a millisecond the armature's mass turns even an ampere of change
/// into much less than one converter step of motion.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Stuck {
    /// Half-width of the band, in steps of the position converter \[code\].
    pub band_codes: f32,
    /// Reference travel since the anchor that must have moved the reading \[m\].
    pub reference_m: f32,
}

/// Electrical residual (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Residual {
    /// Absolute widening of the admissible envelope (converter noise), in steps of the
    /// current converter \[code\].
    pub noise_codes: f32,
    /// Relative widening of the admissible change \[-\].
    pub margin: f32,
    /// Consecutive ticks outside the envelope, on one side, before a fault \[tick\]
    /// (at least 2).
    pub confirm_ticks: u16,
    /// One-step excess that no coil can produce \[A\].
    pub jump_a: f32,
    /// Current below which the coil counts as open \[A\].
    pub open_a: f32,
    /// Factor between "outside the bounds" and "broken" \[-\].
    pub gross: f32,
    /// Length of the corner bank's window \[tick\] (at least 2).
    pub window: u16,
}

/// Tracking error too large for too long.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Tracking {
    /// Largest tolerated `|x - r|` \[m\].
    pub error_m: f32,
    /// How long it may be exceeded \[s\].
    pub time_s: f32,
}

/// The optional detectors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
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
        config::within("delay_ticks", f32::from(delay_ticks), 0.0, 1.0)?;
        if let Some(t) = &self.thermal {
            config::positive("monitors.thermal.continuous_a", t.continuous_a)?;
            config::positive("monitors.thermal.allowance_a2s", t.allowance_a2s)?;
        }
        if let Some(s) = &self.stuck {
            config::positive("monitors.stuck.band_codes", s.band_codes)?;
            config::positive("monitors.stuck.reference_m", s.reference_m)?;
        }
        if let Some(r) = &self.residual {
            config::positive("monitors.residual.noise_codes", r.noise_codes)?;
            config::at_least("monitors.residual.margin", r.margin, 0.0)?;
            config::at_least(
                "monitors.residual.confirm_ticks",
                f32::from(r.confirm_ticks),
                2.0,
            )?;
            config::positive("monitors.residual.jump_a", r.jump_a)?;
            config::at_least("monitors.residual.open_a", r.open_a, 0.0)?;
            config::at_least("monitors.residual.gross", r.gross, 1.0)?;
            config::at_least("monitors.residual.window", f32::from(r.window), 2.0)?;
        }
        let tracking_ticks = match &self.tracking {
            Some(t) => {
                config::positive("monitors.tracking.error_m", t.error_m)?;
                let ticks = config::within("monitors.tracking.time_s", t.time_s / ts_s, 1.0, 1e9)?;
                // In [1, 1e9]: the truncation is the intended rounding down.
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let n = ticks as u32;
                n
            }
            None => 0,
        };
        // The deadline in whole periods; positive, and far below u16::MAX at any rate the
        // tick runs at.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let moving_ticks = math::clamp(
            libm::roundf(super::DEADLINE_S / ts_s),
            1.0,
            f32::from(u16::MAX),
        ) as u16;
        let r = plant.resistance_ohm;
        let tol = plant.tolerance.resistance;
        let noise_a = self
            .residual
            .as_ref()
            .map_or(0.0, |r| r.noise_codes * sense.current.scale.abs());
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
            r_nom: r,
            r_lo: r * (1.0 - tol),
            r_hi: r * (1.0 + tol),
            emf_sign: plant.convention.emf_sign(),
            tracking_ticks,
            moving_ticks,
            delayed: delay_ticks > 0,
        })
    }
}

/// The detectors, validated.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Config {
    monitors: Monitors,
    /// `Ts / N^2`, so that `Ts / L(g) = rho(g) Ts / N^2` needs no division.
    ts_over_n2: f32,
    noise_a: f32,
    band_m: f32,
    envelope: Envelope,
    nominal: crate::model::Nominal,
    convention: crate::model::Convention,
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
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct MonitorState {
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
    /// The back-EMF allowance accumulated by the bank since its anchor \[A\].
    bank_emf: f32,
    /// Least-squares sums over the bank's window: `p p`, `p q`, `q q`, `p e`, `q e`.
    fit: [f32; 5],
    off_track: u32,
    primed: bool,
}

impl MonitorState {
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

/// The four corner coils of a step: gain `k / (1 + R k / 2)` and resistance.
type Corners = [(f32, f32); 4];

impl Config {
    /// Runs every enabled detector; the first fault found, if any.
    #[inline]
    pub fn check(&self, st: &mut MonitorState, inp: &Inputs) -> Option<Fault> {
        if !st.primed {
            *st = MonitorState {
                x_last: inp.x_m,
                x_prev: inp.x_m,
                r_at_change: inp.r_m,
                r_prev: inp.r_m,
                i_prev: inp.i_a,
                primed: true,
                ..MonitorState::default()
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

    /// Records the average voltage the bridge applied this tick (`driving = false` when
    /// it coasts, where the coil voltage is set by the freewheeling current).
    #[inline]
    pub fn record_drive(&self, st: &mut MonitorState, u_v: f32, driving: bool) {
        st.u_hist = [(u_v, driving), st.u_hist[0]];
    }

    fn thermal(&self, st: &mut MonitorState, inp: &Inputs) -> Option<Fault> {
        let t = self.monitors.thermal.as_ref()?;
        let excess = inp.i_a * inp.i_a - t.continuous_a * t.continuous_a;
        st.i2t_a2s = math::max(st.i2t_a2s + excess * self.ts_s, 0.0);
        (st.i2t_a2s > t.allowance_a2s).then_some(Fault::OverCurrentI2t)
    }

    fn stuck(&self, st: &mut MonitorState, inp: &Inputs) -> Option<Fault> {
        let s = self.monitors.stuck.as_ref()?;
        let step = inp.x_m - st.x_last;
        st.x_ticks = st.x_ticks.saturating_add(1);
        if step.abs() > self.band_m {
            let dir: i8 = if step > 0.0 { 1 } else { -1 };
            let d = f32::from(dir);
            // Over the reading's last two crossings, both the same way: how far the
            // reading and the reference went.
            let (x_run, r_run) = ((inp.x_m - st.x_prev) * d, (inp.r_m - st.r_prev) * d);
            st.x_moving = dir == st.x_dir
                && r_run > 0.0
                && r_run <= MOVING_RATIO * x_run
                && st.x_ticks.saturating_add(st.x_prev_ticks) <= self.moving_ticks;
            st.x_prev_ticks = st.x_ticks;
            st.x_ticks = 0;
            st.x_travel = 0.0;
            st.x_dir = dir;
            st.x_prev = st.x_last;
            st.r_prev = st.r_at_change;
            st.x_last = inp.x_m;
            st.r_at_change = inp.r_m;
            return None;
        }
        let dir = f32::from(st.x_dir);
        // Stopped: still in one band while the velocity estimate has travelled the
        // reference travel since the exit, and the reference ran on; short of the target.
        st.x_travel += inp.v_mps * dir * self.ts_s;
        let stopped = st.x_travel >= s.reference_m;
        let ran_on = (inp.r_m - st.r_at_change) * dir >= s.reference_m;
        let short = (inp.target_m - st.x_last) * dir > s.reference_m;
        (st.x_moving && stopped && ran_on && short).then_some(Fault::PositionStuck)
    }

    fn residual(&self, st: &mut MonitorState, inp: &Inputs) -> Option<Fault> {
        let r = self.monitors.residual.as_ref()?;
        // The voltage between the two samples: the drive `delay` ticks before the newer.
        let (u, driving) = if self.delayed {
            st.u_hist[1]
        } else {
            st.u_hist[0]
        };
        if !driving {
            st.jumped = false;
            st.bank_ticks = 0;
            return None;
        }
        let g = self.convention.gap_m(inp.x_m);
        let i0 = st.i_prev;
        // Applied voltage plus the motional back-EMF, with its allowance.
        let emf = self.emf_sign * inp.v_mps * i0 * self.nominal.force_coefficient_h_per_m(g);
        let u = u + emf;
        let du = EMF_SPREAD * emf.abs();
        // The four corner coils (L_lo or L_hi, R_lo or R_hi): gain and resistance of
        // `di = k (u - R i) / (1 + R k / 2)`, with `k = Ts / L = Ts rho(g) / N^2`.
        let (k_lo, k_hi) = (
            self.ts_over_n2 * self.envelope.rho_hi(g),
            self.ts_over_n2 * self.envelope.rho_lo(g),
        );
        let gain = |k: f32, res: f32| k / (1.0 + 0.5 * res * k);
        let corners = [
            (gain(k_lo, self.r_lo), self.r_lo),
            (gain(k_lo, self.r_hi), self.r_hi),
            (gain(k_hi, self.r_lo), self.r_lo),
            (gain(k_hi, self.r_hi), self.r_hi),
        ];
        // Folds from +-inf, never NaN: the one-comparison running extremes are exact.
        // Every gain is positive, so the least change takes the least voltage.
        let (mut d_min, mut d_max) = (f32::INFINITY, f32::NEG_INFINITY);
        for (f, res) in corners {
            d_min = math::running_min(d_min, f * (u - du - res * i0));
            d_max = math::running_max(d_max, f * (u + du - res * i0));
        }
        let d_meas = inp.i_a - i0;
        // One step: beyond the interval by more than a coil `gross` times the fastest
        // admissible one could explain, then back inside: the reading stepped.
        let largest = math::running_max(d_min.abs(), d_max.abs());
        let widen = r.margin * largest + self.noise_a;
        let (lo, hi) = (d_min - widen, d_max + widen);
        let offset = st.jumped && !(d_meas < lo || d_meas > hi);
        let reach = r.jump_a + (r.gross - 1.0) * largest;
        st.jumped = (d_meas > hi + reach || d_meas < lo - reach) && inp.i_a.abs() >= r.open_a;
        // The nominal prediction and the regressors of the fit.
        let k = self.ts_over_n2 * self.nominal.reluctance_per_h(g);
        let p = gain(k, self.r_nom) * (u - self.r_nom * i0);
        let fit = (k * i0, d_meas - p, p);
        let bank = self.bank(
            r,
            st,
            inp.i_a,
            i0,
            u,
            du * gain(k_hi, self.r_lo),
            &corners,
            fit,
        );
        if offset {
            return Some(Fault::CurrentOffset);
        }
        bank
    }

    /// The corner bank (see the module documentation): advances the four corner coils by
    /// one period under `u` and compares the reading with their envelope, widened by the
    /// back-EMF allowance `emf_a` of each period since the anchor; accumulates the fit's
    /// sums with the regressor `q = k i`, the deviation `e` and the prediction `p`.
    #[allow(clippy::too_many_arguments)]
    fn bank(
        &self,
        r: &Residual,
        st: &mut MonitorState,
        i_a: f32,
        i0: f32,
        u: f32,
        emf_a: f32,
        corners: &Corners,
        (q, e, p): (f32, f32, f32),
    ) -> Option<Fault> {
        if st.bank_ticks == 0 || (st.bank_ticks >= r.window && st.bank_out == 0) {
            st.bank = [i0; 4];
            st.bank_anchor = i0;
            st.bank_ticks = 0;
            st.bank_out = 0;
            st.bank_side = 0;
            st.bank_emf = 0.0;
            st.fit = [0.0; 5];
        }
        st.bank_ticks = st.bank_ticks.saturating_add(1);
        st.bank_emf += emf_a;
        let [pp, pq, qq, pe, qe] = st.fit;
        st.fit = [pp + p * p, pq + p * q, qq + q * q, pe + p * e, qe + q * e];
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for (c, &(f, res)) in st.bank.iter_mut().zip(corners) {
            *c += f * (u - res * *c);
            lo = math::running_min(lo, *c);
            hi = math::running_max(hi, *c);
        }
        let anchor = st.bank_anchor;
        // Neither distance is NaN (the folds skip NaN, the anchor is a finite reading).
        let spread = math::running_max((hi - anchor).abs(), (lo - anchor).abs());
        let widen = r.margin * spread + self.noise_a + st.bank_emf;
        let side: i8 = if i_a > hi + widen {
            1
        } else if i_a < lo - widen {
            -1
        } else {
            0
        };
        st.bank_out = if side == 0 {
            0
        } else if side == st.bank_side {
            st.bank_out.saturating_add(1)
        } else {
            1
        };
        st.bank_side = side;
        if st.bank_out < r.confirm_ticks {
            return None;
        }
        if i_a.abs() < r.open_a {
            // Every admissible coil is beyond the allowance on one side of the reading.
            return Some(Fault::CoilOpen);
        }
        // The direction the admissible coils were driven: all up, all down, or holding.
        let drive: i8 = if lo > anchor {
            1
        } else if hi < anchor {
            -1
        } else {
            0
        };
        let along = (i_a - anchor) * f32::from(drive);
        // `side` is 1 or -1 here (the reading is outside): opposite a drive that is not 0.
        if drive != 0 && side != drive && along > -self.noise_a {
            // Behind every admissible coil, and not against the drive. The least
            // admissible change: every corner lies on the drive's side of the anchor and
            // (rounding is monotonic) the nearest is `lo` when rising, `hi` when falling.
            let least = if drive > 0 { lo - anchor } else { anchor - hi };
            return Some(if along * r.gross < least {
                Fault::CurrentStuck
            } else {
                Fault::ModelBounds
            });
        }
        // Ahead of the drive, against it, or away while holding: a coil that carries more
        // current than any admissible one on this voltage.
        Some(if self.resistance_fit(&st.fit) < self.r_lo / r.gross {
            Fault::CoilShort
        } else {
            Fault::ModelBounds
        })
    }

    /// Resistance fitted over the bank's window, `R_nom - b`; all of the deviation is
    /// taken as resistance when the two regressors cannot be separated.
    fn resistance_fit(&self, fit: &[f32; 5]) -> f32 {
        let [pp, pq, qq, pe, qe] = *fit;
        let det = pp * qq - pq * pq;
        let b = if det > 1e-3 * pp * qq && det > 0.0 {
            (pp * qe - pq * pe) / det
        } else if qq > 0.0 {
            // Proportional regressors (holding on a constant voltage): all resistance.
            qe / qq
        } else {
            0.0
        };
        self.r_nom - b
    }

    fn tracking(&self, st: &mut MonitorState, inp: &Inputs) -> Option<Fault> {
        let t = self.monitors.tracking.as_ref()?;
        if (inp.x_m - inp.r_m).abs() > t.error_m {
            st.off_track = st.off_track.saturating_add(1);
        } else {
            st.off_track = 0;
        }
        (st.off_track >= self.tracking_ticks).then_some(Fault::Tracking)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TS: f32 = 1.0 / 20_000.0;

    fn cfg(delay: u8) -> Config {
        crate::actuator::Actuator::PRODUCT
            .settings()
            .unwrap()
            .monitors
            .build(&Plant::paper(), &Calibration::board(), TS, delay)
            .unwrap()
    }

    /// Nominal Tustin step of the paper's coil at gap g.
    fn coil_step(g: f32, u: f32, i: f32, r: f32, l_scale: f32) -> f32 {
        let l = crate::model::Magnetics::paper().inductance_h(g) * l_scale;
        let k = TS / l;
        i + k * (u - r * i) / (1.0 + 0.5 * r * k)
    }

    fn run(c: &Config, r_ohm: f32, l_scale: f32, sensor: impl Fn(f32) -> f32) -> Option<Fault> {
        let mut st = MonitorState::default();
        let mut i = 2.0_f32;
        let g = 3e-3;
        for k in 0..200 {
            // A square wave of +-6 V around the holding voltage.
            let u = if (k / 20) % 2 == 0 { 6.0 } else { -4.0 };
            let inp = Inputs {
                x_m: g + if k % 2 == 0 { 1e-6 } else { 0.0 },
                i_a: sensor(i),
                r_m: g,
                target_m: 3e-3,
                v_mps: 0.0,
            };
            if let Some(f) = c.check(&mut st, &inp) {
                return Some(f);
            }
            c.record_drive(&mut st, u, true);
            i = coil_step(g, u, i, r_ohm, l_scale);
        }
        None
    }

    #[test]
    fn an_admissible_coil_raises_nothing() {
        let c = cfg(0);
        for (r, l) in [
            (0.4, 1.0),
            (0.32, 0.84),
            (0.48, 1.24),
            (0.32, 1.24),
            (0.48, 0.84),
        ] {
            assert_eq!(run(&c, r, l, |i| i), None, "R {r} L x{l}");
        }
    }

    #[test]
    fn broken_coils_and_sensors_are_named() {
        let c = cfg(0);
        assert_eq!(run(&c, 0.4, 1.0, |_| 2.0), Some(Fault::CurrentStuck));
        assert_eq!(run(&c, 0.4, 1.0, |_| 0.0), Some(Fault::CoilOpen));
        // A coil 70 % more inductive than nominal (the bounds allow 25 %).
        assert_eq!(run(&c, 0.4, 1.7, |i| i), Some(Fault::ModelBounds));
    }

    /// A reading that lags every admissible coil under a steady drive, in either direction
    /// of the drive: frozen, it is a stuck sensor; still moving at more than half the
    /// slowest coil's pace, it is a plant outside the bounds. The verdict compares the
    /// reading's change with the bank's least admissible change on the side it moves to.
    #[test]
    fn a_lagging_reading_is_stuck_or_out_of_bounds_in_both_directions() {
        let c = cfg(0);
        let g = 3e-3;
        for (u, i_start) in [(6.0_f32, 2.0_f32), (-6.0, 8.0)] {
            for (pace, expect) in [(0.0, Fault::CurrentStuck), (0.6, Fault::ModelBounds)] {
                let mut st = MonitorState::default();
                let mut i = i_start;
                let mut found = None;
                for k in 0..20 {
                    let inp = Inputs {
                        x_m: g + (k % 2) as f32 * 1e-6,
                        // The nominal coil's change since the start, scaled by `pace`.
                        i_a: i_start + pace * (i - i_start),
                        r_m: g,
                        target_m: 3e-3,
                        v_mps: 0.0,
                    };
                    if let Some(f) = c.check(&mut st, &inp) {
                        found = Some((f, k));
                        break;
                    }
                    c.record_drive(&mut st, u, true);
                    i = coil_step(g, u, i, 0.4, 1.0);
                }
                let (f, k) = found.unwrap_or_else(|| panic!("u {u} pace {pace}: nothing"));
                assert_eq!(f, expect, "u {u} pace {pace}");
                assert!(k <= 6, "u {u} pace {pace}: after {k} ticks");
            }
        }
    }

    /// The issue's coil short: the resistance drops to 0.05 ohm while the controller holds
    /// 6 A at 3 mm with the voltage a healthy coil needs (2.4 V).
    #[test]
    fn a_shorted_coil_is_caught_while_holding() {
        let c = cfg(0);
        let mut st = MonitorState::default();
        let mut i = 6.0_f32;
        let mut found = None;
        for k in 0..50 {
            let inp = Inputs {
                x_m: 3e-3 + (k % 2) as f32 * 1e-6,
                i_a: i,
                r_m: 3e-3,
                target_m: 3e-3,
                v_mps: 0.0,
            };
            if let Some(f) = c.check(&mut st, &inp) {
                found = Some((f, k));
                break;
            }
            c.record_drive(&mut st, 2.4, true);
            i = coil_step(3e-3, 2.4, i, 0.05, 1.0);
        }
        let (f, k) = found.unwrap();
        assert_eq!(f, Fault::CoilShort);
        assert!(k <= 6, "{k}");
    }

    #[test]
    fn an_offset_step_is_caught_in_one_tick() {
        let c = cfg(0);
        let mut st = MonitorState::default();
        let inp = |i_a| Inputs {
            x_m: 3e-3,
            i_a,
            r_m: 3e-3,
            target_m: 3e-3,
            v_mps: 0.0,
        };
        // Holding 6 A at 2.4 V; the reading steps by +2.5 A and stays offset.
        assert_eq!(c.check(&mut st, &inp(6.0)), None);
        c.record_drive(&mut st, 2.4, true);
        assert_eq!(c.check(&mut st, &inp(6.0)), None);
        c.record_drive(&mut st, 2.4, true);
        assert_eq!(c.check(&mut st, &inp(8.5)), None);
        c.record_drive(&mut st, 2.4, true);
        assert_eq!(c.check(&mut st, &inp(8.5)), Some(Fault::CurrentOffset));
    }

    #[test]
    fn a_frozen_position_during_a_move_is_stuck() {
        let c = cfg(0);
        let mut st = MonitorState::default();
        let mut found = None;
        let reference = |k: i32| 2e-3 + k as f32 * 2e-6; // moving at 4 cm/s
        for k in 0..60 {
            // Following the reference for 20 ticks, then frozen at 40 um with +-2 codes of
            // converter noise.
            let x_m = if k < 20 {
                reference(k)
            } else {
                reference(20) + ((k * 7) % 5) as f32 * 1.085e-6 - 2.17e-6
            };
            let inp = Inputs {
                x_m,
                i_a: 5.0,
                r_m: reference(k),
                target_m: 3e-3,
                v_mps: 0.04,
            };
            if let Some(f) = c.check(&mut st, &inp) {
                found = Some((f, k));
                break;
            }
            c.record_drive(&mut st, 2.0, false);
        }
        // The 12th tick after the last exit: the velocity estimate (2 um per tick) has then
        // travelled the 22.2 um of reference travel (1 + sqrt 2 bands of 9.2 um), and so
        // has the reference. The last exit is one of the first frozen readings (the last
        // step, 10 um, plus noise): at most 2 ticks after the freeze.
        let (fault, k) = found.unwrap();
        assert_eq!(fault, Fault::PositionStuck);
        assert!((20 + 12..=20 + 12 + 2).contains(&k), "{k}");

        // The same frozen reading from rest (an armature that a move sets off lags while
        // the coil builds its current): healthy, no fault; also when the converter's noise
        // takes two readings out of each other's band, one up, then one down.
        let mut st = MonitorState::default();
        for k in 0..60 {
            let noise_codes = match k {
                3 => 4.5,
                5 => -4.5,
                _ => ((k * 7) % 5) as f32 - 2.0,
            };
            let inp = Inputs {
                x_m: 2e-3 + noise_codes * 1.085e-6,
                i_a: 5.0,
                r_m: reference(k),
                target_m: 3e-3,
                v_mps: 0.0,
            };
            assert_eq!(c.check(&mut st, &inp), None, "tick {k}");
            c.record_drive(&mut st, 2.0, false);
        }
        // At rest nothing is expected to move: no fault.
        let mut st = MonitorState::default();
        for _ in 0..1000 {
            let inp = Inputs {
                x_m: 2e-3,
                i_a: 5.0,
                r_m: 2e-3,
                target_m: 3e-3,
                v_mps: 0.0,
            };
            assert_eq!(c.check(&mut st, &inp), None);
            c.record_drive(&mut st, 2.0, false);
        }
    }

    #[test]
    fn i2t_allows_the_rating_and_trips_the_peak_after_its_time() {
        let c = cfg(0);
        let thermal = c.monitors.thermal.unwrap();
        // The product's coil: rated 12 A, 13.2 A for 0.1 s.
        assert_eq!(thermal.continuous_a, 12.0);
        let mut st = MonitorState::default();
        let at = |i_a| Inputs {
            x_m: 2e-3,
            i_a,
            r_m: 2e-3,
            target_m: 3e-3,
            v_mps: 0.0,
        };
        // At the peak current the allowance (13.2^2 - 12^2) 0.1 s lasts 0.1 s: 2000 ticks.
        let mut tripped = None;
        for k in 0..4000 {
            if let Some(f) = c.check(&mut st, &at(13.2)) {
                tripped = Some((f, k));
                break;
            }
        }
        let (f, k) = tripped.unwrap();
        assert_eq!(f, Fault::OverCurrentI2t);
        assert!((1995..=2005).contains(&k), "{k}");
        // At the rating it never trips; below it, it cools down to zero.
        let mut st = MonitorState::default();
        for _ in 0..100 {
            c.check(&mut st, &at(13.0));
        }
        assert!(st.i2t_a2s > 0.0);
        for _ in 0..100_000 {
            assert_eq!(c.check(&mut st, &at(12.0)), None);
        }
        for _ in 0..100_000 {
            assert_eq!(c.check(&mut st, &at(11.0)), None);
        }
        assert_eq!(st.i2t_a2s, 0.0);
    }

    #[test]
    fn tracking_error_must_last() {
        let c = cfg(0);
        let mut st = MonitorState::default();
        let off = Inputs {
            x_m: 1e-3,
            i_a: 1.0,
            r_m: 3e-3,
            target_m: 3e-3,
            v_mps: 0.0,
        };
        c.check(&mut st, &off);
        let mut n = 0;
        while c
            .check(
                &mut st,
                &Inputs {
                    x_m: 1e-3 + (n % 2) as f32 * 1e-6,
                    ..off
                },
            )
            .is_none()
        {
            n += 1;
            assert!(n < 5000);
        }
        // 50 ms at 20 kHz.
        assert_eq!(n + 1, 1000);
    }

    #[test]
    fn bad_monitor_settings_are_named() {
        let mut m = crate::actuator::Actuator::PRODUCT
            .settings()
            .unwrap()
            .monitors;
        m.residual.as_mut().unwrap().gross = 0.5;
        let e = m
            .build(&Plant::paper(), &Calibration::board(), TS, 0)
            .unwrap_err();
        assert_eq!(e.param, "monitors.residual.gross");
        let mut m = crate::actuator::Actuator::PRODUCT
            .settings()
            .unwrap()
            .monitors;
        m.tracking.as_mut().unwrap().time_s = 0.0;
        let e = m
            .build(&Plant::paper(), &Calibration::board(), TS, 0)
            .unwrap_err();
        assert_eq!(e.param, "monitors.tracking.time_s");
    }
}
