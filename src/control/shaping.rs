//! Reference shaping: a set point becomes a smooth reference `(r, r', r'')` that the
//! actuator can follow within its current limit.
//!
//! Each set-point change plans a quintic (minimum-jerk) move from the present reference
//! state `(p0, v0, a0)` to `(p1, 0, 0)` in a time `T`. In normalised time `s = t/T`:
//!
//! ```text
//! r(s) = p0 + v0 T s + a0 T^2 s^2/2 + h3 s^3 + h4 s^4 + h5 s^5
//! h3 = 10 D - 6 v0 T - 3/2 a0 T^2      D = p1 - p0
//! h4 = -15 D + 8 v0 T + 3/2 a0 T^2
//! h5 = 6 D - 3 v0 T - 1/2 a0 T^2
//! ```
//!
//! A rest-to-rest quintic over a distance `D` in a time `T` peaks at
//! `|r''| = c_a D / T^2` and `|r'| = c_v D / T` (`c_a = 10/sqrt(3)`, `c_v = 15/8`). The
//! magnet only pulls along `+x` and the spring only pulls back, so each half of the move
//! has its own budget. Accelerating along `+x` (first half of an upward move, second half
//! of a downward one) the magnet at the current limit on the weakest plant of the bounds
//! must beat the spring; the other way only the spring is available. Friction opposes the
//! motion: it eats the magnet's budget on the way up and the spring's on the way down, and
//! helps the other phase (which is left as margin). With `x_mid` the middle of the move
//! and `x_lo` its lower end:
//!
//! ```text
//! F_up   = min over {x_lo, x_mid} of (mu_lo(g) I_max^2 / 2 - K x - F0)
//! F_down = K x_mid + F0
//! up move:    m c_a D / T^2 + lambda c_v D / T = margin F_up,   m c_a D / T^2 = margin F_down
//! down move:  m c_a D / T^2 = margin F_up,   m c_a D / T^2 + lambda c_v D / T = margin F_down
//! T = max(the roots, sqrt(c_a D / a_cfg), T_min)
//! ```
//!
//! `margin < 1` leaves room for the feedback and for the plant uncertainty (mass, spring,
//! friction, surfaces).

use crate::control::config::{self, Error};
use crate::control::law::Reference;
use crate::control::math;
use crate::control::model::{Envelope, Plant};

/// `10 / sqrt(3)`: peak acceleration of a unit rest-to-rest quintic in unit time.
const QUINTIC_PEAK_ACCEL: f32 = 5.773_503;
/// `15 / 8`: peak velocity of a unit rest-to-rest quintic in unit time.
const QUINTIC_PEAK_VEL: f32 = 1.875;

/// Settling target of a move per unit of its minimum-time move \[-\]: the planner moves at
/// a margin of the force budget (a move at margin `m` takes `1/sqrt(m)` of the minimum
/// time), and the loop needs the rest to enter the 2 % band; 1.5 allows a margin of 0.5
/// (1.41) with 6 % of the move left for the loop.
pub const SETTLING_PER_MINIMUM_MOVE: f32 = 1.5;

/// The paper's settling claim, the floor of every settling target \[s\]: the law does not
/// yet meet the settling, overshoot and ripple targets at once within 1.5 minimum moves
/// on fast actuators, so a move the limits allow in less is still given 0.2 s.
pub const SETTLING_CLAIM_S: f32 = 0.2;

/// Reference-shaping parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Settings {
    /// Upper limit on the reference acceleration \[m/s^2\].
    pub accel_max_mps2: f32,
    /// Coil-current limit the moves are planned for \[A\].
    pub current_max_a: f32,
    /// Fraction of the available acceleration a move may use, in (0, 1].
    pub margin: f32,
    /// Shortest move duration \[s\].
    pub duration_min_s: f32,
    /// Time the coil's current takes from zero to `current_max_a` at full drive, at the
    /// closed stop (its largest inductance) \[s\]; 0 (the default) for an ideal current
    /// source. Only the settling target uses it ([`Config::minimum_time_s`]).
    #[cfg_attr(feature = "serde", serde(default))]
    pub current_rise_s: f32,
}

impl Settings {
    /// Validates and builds the planner for `plant` at the sample period `ts_s`.
    ///
    /// # Errors
    /// The first bad parameter, by name.
    pub fn build(&self, plant: &Plant, ts_s: f32) -> Result<Config, Error> {
        let envelope = plant.envelope()?;
        config::positive("shaping.accel_max_mps2", self.accel_max_mps2)?;
        config::positive("shaping.current_max_a", self.current_max_a)?;
        config::within("shaping.margin", self.margin, f32::MIN_POSITIVE, 1.0)?;
        config::at_least("shaping.duration_min_s", self.duration_min_s, 0.0)?;
        config::at_least("shaping.current_rise_s", self.current_rise_s, 0.0)?;
        config::sample_period(ts_s)?;
        Ok(Config {
            settings: *self,
            envelope,
            plant: *plant,
            ts_s,
        })
    }
}

/// A validated planner.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    settings: Settings,
    envelope: Envelope,
    plant: Plant,
    ts_s: f32,
}

/// The move in progress.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    /// Set point the move goes to \[m\].
    pub target_m: f32,
    p0: f32,
    v0_t: f32,
    half_a0_t2: f32,
    h3: f32,
    h4: f32,
    h5: f32,
    duration_s: f32,
    inv_duration: f32,
    ticks: u32,
    moving: bool,
    primed: bool,
}

impl Config {
    /// Force budgets `(F_up, F_down)` \[N\] for a move between `x0_m` and `x1_m`, before
    /// the margin.
    #[must_use]
    pub fn force_budget_n(&self, x0_m: f32, x1_m: f32) -> (f32, f32) {
        let p = &self.plant;
        let i2 = 0.5 * self.settings.current_max_a * self.settings.current_max_a;
        let up = |x: f32| self.envelope.mu_lo(p.gap_m(x)) * i2 - p.spring_force_n(x);
        let x_lo = math::min(x0_m, x1_m);
        let x_mid = 0.5 * (x0_m + x1_m);
        (math::min(up(x_lo), up(x_mid)), p.spring_force_n(x_mid))
    }

    /// Duration \[s\] of a rest-to-rest move over `distance_m` with the force budget
    /// `force_n`: the root of `m c_a D / T^2 + lambda c_v D / T = margin F` (without the
    /// friction term when friction helps).
    fn duration_for(&self, distance_m: f32, force_n: f32, friction: bool, margin: f32) -> f32 {
        let f = margin * force_n;
        if f <= 0.0 {
            return f32::INFINITY;
        }
        // In y = 1/T: a y^2 + b y - f = 0 with a, b >= 0.
        let a = self.plant.mass_kg * QUINTIC_PEAK_ACCEL * distance_m;
        let b = if friction {
            self.plant.friction_n_s_per_m * QUINTIC_PEAK_VEL * distance_m
        } else {
            0.0
        };
        let y = 2.0 * f / (b + math::sqrt(b * b + 4.0 * a * f));
        1.0 / y
    }

    /// The fastest move from `x0_m` to `x1_m` the limits allow, coil included \[s\]: the
    /// planner's own quintic with the whole force budget ([`Config::force_budget_n`] at
    /// margin 1: the magnet at the current limit on the weakest plant one way, the spring
    /// alone the other), friction included, no lower bound on the duration; plus two
    /// current rises ([`Settings::current_rise_s`]). The quintic asks for its peak force at
    /// once in each half of the move, but the coil builds the current only as fast as its
    /// inductance and the drive allow: once from the holding level to the limit to
    /// accelerate, once back through it to brake. Each is bounded by the rise from zero at
    /// full drive through the largest inductance. A move is smooth to be followed at all: a
    /// bang-bang move is not one any actuator can make.
    #[must_use]
    pub fn minimum_time_s(&self, x0_m: f32, x1_m: f32) -> f32 {
        if x0_m == x1_m {
            return 0.0;
        }
        self.duration_with_margin(x0_m, x1_m, 1.0) + 2.0 * self.settings.current_rise_s
    }

    /// The settling target of a move from `x0_m` to `x1_m` \[s\]: [`SETTLING_PER_MINIMUM_MOVE`]
    /// times its [`Config::minimum_time_s`], at least [`SETTLING_CLAIM_S`].
    #[must_use]
    pub fn settling_target_s(&self, x0_m: f32, x1_m: f32) -> f32 {
        math::max(
            SETTLING_CLAIM_S,
            SETTLING_PER_MINIMUM_MOVE * self.minimum_time_s(x0_m, x1_m),
        )
    }

    /// Duration \[s\] of a move from `x0_m` to `x1_m` (before the minimum duration).
    #[must_use]
    pub fn duration_s(&self, x0_m: f32, x1_m: f32) -> f32 {
        let t_cfg =
            math::sqrt(QUINTIC_PEAK_ACCEL * (x1_m - x0_m).abs() / self.settings.accel_max_mps2);
        math::max(
            t_cfg,
            self.duration_with_margin(x0_m, x1_m, self.settings.margin),
        )
    }

    /// Duration \[s\] of a move within `margin` of the force budgets.
    fn duration_with_margin(&self, x0_m: f32, x1_m: f32, margin: f32) -> f32 {
        let d = (x1_m - x0_m).abs();
        let up = x1_m > x0_m;
        let (f_up, f_down) = self.force_budget_n(x0_m, x1_m);
        math::max(
            self.duration_for(d, f_up, up, margin),
            self.duration_for(d, f_down, !up, margin),
        )
    }

    /// Starts the reference at the first measured position `x_m`, at rest.
    pub fn start(&self, state: &mut State, x_m: f32) {
        *state = State {
            target_m: x_m,
            p0: x_m,
            primed: true,
            ..State::default()
        };
    }

    /// The reference for this tick toward `setpoint_m`; a new set point plans a new move
    /// from the present reference state.
    #[inline]
    pub fn step(&self, state: &mut State, setpoint_m: f32) -> Reference {
        if !state.primed {
            self.start(state, setpoint_m);
        }
        if setpoint_m != state.target_m {
            let now = self.evaluate(state);
            self.plan(state, now, setpoint_m, self.settings.duration_min_s);
        }
        let r = self.evaluate(state);
        if state.moving {
            state.ticks = state.ticks.saturating_add(1);
        }
        r
    }

    /// Plans a move to `target_m` from the present reference that lasts at least
    /// `duration_s` (and never less than the limits allow): a move of a chosen duration,
    /// ordered outside the tick. The next tick with `target_m` as its set point follows it
    /// without planning again. Starts the reference at `x_m` if it has not started.
    pub fn retarget(&self, state: &mut State, x_m: f32, target_m: f32, duration_s: f32) {
        if !state.primed {
            self.start(state, x_m);
        }
        let now = self.evaluate(state);
        self.plan(
            state,
            now,
            target_m,
            math::max(duration_s, self.settings.duration_min_s),
        );
    }

    fn plan(&self, state: &mut State, from: Reference, target_m: f32, floor_s: f32) {
        let d = target_m - from.x_m;
        let t = math::max(self.duration_s(from.x_m, target_m), floor_s);
        if !(t.is_finite() && t > self.ts_s) {
            // Too short to shape, or no force available to move (a target at the closed
            // end, where the spring force vanishes): jump and let the feedback do it.
            *state = State {
                target_m,
                p0: target_m,
                primed: true,
                ..State::default()
            };
            return;
        }
        let v0_t = from.v_mps * t;
        let a0_t2 = from.a_mps2 * t * t;
        *state = State {
            target_m,
            p0: from.x_m,
            v0_t,
            half_a0_t2: 0.5 * a0_t2,
            h3: 10.0 * d - 6.0 * v0_t - 1.5 * a0_t2,
            h4: -15.0 * d + 8.0 * v0_t + 1.5 * a0_t2,
            h5: 6.0 * d - 3.0 * v0_t - 0.5 * a0_t2,
            duration_s: t,
            inv_duration: 1.0 / t,
            ticks: 0,
            moving: true,
            primed: true,
        };
    }

    fn evaluate(&self, state: &mut State) -> Reference {
        if !state.moving {
            return Reference::hold(state.target_m);
        }
        // u32 -> f32 is exact below 2^24 ticks (14 min at 20 kHz); moves last < 1 s.
        #[expect(clippy::cast_precision_loss)]
        let s = state.ticks as f32 * self.ts_s * state.inv_duration;
        if s >= 1.0 {
            state.moving = false;
            return Reference::hold(state.target_m);
        }
        let (v0, a0) = (state.v0_t, 2.0 * state.half_a0_t2);
        let (h3, h4, h5) = (state.h3, state.h4, state.h5);
        let x = state.p0 + s * (v0 + s * (state.half_a0_t2 + s * (h3 + s * (h4 + s * h5))));
        let dx = v0 + s * (a0 + s * (3.0 * h3 + s * (4.0 * h4 + s * 5.0 * h5)));
        let ddx = a0 + s * (6.0 * h3 + s * (12.0 * h4 + s * 20.0 * h5));
        let inv_t = state.inv_duration;
        Reference {
            x_m: x,
            v_mps: dx * inv_t,
            a_mps2: ddx * inv_t * inv_t,
        }
    }
}

impl State {
    /// Duration of the move in progress (or of the last one) \[s\].
    #[must_use]
    pub const fn duration_s(&self) -> f32 {
        self.duration_s
    }

    /// `false` until the planner has been started.
    #[must_use]
    pub const fn is_primed(&self) -> bool {
        self.primed
    }

    /// `true` while a move is in progress.
    #[must_use]
    pub const fn moving(&self) -> bool {
        self.moving
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TS: f32 = 1.0 / 20_000.0;

    fn planner() -> Config {
        Settings {
            accel_max_mps2: 10.0,
            current_max_a: 12.0,
            margin: 0.8,
            duration_min_s: 0.0,
            current_rise_s: 0.0,
        }
        .build(&Plant::paper(), TS)
        .unwrap()
    }

    #[test]
    fn budgets_follow_spring_and_magnet() {
        let p = planner();
        // 1 -> 3 mm: the spring at the middle (2 mm) decelerates, 0.24 N.
        let (up, down) = p.force_budget_n(1e-3, 3e-3);
        assert!((down - 0.24).abs() < 1e-6, "{down}");
        // The magnet at 12 A on the weakest plant, at the middle of the move (2 mm):
        // mu_lo(2 mm) = 0.035 H/m, F = 0.035 * 72 - 0.24 = 2.28 N.
        assert!((up - 2.28).abs() < 0.01, "{up}");
        // Near the top the magnet budget is small: mu_lo(3.85 mm) = 0.0095 H/m.
        let (up, _) = p.force_budget_n(3.8e-3, 3.9e-3);
        let env = Plant::paper().envelope().unwrap();
        let expect = env.mu_lo(3.85e-3) * 72.0 - 120.0 * 3.85e-3;
        assert!((up - expect).abs() < 1e-4, "{up} vs {expect}");
    }

    /// The planned move needs at most the budgeted force, friction included.
    #[test]
    fn a_move_is_smooth_reaches_the_target_and_stays_in_budget() {
        let p = planner();
        let mut st = State::default();
        p.start(&mut st, 1e-3);
        let (m, k, lam) = (0.1_f32, 120.0_f32, 5.0_f32);
        let mut prev = p.step(&mut st, 3e-3);
        let duration = st.duration_s();
        // Spring budget 0.8 * 0.24 N (friction helps the deceleration of an upward move):
        // 1.1547e-3 y^2 = 0.192, T = 1/y = 0.0776 s.
        assert!((duration - 0.0776).abs() < 1e-3, "{duration}");
        let (mut worst_down, mut worst_up) = (0.0_f32, 0.0_f32);
        for _ in 0..4000 {
            let r = p.step(&mut st, 3e-3);
            // Monotone up to the f32 rounding of the polynomial (a few nm).
            assert!(r.x_m >= prev.x_m - 1e-8, "monotone");
            // Velocity is the derivative of the position (within one tick).
            let dv = (r.x_m - prev.x_m) / TS - 0.5 * (r.v_mps + prev.v_mps);
            assert!(dv.abs() < 2e-4, "{dv}");
            // Magnet force the move needs: m a + lambda v + K x >= 0 always (spring and
            // friction decelerate within their force), and never more than the magnet
            // budget.
            let f_mag = m * r.a_mps2 + lam * r.v_mps + k * r.x_m;
            worst_down = worst_down.min(f_mag);
            worst_up = worst_up.max(m * r.a_mps2 + lam * r.v_mps);
            prev = r;
        }
        assert_eq!(prev, Reference::hold(3e-3));
        assert!(!st.moving());
        assert!(worst_down >= 0.0, "{worst_down}");
        let (up, _) = p.force_budget_n(1e-3, 3e-3);
        assert!(worst_up <= 0.8 * up, "{worst_up}");
    }

    /// The target allows the whole force budget plus two current rises, times 1.5, and at
    /// least the paper's 0.2 s.
    #[test]
    fn the_settling_target_is_one_and_a_half_minimum_moves_with_two_rises_or_the_floor() {
        let ideal = planner();
        // 1 -> 3 mm at margin 1: the spring's 0.24 N decelerates, 1.1547e-3 y^2 = 0.24,
        // T = 1/y = 0.06936 s (the magnet's 2.28 N is the shorter root).
        let t0 = ideal.minimum_time_s(1e-3, 3e-3);
        assert!((t0 - 0.069_36).abs() < 1e-4, "{t0}");
        let coil = Settings {
            current_rise_s: 5e-3,
            ..ideal.settings
        }
        .build(&Plant::paper(), TS)
        .unwrap();
        let t = coil.minimum_time_s(1e-3, 3e-3);
        assert!((t - (t0 + 0.010)).abs() < 1e-6, "{t}");
        // 1.5 t is below the paper's 0.2 s: the floor applies; a slower coil lifts it.
        assert_eq!(coil.settling_target_s(1e-3, 3e-3), 0.2);
        let slow = Settings {
            current_rise_s: 0.05,
            ..ideal.settings
        }
        .build(&Plant::paper(), TS)
        .unwrap();
        let target = slow.settling_target_s(1e-3, 3e-3);
        assert!((target - 1.5 * (t0 + 0.1)).abs() < 1e-6, "{target}");
        // No move, no time.
        assert_eq!(slow.minimum_time_s(2e-3, 2e-3), 0.0);
    }

    #[test]
    fn a_new_set_point_mid_move_continues_smoothly() {
        let p = planner();
        let mut st = State::default();
        p.start(&mut st, 1e-3);
        let mut prev = p.step(&mut st, 3e-3);
        for _ in 0..1000 {
            prev = p.step(&mut st, 3e-3);
        }
        let r = p.step(&mut st, 2e-3);
        // Position, velocity and acceleration are continuous across the re-plan: the new
        // sample is one tick along the old motion.
        let x_next = prev.x_m + prev.v_mps * TS + 0.5 * prev.a_mps2 * TS * TS;
        assert!((r.x_m - x_next).abs() < 1e-8, "{} vs {x_next}", r.x_m);
        assert!((r.v_mps - (prev.v_mps + prev.a_mps2 * TS)).abs() < 1e-4);
        assert!((r.a_mps2 - prev.a_mps2).abs() < 0.01);
        for _ in 0..5000 {
            prev = p.step(&mut st, 2e-3);
        }
        assert_eq!(prev.x_m, 2e-3);
    }

    #[test]
    fn bad_settings_are_named() {
        let s = Settings {
            accel_max_mps2: 10.0,
            current_max_a: 12.0,
            margin: 1.5,
            duration_min_s: 0.0,
            current_rise_s: 0.0,
        };
        assert_eq!(
            s.build(&Plant::paper(), TS).unwrap_err().param,
            "shaping.margin"
        );
    }
}
