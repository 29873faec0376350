//! The closed-loop holds that measure the spring, the mass and the friction: their
//! captures, their attempts, and the mechanics fitted from them.

use ema::control::actuator::Actuator;
use ema::control::sense::PositionCorrection;
use ema::device::commission::Report;

use super::{
    fit_armature, fit_spring, hold_inductance, hold_probe, measured, probe_capture, pull, Armature,
    ChannelNoise, Circuit, HoldInductance, ProbeSample, Specimen, Spring, HOLD_PROBE_RUNS,
};
use crate::simulation::plant::Params;
use crate::simulation::scenario::{Sensors, TruePlant};
use crate::simulation::Error;

/// Share of each hold of [`mechanics`] averaged: its end, once the move and its settling
/// are over (the hold lasts the move's settling target plus twice the steady window).
pub const HOLD_WINDOW_SHARE: f64 = 0.4;

/// The board's capture of a move spans this many of the largest move's minimum-time
/// moves (at most the hold before its window): time for the move and its settling, which
/// [`fit_armature`] fits.
pub const MOVE_CAPTURE_MOVES: f64 = 4.0;

/// What the closed-loop holds measure: the spring, and the mass and the friction when
/// some move could be fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mechanics {
    /// The spring's rate and preload ([`fit_spring`]).
    pub spring: Spring,
    /// The mass and the friction ([`fit_armature`]).
    pub armature: Option<Armature>,
    /// The inductance at each hold, from its probe
    /// ([`hold_inductance`](super::hold_inductance)); none where no probe ran or read
    /// one.
    pub inductances: [Option<HoldInductance>; crate::simulation::actuator::SEQUENCE.len()],
    /// The magnetic circuit fitted to the stops' inductances and the holds'
    /// ([`Circuit::fit`]): the pull the spring and the mass are read with.
    pub circuit: Circuit,
}

impl Mechanics {
    /// Each hold's inductance error against `plant`'s at the hold's position, relative
    /// (NaN where the probe read nothing).
    #[must_use]
    pub fn inductance_errors(
        &self,
        plant: &Params,
    ) -> [f64; crate::simulation::actuator::SEQUENCE.len()] {
        self.inductances.map(|p| {
            p.map_or(f64::NAN, |h| {
                h.inductance_h / plant.inductance_h(plant.gap_m(h.x_m)) - 1.0
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
            .map(|h| {
                #[expect(clippy::cast_possible_truncation)]
                let form = plant.magnetics.inductance_h(plant.gap_m(h.x_m as f32));
                (f64::from(form) / h.inductance_h - 1.0).abs()
            })
            .reduce(crate::simulation::targets::worse)
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
        inductances: [Option<HoldInductance>; crate::simulation::actuator::SEQUENCE.len()],
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

/// A hold whose window's position scatters (one standard deviation) over more than this
/// share of the stroke is not at rest: the loop limit-cycles about it.
pub const REST_SHARE: f64 = 0.002;

/// The readings of the holds as the board captures them, one `(position [m], current
/// [A])` per capture sample: the position's mean over its ticks, the current's root mean
/// square (`ema::device`'s capture).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Holds {
    /// Each hold's move from its start, one sample every `move_dt_s`.
    pub moves: [Vec<(f64, f64)>; crate::simulation::actuator::SEQUENCE.len()],
    /// Time between the moves' samples \[s\].
    pub move_dt_s: f64,
    /// Each hold's window, once the move has settled: its last [`HOLD_WINDOW_SHARE`],
    /// one sample every `window_dt_s`.
    pub windows: [Vec<(f64, f64)>; crate::simulation::actuator::SEQUENCE.len()],
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
    use crate::simulation::actuator::SEQUENCE;
    let hold_s = crate::simulation::actuator::segment_s(settings, stroke_m);
    let largest = (1..SEQUENCE.len())
        .filter_map(|k| {
            crate::simulation::actuator::minimum_move_s(
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
/// ([`crate::simulation::actuator::SEQUENCE`], 1/8 to 7/8 of the stroke), the loop closed with the
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
    draw: Option<&Specimen>,
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
/// the observer's bandwidth [`RETRY_GAIN_SHARE`] times the attempt's before. A hold a
/// monitor ends is most often an armature lighter than its file's: the observer, with
/// the file's mass, mispredicts its acceleration in proportion to the loop's gains, and a
/// fast loop turns that into a runaway disturbance estimate, an overshoot, and a velocity
/// from which a detector names a fault the board does not have. A slower loop holds such
/// an armature to the end. Three attempts bring the gains down to `0.6^2 = 0.36` of the
/// default, slow enough for an armature tens of per cent lighter, for at most three
/// holds' time; holds that still fault then point at something else than the mass
/// (`hil-sim commission NAME` counts the attempts and the holds that measured nothing).
pub const HOLD_ATTEMPTS: u32 = 3;

/// Share of an attempt's loop gains, the backstepping's `alpha` and the observer's
/// bandwidth, the next attempt at the holds runs with \[-\] (see [`HOLD_ATTEMPTS`]): the
/// attempts fail on an armature lighter than its file's, whose acceleration the observer
/// mispredicts in proportion to the loop's gains, so the gains are what is lowered.
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
pub(super) fn hold_once(
    a: &Actuator,
    m: &Actuator,
    report: &Report,
    plant: &Params,
    draw: Option<&Specimen>,
) -> Result<(Result<Mechanics, &'static str>, f64), Error> {
    let mut sc = crate::simulation::actuator::scenario("holds", m)?;
    sc.plant = TruePlant::Given(plant.clone());
    // The routine's converter, its errors on every channel; the loop holds through the
    // file's calibration, and the fits correct the positions with the end stops
    // ([`corrected`](super::corrected)).
    let code_m = f64::from(sc.controller.sense.position.scale);
    if let (Sensors::Adc(adc), Some(d)) = (&mut sc.sensors, draw) {
        *adc = d.converter(adc, plant.stroke_m, code_m, &PositionCorrection::NONE);
    }
    let stroke_m = f64::from(m.mechanics.stroke_m);
    let rate = sc.rate_hz();
    let hold_ticks =
        (crate::simulation::actuator::segment_s(&sc.controller, stroke_m) * rate).round() as usize;
    let window_ticks = (HOLD_WINDOW_SHARE * hold_ticks as f64).round() as usize;
    let run = crate::simulation::sim::run(&sc)?;
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
    sc.inductance_probes = (0..crate::simulation::actuator::SEQUENCE.len())
        .flat_map(|k| (0..HOLD_PROBE_RUNS).map(move |r| (k, r)))
        .map(|(k, r)| crate::simulation::scenario::InductanceProbe {
            at_s: probe_at(k, r) as f64 / rate,
            ..probe
        })
        .collect();
    let probed = crate::simulation::sim::run(&sc)?;
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
    let noise = ChannelNoise::of(a);
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
        hold_inductance(&runs, &probe, delay, 1.0 / rate, report, line, noise)
    });
    let probes = crate::simulation::actuator::SEQUENCE.len() * HOLD_PROBE_RUNS * span;
    let took_s = (run.samples.len() + probes) as f64 / rate;
    Ok((Ok(Mechanics::fit(report, a, &holds, inductances)), took_s))
}
