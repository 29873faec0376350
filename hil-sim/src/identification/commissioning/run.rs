//! Commissionings of simulated actuators, the plants they run on, what they are judged
//! against, and the commissioned actuator's closed loop.

use ema::control::actuator::Actuator;
use ema::control::bridge::HBridge;
use ema::control::sense::PositionCorrection;
use ema::device::commission::{Abort, Identification, Plan, Report, Step};
use rand::Rng;

use super::{measured, Mechanics};
use crate::simulation::board::scenario;
use crate::simulation::hal::{self, Adc, CalibrationClass, ChannelError};
use crate::simulation::plant::{ForceModel, Params, Surface};
use crate::simulation::scenario::{Scenario, Sensors, TruePlant};
use crate::simulation::sim::Stepper;
use crate::simulation::targets::{Targets, Worst};
use crate::simulation::Error;

/// An actuator drawn off its file, as a user's is: the airgap surfaces, the coil's
/// resistance, the spring rate, the mass each within +-30 % (a preload the file gives
/// with the spring's rate; where it gives none, an unknown one up to a fifth of the
/// spring's force over the stroke), the friction within +-50 %, and a position sensor
/// whose offset and gain are each within +-3 % (of the stroke, of the span), the current
/// and bus channels' gain and offset within the converters' class
/// ([`CalibrationClass::default`]: a current gain error goes straight into the resistance
/// measured, `R = du / di`), and the converter's noise its own realisation: the
/// inductances come from a few noisy current samples of a decay, so one noise sequence
/// shared by every draw would give every draw the same error and hide its scatter.
///
/// The airgap surfaces' shape is drawn too: half the specimens keep the file's (a
/// constant surface stays constant), half have poles whose sides grow with the gap by
/// `k g` more than the file's (fringing), `k` uniform from none to the largest growth
/// [`largest_spread`] allows: the one at which the drawn surface, at its file's value at
/// mid-stroke, reaches the file's surface tolerance at a stop (for the product's
/// 7.5 mm square pole over gaps of 0.5 to 4.5 mm and a 20 % tolerance, `k` up to 0.36,
/// 20 % more surface at the open stop and 18 % less at the closed one). The file's
/// controller is designed for every surface within that tolerance over the stroke (its
/// surface bounds, [`ema::control::model::Plant::physical_bounds`]), so a growth within
/// it is one the file was written for; a wider one is another actuator. That growth is
/// also well inside the largest the commissioning's fit considers ([`super::GROWTH_MAX`],
/// the pull at the open stop vanishing): the product's largest is `q g = 0.24` at its
/// open stop. A growing surface pulls with `-dL/dg`, its growth included
/// ([`ForceModel::EnergyConsistent`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Specimen {
    /// Factors on the file's surfaces, resistance, spring rate, mass and friction.
    pub factors: Factors,
    /// The unknown preload of a file that gives none, as a share of the spring's force
    /// over the stroke \[-\].
    pub preload_share: f64,
    /// The position sensor's gain error \[-\].
    pub gain_error: f64,
    /// Its offset as a share of the stroke \[-\].
    pub offset_share: f64,
    /// Seed of the converter's noise.
    pub noise_seed: u64,
    /// The current channel's gain and offset error.
    pub current: ChannelError,
    /// The bus channel's.
    pub vbus: ChannelError,
    /// The airgap surfaces' growth with the gap, as a share of the largest
    /// ([`largest_spread`]) \[-\]: 0 keeps the file's shape.
    pub growth_share: f64,
}

/// The factors a [`Specimen`] puts on the file's values \[-\].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Factors {
    /// On the airgap's surfaces.
    pub surfaces: f64,
    /// On the coil's resistance.
    pub resistance: f64,
    /// On the spring's rate.
    pub spring: f64,
    /// On the mass.
    pub mass: f64,
    /// On the friction.
    pub friction: f64,
}

impl Factors {
    /// Every factor 1: the file's values.
    pub const NONE: Self = Self {
        surfaces: 1.0,
        resistance: 1.0,
        spring: 1.0,
        mass: 1.0,
        friction: 1.0,
    };
}

impl Specimen {
    /// One draw.
    pub fn new<R: Rng + ?Sized>(rng: &mut R) -> Self {
        let mut f = |s: f64| rng.random_range(1.0 - s..1.0 + s);
        let factors = Factors {
            surfaces: f(0.3),
            resistance: f(0.3),
            spring: f(0.3),
            mass: f(0.3),
            friction: f(0.5),
        };
        Self {
            factors,
            preload_share: rng.random_range(0.0..0.2),
            gain_error: rng.random_range(-0.03..0.03),
            offset_share: rng.random_range(-0.03..0.03),
            noise_seed: rng.random(),
            current: CalibrationClass::default().draw_channel(rng),
            vbus: CalibrationClass::default().draw_channel(rng),
            // Drawn last, so that every draw before keeps its value for a seed.
            growth_share: if rng.random_bool(0.5) {
                rng.random_range(0.0..1.0)
            } else {
                0.0
            },
        }
    }

    /// `adc` with this draw's errors on its three channels (their noise kept) and its
    /// noise seed, for a stroke of `stroke_m` read in position codes of `code_m` of the
    /// file's calibration, seen through a calibration with `correction` applied.
    ///
    /// The simulated converter's ideal transfer is the controller's calibration, so the
    /// sensor's own transfer is stated against it: a sensor reading `x (1 + e) + o` in the
    /// file's calibration reads `x (1 + e) / g + (o - o_c)` in one corrected by a gain `g`
    /// and an offset `o_c` (exactly the same codes).
    #[must_use]
    pub fn converter(
        &self,
        adc: &Adc,
        stroke_m: f64,
        code_m: f64,
        correction: &PositionCorrection,
    ) -> Adc {
        let mut out = *adc;
        let (gain, offset) = self.position_error(stroke_m, code_m);
        out.position.gain_error = (1.0 + gain) / f64::from(correction.gain) - 1.0;
        out.position.offset_code = offset - f64::from(correction.offset_codes);
        for (ch, e) in [(&mut out.current, self.current), (&mut out.vbus, self.vbus)] {
            ch.gain_error = e.gain_error;
            ch.offset_code = e.offset_code;
        }
        out.seed = self.noise_seed;
        out
    }

    /// The factor the converters' gains put on a resistance or an inductance the board
    /// reads \[-\]: `(1 + bus gain error) / (1 + current gain error)`. The bridge sets its
    /// duty for the bus as read, so the voltage it applies is the drive set over `1 + bus
    /// gain error`, and the current is read `1 + current gain error` times too large:
    /// `R = du / di` from the drive set and the current read carries the factor, and so
    /// does every inductance read with that `R` (a decay's or a probe's `-Ts R / ln a`).
    /// The controller runs in the same units, so these are what it needs; the physical
    /// values differ by the converters' scale, which the tolerances written carry
    /// ([`super::CONVERTER_SCALE`]).
    #[must_use]
    pub fn channel_factor(&self) -> f64 {
        (1.0 + self.vbus.gain_error) / (1.0 + self.current.gain_error)
    }

    /// The position sensor's gain error \[-\] and offset \[code\] for a stroke of `stroke_m`
    /// read in codes of `code_m`.
    #[must_use]
    pub fn position_error(&self, stroke_m: f64, code_m: f64) -> (f64, f64) {
        (self.gain_error, self.offset_share * stroke_m / code_m)
    }

    /// `plant` (the file's, whose surface tolerance is `surface_tolerance`) drawn: its
    /// values by the factors, its surfaces grown by [`Specimen::growth_share`] of the
    /// largest growth that tolerance allows ([`largest_spread`]).
    #[must_use]
    pub fn apply(&self, plant: &Params, surface_tolerance: f64) -> Params {
        let Factors {
            surfaces,
            resistance: r,
            spring: k,
            mass: m,
            friction,
        } = self.factors;
        let mut p = plant.clone();
        p.scale_surfaces(surfaces);
        if self.growth_share > 0.0 {
            let gaps = p.gap_range_m();
            for s in &mut p.gaps {
                *s = grown(*s, self.growth_share, surface_tolerance, gaps);
            }
        }
        // A real magnet pulls with `-dL/dg`, whatever its file: a surface that grows with
        // the gap, drawn so or the file's own, pulls with its growth included.
        if p.surface_grows() {
            p.force = ForceModel::EnergyConsistent;
        }
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

/// The sides `(a, b)` \[m\] and the spread `k` \[-\] of surface `s` seen as a rectangular
/// pole, `S(g) = (a + k g)(b + k g)` (a constant surface: a square one, `k = 0`).
fn pole(s: Surface) -> (f64, f64, f64) {
    match s {
        Surface::Constant { s_m2 } => (s_m2.sqrt(), s_m2.sqrt(), 0.0),
        Surface::Rectangular { a_m, b_m, spread } => (a_m, b_m, spread),
    }
}

/// Surface `s` with its sides growing by `k g` more, `k` the `share` of
/// [`largest_spread`]`(s, tolerance, gaps)`, at the same surface at the mid gap:
/// `S'(g) = (a + k_0 g + k (g - g_mid))(b + k_0 g + k (g - g_mid))`.
fn grown(s: Surface, share: f64, tolerance: f64, gaps: (f64, f64)) -> Surface {
    let (a, b, spread) = pole(s);
    let k = share * largest_spread(s, tolerance, gaps);
    let mid = 0.5 * (gaps.0 + gaps.1);
    Surface::Rectangular {
        a_m: a - k * mid,
        b_m: b - k * mid,
        spread: spread + k,
    }
}

/// The largest extra growth of the sides of surface `s` with the gap, `k` \[-\], that
/// keeps the surface, at its own value at the mid gap of `gaps` (smallest, largest
/// \[m\]), within `1 +- tolerance` times its own at every gap between: the surface
/// bounds the file's controller is designed for. The bound is reached at a stop: at the
/// largest gap, `(1 + k d / A)(1 + k d / B) = 1 + tolerance`, at the smallest `(1 - k d /
/// A)(1 - k d / B) = 1 - tolerance`, `d` half the gaps' span and `A`, `B` the sides
/// there (with the surface's own growth).
#[must_use]
pub fn largest_spread(s: Surface, tolerance: f64, gaps: (f64, f64)) -> f64 {
    let (a, b, spread) = pole(s);
    let d = 0.5 * (gaps.1 - gaps.0);
    // The smaller positive root of `u v k^2 + sign (u + v) k - sign t = 0` for the
    // sides' reach `u = d / A`, `v = d / B` at gap `g`: the open stop grows (sign +1),
    // the closed one shrinks (sign -1); `2 t / (p + sqrt(p^2 + sign 4 u v t))`.
    let root = |g: f64, sign: f64| {
        let (u, v) = (d / (a + spread * g), d / (b + spread * g));
        let (p, w) = (u + v, u * v);
        2.0 * tolerance / (p + (p * p + sign * 4.0 * w * tolerance).sqrt())
    };
    root(gaps.1, 1.0).min(root(gaps.0, -1.0))
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

/// What a commissioning read wrong ([`Outcome::errors`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Errors {
    /// The resistance's error, relative \[-\].
    pub resistance: f64,
    /// The inductance's error at the open stop, relative \[-\].
    pub inductance_open: f64,
    /// The inductance's error at the closed stop, relative \[-\].
    pub inductance_closed: f64,
    /// The inductance curve's over the stroke ([`Outcome::curve_error`], unsigned) \[-\].
    pub curve: f64,
    /// The open stop reading's error \[position codes\].
    pub open_codes: f64,
    /// The closed stop reading's error \[position codes\].
    pub closed_codes: f64,
}

impl Outcome {
    /// Relative errors of the resistance, the two inductances and the inductance curve
    /// over the stroke, and the end stops' errors in position codes; `None` for a
    /// commissioning that stopped.
    #[must_use]
    pub fn errors(&self) -> Option<Errors> {
        let r = self.report.ok()?;
        let rel = |got: f32, want: f64| f64::from(got) / want - 1.0;
        let codes = |got: f32, want: f64| (f64::from(got) - want).abs() / self.code_m;
        Some(Errors {
            resistance: rel(r.resistance.ohm, self.resistance_ohm),
            inductance_open: rel(r.inductance.open_h, self.inductance_h[0]),
            inductance_closed: rel(r.inductance.closed_h, self.inductance_h[1]),
            curve: self.curve_error,
            open_codes: codes(r.ends.open_m, self.ends_m[0]),
            closed_codes: codes(r.ends.closed_m, self.ends_m[1]),
        })
    }
}

/// The plant of actuator `a`'s file, or `draw`n from it.
///
/// # Errors
/// An actuator whose settings do not derive.
pub fn true_plant(a: &Actuator, draw: Option<&Specimen>) -> Result<Params, Error> {
    Ok(plant_of(&scenario(a, true)?, draw))
}

/// The plant of the board scenario `sc`, or `draw`n from it.
pub(super) fn plant_of(sc: &Scenario, draw: Option<&Specimen>) -> Params {
    let file = sc.plant.resolve(&sc.controller.plant);
    let tolerance = f64::from(sc.controller.plant.tolerance.surface);
    draw.map_or_else(|| file.clone(), |d| d.apply(&file, tolerance))
}

/// Plants a tuning is validated on in [`closed_loop`] (the tune command's default is 100:
/// this runs once per commissioned actuator).
pub const CLOSED_LOOP_VALIDATION: usize = 20;

/// What a commissioned actuator does once tuned, in closed loop on its true plant.
#[derive(Clone, Debug, PartialEq)]
pub enum ClosedLoop {
    /// The measured actuator breaks a physical rule (a spring that pushes the wrong way, a
    /// resistance the supply cannot drive the rated current through): its file is refused
    /// by name, as `bench commission` refuses to write it.
    Refused(String),
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
            ClosedLoop::Refused(_) => vec!["refused"],
            ClosedLoop::Untuned(_) => vec!["untuned"],
            ClosedLoop::Ran { worst, targets } => worst.misses(targets),
        }
    }
}

/// Tunes the actuator `report` (and `mechanics`, when measured) measured on file `a`
/// ([`measured`]) at the board's rate, as `bench commission --tune` does, and runs its
/// evaluation sequence on the true `plant` with the position sensor's gain and offset the
/// end stops measured taken out ([`PositionCorrection::from_stops`], as
/// `bench commission --apply` sets them). The converter is the board's, with its typical
/// noise and the errors of `draw` (the sensor that was commissioned; `None`: none), so
/// the steady error is judged on the true position with what the correction leaves.
///
/// Measured values no actuator can have (a rule of
/// [`Actuator::check_consistency`] broken) give [`ClosedLoop::Refused`], named by the rule.
///
/// # Errors
/// Settings that do not derive; a correction beyond the calibration's room.
pub fn closed_loop(
    a: &Actuator,
    report: &Report,
    mechanics: Option<&Mechanics>,
    plant: &Params,
    draw: Option<&Specimen>,
) -> Result<ClosedLoop, Error> {
    let checked = measured(a, report, mechanics)
        .and_then(|(m, _)| m.check_consistency().map(|_| m).map_err(Error::Actuator));
    let m = match checked {
        Ok(m) => m,
        Err(e @ Error::Actuator(_)) => return Ok(ClosedLoop::Refused(e.to_string())),
        Err(e) => return Err(e),
    };
    let rate = f64::from(a.board.rate_hz);
    let space = crate::analysis::tune::Space::for_actuator(&m, rate)?;
    let tuned = crate::analysis::tune::tune(
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
    let mut sc = crate::simulation::actuator::scenario("commissioned", &t)?;
    sc.plant = TruePlant::Given(plant.clone());
    let code_m = f64::from(a.calibration().position.scale);
    let correction = stops_correction(a, report);
    sc.controller.sense = t.calibration_with(&correction).map_err(Error::Actuator)?;
    if let (Sensors::Adc(adc), Some(d)) = (&mut sc.sensors, draw) {
        *adc = d.converter(adc, plant.stroke_m, code_m, &correction);
    }
    let run = crate::simulation::sim::run(&sc)?;
    let targets = Targets::for_scenario(&sc);
    Ok(ClosedLoop::Ran {
        worst: Worst::of([&run.metrics], &targets),
        targets,
    })
}

/// The position sensor's correction the end stops of `report` give, read through the
/// calibration of file `a`.
#[must_use]
pub fn stops_correction(a: &Actuator, report: &Report) -> PositionCorrection {
    PositionCorrection::from_stops(
        report.ends.open_m,
        report.ends.closed_m,
        a.mechanics.stroke_m,
        a.calibration().position.scale,
    )
}

/// Commissions actuator `a` (its file), the plant the file's or `draw`n from it.
///
/// # Errors
/// An actuator whose settings do not derive.
pub fn run(a: &Actuator, draw: Option<&Specimen>) -> Result<Outcome, Error> {
    run_on(a, &plant_of(&scenario(a, true)?, draw), draw)
}

/// Commissions actuator `a` (its file) on `plant`, its position sensor and its converter's
/// noise `draw`n as [`run`]'s.
///
/// # Errors
/// An actuator whose settings do not derive; a plant that does not validate.
pub fn run_on(a: &Actuator, plant: &Params, draw: Option<&Specimen>) -> Result<Outcome, Error> {
    let sc = scenario(a, true)?;
    let code_m = f64::from(sc.controller.sense.position.scale);
    let plant = plant.clone();
    let mut stepper = Stepper::for_scenario(&sc, plant.clone(), sc.integration.substeps)?;
    let adc = match &sc.sensors {
        Sensors::Adc(adc) => *adc,
        Sensors::Ideal => Adc::default(),
    };
    let adc = draw.map_or(adc, |d| {
        d.converter(&adc, plant.stroke_m, code_m, &PositionCorrection::NONE)
    });
    let mut converter = adc.start(&sc.controller.sense);
    let (gain, offset_code) = draw.map_or((0.0, 0.0), |d| d.position_error(plant.stroke_m, code_m));
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

/// Positions, evenly spaced over the stroke with both stops, at which [`curve_error`]
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
        .fold(0.0, crate::simulation::targets::worse))
}
