//! Drawn actuators: plausible actuators nobody tuned anything on, for judging the rules
//! out of sample.
//!
//! The family in the repository was chosen while the rules were written; a rule that
//! holds only on it is a fit. [`draw`] draws an actuator file over the span of what the
//! product is for, each quantity log-uniform over its range ([`RANGES`]):
//!
//! | quantity | range |
//! |---|---|
//! | moving mass | 2 g to 2 kg |
//! | stroke | 0.3 to 12 mm; the residual gap 5 % to 30 % of it, at least 20 um |
//! | spring | 20 to 10 000 N/m; a preload (half the draws) of 10 % to 100 % of the stroke's spring force |
//! | friction | 0.02 to 1 of critical damping, `2 zeta sqrt(K m)` |
//! | coil time constant `L / R` | 0.05 to 100 ms at the closed stop (drawn), and at least 0.05 ms at the open stop |
//! | magnetic circuit | a third each: one gap, two gaps (either with a constant surface or, half the time, one that grows with the gap by 0.5 to 2 per metre of gap), or the two inductances a bench reads |
//! | flux density where the hardest hold is | 0.2 to 1.2 T (sets the pole face) |
//! | iron path | 0.1 % to 30 % of the closed gap's reluctance |
//! | supply | 5 to 60 V |
//! | rate | 8 to 50 kHz |
//! | rated current | 1.1 to 2 times what the hold rule needs (a designer's margin); the peak 1.1 to 1.5 times the rating |
//! | hot coil's drop at the rated current | 30 % to 90 % of the bridge's largest voltage (sets the turns) |
//! | position span | the stroke to 1.25 times it; current and bus channels 1 to 1.5 times the least full scale the rules allow |
//!
//! The coil follows from the rest as a designer would wind it: the ampere-turns from the
//! force the hold needs, the turns from the voltage the supply leaves for them, the
//! resistance from the time constant; a winding of 10 to 5000 turns and 0.05 to 30 A
//! (what a board of this class drives), or the generator draws again. Every number is rounded to three significant
//! figures, as a datasheet gives it, before the rules are checked.
//!
//! Physical consistency is a rule, not a draw: a drawn actuator is kept only when it meets
//! the rules of [`ema::control::actuator::Consistency`] (its current holds it anywhere on
//! the stroke with a margin, its supply drives its rated current through the hot coil, its
//! iron is not saturated where it is held, its magnet pulls at every gap on every surface
//! the tolerance allows) and [`Actuator::settings`] derives every setting; otherwise the
//! generator draws again, and counts why ([`Drawn::redrawn`]). A hand-written file that
//! breaks a rule is refused by `tune` with the rule named.
//!
//! Actuator `k` of seed `s` is the same whatever the number drawn: each has its own
//! random stream ([`crate::analysis::montecarlo::draw_seed`] of both).
//!
//! ```
//! let drawn = hil_sim::analysis::drawn::draw(3, 7).unwrap();
//! assert_eq!(drawn.len(), 3);
//! for d in &drawn {
//!     // Every drawn actuator meets the rules and builds its settings.
//!     d.actuator.check_consistency().unwrap();
//!     d.actuator.settings().unwrap();
//! }
//! // The same actuator, whatever the number drawn.
//! assert_eq!(hil_sim::analysis::drawn::draw(1, 7).unwrap()[0], drawn[0]);
//! ```

use std::collections::BTreeMap;

use ema::control::actuator::{
    Actuator, Board, Coil, Magnetics, Mechanics, Tolerances, BREAK_PER_PEAK, RIPPLE_SHARE,
};
use ema::control::model::MU0_H_PER_M;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use crate::analysis::montecarlo::draw_seed;

/// A closed range `[lo, hi]` a quantity is drawn in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Smallest value.
    pub lo: f64,
    /// Largest value.
    pub hi: f64,
}

/// The ranges the generator draws in (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ranges {
    /// Moving mass \[kg\].
    pub mass_kg: Range,
    /// Stroke \[m\].
    pub stroke_m: Range,
    /// Residual gap per unit of stroke \[-\].
    pub residual_per_stroke: Range,
    /// Spring rate \[N/m\].
    pub spring_n_per_m: Range,
    /// Preload per unit of the spring's force over the stroke \[-\].
    pub preload_share: Range,
    /// Friction per unit of critical damping \[-\].
    pub damping_ratio: Range,
    /// Coil time constant at the closed stop \[s\].
    pub coil_s: Range,
    /// Fringing coefficient \[-\].
    pub fringing_coefficient: Range,
    /// Growth of a pole side per metre of gap, when the surface grows \[-\].
    pub fringing_spread: Range,
    /// Flux density where the hardest hold is \[T\].
    pub flux_density_t: Range,
    /// Iron path's reluctance per unit of the closed gap's \[-\].
    pub iron_share: Range,
    /// Supply \[V\].
    pub supply_v: Range,
    /// Interrupt rate \[Hz\].
    pub rate_hz: Range,
    /// Rated current per unit of what the hold rule needs \[-\].
    pub rated_per_hold: Range,
    /// Peak current per unit of the rated current \[-\].
    pub peak_per_rated: Range,
    /// The hot coil's drop at the rated current per unit of the bridge's largest voltage
    /// \[-\].
    pub drop_share: Range,
    /// Position span per unit of stroke \[-\].
    pub span_per_stroke: Range,
    /// Current and bus full scales per unit of the least the rules allow \[-\].
    pub full_scale_share: Range,
    /// Turns the winding may come to \[-\].
    pub turns: Range,
    /// Rated current the winding may come to \[A\].
    pub rated_current_a: Range,
}

const fn range(lo: f64, hi: f64) -> Range {
    Range { lo, hi }
}

/// The ranges of the module documentation.
pub const RANGES: Ranges = Ranges {
    mass_kg: range(0.002, 2.0),
    stroke_m: range(0.3e-3, 12e-3),
    residual_per_stroke: range(0.05, 0.3),
    spring_n_per_m: range(20.0, 10_000.0),
    preload_share: range(0.1, 1.0),
    damping_ratio: range(0.02, 1.0),
    coil_s: range(0.05e-3, 100e-3),
    fringing_coefficient: range(1.0, 1.3),
    fringing_spread: range(0.5, 2.0),
    flux_density_t: range(0.2, 1.2),
    iron_share: range(0.001, 0.3),
    supply_v: range(5.0, 60.0),
    rate_hz: range(8_000.0, 50_000.0),
    rated_per_hold: range(1.1, 2.0),
    peak_per_rated: range(1.1, 1.5),
    drop_share: range(0.3, 0.9),
    span_per_stroke: range(1.0, 1.25),
    full_scale_share: range(1.0, 1.5),
    turns: range(10.0, 5000.0),
    rated_current_a: range(0.05, 30.0),
};

/// Smallest residual gap \[m\]: a non-magnetic shim or plating thinner than this is not
/// made.
const RESIDUAL_MIN_M: f64 = 20e-6;

/// Attempts per actuator before the generator gives up (a defect of the ranges: with
/// [`RANGES`], fewer than two draws are refused for each actuator kept, most of them for a
/// winding outside the generator's turns or currents).
const ATTEMPTS: usize = 1000;

/// A drawn actuator.
#[derive(Clone, Debug, PartialEq)]
pub struct Drawn {
    /// Its index in the draw.
    pub index: usize,
    /// The seed it was drawn with.
    pub seed: u64,
    /// The actuator (no tuning).
    pub actuator: Actuator,
    /// The drawn magnetic circuit's kind: `one gap`, `two gaps`, each `growing` or not, or
    /// `inductances`.
    pub circuit: &'static str,
    /// Draws refused before this one, by the reason the settings gave.
    pub redrawn: BTreeMap<String, usize>,
}

impl Drawn {
    /// Its name: `drawn-<seed>-<index>`.
    #[must_use]
    pub fn name(&self) -> String {
        format!("drawn-{}-{:03}", self.seed, self.index)
    }

    /// The actuator file, with a comment that says where it comes from.
    ///
    /// # Errors
    /// A value TOML cannot write (none of an actuator's).
    pub fn text(&self) -> Result<String, toml::ser::Error> {
        let a = &self.actuator;
        let body = toml::to_string(a)?;
        Ok(format!(
            "# Drawn actuator {} of seed {} ({}): {} g, {} mm, {} N/m, {} V, {} kHz.\n\
             # Written by `hil-sim actuators --draw`; the ranges and rules: hil_sim::analysis::drawn.\n\n{body}",
            self.index,
            self.seed,
            self.circuit,
            sig3(f64::from(a.mechanics.mass_kg) * 1e3),
            sig3(f64::from(a.mechanics.stroke_m) * 1e3),
            sig3(f64::from(a.mechanics.spring_n_per_m)),
            sig3(f64::from(a.board.supply_v)),
            sig3(f64::from(a.board.rate_hz) / 1e3),
        ))
    }
}

/// Draws `n` actuators with seed `seed`, each redrawn until the rules accept it.
///
/// # Errors
/// An actuator that no draw in 1000 gets through the rules (a defect of the
/// ranges), with the reasons counted.
pub fn draw(n: usize, seed: u64) -> anyhow::Result<Vec<Drawn>> {
    (0..n).map(|index| draw_one(seed, index)).collect()
}

/// Actuator `index` of seed `seed`.
///
/// # Errors
/// As [`draw`].
pub fn draw_one(seed: u64, index: usize) -> anyhow::Result<Drawn> {
    let mut rng = Pcg64Mcg::seed_from_u64(draw_seed(seed, index));
    let mut redrawn = BTreeMap::new();
    for _ in 0..ATTEMPTS {
        let (actuator, circuit) = match candidate(&mut rng) {
            Ok(c) => c,
            Err(outside) => {
                *redrawn.entry(outside.to_owned()).or_insert(0) += 1;
                continue;
            }
        };
        match actuator
            .check_consistency()
            .and_then(|_| actuator.settings())
        {
            Ok(_) => {
                return Ok(Drawn {
                    index,
                    seed,
                    actuator,
                    circuit,
                    redrawn,
                })
            }
            Err(e) => *redrawn.entry(e.param.to_owned()).or_insert(0) += 1,
        }
    }
    anyhow::bail!(
        "actuator {index} of seed {seed}: no draw in {ATTEMPTS} meets the rules (refused by \
         field: {redrawn:?})"
    )
}

/// Log-uniform in `r`.
fn log_uniform(rng: &mut impl Rng, r: Range) -> f64 {
    (r.lo.ln() + rng.random::<f64>() * (r.hi.ln() - r.lo.ln())).exp()
}

/// `v` to three significant figures, as `f32` (what a datasheet gives).
#[expect(clippy::cast_possible_truncation)]
fn sig3(v: f64) -> f32 {
    if v == 0.0 || !v.is_finite() {
        return v as f32;
    }
    let scale = 10f64.powi(2 - v.abs().log10().floor() as i32);
    let rounded = (v * scale).round() / scale;
    // Through the decimal text, so that the file's number is the f32 the rules checked.
    format!("{rounded:.12e}")
        .parse::<f32>()
        .unwrap_or(rounded as f32)
}

/// `v` to three significant figures rounded up, as `f32`: a full scale a rule bounds from
/// below.
#[expect(clippy::cast_possible_truncation)]
fn sig3_up(v: f64) -> f32 {
    let scale = 10f64.powi(2 - v.abs().log10().floor() as i32);
    let up = (v * scale).ceil() / scale;
    let f = sig3(up);
    if f64::from(f) < v {
        f.next_up()
    } else {
        f
    }
}

/// One candidate: every quantity drawn, the coil wound to match (see the module
/// documentation). The rules are not checked here; the generator's own ranges are (the
/// error names the one the winding left).
fn candidate(rng: &mut impl Rng) -> Result<(Actuator, &'static str), &'static str> {
    let r = &RANGES;
    let mass = log_uniform(rng, r.mass_kg);
    let stroke = log_uniform(rng, r.stroke_m);
    let residual = (stroke * log_uniform(rng, r.residual_per_stroke)).max(RESIDUAL_MIN_M);
    let spring = log_uniform(rng, r.spring_n_per_m);
    let preload = if rng.random::<bool>() {
        spring * stroke * log_uniform(rng, r.preload_share)
    } else {
        0.0
    };
    let friction = 2.0 * log_uniform(rng, r.damping_ratio) * (spring * mass).sqrt();
    let coil_s = log_uniform(rng, r.coil_s);
    let kind = rng.random_range(0..3u8);
    let gaps = if kind == 1 { 2.0 } else { 1.0 };
    let growing = kind != 2 && rng.random::<bool>();
    let coefficient = log_uniform(rng, r.fringing_coefficient);
    let spread = if growing {
        log_uniform(rng, r.fringing_spread)
    } else {
        0.0
    };
    let flux_density = log_uniform(rng, r.flux_density_t);
    let iron_share = log_uniform(rng, r.iron_share);
    let supply = log_uniform(rng, r.supply_v);
    let rate = log_uniform(rng, r.rate_hz);
    let rated_per_hold = log_uniform(rng, r.rated_per_hold);
    let peak_per_rated = log_uniform(rng, r.peak_per_rated);
    let drop_share = log_uniform(rng, r.drop_share);
    let span = stroke * log_uniform(rng, r.span_per_stroke);
    let current_fs_share = log_uniform(rng, r.full_scale_share);
    let vbus_fs_share = log_uniform(rng, r.full_scale_share);

    // The pole face: the hardest hold (the stiff spring at the closed stop, the largest
    // force) at the drawn flux density, F = gaps B^2 S / (2 mu0).
    let mu0 = f64::from(MU0_H_PER_M);
    let tolerance = Tolerances::default();
    let hold_n = (1.0 + f64::from(tolerance.spring)) * (spring * stroke + preload);
    let surface = 2.0 * mu0 * hold_n / (gaps * flux_density * flux_density);
    let side = (surface / coefficient).sqrt();
    let gap_reluctance = gaps * residual / (mu0 * surface);
    let iron = iron_share * gap_reluctance;
    let magnetics = Magnetics::Geometry {
        gaps: gaps as f32,
        pole_a_m: sig3(side),
        pole_b_m: sig3(side),
        fringing_coefficient: sig3(coefficient),
        fringing_spread: sig3(spread),
        iron_reluctance_per_h: sig3(iron),
    };
    let mechanics = Mechanics {
        mass_kg: sig3(mass),
        spring_n_per_m: sig3(spring),
        preload_n: sig3(preload),
        friction_n_s_per_m: sig3(friction),
        stroke_m: sig3(stroke),
        residual_gap_m: sig3(residual),
    };
    // A trial winding of 100 turns at 1 A gives the ampere-turns the hold rule needs
    // (force and inductance both go with N^2, the holding current with 1/N).
    let trial_turns = 100.0;
    let board = |supply_v: f64, peak_a: f64| Board {
        supply_v: sig3(supply_v),
        rate_hz: sig3(rate),
        position_span_m: sig3(span),
        current_full_scale_a: sig3_up(
            current_fs_share * f64::from(BREAK_PER_PEAK) * peak_a * 2048.0 / 2047.0,
        ),
        vbus_full_scale_v: sig3_up(vbus_fs_share * 1.15 * 1.25 * f64::from(sig3(supply_v))),
    };
    let mut act = Actuator {
        mechanics,
        coil: Coil {
            resistance_ohm: 1.0,
            turns: trial_turns as f32,
            rated_current_a: 1.0,
            peak_current_a: 1.5,
            peak_time_s: ema::control::actuator::DEFAULT_PEAK_TIME_S,
        },
        magnetics,
        board: board(supply, 1.5),
        tolerance,
        tuning: None,
    };
    let trial = act.consistency().map_err(|e| e.param)?;
    let limit_a = f64::from(act.current_limit_a());
    let hold_ampere_turns = trial_turns * limit_a / f64::from(trial.hold_ratio);
    let rated_ampere_turns = hold_ampere_turns * rated_per_hold / (1.0 - f64::from(RIPPLE_SHARE));
    // The closed stop's reluctance, from the trial winding's inductance there.
    let plant = act.plant().map_err(|e| e.param)?;
    let closed_reluctance = f64::from(
        plant
            .magnetics
            .reluctance_per_h(plant.gap_m(plant.stroke_m)),
    );
    // R I = N^2 / (rho tau) * NI / N = N NI / (rho tau): the turns that put the hot coil's
    // drop at the drawn share of the bridge's largest voltage.
    let bridge_v = supply * f64::from(ema::control::bridge::max_modulation(rate as f32));
    let hot = 1.0 + f64::from(tolerance.resistance);
    let turns = (drop_share * bridge_v * closed_reluctance * coil_s / (hot * rated_ampere_turns))
        .round()
        .max(1.0);
    let rated = rated_ampere_turns / turns;
    let peak = rated * peak_per_rated;
    if turns < r.turns.lo || turns > r.turns.hi {
        return Err("turns outside the generator's range");
    }
    if rated < r.rated_current_a.lo || rated > r.rated_current_a.hi {
        return Err("rated current outside the generator's range");
    }
    let open_s =
        coil_s * closed_reluctance / f64::from(plant.magnetics.reluctance_per_h(plant.gap_m(0.0)));
    if open_s < r.coil_s.lo {
        return Err("coil L/R at the open stop below the generator's range");
    }
    act.coil = Coil {
        resistance_ohm: sig3(turns * turns / (closed_reluctance * coil_s)),
        turns: turns as f32,
        rated_current_a: sig3(rated),
        peak_current_a: sig3(peak),
        peak_time_s: ema::control::actuator::DEFAULT_PEAK_TIME_S,
    };
    act.board = board(supply, f64::from(sig3(peak)));
    let circuit = match (kind, growing) {
        (2, _) => {
            // The same circuit as a bench reads it: the two stops' inductances.
            let l = |x: f32| {
                plant.magnetics.inductance_h(plant.gap_m(x)) * (turns / trial_turns).powi(2) as f32
            };
            act.magnetics = Magnetics::Inductance {
                open_h: sig3(f64::from(l(0.0))),
                closed_h: sig3(f64::from(l(plant.stroke_m))),
            };
            "inductances"
        }
        (1, true) => "two gaps, growing",
        (1, false) => "two gaps",
        (_, true) => "one gap, growing",
        (_, false) => "one gap",
    };
    Ok((act, circuit))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_significant_figures_round_trip_through_the_file() {
        assert_eq!(sig3(0.012_345), 0.0123);
        assert_eq!(sig3(98_765.0), 98_800.0);
        assert_eq!(sig3(1.0), 1.0);
    }
}
