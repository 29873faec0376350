//! What a commissioning is asked to do: the [`Plan`] built from the actuator file, and the
//! [`Coil`] it starts from.

use super::decay::relative_error;
use super::Report;
use super::{
    AVERAGE_TIME_CONSTANTS, FILE_TOLERANCE, HIGH_SHARE, LOW_SHARE, MAX_PROBE_CYCLES, MIN_AVERAGE_S,
    PATIENCE_PERIODS, PROBE_HIGH_SHARE, PROBE_LOW_PER_HIGH, PROBE_PULL_SHARE, PROBE_READINGS,
    RAMP_PERIODS, RELEASE_PERIODS, SETTLE_TIME_CONSTANTS,
};
use crate::control::math;

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
    /// Largest peak-to-peak of the position readings over a window with the armature at rest
    /// \[m\] (the sensor's noise): a wider one restarts the window.
    pub still_m: f32,
    /// Largest difference between the mean positions of a window's two halves with the
    /// armature at rest \[m\]: four deviations of that difference, as [`Plan::still_m`]
    /// is twice four deviations of the difference of two readings. A larger one is a slow
    /// creep (an overdamped armature coming back to a stop with little preload, well
    /// inside the noise's peak-to-peak) and restarts the window.
    pub drift_m: f32,
    /// Ticks waited after the coil is switched off before the open stop's window (and at
    /// each hold at the closed stop).
    pub release_ticks: u32,
    /// Ticks of the approach's voltage ramp.
    pub ramp_ticks: u32,
    /// Ticks a hold may spend restarting its window (each restart with the wait for the
    /// coil to settle before it): [`PATIENCE_PERIODS`] of the slowest mechanical period,
    /// and at least one restart (the settle and two windows). A coil slower than its
    /// armature holds the armature at a stop until its current has decayed, so the
    /// armature leaves it inside the wait's settling part, which the window covers: 4
    /// periods of a 3 g armature are 31 ms, one window of its 84 ms coil 0.5 s.
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
        // The slowest armature admitted: spring softer and mass heavier by FILE_TOLERANCE.
        let slowest_w = natural_rad_s * math::sqrt((1.0 - FILE_TOLERANCE) / (1.0 + FILE_TOLERANCE));
        let period_s = 2.0 * core::f32::consts::PI / slowest_w;
        let slowest_s = closed_inductance_h * (1.0 + FILE_TOLERANCE)
            / (resistance_ohm * (1.0 - FILE_TOLERANCE));
        let slowest_open_s =
            open_inductance_h * (1.0 + FILE_TOLERANCE) / (resistance_ohm * (1.0 - FILE_TOLERANCE));
        let settle_s = SETTLE_TIME_CONSTANTS * slowest_s;
        // The weakest spring's force over the stroke against the strongest magnet's pull.
        let pull_a = math::sqrt(
            2.0 * PROBE_PULL_SHARE * spring_n_per_m * (1.0 - FILE_TOLERANCE) * stroke_m
                / (open_force_h_per_m * (1.0 + FILE_TOLERANCE)),
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
            patience_ticks: ticks(PATIENCE_PERIODS * period_s)?
                .max(ticks(settle_s)?.saturating_add(average_ticks.saturating_mul(2))),
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

    /// Two standard errors of the inductances `report` read at the open and at the closed
    /// stop, relative, from the current converter's noise, `noise_a` RMS per reading \[A\]:
    /// the readings' noise carried through the fit's two weighted sums and their ratio, to
    /// first order. The open stop's from the probe's [`Plan::probe_halves`] steps between
    /// its two levels, the closed stop's from the one step between its two holds'
    /// currents. Each is the larger of the errors at the factor per period the reading and
    /// the measured resistance give and at the file's ([`Plan::guess_factor`]): noise that
    /// read a decay far slower than it is predicts too small an error at its own reading.
    /// (The open stop's is the probe's, whose reading the small pull moved off the stop:
    /// the line to the stop hardly scales it.)
    ///
    /// A coil whose time constant is about the period is over within a reading or two of
    /// the converter's delay, and the fit reads the shape of the decay from few, small
    /// readings: at the open stop of a fast coil the noise, not the method, bounds what the
    /// reading is worth, and this says by how much. `NaN` for an inductance that is not
    /// positive.
    #[must_use]
    pub fn inductance_uncertainty(&self, report: &Report, noise_a: f32) -> [f32; 2] {
        let r = report.resistance.ohm;
        let [near_a, full_a] = report.resistance.i_a;
        let [open_guess, closed_guess] = self.guess_factor;
        // Two standard errors of one fit, the larger at the reading's factor and at the
        // file's (`guess`): noise that read a decay far slower than it is would predict
        // itself too small an error.
        let fit = |step_a: f32, steps: f32, read_h: f32, guess: f32| {
            let at = |factor: f32| {
                relative_error(step_a, steps, noise_a, factor, guess, self.skip_readings)
            };
            2.0 * math::max(at(libm::expf(-self.period_s * r / read_h)), at(guess))
        };
        #[expect(clippy::cast_precision_loss)]
        let probe_steps = self.probe_halves() as f32;
        [
            fit(
                self.probe_a[1] - self.probe_a[0],
                probe_steps,
                report.inductance.open_h,
                open_guess,
            ),
            fit(
                (full_a - near_a).abs(),
                1.0,
                report.inductance.closed_h,
                closed_guess,
            ),
        ]
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
