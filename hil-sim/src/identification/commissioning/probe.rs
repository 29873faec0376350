//! The inductance probes at the holds: their size, their capture and the inductance read
//! from them.

use ema::control::actuator::Actuator;
use ema::device::commission::Report;

use super::{corrected, Circuit};

/// Share of the rated current the inductance probe at each hold steps the desired
/// current up and down by. A larger step stands further above the converter's noise, but
/// every step tests the residual detector's bounds, which rest on the stops' two-point
/// line and miss a coil by a few per cent between the stops: a step small beside the
/// hold's current stays inside them, so that a probe never latches a fault (such as
/// `coil_short`) on a healthy coil.
pub const HOLD_PROBE_SHARE: f64 = 0.05;

/// Periods at each level of the hold's probe: the second half's readings are each
/// level's mean, and the relation the probe's estimate rests on is exact whether or not
/// the coil's current settles within a level, so a level need not last until it settles.
/// Short levels keep the pull's square wave fast beside the armature, which then barely
/// moves under it; longer ones let it follow the wave, and its motion biases the reading.
pub const HOLD_PROBE_HALF_TICKS: u16 = 16;

/// Cycles of each of the hold's probes (up and down): as many as the board's capture
/// holds at every tick with the converter's delay and a tick after them
/// ([`probe_capture`]); [`HOLD_PROBE_RUNS`] probes per hold.
pub const HOLD_PROBE_CYCLES: u16 = 7;

/// Probes at each hold, one captured at a time: the estimate's uncertainty falls as the
/// square root of the number of its cycles, and three probes of [`HOLD_PROBE_CYCLES`]
/// give about as many as one of 16 cycles would. That one would need levels half as long
/// to fit the capture, within which a slow coil's current does not step; more probes cost
/// only the hold's time.
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

/// The inductance probe at each hold of [`mechanics`](super::mechanics) for the measured
/// actuator `a` (its start is set per hold): [`HOLD_PROBE_SHARE`] of the rated current,
/// [`HOLD_PROBE_CYCLES`] cycles of [`HOLD_PROBE_HALF_TICKS`] periods at each level.
#[must_use]
pub fn hold_probe(a: &Actuator) -> crate::simulation::scenario::InductanceProbe {
    crate::simulation::scenario::InductanceProbe {
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
/// level's length over twice the coil's time constant. The uncertainty is the scatter of
/// the cycles (a step down and the step up after it), over every run. `None` without two
/// such cycles, or a current that did not step.
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
pub(super) fn probe_pairs(
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

/// The inductance one hold's probes read ([`hold_inductance`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HoldInductance {
    /// The hold's mean position, corrected with the end stops the commissioning measured
    /// \[m\].
    pub x_m: f64,
    /// The inductance there \[H\].
    pub inductance_h: f64,
    /// Two standard errors of it \[H\].
    pub uncertainty_h: f64,
}

impl HoldInductance {
    /// Half the 99 % interval of the inductance ([`coverage_factor`](super::coverage_factor)
    /// per two standard errors, as the stops' and the circuit's) \[H\].
    #[must_use]
    pub fn interval_h(&self) -> f64 {
        super::circuit::interval_per_two_se() * self.uncertainty_h
    }
}

/// The converters' noise on the three channels a probe reads, RMS, each in its channel's
/// unit: what [`hold_inductance`] carries through its estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelNoise {
    /// On the current reading \[A\].
    pub current_a: f64,
    /// On the position reading \[m\].
    pub position_m: f64,
    /// On the bus reading \[V\].
    pub vbus_v: f64,
}

impl ChannelNoise {
    /// The board's noise ([`ema::control::sense::NOISE_RMS_CODES`]) on each channel of the
    /// actuator file `a`'s calibration.
    #[must_use]
    pub fn of(a: &Actuator) -> Self {
        let c = a.calibration();
        let rms = |scale: f32| f64::from(ema::control::sense::NOISE_RMS_CODES * scale.abs());
        Self {
            current_a: rms(c.current.scale),
            position_m: rms(c.position.scale),
            vbus_v: rms(c.vbus.scale),
        }
    }
}

/// One hold's inductance from its probes' captures (the board's samples at every tick
/// from each probe's first), read with [`probe_inductance`] for the `probe`, the
/// converter `delay` ticks late, the period `ts_s`, the commissioning's `report` and the
/// `line` through its stops' inductances ([`Circuit::through_stops`]): the mean position
/// corrected with the end stops the `report` measured, `x = stroke (y - y_open) /
/// (y_closed - y_open)`, the inductance and two standard errors of it; `None` when the
/// probes read nothing or the converters' noise carries the reading out of the
/// estimate's domain. The same reading on the bench and in
/// [`mechanics`](super::mechanics).
///
/// **Its uncertainty** is the larger of two: the scatter of the probes' cycles
/// ([`probe_inductance`]), and what the converters' `noise` alone leaves the estimate,
/// each reading's noise carried through it to first order (its derivative by each
/// reading, taken by differences) and summed in quadrature. On a coil whose time constant
/// is about the period, the current settles within a level and the estimate of `exp(-Ts
/// R / L)` rests on little: the noise leaves a few per cent, which the scatter of the
/// cycles reads only within a fifth or so either way, and the prediction keeps a
/// scatter that came out small from making the reading look surer than it is. A reading
/// is not dropped for being uncertain: the circuit's fit weighs each by its uncertainty
/// ([`Circuit::fit`]), and the surface's tolerance written carries the least certain
/// ([`measured`](super::measured)). A fixed ceiling on the uncertainty (3 %) had
/// dropped the open side's hold of a coil as fast as the period on 30 of 100
/// commissionings, the converter's noise taken for an armature that did not keep still.
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
    probe: &crate::simulation::scenario::InductanceProbe,
    delay: usize,
    ts_s: f64,
    report: &Report,
    line: Circuit,
    noise: ChannelNoise,
) -> Option<HoldInductance> {
    let read = HoldReading {
        probe,
        delay,
        ts_s,
        report,
        line,
    };
    let (x, motion) = read.position_and_motion(runs)?;
    let (l, scatter) = read.inductance(runs, motion)?;
    let from_noise = read.noise_uncertainty(runs, motion, l, noise);
    // A reading that a hundredth of the noise carries out of the estimate's domain
    // (`exp(-Ts R / L)` at 0 or 1) says nothing.
    if from_noise.is_nan() {
        return None;
    }
    let uncertainty = scatter.max(from_noise);
    Some(HoldInductance {
        x_m: x,
        inductance_h: l,
        uncertainty_h: uncertainty,
    })
}

/// One channel's reading of a [`ProbeSample`], to be moved.
type Reading = fn(&mut ProbeSample) -> &mut f64;

/// What [`hold_inductance`] reads a hold's probes with.
struct HoldReading<'a> {
    probe: &'a crate::simulation::scenario::InductanceProbe,
    delay: usize,
    ts_s: f64,
    report: &'a Report,
    line: Circuit,
}

impl HoldReading<'_> {
    /// The hold's mean position, corrected with the end stops, and the coefficient of the
    /// armature's motion for [`probe_inductance`]; `None` without samples.
    fn position_and_motion(&self, runs: &[Vec<ProbeSample>]) -> Option<(f64, f64)> {
        let position = corrected(self.report, self.line.stroke_m);
        let (n, i_sum, y_sum) = runs
            .iter()
            .flat_map(|s| s.iter().take(self.probe.ticks()))
            .fold((0.0, 0.0, 0.0), |(n, i, y), q| {
                (n + 1.0, i + q.i_a, y + q.y_m)
            });
        if n == 0.0 {
            return None;
        }
        let x = position(y_sum / n);
        let r_ohm = f64::from(self.report.resistance.ohm);
        Some((
            x,
            (i_sum / n) * self.line.force_coefficient_h_per_m(x) / r_ohm,
        ))
    }

    /// The inductance and the scatter of its cycles ([`probe_inductance`]), the drive
    /// scaled by the bus's sag, the positions corrected with the end stops.
    fn inductance(&self, runs: &[Vec<ProbeSample>], motion: f64) -> Option<(f64, f64)> {
        let ticks = self.probe.ticks();
        let delay = self.delay;
        let position = corrected(self.report, self.line.stroke_m);
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
        probe_inductance(
            &slices,
            motion,
            usize::from(self.probe.half_ticks),
            delay,
            self.ts_s,
            f64::from(self.report.resistance.ohm),
        )
    }

    /// Two standard errors of the inductance `l` read from `runs` that the converters'
    /// `noise` alone leaves: each reading moved by a hundredth of its channel's noise,
    /// the estimate's change over the move times the noise, summed in quadrature over
    /// every reading of the three channels. The motion's coefficient is held (its share
    /// of the noise is of second order).
    fn noise_uncertainty(
        &self,
        runs: &[Vec<ProbeSample>],
        motion: f64,
        l: f64,
        noise: ChannelNoise,
    ) -> f64 {
        let channels: [(f64, Reading); 3] = [
            (noise.current_a, |q| &mut q.i_a),
            (noise.position_m, |q| &mut q.y_m),
            (noise.vbus_v, |q| &mut q.vbus_v),
        ];
        let mut moved = runs.to_vec();
        let mut variance = 0.0;
        for (sigma, reading) in channels {
            if sigma <= 0.0 {
                continue;
            }
            let step = 0.01 * sigma;
            for r in 0..moved.len() {
                for k in 0..moved[r].len() {
                    let was = *reading(&mut moved[r][k]);
                    *reading(&mut moved[r][k]) = was + step;
                    let changed = self.inductance(&moved, motion).map_or(f64::NAN, |m| m.0);
                    *reading(&mut moved[r][k]) = was;
                    variance += ((changed - l) / step * sigma).powi(2);
                }
            }
        }
        2.0 * variance.sqrt()
    }
}
