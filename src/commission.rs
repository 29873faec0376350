//! Commissioning: measuring the actuator on the board before the loop is closed on it.
//!
//! A user's coil never has its datasheet's resistance: the winding's tolerance and its
//! temperature move it by tens of per cent, and the law's current loop, the residual
//! detector's bounds and the thermal model all start from it. The first measurement is
//! therefore the coil's resistance, with the loop open:
//!
//! 1. two voltage steps, `u1` then `u2`, each chosen for a fraction of the rated current
//!    ([`LOW_SHARE`], [`HIGH_SHARE`]) at the file's resistance;
//! 2. at each, wait [`SETTLE_TIME_CONSTANTS`] of the slowest coil time constant the
//!    identification admits (the closed gap's inductance over the lowest resistance,
//!    [`SPREAD`] around the file), then average the applied voltage and the measured
//!    current over as many ticks again (at least [`MIN_AVERAGE_S`]);
//! 3. `R = (u2 - u1) / (i2 - i1)`. The difference removes what is constant in both steps:
//!    the current sensor's residual offset and the bridge's voltage drops. At steady state
//!    the armature is at rest wherever the force left it, so no back-EMF enters.
//!
//! The uncertainty reported is two standard errors of that quotient from the spread of the
//! averaged currents: the converter's noise only, not what a slow residual motion of the
//! armature leaves (a window in which the position moves more than its noise is averaged
//! again, up to [`MAX_RESTARTS`] times). The step is abandoned, with its reason, when the current exceeds the
//! rating (a coil far below the file's resistance) or the currents of the two steps do not
//! differ (an open coil); a fault, a disarm or any other order also ends it. Everything
//! here runs in the control interrupt: no allocation, no panic, `f32` only.

use serde::{Deserialize, Serialize};

use crate::math;
use crate::sense::Measurement;

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
/// Averaging windows a step may restart because the armature was still moving (its
/// motion induces a voltage the steady state must not contain) before it gives up.
pub const MAX_RESTARTS: u32 = 20;

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
    /// Largest spread of the position readings over a window with the armature at rest
    /// \[m\] (the sensor's noise): a wider one restarts the window.
    pub still_m: f32,
}

impl Plan {
    /// The plan for a coil of `resistance_ohm` (the file's), `closed_inductance_h` (its
    /// largest inductance, at the closed gap), rated for `rated_a`, at `rate_hz`, with a
    /// position reading whose noise spans `still_m` at rest. `None` for values that are
    /// not positive and finite.
    #[must_use]
    pub fn for_coil(
        resistance_ohm: f32,
        closed_inductance_h: f32,
        rated_a: f32,
        rate_hz: f32,
        still_m: f32,
    ) -> Option<Self> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        if !(positive(resistance_ohm)
            && positive(closed_inductance_h)
            && positive(rated_a)
            && positive(rate_hz)
            && positive(still_m))
        {
            return None;
        }
        let slowest_s = closed_inductance_h * (1.0 + SPREAD) / (resistance_ohm * (1.0 - SPREAD));
        let settle_s = SETTLE_TIME_CONSTANTS * slowest_s;
        let ticks = |s: f32| {
            let t = libm::ceilf(s * rate_hz);
            if (1.0..1e9).contains(&t) {
                // A whole number (ceil) within u32's range.
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                Some(t as u32)
            } else {
                None
            }
        };
        Some(Self {
            u_v: [
                LOW_SHARE * rated_a * resistance_ohm,
                HIGH_SHARE * rated_a * resistance_ohm,
            ],
            settle_ticks: ticks(settle_s)?,
            average_ticks: ticks(math::max(settle_s, MIN_AVERAGE_S))?,
            abort_a: rated_a,
            still_m,
        })
    }

    /// Ticks the whole identification takes.
    #[must_use]
    pub const fn ticks(&self) -> u64 {
        let one = (self.settle_ticks as u64).saturating_add(self.average_ticks as u64);
        one.saturating_mul(2)
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
    /// The armature never came to rest (see [`MAX_RESTARTS`]).
    NotAtRest,
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

/// One step's averaging window: sums of deviations from its first reading (which keeps
/// the sum of squares well conditioned).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Window {
    i_ref: f32,
    n: u32,
    u: f32,
    di: f32,
    di2: f32,
    vbus: f32,
    x_min: f32,
    x_max: f32,
}

impl Window {
    const EMPTY: Self = Self {
        i_ref: 0.0,
        n: 0,
        u: 0.0,
        di: 0.0,
        di2: 0.0,
        vbus: 0.0,
        x_min: 0.0,
        x_max: 0.0,
    };

    fn add(&mut self, u_v: f32, m: &Measurement) {
        let (i_a, vbus_v) = (m.i_a, m.vbus_v);
        if self.n == 0 {
            self.i_ref = i_a;
            self.x_min = m.x_m;
            self.x_max = m.x_m;
        }
        self.x_min = math::min(self.x_min, m.x_m);
        self.x_max = math::max(self.x_max, m.x_m);
        self.n = self.n.saturating_add(1);
        self.u += u_v;
        let d = i_a - self.i_ref;
        self.di += d;
        self.di2 += d * d;
        self.vbus += vbus_v;
    }

    /// Mean voltage, mean current, variance of the mean current.
    fn means(&self) -> (f32, f32, f32) {
        let n = self.n.max(1) as f32;
        let mean_d = self.di / n;
        let var = math::max(self.di2 / n - mean_d * mean_d, 0.0);
        (self.u / n, self.i_ref + mean_d, var / n)
    }
}

/// What the identification asks of the bridge at one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Apply this voltage \[V\].
    Drive(f32),
    /// Finished: coast; the result.
    Done(Result<Resistance, Abort>),
}

/// A resistance identification in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identification {
    plan: Plan,
    /// In the second step.
    second: bool,
    /// Ticks into the step.
    tick: u32,
    /// Windows restarted in this step.
    restarts: u32,
    windows: [Window; 2],
}

impl Identification {
    /// Starts `plan`.
    #[must_use]
    pub const fn new(plan: Plan) -> Self {
        Self {
            plan,
            second: false,
            tick: 0,
            restarts: 0,
            windows: [Window::EMPTY; 2],
        }
    }

    /// The plan.
    #[must_use]
    pub const fn plan(&self) -> &Plan {
        &self.plan
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
        let settle = self.plan.settle_ticks;
        if self.tick > settle {
            // The averaging window starts after the wait, so that every reading in it
            // ends a whole period of the step's own voltage (a drive takes effect one
            // period after it is set).
            let [first, second] = &mut self.windows;
            let window = if self.second { second } else { first };
            window.add(applied_v, m);
        }
        self.tick = self.tick.saturating_add(1);
        if self.tick > settle.saturating_add(self.plan.average_ticks) {
            let [first, second] = &mut self.windows;
            let window = if self.second { second } else { first };
            if window.x_max - window.x_min > self.plan.still_m {
                // The armature moved during the window: its motion induced a voltage.
                // Average again from here.
                self.restarts = self.restarts.saturating_add(1);
                if self.restarts > MAX_RESTARTS {
                    return Step::Done(Err(Abort::NotAtRest));
                }
                *window = Window::EMPTY;
                self.tick = settle.saturating_add(1);
            } else if self.second {
                return Step::Done(self.result());
            } else {
                self.second = true;
                self.tick = 0;
                self.restarts = 0;
            }
        }
        let [low, high] = self.plan.u_v;
        Step::Drive(if self.second { high } else { low })
    }

    fn result(&self) -> Result<Resistance, Abort> {
        let [first, second] = &self.windows;
        let (u1, i1, var1) = first.means();
        let (u2, i2, var2) = second.means();
        let di = i2 - i1;
        // Less than a tenth of the expected difference: nothing answers the voltage.
        let expected = (HIGH_SHARE - LOW_SHARE) * self.plan.abort_a;
        if di.is_nan() || di <= 0.1 * expected {
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
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A coil `L i' = u - R i - e`, with a constant sensor offset `e_a` and a bridge drop
    /// `drop_v`, exact exponential per tick; the drive applies one period late.
    fn identify(r: f32, l: f32, offset_a: f32, drop_v: f32) -> (Plan, Result<Resistance, Abort>) {
        let rate = 20_000.0;
        let plan = Plan::for_coil(2.0, 0.02, 4.0, rate, 1e-5).unwrap();
        let mut id = Identification::new(plan);
        let (mut i, mut pending, mut applied) = (0.0_f32, 0.0_f32, 0.0_f32);
        let decay = libm::expf(-r / (l * rate));
        for _ in 0..plan.ticks() + 10 {
            let u = applied - drop_v;
            i = u / r + (i - u / r) * decay;
            let m = Measurement {
                x_m: 0.0,
                i_a: i + offset_a,
                vbus_v: 24.0,
            };
            match id.step(&m, applied) {
                Step::Drive(v) => {
                    applied = pending;
                    pending = v;
                }
                Step::Done(r) => return (plan, r),
            }
        }
        (plan, Err(Abort::Stopped))
    }

    #[test]
    fn the_plan_follows_the_coil() {
        let p = Plan::for_coil(2.0, 0.02, 4.0, 20_000.0, 1e-5).unwrap();
        // Slowest coil: 0.02 * 1.5 / (2 * 0.5) = 30 ms; six of them, 180 ms = 3600 ticks.
        assert_eq!(p.settle_ticks, 3600);
        assert_eq!(p.average_ticks, 3600);
        assert_eq!(p.u_v, [0.3 * 4.0 * 2.0, 0.6 * 4.0 * 2.0]);
        assert_eq!(p.abort_a, 4.0);
        // A fast coil averages at least 20 ms.
        let fast = Plan::for_coil(20.0, 0.002, 0.3, 50_000.0, 1e-5).unwrap();
        assert_eq!(fast.average_ticks, 1000);
        assert!(Plan::for_coil(0.0, 0.02, 4.0, 20_000.0, 1e-5).is_none());
        assert!(Plan::for_coil(2.0, f32::NAN, 4.0, 20_000.0, 1e-5).is_none());
    }

    #[test]
    fn the_resistance_is_found_through_an_offset_and_a_drop() {
        for r in [1.4_f32, 2.0, 2.6] {
            let (_, got) = identify(r, 0.02, 0.05, 0.3);
            let got = got.unwrap();
            assert!((got.ohm / r - 1.0).abs() < 1e-3, "{r}: {got:?}");
        }
    }

    #[test]
    fn a_low_resistance_stops_above_the_rating_and_an_open_coil_is_named() {
        // 2 ohm in the file, 1.1 ohm in the coil: the second step drives 4.8 V, 4.4 A.
        assert_eq!(identify(1.1, 0.02, 0.0, 0.0).1, Err(Abort::OverRated));
        assert_eq!(identify(1e6, 0.02, 0.0, 0.0).1, Err(Abort::NoResponse));
    }
}
