//! The board's commissioning routine (`ema::device::commission`) against simulated
//! actuators: the core's identification ticking as the control interrupt runs it (convert,
//! identify, drive the board's bridge on the mock pins), the converter with its typical
//! noise, quantisation and delay, the plant's RK4 with its end stops. The routine starts
//! from the file; the plant is the file's, or one drawn wider than the file (see [`Draw`]).
//!
//! What is judged against the plant's own values: the resistance, the inductance at both
//! stops (the plant's fringing included), the position readings at both stops (the drawn
//! sensor's gain and offset included), the largest true coil current, the actuator time.
//!
//! The spring, the mass and the friction are measured after the routine, the loop closed
//! ([`mechanics`]): the host tool holds the armature at four positions through the
//! board's link (`bench commission --mechanics`) and captures each move and each hold.
//! At the end of each hold, after its window, inductance probes ([`ema::control::Probe`],
//! [`hold_probe`]; on the board `Command::Probe`, each captured at every tick from its
//! first) step the loop's desired current up and down about the hold's: the armature
//! stays where the loop holds it (between the stops, where the magnet's stiffness
//! exceeds the spring's and no open-loop step could leave it), and the drive and the
//! current readings give the inductance there ([`probe_inductance`],
//! [`hold_inductance`]). With the stops', six inductances along the stroke: the
//! reluctance model, the iron's `rho_0`, the airgap's `rho_x` and how its surface grows
//! with the gap, is fitted to them ([`Circuit::fit`]). The magnet's pull read from the
//! captured current and that circuit gives the spring from the holds ([`fit_spring`])
//! and, with it, the mass and the friction from the moves ([`fit_armature`]): the same
//! fits on the bench and here. The file written carries the fitted circuit. A monitor
//! that ends the holds ends an attempt: they run again with a slower loop
//! ([`HOLD_ATTEMPTS`]), and the actuator time counts every attempt.
//!
//! The actuator file a commissioning writes ([`measured`]) carries, for the spring, the
//! mass and the friction, the tolerance their measurement leaves ([`SPRING_CLASS`],
//! [`MASS_CLASS`], [`FRICTION_CLASS_DAMPING`]) rather than the datasheet's, and for the
//! surfaces the spread of the circuit's fit ([`SURFACE_CLASS`]): `tune` then validates
//! its gains on plants around what was measured, as far off as the measurement may be,
//! and the controller's robust model is built on the same (the test
//! `a_light_lightly_damped_product_is_tuned_with_the_tolerances_its_measurement_leaves`).

use ema::control::actuator::Actuator;
use ema::control::bridge::HBridge;
use ema::device::commission::{Abort, Identification, Plan, Report, Step};
use rand::Rng;

use crate::bench::board::scenario;
use crate::hal::{self, Adc};
use crate::plant::Params;
use crate::scenario::{Scenario, Sensors, TruePlant};
use crate::sim::Stepper;
use crate::targets::{Targets, Worst};
use crate::Error;

/// An actuator drawn off its file, as a user's is: the airgap surfaces, the coil's
/// resistance, the spring rate, the mass each within +-30 % (a preload the file gives
/// with the spring's rate; where it gives none, an unknown one up to a fifth of the
/// spring's force over the stroke), the friction within +-50 %, and a position sensor
/// whose offset and gain are each within +-3 % (of the stroke, of the span), and the
/// converter's noise its own realisation: the inductances come from a few noisy current
/// samples of a decay, so one noise sequence shared by every draw would give every draw
/// the same error and hide its spread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Draw {
    /// Surfaces, resistance, spring rate, mass, friction: factors on the file's \[-\].
    pub factors: [f64; 5],
    /// The unknown preload of a file that gives none, as a share of the spring's force
    /// over the stroke \[-\].
    pub preload_share: f64,
    /// The position sensor's gain error \[-\].
    pub gain_error: f64,
    /// Its offset as a share of the stroke \[-\].
    pub offset_share: f64,
    /// Seed of the converter's noise.
    pub noise_seed: u64,
}

impl Draw {
    /// One draw.
    pub fn new<R: Rng + ?Sized>(rng: &mut R) -> Self {
        let mut f = |s: f64| rng.random_range(1.0 - s..1.0 + s);
        let factors = [f(0.3), f(0.3), f(0.3), f(0.3), f(0.5)];
        Self {
            factors,
            preload_share: rng.random_range(0.0..0.2),
            gain_error: rng.random_range(-0.03..0.03),
            offset_share: rng.random_range(-0.03..0.03),
            noise_seed: rng.random(),
        }
    }

    /// The position sensor's gain error \[-\] and offset \[code\] for a stroke of `stroke_m`
    /// read in codes of `code_m`.
    #[must_use]
    pub fn position_error(&self, stroke_m: f64, code_m: f64) -> (f64, f64) {
        (self.gain_error, self.offset_share * stroke_m / code_m)
    }

    /// `plant` (the file's) drawn.
    #[must_use]
    pub fn apply(&self, plant: &Params) -> Params {
        let [surfaces, r, k, m, friction] = self.factors;
        let mut p = plant.clone();
        p.scale_surfaces(surfaces);
        p.resistance_ohm *= r;
        p.spring_n_per_m *= k;
        p.mass_kg *= m;
        p.friction_n_s_per_m *= friction;
        p.preload_n = if p.preload_n > 0.0 {
            p.preload_n * k
        } else {
            self.preload_share * p.spring_n_per_m * p.stroke_m
        };
        p
    }
}

/// How far the mass [`fit_armature`] reads may be off, relative (the `hil-sim commission`
/// table's row of it, whose target this is): above the largest error over the family's
/// drawn plants but for about one drawn positioner in a thousand (a magnet 30 % weaker
/// than its file, a damping ratio below 0.1), which the row counts.
pub const MASS_CLASS: f64 = 0.08;

/// How far the airgap surfaces of the circuit [`Circuit::fit`] reads may be off,
/// relative: the inductance curve's target (the `hil-sim commission` table's rows of
/// it), above its largest error over the family's drawn plants.
pub const SURFACE_CLASS: f64 = 0.05;

/// How far the spring's rate [`fit_spring`] reads may be off, relative (the `hil-sim
/// commission` table's row of it, whose target this is): above the largest error over
/// the family's drawn plants, once the holds' windows are averaged with the armature's
/// inertia taken out.
pub const SPRING_CLASS: f64 = 0.05;

/// How far the friction [`fit_armature`] reads may be off, as a share of the critical
/// damping `2 sqrt(K m)`: above the largest error over the family's drawn plants (the
/// `hil-sim commission` table's row of it, whose target this is). Lightly damped
/// actuators read their friction tens of per cent off, but the error is this small
/// against the damping that matters to the loop.
pub const FRICTION_CLASS_DAMPING: f64 = 0.05;

/// The least iron reluctance an actuator measured by a commissioning keeps, as a share of
/// the closed gap's total (see [`measured`], [`Circuit::fit`]): above none, as the model
/// needs, and far below any real iron's (the paper's actuator's is 4.5e-5), so that the
/// floor bends no line the readings give. (At a hundredth, the floor bent the fitted line
/// of drawn products 0.7 % off at their closed stop, where their iron is far below it.)
pub const IRON_SHARE: f32 = 1e-6;

/// The actuator a commissioning measured: `file` (the board's) with the measured
/// resistance and magnetic circuit, the spring, the mass and the friction when measured
/// ([`mechanics`]; a friction fitted below zero, a light one read through the noise, is
/// taken as none), the tuning dropped (it was for another actuator); and the factor the
/// two-inductance form's inductances were moved by (below).
///
/// The magnetic circuit: with the holds measured, the one fitted to their inductances
/// and the stops' ([`Circuit::fit`]), in the file's form: a pole geometry's sides, growth
/// (`fringing_spread`) and iron reluctance (its gap count, fringing coefficient and
/// aspect kept), or the fitted circuit's inductances at the two stops. Without them, the
/// stops' two inductances.
///
/// A measured spring, mass and friction carry the tolerance their measurement leaves,
/// when it is below the file's: the spring [`SPRING_CLASS`], the mass [`MASS_CLASS`], the
/// friction [`FRICTION_CLASS_DAMPING`] of the critical damping `2 sqrt(K m)` of the
/// measured spring and mass (a datasheet's friction is an estimate, +-50 % by default;
/// the moves read it to a few hundredths of the critical damping). The surfaces, the
/// paper's uncertainty, carry the spread of the circuit's fit: [`SURFACE_CLASS`], or the
/// largest deviation of the written form from the holds' probes where that is larger
/// ([`Mechanics::form_deviation`]), never more than the file's unless the probes ask for
/// it. The resistance keeps the file's: it moves with the coil's temperature.
///
/// The two-inductance form is `1/L` linear in the gap, `(rho_x g + rho_0) / N^2`, the
/// iron's `rho_0` positive. A real circuit's fringing bends the line (the surface grows
/// with the gap), and through the two inductances its intercept can fall below zero:
/// then both are moved, by the same factor in opposite directions, to the nearest line
/// whose `rho_0` is [`IRON_SHARE`] of the closed gap's reluctance.
///
/// # Errors
/// Measured values no actuator can have (the actuator does not validate).
pub fn measured(
    file: &Actuator,
    report: &Report,
    mechanics: Option<&Mechanics>,
) -> Result<(Actuator, f32), Error> {
    let mut a = *file;
    a.coil.resistance_ohm = report.resistance.ohm;
    #[expect(clippy::cast_possible_truncation)]
    if let Some(m) = mechanics {
        a.mechanics.spring_n_per_m = m.spring.n_per_m as f32;
        a.mechanics.preload_n = m.spring.preload_n as f32;
        a.tolerance.spring = a.tolerance.spring.min(SPRING_CLASS as f32);
        if let Some(arm) = m.armature {
            a.mechanics.mass_kg = arm.mass_kg as f32;
            a.mechanics.friction_n_s_per_m = arm.friction_n_s_per_m.max(0.0) as f32;
            a.tolerance.mass = a.tolerance.mass.min(MASS_CLASS as f32);
            let critical = 2.0 * (m.spring.n_per_m * arm.mass_kg).max(0.0).sqrt();
            let class = FRICTION_CLASS_DAMPING * critical / arm.friction_n_s_per_m;
            if arm.friction_n_s_per_m > 0.0 && class < f64::from(a.tolerance.friction) {
                a.tolerance.friction = class as f32;
            }
        }
    }
    let circuit = mechanics.map(|m| m.circuit);
    let mut moved = 1.0;
    match (circuit, a.magnetics) {
        (Some(c), file @ ema::control::actuator::Magnetics::Geometry { .. }) => {
            a.magnetics = c.geometry(a.coil.turns, file);
        }
        (circuit, _) => {
            let (open_h, closed_h) = circuit.map_or(
                (report.inductance.open_h, report.inductance.closed_h),
                |c| {
                    (
                        c.inductance_h(0.0) as f32,
                        c.inductance_h(c.stroke_m) as f32,
                    )
                },
            );
            let (g_open, g_closed) = (
                a.mechanics.residual_gap_m + a.mechanics.stroke_m,
                a.mechanics.residual_gap_m,
            );
            let (rho_o, rho_c) = (1.0 / open_h, 1.0 / closed_h);
            let q = g_closed / (g_open - g_closed);
            let intercept = rho_c - (rho_o - rho_c) * q;
            if intercept < IRON_SHARE * rho_c {
                moved = ((1.0 - IRON_SHARE + q) * rho_c / (q * rho_o)).sqrt();
            }
            a.magnetics = ema::control::actuator::Magnetics::Inductance {
                open_h: open_h / moved,
                closed_h: closed_h * moved,
            };
        }
    }
    a.tuning = None;
    a.plant().map_err(Error::Actuator)?;
    #[expect(clippy::cast_possible_truncation)]
    if let Some(d) = mechanics.and_then(|m| m.form_deviation(&a)) {
        a.tolerance.surface = a.tolerance.surface.min(SURFACE_CLASS as f32).max(d as f32);
    }
    Ok((a, moved))
}

/// Share of each hold of [`mechanics`] averaged: its end, once the move and its settling
/// are over (the hold lasts the move's settling target plus twice the steady window).
pub const HOLD_WINDOW_SHARE: f64 = 0.4;

/// The board's capture of a move spans this many of the largest move's minimum-time
/// moves (at most the hold before its window): time for the move and its settling, which
/// [`fit_armature`] fits.
pub const MOVE_CAPTURE_MOVES: f64 = 4.0;

/// The spring measured by [`mechanics`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    /// Rate \[N/m\].
    pub n_per_m: f64,
    /// Preload at the open stop \[N\] (a fit below zero, a spring without preload read
    /// through the noise, is taken as none).
    pub preload_n: f64,
    /// Two standard errors of the rate, from the holds' fit's residuals (kept when the
    /// moves correct the rate: [`Mechanics::fit`]) \[N/m\].
    pub spread_n_per_m: f64,
    /// The holds: corrected position \[m\] and mean magnetic force \[N\].
    pub holds: [(f64, f64); crate::actuator::SEQUENCE.len()],
}

/// What the closed-loop holds measure: the spring, and the mass and the friction when
/// some move could be fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mechanics {
    /// The spring's rate and preload ([`fit_spring`]).
    pub spring: Spring,
    /// The mass and the friction ([`fit_armature`]).
    pub armature: Option<Armature>,
    /// The inductance at each hold, from its probe ([`probe_inductance`]): corrected
    /// position \[m\], inductance \[H\] and two standard errors of it \[H\]; none
    /// where no probe ran or its spread exceeds [`HOLD_PROBE_MAX_SPREAD`].
    pub inductances: [Option<(f64, f64, f64)>; crate::actuator::SEQUENCE.len()],
    /// The magnetic circuit fitted to the stops' inductances and the holds'
    /// ([`Circuit::fit`]): the pull the spring and the mass are read with.
    pub circuit: Circuit,
}

impl Mechanics {
    /// Each hold's inductance error against `plant`'s at the hold's position, relative
    /// (NaN where the probe read nothing).
    #[must_use]
    pub fn inductance_errors(&self, plant: &Params) -> [f64; crate::actuator::SEQUENCE.len()] {
        self.inductances.map(|p| {
            p.map_or(f64::NAN, |(x, l, _)| {
                l / plant.inductance_h(plant.gap_m(x)) - 1.0
            })
        })
    }

    /// The largest deviation, relative, of the inductance `a`'s circuit gives (the
    /// written file's, [`measured`]) from the one each hold's probe read (`None` when no
    /// probe read one): how far the circuit's form misses the actuator between the stops,
    /// as far as the probes see.
    #[must_use]
    pub fn form_deviation(&self, a: &Actuator) -> Option<f64> {
        let plant = a.plant().ok()?;
        self.inductances
            .iter()
            .flatten()
            .map(|&(x, l, _)| {
                #[expect(clippy::cast_possible_truncation)]
                let form = plant.magnetics.inductance_h(plant.gap_m(x as f32));
                (f64::from(form) / l - 1.0).abs()
            })
            .reduce(crate::targets::worse)
    }

    /// The magnetic circuit from the stops' inductances (the commissioning's `report`)
    /// and the holds' `inductances` ([`Circuit::fit`], for the actuator file `a`), and
    /// with its pull the spring from the `holds`' windows ([`fit_spring`]), the mass and
    /// the friction from their moves ([`fit_armature`]). When a hold is not at rest
    /// ([`REST_SHARE`]), the spring's rate is corrected by what the moves read it missed
    /// ([`Armature::stiffness_n_per_m`]), its line turned about the holds' mean. With
    /// the armature's inertia taken out of the windows ([`fit_spring`]) a hold that
    /// limit-cycles reads the rate nearly as well as one at rest; the correction still
    /// lowers the median error of such holds on drawn plungers, positioners and products
    /// (300 of each, seed 1: 0.84 -> 0.47 %, 0.23 -> 0.17 %, 0.09 -> 0.07 %). At rest the
    /// holds read it better than the moves.
    #[must_use]
    pub fn fit(
        report: &Report,
        a: &Actuator,
        holds: &Holds,
        inductances: [Option<(f64, f64, f64)>; crate::actuator::SEQUENCE.len()],
    ) -> Self {
        let circuit = Circuit::fit(report, a, &inductances);
        let stroke_m = circuit.stroke_m;
        let dt_s = holds.window_dt_s;
        // The moves read the mass and the friction with the spring the windows read
        // without them; the windows again with them.
        let mut spring = fit_spring(report, circuit, &holds.windows, dt_s, None);
        let armature = fit_armature(report, circuit, &spring, holds).and_then(|arm| {
            spring = fit_spring(
                report,
                circuit,
                &holds.windows,
                dt_s,
                Some((arm.mass_kg, arm.friction_n_s_per_m)),
            );
            fit_armature(report, circuit, &spring, holds)
        });
        let force = pull(report, circuit);
        #[expect(clippy::cast_precision_loss)]
        let restless = holds.windows.iter().any(|w| {
            let x: Vec<f64> = w.iter().map(|&(y, i)| force(y, i).0).collect();
            let n = x.len() as f64;
            let mean = x.iter().sum::<f64>() / n;
            (x.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt() > REST_SHARE * stroke_m
        });
        if let Some(arm) = armature.filter(|_| restless) {
            #[expect(clippy::cast_precision_loss)]
            let n = spring.holds.len() as f64;
            let x = spring.holds.iter().map(|h| h.0).sum::<f64>() / n;
            let f = spring.holds.iter().map(|h| h.1).sum::<f64>() / n;
            spring.n_per_m += arm.stiffness_n_per_m;
            spring.preload_n = (f - spring.n_per_m * x).max(0.0);
        }
        Self {
            spring,
            armature,
            inductances,
            circuit,
        }
    }
}

/// A hold whose window's position spreads (one standard deviation) over more than this
/// share of the stroke is not at rest: the loop limit-cycles about it.
pub const REST_SHARE: f64 = 0.002;

/// The readings of the holds as the board captures them, one `(position [m], current
/// [A])` per capture sample: the position's mean over its ticks, the current's root mean
/// square (`ema::device`'s capture).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Holds {
    /// Each hold's move from its start, one sample every `move_dt_s`.
    pub moves: [Vec<(f64, f64)>; crate::actuator::SEQUENCE.len()],
    /// Time between the moves' samples \[s\].
    pub move_dt_s: f64,
    /// Each hold's window, once the move has settled: its last [`HOLD_WINDOW_SHARE`],
    /// one sample every `window_dt_s`.
    pub windows: [Vec<(f64, f64)>; crate::actuator::SEQUENCE.len()],
    /// Time between the windows' samples \[s\].
    pub window_dt_s: f64,
}

/// The capture decimations of the holds with `settings` over `stroke_m` at `rate_hz`:
/// `(move, window)`. A move's capture spans [`MOVE_CAPTURE_MOVES`] of the largest move's
/// minimum-time move, at most the hold before its window; a window's, the whole hold (the
/// window is its last [`HOLD_WINDOW_SHARE`]); each in the board's
/// [`ema::device::CAPTURE_CAPACITY`] samples.
#[must_use]
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_precision_loss
)]
pub fn decimations(settings: &ema::control::Settings, stroke_m: f64, rate_hz: f64) -> (u16, u16) {
    use crate::actuator::SEQUENCE;
    let hold_s = crate::actuator::segment_s(settings, stroke_m);
    let largest = (1..SEQUENCE.len())
        .filter_map(|k| {
            crate::actuator::minimum_move_s(
                settings,
                SEQUENCE[k - 1] * stroke_m,
                SEQUENCE[k] * stroke_m,
            )
        })
        .fold(0.0, f64::max);
    let move_s = if largest > 0.0 {
        (MOVE_CAPTURE_MOVES * largest).min((1.0 - HOLD_WINDOW_SHARE) * hold_s)
    } else {
        (1.0 - HOLD_WINDOW_SHARE) * hold_s
    };
    let ticks = |span_s: f64| {
        (span_s * rate_hz / ema::device::CAPTURE_CAPACITY as f64)
            .ceil()
            .clamp(1.0, f64::from(u16::MAX)) as u16
    };
    (ticks(move_s), ticks(hold_s))
}

/// The spring's rate and preload, and the mass and the friction, from four closed-loop
/// holds at the positions of the actuator's evaluation sequence
/// ([`crate::actuator::SEQUENCE`], 1/8 to 7/8 of the stroke), the loop closed with the
/// settings the measured actuator derives ([`measured`], the file's spring and mass, the
/// default tuning) on the `plant`, its position sensor `draw`n; each hold lasts as in the
/// evaluation sequence, its settling target and twice the steady window. The board's
/// captures ([`Holds`], [`decimations`]) are what is fitted: [`fit_spring`] on the
/// windows, [`fit_armature`] on the moves.
///
/// The loop holds with the default tuning, for the file's mass and spring: on a plant far
/// from them it may limit-cycle about a hold, and the holds then read the spring several
/// per cent off, or a monitor ends them. A monitor that ends them (an armature much
/// lighter than the file's: the observer's velocity, from the file's mass, runs on after
/// the armature has stopped) ends an attempt: the holds run again with a slower loop
/// ([`hold_tuning`]), up to [`HOLD_ATTEMPTS`] in all.
///
/// # Errors
/// Measured values no actuator can have; settings that do not derive.
pub fn mechanics(
    a: &Actuator,
    report: &Report,
    plant: &Params,
    draw: Option<&Draw>,
) -> Result<Holding, Error> {
    let (m, _) = measured(a, report, None)?;
    let mut faults = Vec::new();
    let mut took_s = 0.0;
    for attempt in 0..HOLD_ATTEMPTS {
        let mut held = m;
        held.tuning = Some(hold_tuning(&m, attempt)?);
        let (result, s) = hold_once(a, &held, report, plant, draw)?;
        took_s += s;
        match result {
            Ok(mechanics) => {
                return Ok(Holding {
                    mechanics: Some(mechanics),
                    faults,
                    took_s,
                })
            }
            Err(f) => faults.push(f),
        }
    }
    Ok(Holding {
        mechanics: None,
        faults,
        took_s,
    })
}

/// Attempts at the holds of [`mechanics`] (and of the bench's): the first with the
/// default tuning, each after a fault with a slower loop, the backstepping's `alpha` and
/// the observer's bandwidth [`RETRY_GAIN_SHARE`] times the attempt's before. On the
/// family's drawn plants the holds that a monitor ends are armatures 10-30 % lighter
/// than their file's, whose moves' acceleration the observer, with the file's mass,
/// mispredicts in proportion: on the 12 V solenoid the stuck-sensor monitor ends them,
/// on the 50 kHz pilot the observer's disturbance runs away on the first move, which
/// overshoots its target several times over with the coil off, and the residual
/// detector, reading the back-EMF from that velocity, names `current_stuck`. The
/// slower loop holds them to their end (`hil-sim commission NAME` counts the attempts
/// and the holds that measured nothing).
pub const HOLD_ATTEMPTS: u32 = 3;

/// Share of an attempt's loop gains, the backstepping's `alpha` and the observer's
/// bandwidth, the next attempt at the holds runs with \[-\] (see [`HOLD_ATTEMPTS`]).
/// Gentler moves alone (the reference shaping's margin halved) did not help the 50 kHz
/// pilot: 18 of 1000 drawn pilots measured nothing after three attempts, none with
/// this share.
pub const RETRY_GAIN_SHARE: f32 = 0.6;

/// The tuning the holds' `attempt` (from 0) runs with on the measured actuator `m`: its
/// default, its gains times [`RETRY_GAIN_SHARE`] per attempt before.
///
/// # Errors
/// An actuator whose tuning does not derive.
pub fn hold_tuning(m: &Actuator, attempt: u32) -> Result<ema::control::actuator::Tuning, Error> {
    let mut t = m.tuning_or_default().map_err(Error::Actuator)?;
    for _ in 0..attempt {
        t.alpha_per_s *= RETRY_GAIN_SHARE;
        t.observer_rad_s *= RETRY_GAIN_SHARE;
    }
    Ok(t)
}

/// What the holds of [`mechanics`] gave.
#[derive(Clone, Debug, PartialEq)]
pub struct Holding {
    /// What they measured; none when a fault ended every attempt (the last of
    /// [`Holding::faults`]: the file keeps its spring and mass).
    pub mechanics: Option<Mechanics>,
    /// The faults that ended attempts, in order.
    pub faults: Vec<&'static str>,
    /// Actuator time the attempts took, the probes at the end of each hold included
    /// (the simulation runs them in a second pass over the holds' windows; the board after
    /// each window) \[s\].
    pub took_s: f64,
}

/// One attempt at the holds of [`mechanics`] with the file `a` measured as `m` (its
/// tuning the attempt's): what they measured or the fault that ended them, and the
/// actuator time they took \[s\].
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_precision_loss
)]
fn hold_once(
    a: &Actuator,
    m: &Actuator,
    report: &Report,
    plant: &Params,
    draw: Option<&Draw>,
) -> Result<(Result<Mechanics, &'static str>, f64), Error> {
    let mut sc = crate::actuator::scenario("holds", m)?;
    sc.plant = TruePlant::Given(plant.clone());
    let code_m = f64::from(sc.controller.sense.position.scale);
    if let (Sensors::Adc(adc), Some(d)) = (&mut sc.sensors, draw) {
        (adc.position.gain_error, adc.position.offset_code) =
            d.position_error(plant.stroke_m, code_m);
        adc.seed = d.noise_seed;
    }
    let stroke_m = f64::from(m.mechanics.stroke_m);
    let rate = sc.rate_hz();
    let hold_ticks = (crate::actuator::segment_s(&sc.controller, stroke_m) * rate).round() as usize;
    let window_ticks = (HOLD_WINDOW_SHARE * hold_ticks as f64).round() as usize;
    let run = crate::sim::run(&sc)?;
    if let Some((k, f)) = run
        .samples
        .iter()
        .enumerate()
        .find_map(|(k, s)| Some((k, s.fault?)))
    {
        return Ok((Err(f.name()), (k + 1) as f64 / rate));
    }
    // The same holds again, each ended by inductance probes, once the move has long
    // settled, each probe's capture the converter's delay and a tick longer than it (the
    // readings that answer its last levels come that much later); a run of its own, so
    // that the spring and the mass are read without them.
    let probe = hold_probe(m);
    let delay = usize::from(sc.controller.delay_ticks);
    let span = probe_capture(probe.ticks(), delay);
    let probe_at = |k: usize, r: usize| {
        (k + 1) * hold_ticks - (HOLD_PROBE_RUNS * span).min(window_ticks) + r * span
    };
    sc.inductance_probes = (0..crate::actuator::SEQUENCE.len())
        .flat_map(|k| (0..HOLD_PROBE_RUNS).map(move |r| (k, r)))
        .map(|(k, r)| crate::scenario::InductanceProbe {
            at_s: probe_at(k, r) as f64 / rate,
            ..probe
        })
        .collect();
    let probed = crate::sim::run(&sc)?;
    let (move_decimation, window_decimation) = decimations(&sc.controller, stroke_m, rate);
    // The board's capture from `from`: the position's mean over each sample's ticks, the
    // current's root mean square signed as at the last.
    let capture = |from: usize, ticks: usize, decimation: u16| {
        run.samples
            .get(from..(from + ticks).min(run.samples.len()))
            .unwrap_or_default()
            .chunks_exact(usize::from(decimation))
            .take(ema::device::CAPTURE_CAPACITY)
            .map(|c| {
                let n = c.len() as f64;
                let (x, i2) = c.iter().fold((0.0, 0.0), |(x, i2), q| {
                    (x + q.x_meas_m, i2 + q.i_meas_a * q.i_meas_a)
                });
                let last = c.last().map_or(0.0, |q| q.i_meas_a);
                (x / n, (i2 / n).sqrt().copysign(last))
            })
            .collect::<Vec<_>>()
    };
    let holds = Holds {
        moves: core::array::from_fn(|k| {
            capture(k * hold_ticks, hold_ticks - window_ticks, move_decimation)
        }),
        move_dt_s: f64::from(move_decimation) / rate,
        window_dt_s: f64::from(window_decimation) / rate,
        windows: core::array::from_fn(|k| {
            capture(
                (k + 1) * hold_ticks - window_ticks,
                window_ticks,
                window_decimation,
            )
        }),
    };
    // A probe that latched a fault, or ran after one, reads nothing.
    let faulted_at = probed.samples.iter().position(|s| s.fault.is_some());
    let line = Circuit::through_stops(report, a);
    let inductances = core::array::from_fn(|k| {
        let end = probe_at(k, HOLD_PROBE_RUNS - 1) + span;
        if faulted_at.is_some_and(|f| f < end) {
            return None;
        }
        let runs = (0..HOLD_PROBE_RUNS)
            .map(|r| {
                let s = probed.samples.get(probe_at(k, r)..probe_at(k, r) + span)?;
                Some(
                    s.iter()
                        .map(|q| ProbeSample {
                            y_m: q.x_meas_m,
                            u_v: q.u_drive_v,
                            i_a: q.i_meas_a,
                            vbus_v: q.vbus_meas_v,
                        })
                        .collect(),
                )
            })
            .collect::<Option<Vec<_>>>()?;
        hold_inductance(&runs, &probe, delay, 1.0 / rate, report, line)
    });
    let probes = crate::actuator::SEQUENCE.len() * HOLD_PROBE_RUNS * span;
    let took_s = (run.samples.len() + probes) as f64 / rate;
    Ok((Ok(Mechanics::fit(report, a, &holds, inductances)), took_s))
}

/// Share of the rated current the inductance probe at each hold steps the desired
/// current up and down by: small beside the hold's current, so that the residual
/// detector's bounds, which the probe's steps test at every tick, hold on a coil the
/// stops' two-point line misses by a few per cent between them (at a tenth of the
/// rating, a drawn micro-valve's probe latched `coil_short`).
pub const HOLD_PROBE_SHARE: f64 = 0.05;

/// Periods at each level of the hold's probe: the second half's readings are each
/// level's mean, and the relation the probe's estimate rests on is exact whether or not
/// the coil's current settles within a level. Longer levels do worse: sized at four
/// times the closed coil's slew over the step, they read the positioner's holds with a
/// median error of 1.6 % instead of 0.28 % over 1000 drawn plants (the pull's square
/// wave, slower, moves the armature more).
pub const HOLD_PROBE_HALF_TICKS: u16 = 16;

/// Largest spread (two standard errors, relative) of an inductance a hold's probe reads
/// for it to count as read: a wider one is a hold the armature did not keep still.
pub const HOLD_PROBE_MAX_SPREAD: f64 = 0.03;

/// Cycles of each of the hold's probes (up and down): as many as the board's capture
/// holds at every tick with the converter's delay and a tick after them
/// ([`probe_capture`]); [`HOLD_PROBE_RUNS`] probes per hold.
pub const HOLD_PROBE_CYCLES: u16 = 7;

/// Probes at each hold, one captured at a time: the estimate's spread falls as the square
/// root of their cycles' number, and three give about as many as one probe of 16 cycles
/// (levels half as long, more cycles in the same capture, read a drawn 12 V solenoid's
/// holds up to 7 % off, measured before [`hold_inductance`] took out the supply's sag and
/// the armature's motion: its coil does not step within them).
pub const HOLD_PROBE_RUNS: usize = 3;

/// The board's capture of a probe of `ticks`, the converter `delay` ticks late: the
/// probe's ticks, the delay and one tick more \[samples\].
#[must_use]
pub const fn probe_capture(ticks: usize, delay: usize) -> usize {
    ticks + delay + 1
}

// The hold's probe is one the board accepts, and it fits the board's capture with the
// largest delay the stages accept.
const _: () = assert!(HOLD_PROBE_SHARE <= ema::device::PROBE_MAX_SHARE as f64);
const _: () = assert!(
    probe_capture(
        2 * HOLD_PROBE_CYCLES as usize * HOLD_PROBE_HALF_TICKS as usize,
        1
    ) <= ema::device::CAPTURE_CAPACITY
);

/// The inductance probe at each hold of [`mechanics`] for the measured actuator `a`
/// (its start is set per hold): [`HOLD_PROBE_SHARE`] of the rated current,
/// [`HOLD_PROBE_CYCLES`] cycles of [`HOLD_PROBE_HALF_TICKS`] periods at each level.
#[must_use]
pub fn hold_probe(a: &Actuator) -> crate::scenario::InductanceProbe {
    crate::scenario::InductanceProbe {
        at_s: 0.0,
        amplitude_a: HOLD_PROBE_SHARE * f64::from(a.coil.rated_current_a),
        half_ticks: HOLD_PROBE_HALF_TICKS,
        cycles: HOLD_PROBE_CYCLES,
    }
}

/// The inductance that inductance probes ([`ema::control::Probe`]) read, from the board's
/// drive `u_v` (the voltage set at each tick, applied over the period after it) and its
/// current readings `i_a` (each `delay` periods old), both from a probe's first tick, for
/// each of the `runs`; `half_ticks` at each level, `r_ohm` the coil's resistance, `ts_s`
/// the period: `(inductance [H], two standard errors of it [H])`.
///
/// With the armature all but still and the voltage held over each period, the coil's
/// current obeys `i(k+1) - i(k) = (1 - a) (u(k) / R - i(k))`, `a = exp(-Ts R / L)`,
/// exactly, however few periods its time constant spans; summed from any reading `j`
/// to any later `k`, `i(k) - i(j) = (1 - a) (C(k) - C(j))`, `C` the running sum of
/// `u / R - i`. Each level is read as the means of `i` and of `C` over its second half,
/// and each step from one level to the next gives a change of both: `1 - a` is the sum
/// of the changes into the upper levels less those into the lower ones, the one over the
/// other. A constant error of the applied voltage (the bridge's drops) cancels between
/// the steps up and down, and a resistance a fraction off costs that fraction times a
/// level's length over twice the coil's time constant. The spread is the cycles' (a
/// step down and the step up after it), over every run. `None` without two such cycles,
/// or a current that did not step.
#[must_use]
#[expect(clippy::cast_precision_loss)]
pub fn probe_inductance(
    runs: &[(&[f64], &[f64], &[f64])],
    motion_a_s_per_m: f64,
    half_ticks: usize,
    delay: usize,
    ts_s: f64,
    r_ohm: f64,
) -> Option<(f64, f64)> {
    let pairs: Vec<(f64, f64)> = runs
        .iter()
        .flat_map(|&(u_v, i_a, x_m)| {
            probe_pairs(
                u_v,
                i_a,
                x_m,
                motion_a_s_per_m / ts_s,
                half_ticks,
                delay,
                r_ohm,
            )
        })
        .collect();
    if pairs.len() < 2 {
        return None;
    }
    let inductance = |di: f64, e: f64| {
        let a = 1.0 - di / e;
        (a > 0.0 && a < 1.0).then(|| -ts_s * r_ohm / a.ln())
    };
    let (di, e) = pairs
        .iter()
        .fold((0.0, 0.0), |(d, e), p| (d + p.0, e + p.1));
    let l = inductance(di, e)?;
    let n = pairs.len() as f64;
    let var = pairs
        .iter()
        .map(|p| (inductance(p.0, p.1).unwrap_or(f64::INFINITY) - l).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    Some((l, 2.0 * (var / n).sqrt()))
}

/// One probe's cycles for [`probe_inductance`]: for each step down and the step up after
/// it, the current's change and the running sum's (the upper levels' less the lower's).
#[expect(clippy::cast_precision_loss)]
fn probe_pairs(
    u_v: &[f64],
    i_a: &[f64],
    x_m: &[f64],
    motion_per_m: f64,
    half_ticks: usize,
    delay: usize,
    r_ohm: f64,
) -> Vec<(f64, f64)> {
    let levels = if half_ticks < 2 {
        0
    } else {
        u_v.len().min(i_a.len().saturating_sub(delay)) / half_ticks
    };
    let mut c = 0.0;
    let running: Vec<(f64, f64)> = (0..levels * half_ticks)
        .map(|k| {
            let i = i_a[k + delay];
            let x = x_m.get(k + delay).copied().unwrap_or(0.0);
            let here = (i, c - motion_per_m * x);
            c += u_v[k] / r_ohm - i;
            here
        })
        .collect();
    let read = |h: usize| {
        let w = &running[h * half_ticks + half_ticks / 2..(h + 1) * half_ticks];
        let n = w.len() as f64;
        w.iter()
            .fold((0.0, 0.0), |(i, c), q| (i + q.0 / n, c + q.1 / n))
    };
    let reads: Vec<(f64, f64)> = (0..levels).map(read).collect();
    (1..levels.saturating_sub(1))
        .step_by(2)
        .map(|h| {
            let (before, down, up) = (reads[h - 1], reads[h], reads[h + 1]);
            (
                (up.0 - down.0) - (down.0 - before.0),
                (up.1 - down.1) - (down.1 - before.1),
            )
        })
        .collect()
}

/// What the board captures of a probe at every tick: the position and the current as
/// read, the drive set, the bus as read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbeSample {
    /// Position reading \[m\].
    pub y_m: f64,
    /// Average coil voltage the bridge was set to \[V\].
    pub u_v: f64,
    /// Current reading \[A\].
    pub i_a: f64,
    /// Bus reading \[V\].
    pub vbus_v: f64,
}

/// One hold's inductance from its probes' captures (the board's samples at every tick
/// from each probe's first), read with [`probe_inductance`] for the `probe`, the
/// converter `delay` ticks late, the period `ts_s`, the commissioning's `report` and the
/// `line` through its stops' inductances ([`Circuit::through_stops`]): the mean position
/// corrected with the end stops the `report` measured, `x = stroke (y - y_open) /
/// (y_closed - y_open)`, the
/// inductance and two standard errors of it; `None` when the probes read nothing or
/// their spread exceeds [`HOLD_PROBE_MAX_SPREAD`]. The same reading on the bench and in
/// [`mechanics`].
///
/// Two things the coil sees besides its inductance are taken out first:
/// - **The supply's sag.** The bridge sets its duty for the bus it last read, but over
///   the period the bus sags with the coil's current behind the supply's resistance: the
///   voltage applied is the drive scaled by the bus read after the period over the bus
///   the drive was set for. Near the open stop, where the coil's time constant is about
///   a period, this alone read drawn valves up to 4 % high.
/// - **The armature's motion.** The probe's pull steps the armature back and forth by
///   micrometres, and the flux it moves, `i L'(x) dx`, comes with the current's steps in
///   antiphase: near the closed stop, where `L'` is large, it read the valves' holds 2 %
///   low. It is taken out with the hold's current, the position readings and the
///   `line`'s `L'`.
#[must_use]
pub fn hold_inductance(
    runs: &[Vec<ProbeSample>],
    probe: &crate::scenario::InductanceProbe,
    delay: usize,
    ts_s: f64,
    report: &Report,
    line: Circuit,
) -> Option<(f64, f64, f64)> {
    let ticks = probe.ticks();
    let position = corrected(report, line.stroke_m);
    let split: Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> = runs
        .iter()
        .map(|s| {
            let applied = (0..ticks.min(s.len()))
                .map(|k| {
                    let (set, after) = (s[k].vbus_v, s.get(k + 1 + delay).map(|q| q.vbus_v));
                    match after {
                        Some(after) if set > 0.0 => s[k].u_v * after / set,
                        _ => s[k].u_v,
                    }
                })
                .collect();
            (
                applied,
                s.iter().map(|q| q.i_a).collect(),
                s.iter().map(|q| position(q.y_m)).collect(),
            )
        })
        .collect();
    let slices: Vec<(&[f64], &[f64], &[f64])> = split
        .iter()
        .map(|(u, i, x)| (u.as_slice(), i.as_slice(), x.as_slice()))
        .collect();
    let (n, i_sum, y_sum) = runs
        .iter()
        .flat_map(|s| s.iter().take(ticks))
        .fold((0.0, 0.0, 0.0), |(n, i, y), q| {
            (n + 1.0, i + q.i_a, y + q.y_m)
        });
    let x = position(y_sum / n);
    let r_ohm = f64::from(report.resistance.ohm);
    let (l, spread) = probe_inductance(
        &slices,
        (i_sum / n) * line.force_coefficient_h_per_m(x) / r_ohm,
        usize::from(probe.half_ticks),
        delay,
        ts_s,
        r_ohm,
    )?;
    (spread < HOLD_PROBE_MAX_SPREAD * l).then_some((x, l, spread))
}

/// The spring's rate and preload from the readings `(position [m], current [A])` of each
/// hold's window (the loop holding the armature), one every `dt_s`, the commissioning's
/// `report`, the magnetic `circuit` measured and, once the moves have read them, the
/// armature's mass and friction (`dynamics`, `(m [kg], c [N s/m])`).
///
/// The pull is `F = i^2 L'(x) / 2` with the `circuit` measured ([`Circuit::fit`]). Each
/// reading's position is corrected with the measured end stops, `x = stroke (y - y_open)
/// / (y_closed - y_open)`. Each window's force and position are averaged reading by
/// reading with a weight that vanishes at both ends, `w(t) = sin^2(pi t / T)`: over the
/// window the equation of motion averages to `<F> - m <a> - c <v> = K <x> + F0`, and by
/// parts `<a> = <w'' x>` and `<v> = -<w' x>` (w and w' vanish at the ends), read from the
/// positions alone, without differencing their noise. A loop that limit-cycles about a
/// hold does not end its window at the speed it started it: a 1 kg plunger's hold near
/// its closed stop, a tenth of a cycle past a whole one, read the pull 1 % above the
/// spring without these terms, and the rate 5.8 % off. `K` and `F0` are the least
/// squares line through the holds.
#[must_use]
pub fn fit_spring(
    report: &Report,
    circuit: Circuit,
    holds: &[Vec<(f64, f64)>; crate::actuator::SEQUENCE.len()],
    dt_s: f64,
    dynamics: Option<(f64, f64)>,
) -> Spring {
    use core::f64::consts::PI;
    let force = pull(report, circuit);
    let (mass_kg, friction) = dynamics.unwrap_or((0.0, 0.0));
    let means = holds.each_ref().map(|w| {
        #[expect(clippy::cast_precision_loss)]
        let n = w.len() as f64;
        let rate = PI / (n * dt_s);
        let (sw, sx, sf, sa, sv) = w.iter().enumerate().fold(
            (0.0, 0.0, 0.0, 0.0, 0.0),
            |(sw, sx, sf, sa, sv), (k, &(y, i))| {
                let (x, f) = force(y, i);
                #[expect(clippy::cast_precision_loss)]
                let phase = PI * (k as f64 + 0.5) / n;
                let w = phase.sin().powi(2);
                let w1 = rate * (2.0 * phase).sin();
                let w2 = 2.0 * rate * rate * (2.0 * phase).cos();
                (sw + w, sx + w * x, sf + w * f, sa + w2 * x, sv - w1 * x)
            },
        );
        (sx / sw, (sf - mass_kg * sa - friction * sv) / sw)
    });
    #[expect(clippy::cast_precision_loss)]
    let n = means.len() as f64;
    let mx = means.iter().map(|h| h.0).sum::<f64>() / n;
    let mf = means.iter().map(|h| h.1).sum::<f64>() / n;
    let sxx: f64 = means.iter().map(|h| (h.0 - mx).powi(2)).sum();
    let k = means.iter().map(|h| (h.0 - mx) * (h.1 - mf)).sum::<f64>() / sxx;
    let preload = mf - k * mx;
    let residual: f64 = means
        .iter()
        .map(|h| (h.1 - preload - k * h.0).powi(2))
        .sum();
    Spring {
        n_per_m: k,
        preload_n: preload.max(0.0),
        spread_n_per_m: 2.0 * (residual / (n - 2.0) / sxx).sqrt(),
        holds: means,
    }
}

/// The magnet's pull the commissioning's `report` reads from a position reading `y` \[m\]
/// and a current `i` \[A\], with the position corrected by the measured end stops and
/// the `circuit` measured: `(x [m], F [N])`, `F = i^2 L'(x) / 2`
/// ([`Circuit::force_coefficient_h_per_m`]), `x = stroke (y - y_open) / (y_closed -
/// y_open)`.
fn pull(report: &Report, circuit: Circuit) -> impl Fn(f64, f64) -> (f64, f64) {
    let position = corrected(report, circuit.stroke_m);
    move |y: f64, i: f64| {
        let x = position(y);
        (x, 0.5 * i * i * circuit.force_coefficient_h_per_m(x))
    }
}

/// The position \[m\] of a reading `y` \[m\] corrected with the end stops the
/// commissioning's `report` measured, `x = stroke (y - y_open) / (y_closed - y_open)`,
/// within the stroke.
fn corrected(report: &Report, stroke_m: f64) -> impl Fn(f64) -> f64 {
    let (open, closed) = (
        f64::from(report.ends.open_m),
        f64::from(report.ends.closed_m),
    );
    move |y: f64| (stroke_m * (y - open) / (closed - open)).clamp(0.0, stroke_m)
}

/// How well the routine's step responses read an end stop's inductance, two standard
/// errors, relative: the weight of the stops' readings in [`Circuit::fit`] (the routine
/// reports no spread of its own). About what the holds' probes read: the family's drawn
/// plants read the stops with median errors of 0.1 % to 1 % (`hil-sim commission`),
/// the holds with two standard errors of 0.2 % to 0.9 %. Weighed as the 5 % the
/// routine is held to, the stops counted for nothing beside the holds, and the line
/// through the holds alone, extrapolated, read the 12 V solenoid's force near its closed
/// stop 2 % off and its spring up to 10 % off (100 drawn plants). Either way of 1 % it
/// does worse: on 1000 drawn 12 V solenoids, weighed as 0.5 % the stops read 10
/// springs more than 5 % off, as 2 % five, as 1 % one (5.4 %).
pub const STOP_INDUCTANCE_CLASS: f64 = 0.01;

/// How much better, in standard deviations, a surface growing with the gap must explain
/// the inductances than a constant one for [`Circuit::fit`] to keep it (the weighted sum of
/// squared residuals falls by at least its square). A growth fitted to the readings'
/// noise bends the force's slope, and a stop read a few times further off than
/// [`STOP_INDUCTANCE_CLASS`] (the 12 V solenoid's open stop, up to 2.7 %) looks like
/// growth: on 1000 drawn 12 V solenoids, whose surface is constant, a growth kept at
/// three deviations read 4 springs more than 5 % off (up to 8.4 %), at five one to
/// three in a thousand (up to 5.4 %, on two sets of draws; with the open stop's probe
/// twice as long, [`ema::device::commission::PROBE_READINGS`], none and one, 5.2 %). A
/// growth that matters is still kept: a pole whose sides grow by 0.3 of the gap, 14 % off
/// the stops' line, is read within 2 % of its growth (the tests).
pub const GROWTH_SIGNIFICANCE: f64 = 5.0;

/// The largest surface growth [`Circuit::fit`] considers, as `q g` at the open stop: at
/// `q g = 1` a square pole's airgap reluctance `g / S(g)` stops rising with the gap and
/// the pull at the open stop vanishes, which no reluctance actuator does.
pub const GROWTH_MAX: f64 = 0.9;

/// The magnetic circuit a commissioning reads, in the paper's reluctance model with
/// fringing: `N^2 / L(g) = rho_0 + rho_x(g) g`, each airgap's surface growing with the
/// gap as a rectangular pole's does, `S(g) = S(0) (1 + q g)(1 + q g / beta)` (the
/// pole's sides `a` and `b = beta a` each grown by `k g`, `q = k / a`), so
/// `1/L(g) = c0 + c1 g / ((1 + q g)(1 + q g / beta))`.
///
/// Through the stops alone ([`Circuit::through_stops`]) it is the two-inductance form,
/// `q = 0`; with the holds' probes ([`Circuit::fit`]) six inductances along the stroke
/// fix `c0`, `c1` and `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circuit {
    /// `c0 = rho_0 / N^2`, the iron's share of `1/L` \[1/H\].
    pub iron_per_h: f64,
    /// `c1 = rho_x(0) / N^2`, the slope of `1/L` against the gap at a closed gap
    /// \[1/(H m)\].
    pub gap_per_h_m: f64,
    /// The surface's growth `q` \[1/m\].
    pub growth_per_m: f64,
    /// The pole's aspect `beta = b / a` \[-\].
    pub aspect: f64,
    /// The airgap at the open stop, the file's residual gap and stroke \[m\].
    pub open_gap_m: f64,
    /// The stroke \[m\].
    pub stroke_m: f64,
}

impl Circuit {
    /// The airgap at position `x_m` \[m\].
    #[must_use]
    pub fn gap_m(&self, x_m: f64) -> f64 {
        self.open_gap_m - x_m
    }

    /// `g / ((1 + q g)(1 + q g / beta))` and its derivative against `g`.
    fn shape(&self, g_m: f64) -> (f64, f64) {
        shape(self.growth_per_m, self.aspect, g_m)
    }

    /// `1/L` at position `x_m` \[1/H\].
    #[must_use]
    pub fn inverse_h(&self, x_m: f64) -> f64 {
        self.iron_per_h + self.gap_per_h_m * self.shape(self.gap_m(x_m)).0
    }

    /// The inductance at position `x_m` \[H\].
    #[must_use]
    pub fn inductance_h(&self, x_m: f64) -> f64 {
        1.0 / self.inverse_h(x_m)
    }

    /// `dL/dx` at position `x_m`, the force coefficient: the pull is `i^2 / 2` times it
    /// \[H/m\]. (The airgap closes as `x` grows: `dL/dx = (d(1/L)/dg) L^2`.)
    #[must_use]
    pub fn force_coefficient_h_per_m(&self, x_m: f64) -> f64 {
        let inverse = self.inverse_h(x_m);
        self.gap_per_h_m * self.shape(self.gap_m(x_m)).1 / (inverse * inverse)
    }

    /// The airgap surface at the open stop over the surface at the closed stop \[-\].
    #[must_use]
    pub fn surface_growth(&self) -> f64 {
        let (q, b) = (self.growth_per_m, self.aspect);
        let s = |g: f64| (1.0 + q * g) * (1.0 + q * g / b);
        s(self.open_gap_m) / s(self.open_gap_m - self.stroke_m)
    }

    /// The two-inductance form through the inductances the commissioning's `report`
    /// measured at the stops, for the actuator file `a` (its residual gap and stroke):
    /// `1/L` linear in the gap, `q = 0`.
    #[must_use]
    pub fn through_stops(report: &Report, a: &Actuator) -> Self {
        Self::line(
            f64::from(report.inductance.open_h),
            f64::from(report.inductance.closed_h),
            a,
        )
    }

    /// The two-inductance form through the inductances `open_h` and `closed_h` \[H\] at
    /// the stops of the actuator file `a` (its residual gap and stroke): `1/L` linear in
    /// the gap, `q = 0`.
    #[must_use]
    pub fn line(open_h: f64, closed_h: f64, a: &Actuator) -> Self {
        let (open_gap_m, stroke_m) = gaps(a);
        let (y_open, y_closed) = (1.0 / open_h, 1.0 / closed_h);
        let slope = (y_open - y_closed) / stroke_m;
        Self {
            iron_per_h: y_closed - slope * (open_gap_m - stroke_m),
            gap_per_h_m: slope,
            growth_per_m: 0.0,
            aspect: aspect(a),
            open_gap_m,
            stroke_m,
        }
    }

    /// The circuit in the pole geometry form of `file` (`Magnetics::Geometry`, returned
    /// unchanged otherwise) for a coil of `turns`: its gap count, fringing coefficient and
    /// aspect kept, the sides scaled to the surface the circuit's `c1` asks (`c1 = gaps /
    /// (mu0 S(0) N^2)`, `S(0)` the fringing coefficient times the sides), the growth as
    /// `fringing_spread = q a` and the iron's reluctance `c0 N^2`.
    #[must_use]
    #[expect(clippy::cast_possible_truncation)]
    pub fn geometry(
        &self,
        turns: f32,
        file: ema::control::actuator::Magnetics,
    ) -> ema::control::actuator::Magnetics {
        let ema::control::actuator::Magnetics::Geometry {
            gaps,
            pole_a_m,
            pole_b_m,
            fringing_coefficient,
            ..
        } = file
        else {
            return file;
        };
        let n2 = f64::from(turns).powi(2);
        let surface =
            f64::from(gaps) / (f64::from(ema::control::model::MU0_H_PER_M) * self.gap_per_h_m * n2);
        let scale = (surface
            / (f64::from(fringing_coefficient) * f64::from(pole_a_m) * f64::from(pole_b_m)))
        .sqrt();
        let side = scale * f64::from(pole_a_m);
        ema::control::actuator::Magnetics::Geometry {
            gaps,
            pole_a_m: side as f32,
            pole_b_m: (scale * f64::from(pole_b_m)) as f32,
            fringing_coefficient,
            fringing_spread: (self.growth_per_m * side) as f32,
            iron_reluctance_per_h: (self.iron_per_h * n2) as f32,
        }
    }

    /// The circuit that best fits the stops' inductances (the commissioning's `report`)
    /// and the holds' (`(position [m], inductance [H], two standard errors [H])`, none
    /// where no probe read one), for the actuator file `a` (its residual gap, stroke and
    /// pole's aspect; a file in the two-inductance form: a square pole).
    ///
    /// Weighted least squares on `1/L`, each reading by its own spread (the holds': their
    /// probes'; the stops': [`STOP_INDUCTANCE_CLASS`]): for each growth `q` the line in
    /// `c0`, `c1` is exact, and `q` is searched from none to [`GROWTH_MAX`], on a grid
    /// and then by golden section about its best point, and kept only where it explains
    /// the readings [`GROWTH_SIGNIFICANCE`] standard deviations better than none. The
    /// iron's `c0` is kept at least [`IRON_SHARE`] of the closed stop's `1/L` (the form
    /// the file writes needs a positive iron reluctance). Fewer than two holds read: the
    /// growth is not fitted (a line through the readings).
    #[must_use]
    pub fn fit(report: &Report, a: &Actuator, holds: &[Option<(f64, f64, f64)>]) -> Self {
        let stops = Self::through_stops(report, a);
        let (open_h, closed_h) = (
            f64::from(report.inductance.open_h),
            f64::from(report.inductance.closed_h),
        );
        let class = 0.5 * STOP_INDUCTANCE_CLASS;
        // (gap, 1/L, weight): the weight 1 / sd(1/L)^2, sd(1/L) = (sd(L) / L) / L.
        let mut points = vec![
            (stops.gap_m(0.0), 1.0 / open_h, (open_h / class).powi(2)),
            (
                stops.gap_m(stops.stroke_m),
                1.0 / closed_h,
                (closed_h / class).powi(2),
            ),
        ];
        points.extend(holds.iter().flatten().map(|&(x, l, two_se)| {
            let sd = 0.5 * two_se / l;
            (stops.gap_m(x), 1.0 / l, (l / sd).powi(2))
        }));
        let floor = IRON_SHARE as f64 / closed_h;
        let line = |q: f64| line_fit(&points, q, stops.aspect, floor);
        let best = if holds.iter().flatten().count() < 2 {
            0.0
        } else {
            let most = GROWTH_MAX / stops.open_gap_m;
            let grid = 64;
            #[expect(clippy::cast_precision_loss)]
            let at = |j: usize| most * (j as f64 / grid as f64).powi(2);
            let j = (0..=grid)
                .min_by(|&p, &q| line(at(p)).2.total_cmp(&line(at(q)).2))
                .unwrap_or(0);
            let q = golden(
                |q| line(q).2,
                at(j.saturating_sub(1)),
                at((j + 1).min(grid)),
            );
            let q = if line(q).2 <= line(at(j)).2 { q } else { at(j) };
            // A growth the readings do not ask for is their noise.
            if line(0.0).2 - line(q).2 > GROWTH_SIGNIFICANCE * GROWTH_SIGNIFICANCE {
                q
            } else {
                0.0
            }
        };
        let (c0, c1, _) = line(best);
        Self {
            iron_per_h: c0,
            gap_per_h_m: c1,
            growth_per_m: best,
            ..stops
        }
    }

    /// The largest deviation, relative, of this circuit's inductance from each of the
    /// holds' readings (`(position [m], inductance [H], _)`; `None` when none was read).
    #[must_use]
    pub fn deviation(&self, holds: &[Option<(f64, f64, f64)>]) -> Option<f64> {
        holds
            .iter()
            .flatten()
            .map(|&(x, l, _)| (self.inductance_h(x) / l - 1.0).abs())
            .reduce(crate::targets::worse)
    }
}

/// The file `a`'s airgap at the open stop and its stroke \[m\].
fn gaps(a: &Actuator) -> (f64, f64) {
    let m = &a.mechanics;
    (
        f64::from(m.residual_gap_m) + f64::from(m.stroke_m),
        f64::from(m.stroke_m),
    )
}

/// The pole's aspect `b / a` in file `a` (a square one for the two-inductance form).
fn aspect(a: &Actuator) -> f64 {
    match a.magnetics {
        ema::control::actuator::Magnetics::Geometry {
            pole_a_m, pole_b_m, ..
        } => f64::from(pole_b_m) / f64::from(pole_a_m),
        ema::control::actuator::Magnetics::Inductance { .. } => 1.0,
    }
}

/// `g / ((1 + q g)(1 + q g / beta))` and its derivative against `g`.
fn shape(q: f64, beta: f64, g: f64) -> (f64, f64) {
    let (p1, p2) = (1.0 + q * g, 1.0 + q * g / beta);
    let d = p1 * p2;
    let dd = q * p2 + q / beta * p1;
    (g / d, (d - g * dd) / (d * d))
}

/// The weighted least squares line `1/L = c0 + c1 shape(g)` through `points`
/// (`(gap, 1/L, weight)`) at growth `q`, `c0` at least `floor`: `(c0, c1, weighted sum
/// of the squared residuals)`.
fn line_fit(points: &[(f64, f64, f64)], q: f64, beta: f64, floor: f64) -> (f64, f64, f64) {
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(g, y, w) in points {
        let x = shape(q, beta, g).0;
        sw += w;
        sx += w * x;
        sy += w * y;
        sxx += w * x * x;
        sxy += w * x * y;
    }
    let det = sw * sxx - sx * sx;
    let (mut c0, mut c1) = ((sy * sxx - sx * sxy) / det, (sw * sxy - sx * sy) / det);
    // Below the floor, or no number at all (a singular fit).
    if c0.partial_cmp(&floor) == Some(std::cmp::Ordering::Less) || c0.is_nan() {
        c0 = floor;
        c1 = (sxy - c0 * sx) / sxx;
    }
    let ssr = points
        .iter()
        .map(|&(g, y, w)| w * (y - c0 - c1 * shape(q, beta, g).0).powi(2))
        .sum();
    (c0, c1, ssr)
}

/// The minimum of `f` between `lo` and `hi` by golden-section search (to a millionth of
/// the interval).
fn golden(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let r = 0.5 * (5.0_f64.sqrt() - 1.0);
    let (mut a, mut b) = (hi - r * (hi - lo), lo + r * (hi - lo));
    let (mut fa, mut fb) = (f(a), f(b));
    for _ in 0..30 {
        if fa < fb {
            hi = b;
            b = a;
            fb = fa;
            a = hi - r * (hi - lo);
            fa = f(a);
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + r * (hi - lo);
            fb = f(b);
        }
    }
    0.5 * (lo + hi)
}

/// One commissioning and what it is judged against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// The routine's result.
    pub report: Result<Report, Abort>,
    /// Actuator time it took \[s\].
    pub took_s: f64,
    /// Largest true coil current \[A\].
    pub peak_a: f64,
    /// The plant's resistance \[ohm\].
    pub resistance_ohm: f64,
    /// The plant's inductance at the open and the closed stop \[H\].
    pub inductance_h: [f64; 2],
    /// What the file's calibration reads with the armature at each stop, noise and
    /// quantisation aside \[m\].
    pub ends_m: [f64; 2],
    /// One position code \[m\].
    pub code_m: f64,
    /// Largest relative error over the stroke of the inductance the routine's two stops'
    /// inductances model ([`curve_error`] of the file [`measured`] writes without the
    /// holds) \[-\]; NaN for a commissioning that stopped.
    pub curve_error: f64,
}

impl Outcome {
    /// Relative errors of the resistance, the two inductances and the inductance curve
    /// over the stroke ([`Outcome::curve_error`], unsigned), and the end stops' errors in
    /// position codes; `None` for a commissioning that stopped.
    #[must_use]
    pub fn errors(&self) -> Option<[f64; 6]> {
        let r = self.report.ok()?;
        let rel = |got: f32, want: f64| f64::from(got) / want - 1.0;
        let codes = |got: f32, want: f64| (f64::from(got) - want).abs() / self.code_m;
        Some([
            rel(r.resistance.ohm, self.resistance_ohm),
            rel(r.inductance.open_h, self.inductance_h[0]),
            rel(r.inductance.closed_h, self.inductance_h[1]),
            self.curve_error,
            codes(r.ends.open_m, self.ends_m[0]),
            codes(r.ends.closed_m, self.ends_m[1]),
        ])
    }
}

/// The plant of actuator `a`'s file, or `draw`n from it.
///
/// # Errors
/// An actuator whose settings do not derive.
pub fn true_plant(a: &Actuator, draw: Option<&Draw>) -> Result<Params, Error> {
    Ok(plant_of(&scenario(a, true)?, draw))
}

/// The plant of the board scenario `sc`, or `draw`n from it.
fn plant_of(sc: &Scenario, draw: Option<&Draw>) -> Params {
    let file = sc.plant.resolve(&sc.controller.plant);
    draw.map_or_else(|| file.clone(), |d| d.apply(&file))
}

/// Plants a tuning is validated on in [`closed_loop`] (the tune command's default is 100:
/// this runs once per commissioned actuator).
pub const CLOSED_LOOP_VALIDATION: usize = 20;

/// What a commissioned actuator does once tuned, in closed loop on its true plant.
#[derive(Clone, Debug, PartialEq)]
pub enum ClosedLoop {
    /// No tuning meets every target on the measured actuator's corner plants: the tune's
    /// diagnosis.
    Untuned(String),
    /// The actuator's evaluation sequence on its true plant.
    Ran {
        /// Its worst metrics.
        worst: Worst,
        /// The targets they are judged by.
        targets: Targets,
    },
}

impl ClosedLoop {
    /// The targets missed (`untuned` when no tuning was found).
    #[must_use]
    pub fn misses(&self) -> Vec<&'static str> {
        match self {
            ClosedLoop::Untuned(_) => vec!["untuned"],
            ClosedLoop::Ran { worst, targets } => worst.misses(targets),
        }
    }
}

/// Tunes the actuator `report` (and `mechanics`, when measured) measured on file `a`
/// ([`measured`]) at the board's rate, as `bench commission --tune` does, and runs its
/// evaluation sequence on the true `plant`, the converter with its typical noise but no
/// gain or offset error (the end stops are not yet applied to the calibration, so a
/// sensor's own error would stay in the position).
///
/// # Errors
/// Measured values no actuator can have; settings that do not derive.
pub fn closed_loop(
    a: &Actuator,
    report: &Report,
    mechanics: Option<&Mechanics>,
    plant: &Params,
) -> Result<ClosedLoop, Error> {
    let (m, _) = measured(a, report, mechanics)?;
    let rate = f64::from(a.board.rate_hz);
    let space = crate::tune::Space::for_actuator(&m, rate)?;
    let tuned = crate::tune::tune(
        "commissioned",
        &m,
        &[rate],
        &space,
        1,
        CLOSED_LOOP_VALIDATION,
    )?;
    let Some(t) = tuned.tuned else {
        return Ok(ClosedLoop::Untuned(
            tuned.refusal.map(|r| r.to_string()).unwrap_or_default(),
        ));
    };
    let mut sc = crate::actuator::scenario("commissioned", &t)?;
    sc.plant = TruePlant::Given(plant.clone());
    let run = crate::sim::run(&sc)?;
    let targets = Targets::for_scenario(&sc);
    Ok(ClosedLoop::Ran {
        worst: Worst::of([&run.metrics], &targets),
        targets,
    })
}

/// Commissions actuator `a` (its file), the plant the file's or `draw`n from it.
///
/// # Errors
/// An actuator whose settings do not derive.
pub fn run(a: &Actuator, draw: Option<&Draw>) -> Result<Outcome, Error> {
    run_on(a, &plant_of(&scenario(a, true)?, draw), draw)
}

/// Commissions actuator `a` (its file) on `plant`, its position sensor and its converter's
/// noise `draw`n as [`run`]'s.
///
/// # Errors
/// An actuator whose settings do not derive; a plant that does not validate.
pub fn run_on(a: &Actuator, plant: &Params, draw: Option<&Draw>) -> Result<Outcome, Error> {
    let mut sc = scenario(a, true)?;
    if let (Sensors::Adc(adc), Some(d)) = (&mut sc.sensors, draw) {
        adc.seed = d.noise_seed;
    }
    let plant = plant.clone();
    let mut stepper = Stepper::for_scenario(&sc, plant.clone(), sc.integration.substeps)?;
    let mut converter = match &sc.sensors {
        Sensors::Adc(adc) => adc.start(&sc.controller.sense),
        Sensors::Ideal => Adc::default().start(&sc.controller.sense),
    };
    let position = sc.controller.sense.position;
    let code_m = f64::from(position.scale);
    let (gain, offset_code) = draw.map_or((0.0, 0.0), |d| d.position_error(plant.stroke_m, code_m));
    converter.set_position_error(gain, offset_code);
    let (pwm, dir, en, lines) = hal::bridge_io(sc.bridge.max_duty);
    let Ok(mut bridge) = HBridge::new(pwm, dir, en);
    let cfg = sc.controller.build().map_err(Error::Controller)?;
    // As the board's dispatcher plans it (`ema::device`).
    let plan = Plan::for_actuator(a, a.board.rate_hz).map_err(Error::Actuator)?;
    let mut id = Identification::new(plan);
    let (mut applied, mut peak_a) = (0.0_f32, 0.0_f64);
    let rate = f64::from(a.board.rate_hz);
    let mut report = Err(Abort::Stopped);
    let mut ticks = 0_u64;
    // Ten times the plan without restarts: more is a routine that does not end.
    while ticks < 10 * plan.ticks() {
        ticks += 1;
        let truth = stepper.sample();
        peak_a = peak_a.max(truth.i_a.abs());
        let frame = converter.sample(truth.x_m, truth.i_a, truth.vbus_v);
        let Ok(m) = cfg.sense().convert(&frame) else {
            // A reading the board would latch as a fault.
            report = Err(Abort::Fault);
            break;
        };
        match id.step(&m, applied) {
            Step::Drive(u) => {
                // The mock pins cannot fail.
                applied = bridge
                    .apply_clear(u, m.vbus_v, cfg.max_modulation())
                    .map_or(0.0, |d| d.u_v);
            }
            Step::Done(r) => {
                report = r;
                break;
            }
        }
        stepper.advance(lines.switches(), sc.bridge.mode);
    }
    let ends_m = [0.0, plant.stroke_m].map(|x| x * (1.0 + gain) + offset_code * code_m);
    // A measured circuit no file can hold has no curve: NaN, over any target.
    let curve_error = report.as_ref().map_or(f64::NAN, |r| {
        measured(a, r, None)
            .and_then(|(m, _)| curve_error(&m, &plant))
            .unwrap_or(f64::NAN)
    });
    Ok(Outcome {
        report,
        took_s: ticks as f64 / rate,
        peak_a,
        resistance_ohm: plant.resistance_ohm,
        inductance_h: [0.0, plant.stroke_m].map(|x| plant.inductance_h(plant.gap_m(x))),
        ends_m,
        code_m,
        curve_error,
    })
}

/// Positions, evenly spread over the stroke with both stops, at which [`curve_error`]
/// compares the inductances.
pub const CURVE_POSITIONS: usize = 17;

/// Largest relative error, over [`CURVE_POSITIONS`] positions, of the inductance that
/// the actuator file `model` models (one [`measured`] wrote) against `plant`'s \[-\].
/// Between the stops it is what the written circuit misses of the plant's; NaN
/// propagates.
///
/// # Errors
/// A file whose circuit no actuator can have.
#[expect(clippy::cast_precision_loss, clippy::cast_possible_truncation)]
pub fn curve_error(model: &Actuator, plant: &Params) -> Result<f64, Error> {
    let model = model.plant().map_err(Error::Actuator)?;
    Ok((0..CURVE_POSITIONS)
        .map(|k| {
            let x = plant.stroke_m * k as f64 / (CURVE_POSITIONS - 1) as f64;
            let got = model.magnetics.inductance_h(model.gap_m(x as f32));
            (f64::from(got) / plant.inductance_h(plant.gap_m(x)) - 1.0).abs()
        })
        .fold(0.0, crate::targets::worse))
}

/// The armature's mass and friction measured by [`fit_armature`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Armature {
    /// Moving mass \[kg\].
    pub mass_kg: f64,
    /// Viscous friction \[N s/m\].
    pub friction_n_s_per_m: f64,
    /// The stiffness the spring's fit missed, as the moves read it (`K` in
    /// [`fit_armature`]) \[N/m\].
    pub stiffness_n_per_m: f64,
    /// Moves fitted.
    pub moves: usize,
}

/// A move has settled once its position stays within this share of the move of its
/// target: [`fit_armature`] fits each move up to then.
pub const SETTLED_SHARE: f64 = 0.02;

/// A move that comes this near a stop (as a share of the stroke) may have touched it,
/// where the equation of motion [`fit_armature`] fits does not hold: it is left out.
pub const STOP_SHARE: f64 = 0.01;

/// The mass and the friction from the moves between the holds ([`Holds::moves`], the
/// first, from the open stop, left out), with the `spring` measured from their windows,
/// the commissioning's `report` and the magnetic `circuit` measured; `None` when no move
/// can be fitted.
///
/// Over a move, the equation of motion integrated twice from its start is
/// `m (x - x0 - v0 t) + c ∫(x - x0) + K ∫∫(x - x0) + e t^2 / 2 = ∫∫(F - K' x - F0)`:
/// `F` the magnet's pull read from the current and the measured circuit
/// ([`fit_spring`]'s), `K'` and `F0` the spring's fit, `K` what that fit missed, `e` the
/// force's error at the start. Both sides are integrals of the readings, whose noise they
/// average out. `m`, `c` and `K` are common to the moves; each move has its own start
/// `x0` and velocity `v0` (a loop that limit-cycles about a hold starts no move at rest)
/// and `e`; all by least squares, each move up to where it has settled
/// ([`SETTLED_SHARE`]: later readings carry the force's error at the end, which only grows
/// in the double integral).
///
/// The board's capture averages over its ticks, the current as its root mean square: a
/// sliding-mode current that alternates from tick to tick would, sampled, integrate to a
/// pull off by its ripple, and its mean would miss the ripple's share of the pull.
#[must_use]
#[expect(clippy::cast_precision_loss)]
pub fn fit_armature(
    report: &Report,
    circuit: Circuit,
    spring: &Spring,
    holds: &Holds,
) -> Option<Armature> {
    let stroke_m = circuit.stroke_m;
    let force = pull(report, circuit);
    let near_stop = |x: f64| x < STOP_SHARE * stroke_m || x > (1.0 - STOP_SHARE) * stroke_m;
    let usable: Vec<usize> = (1..holds.moves.len())
        .filter(|&k| {
            !holds.moves[k]
                .iter()
                .any(|&(y, i)| near_stop(force(y, i).0))
        })
        .collect();
    let moves = usable.len();
    if moves == 0 {
        return None;
    }
    // m, c, K; then x0, v0 and e of each move.
    let unknowns = 3 + 3 * moves;
    let dt = holds.move_dt_s;
    let mut rows: Vec<(Vec<f64>, f64)> = Vec::new();
    for (u, &k) in usable.iter().enumerate() {
        let seg = &holds.moves[k];
        let (x0, x1) = (spring.holds.get(k - 1)?.0, spring.holds.get(k)?.0);
        let settled = seg
            .iter()
            .rposition(|&(y, i)| (force(y, i).0 - x1).abs() > SETTLED_SHARE * (x1 - x0).abs())
            .unwrap_or(0);
        // Trapezoidal integrals from the move's start.
        let (mut f1, mut f2, mut j1, mut j2) = (0.0, 0.0, 0.0, 0.0);
        let mut last: Option<(f64, f64)> = None;
        for (n, &(y, i)) in seg.iter().take(settled + 1).enumerate() {
            let (x, f) = force(y, i);
            let net = f - spring.n_per_m * x - spring.preload_n;
            let dx = x - x0;
            if let Some((net0, dx0)) = last {
                let f1_next = f1 + 0.5 * dt * (net0 + net);
                f2 += 0.5 * dt * (f1 + f1_next);
                f1 = f1_next;
                let j1_next = j1 + 0.5 * dt * (dx0 + dx);
                j2 += 0.5 * dt * (j1 + j1_next);
                j1 = j1_next;
            }
            last = Some((net, dx));
            let t = n as f64 * dt;
            let mut r = vec![0.0; unknowns];
            r[0] = dx;
            r[1] = j1;
            r[2] = j2;
            r[3 + 3 * u] = 1.0;
            r[4 + 3 * u] = t;
            r[5 + 3 * u] = 0.5 * t * t;
            rows.push((r, f2));
        }
    }
    let theta = least_squares(&rows, unknowns)?;
    if theta[0].is_nan() || theta[0] <= 0.0 {
        return None;
    }
    Some(Armature {
        mass_kg: theta[0],
        friction_n_s_per_m: theta[1],
        stiffness_n_per_m: theta[2],
        moves,
    })
}

/// Least squares `theta` of `y = r . theta` over `rows`, by the normal equations with the
/// columns scaled to unit norm, solved by Gauss-Jordan elimination with partial pivoting;
/// `None` when they are singular.
fn least_squares(rows: &[(Vec<f64>, f64)], unknowns: usize) -> Option<Vec<f64>> {
    let scale: Vec<f64> = (0..unknowns)
        .map(|c| rows.iter().map(|(r, _)| r[c] * r[c]).sum::<f64>().sqrt())
        .collect();
    if scale.iter().any(|s| s.is_nan() || *s <= 0.0) {
        return None;
    }
    // The normal equations, each row with its right-hand side last.
    let mut a: Vec<Vec<f64>> = (0..unknowns)
        .map(|p| {
            let mut row: Vec<f64> = (0..unknowns)
                .map(|q| rows.iter().map(|(r, _)| r[p] * r[q]).sum::<f64>() / (scale[p] * scale[q]))
                .collect();
            row.push(rows.iter().map(|(r, y)| r[p] * y).sum::<f64>() / scale[p]);
            row
        })
        .collect();
    for c in 0..unknowns {
        let pivot = (c..unknowns).max_by(|&p, &q| a[p][c].abs().total_cmp(&a[q][c].abs()))?;
        a.swap(c, pivot);
        let lead = a[c].clone();
        if lead[c].is_nan() || lead[c].abs() <= 1e-12 {
            return None;
        }
        for (p, row) in a.iter_mut().enumerate() {
            if p != c {
                let f = row[c] / lead[c];
                for (v, l) in row.iter_mut().zip(&lead).skip(c) {
                    *v -= f * l;
                }
            }
        }
    }
    Some(
        a.iter()
            .zip(&scale)
            .enumerate()
            .map(|(c, (row, s))| row[unknowns] / row[c] / s)
            .collect(),
    )
}
