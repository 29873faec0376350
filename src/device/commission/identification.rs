//! The routine itself: the [`Identification`] the control interrupt ticks, its phases and
//! the [`Step`] it gives each tick.

use super::{
    resistance, Abort, Decay, Ends, Inductance, Plan, Report, Window, FULL_SHARE, HIGH_SHARE,
    LOW_SHARE, MIN_TRAVEL_SHARE, NEAR_SHARE,
};
use crate::control::math;
use crate::control::sense::Measurement;

/// What the identification asks of the bridge at one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Apply this voltage \[V\].
    Drive(f32),
    /// Finished: coast; the result.
    Done(Result<Report, Abort>),
}

/// Where an identification stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Phase {
    /// The resistance's first step.
    Low,
    /// Its second step.
    High,
    /// The coil off, the armature at the open stop.
    Open,
    /// The inductance probe's lower level at the open stop.
    ProbeLow,
    /// Its upper level.
    ProbeHigh,
    /// Between the two levels, [`Plan::probe_cycles`] times, ending at the lower: every
    /// step's response fitted.
    ProbeCycle,
    /// The voltage ramp towards the closed stop.
    Ramp,
    /// The first hold at the closed stop.
    Full,
    /// The second, a step down from the first: its response fitted.
    Near,
}

/// How much a hold's window needs the armature at rest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Rest {
    /// Its mean position is a stop's: a window in which the armature moved is averaged
    /// again, for at most [`Plan::patience_ticks`], then the identification gives up.
    Required,
    /// At rest if it comes within the patience, else the window is taken as it is: the
    /// first two steps' resistance only sets the later voltages, and a lightly damped
    /// armature ringing about the pull's equilibrium leaves a back-EMF that averages out.
    Preferred,
    /// The window measures the current's level only; the probe's position is averaged
    /// over its cycle, where its inductance is fitted.
    Any,
}

impl Phase {
    const fn rest(self) -> Rest {
        match self {
            Phase::Open | Phase::Near | Phase::Full => Rest::Required,
            Phase::Low | Phase::High => Rest::Preferred,
            Phase::ProbeLow | Phase::ProbeHigh | Phase::ProbeCycle | Phase::Ramp => Rest::Any,
        }
    }
}

/// Indices of the windows an identification keeps.
pub(super) const OPEN: usize = 0;

pub(super) const PROBE: usize = 1;

pub(super) const NEAR: usize = 2;

pub(super) const FULL: usize = 3;

/// An identification in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identification {
    plan: Plan,
    phase: Phase,
    /// Ticks into the phase.
    tick: u32,
    /// Ticks of windows restarted in this phase, with the waits that preceded them.
    restarts: u32,
    window: Window,
    /// The windows the result is made from (the resistance's first step in the first).
    kept: [Window; 4],
    /// The resistance the first two steps measured, which every later voltage is set
    /// from \[ohm\] (the one reported comes from the closed stop).
    drive_ohm: f32,
    /// The step response being fitted.
    decay: Decay,
    /// The coil's time constant at the probe's position near the open stop \[s\].
    probe_s: f32,
    /// The current at the probe's lower level \[A\].
    probe_end_a: f32,
    /// The voltage over the period the last reading ended \[V\].
    previous_v: f32,
    /// The readings over the probe's cycle, where its inductance is fitted.
    cycle: Window,
}

impl Identification {
    /// Starts `plan`.
    #[must_use]
    pub const fn new(plan: Plan) -> Self {
        Self {
            plan,
            phase: Phase::Low,
            tick: 0,
            restarts: 0,
            window: Window::EMPTY,
            kept: [Window::EMPTY; 4],
            drive_ohm: 0.0,
            decay: Decay::NONE,
            probe_s: 0.0,
            probe_end_a: 0.0,
            previous_v: 0.0,
            cycle: Window::EMPTY,
        }
    }

    /// The plan.
    #[must_use]
    pub const fn plan(&self) -> &Plan {
        &self.plan
    }

    /// The voltage of a share of the rated current at the resistance the first two steps
    /// measured \[V\].
    fn share_v(&self, share: f32) -> f32 {
        self.current_v(share * self.plan.abort_a)
    }

    /// The voltage of current `i_a` at the resistance the first two steps measured \[V\].
    fn current_v(&self, i_a: f32) -> f32 {
        i_a * self.drive_ohm
    }

    /// The phase's drive \[V\] and the ticks it waits before its window.
    fn phase_drive(&self) -> (f32, u32) {
        let p = &self.plan;
        match self.phase {
            Phase::Low => (p.u_v[0], p.settle_ticks),
            Phase::High => (p.u_v[1], p.settle_ticks),
            Phase::Open => (0.0, p.release_ticks),
            // The probe's pull moves the armature: its levels wait as the open stop does.
            Phase::ProbeLow => (self.current_v(p.probe_a[0]), p.release_ticks),
            Phase::ProbeHigh => (self.current_v(p.probe_a[1]), p.release_ticks),
            Phase::ProbeCycle => {
                let wait = p.probe_half_ticks.saturating_mul(p.probe_halves());
                let high = self.tick < wait && self.probe_high(self.tick);
                let [low_a, high_a] = p.probe_a;
                (self.current_v(if high { high_a } else { low_a }), wait)
            }
            Phase::Ramp => {
                let done = self.tick as f32 / p.ramp_ticks.max(1) as f32;
                (self.share_v(FULL_SHARE) * done, p.ramp_ticks)
            }
            Phase::Full => (self.share_v(FULL_SHARE), p.release_ticks),
            Phase::Near => (self.share_v(NEAR_SHARE), p.release_ticks),
        }
    }

    /// Whether the probe's cycle is at its upper level at tick `t`.
    fn probe_high(&self, t: u32) -> bool {
        t.checked_div(self.plan.probe_half_ticks)
            .is_some_and(|half| half & 1 == 1)
    }

    fn enter(&mut self, phase: Phase) {
        self.phase = phase;
        self.tick = 0;
        self.restarts = 0;
        self.window = Window::EMPTY;
        self.decay = match phase {
            // The probe's steps go to levels measured before.
            Phase::ProbeCycle => Decay::towards(self.probe_end_a, 1.0, self.plan.guess_factor[0]),
            // This step's end is the hold's own window, measured after it: the fit takes
            // deviations from the level before and shifts them once it is known.
            Phase::Near => {
                Decay::towards(self.kept[FULL].current().1, 1.0, self.plan.guess_factor[1])
            }
            _ => Decay::NONE,
        };
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
        let (_, wait) = self.phase_drive();
        self.tick = self.tick.saturating_add(1);
        let stepped = applied_v != core::mem::replace(&mut self.previous_v, applied_v);
        if self.tick <= wait {
            if self.phase == Phase::ProbeCycle {
                self.cycle.add(applied_v, m);
            }
            if self.tick.saturating_add(self.plan.settle_ticks) > wait {
                // The coil's current settles over the wait's last part: an armature that
                // moves then (one that snaps onto a stop at the end of a slow creep) is
                // a window whose current still recovers from its back-EMF.
                self.window.span(m.x_m);
            }
            // A step's response, over the wait (as long as the slowest coil needs).
            let p = &self.plan;
            self.decay.add(m.i_a, stepped, p.skip_readings);
            if self.phase == Phase::ProbeCycle
                && self.tick < wait
                && self.tick.is_multiple_of(p.probe_half_ticks)
            {
                // The drive changes level now: the next step goes to the other one.
                let (low_a, high_a) = (self.probe_end_a, self.kept[PROBE].current().1);
                let high = self.probe_high(self.tick);
                if high {
                    self.decay.retarget(high_a, -1.0);
                } else {
                    self.decay.retarget(low_a, 1.0);
                }
            }
        }
        if self.phase == Phase::Ramp {
            if self.tick >= wait {
                self.enter(Phase::Full);
            }
        } else {
            if self.tick > wait {
                // The averaging window starts after the wait, so that every reading in
                // it ends a whole period of the hold's own voltage (a drive takes effect
                // one period after it is set).
                self.window.add(applied_v, m);
                if self.tick == wait.saturating_add(self.plan.average_ticks / 2) {
                    self.window.halve();
                }
            }
            if self.tick > wait.saturating_add(self.plan.average_ticks) {
                let moved = self.window.x_max - self.window.x_min > self.plan.still_m
                    || self.window.drift().abs() > self.plan.drift_m;
                let rest = self.phase.rest();
                let patient = self.restarts.saturating_add(self.plan.average_ticks)
                    <= self.plan.patience_ticks;
                if moved && rest != Rest::Any && patient {
                    // The armature moved during the window or the wait's last part:
                    // its motion induced a voltage, and its mean is no stop's. Average
                    // again once the coil's current has settled from the motion (its
                    // inductance changed, its back-EMF kicked the current); the step
                    // `Near` fits in its wait is not repeated.
                    let settle = if self.phase == Phase::Near {
                        0
                    } else {
                        self.plan.settle_ticks
                    };
                    self.restarts = self
                        .restarts
                        .saturating_add(self.plan.average_ticks.saturating_add(settle));
                    self.window = Window::EMPTY;
                    self.tick = wait.saturating_sub(settle);
                } else if moved && rest == Rest::Required {
                    return Step::Done(Err(Abort::NotAtRest));
                } else if let Some(done) = self.finish() {
                    return Step::Done(done);
                }
            }
        }
        Step::Drive(self.phase_drive().0)
    }

    /// A hold's window is complete: keep it and go on, or end.
    fn finish(&mut self) -> Option<Result<Report, Abort>> {
        let window = self.window;
        let next = match self.phase {
            Phase::Low => {
                self.kept[0] = window;
                Phase::High
            }
            Phase::High => {
                match resistance(
                    &self.kept[0],
                    &window,
                    (HIGH_SHARE - LOW_SHARE) * self.plan.abort_a,
                ) {
                    Ok(r) => self.drive_ohm = r.ohm,
                    Err(a) => return Some(Err(a)),
                }
                Phase::Open
            }
            Phase::Open => {
                self.kept[OPEN] = window;
                Phase::ProbeLow
            }
            Phase::ProbeLow => {
                self.probe_end_a = window.current().1;
                Phase::ProbeHigh
            }
            Phase::ProbeHigh => {
                self.kept[PROBE] = window;
                Phase::ProbeCycle
            }
            Phase::ProbeCycle => match self.time_constant(0.0) {
                Some(s) => {
                    self.probe_s = s;
                    Phase::Ramp
                }
                None => return Some(Err(Abort::NoDecay)),
            },
            Phase::Full => {
                self.kept[FULL] = window;
                Phase::Near
            }
            Phase::Near => {
                self.kept[NEAR] = window;
                return Some(self.report());
            }
            // The ramp ends by its own count (see `step`), never by a window.
            Phase::Ramp => Phase::Full,
        };
        self.enter(next);
        None
    }

    /// The coil's time constant `L / R` from the phase's step response, its end `shift_a`
    /// from the level the fit took its deviations from.
    fn time_constant(&self, shift_a: f32) -> Option<f32> {
        let a = self.decay.factor(shift_a)?;
        Some(-self.plan.period_s / libm::logf(a))
    }

    /// Everything, once the last hold's window is complete.
    fn report(&self) -> Result<Report, Abort> {
        let (open_m, var_open) = self.kept[OPEN].position();
        let (probe_m, _) = self.cycle.position();
        let (near_m, _) = self.kept[NEAR].position();
        let (closed_m, var_closed) = self.kept[FULL].position();
        let travel = closed_m - open_m;
        let stroke = self.plan.stroke_m;
        // A NaN travel (none can come from finite readings) is no travel either.
        if travel.is_nan() || travel.abs() < MIN_TRAVEL_SHARE * stroke {
            return Err(Abort::NoTravel);
        }
        if travel < 0.0 {
            return Err(Abort::Backwards);
        }
        if (closed_m - near_m).abs() > self.plan.still_m {
            return Err(Abort::NoStop);
        }
        // At the closed stop the armature is pressed against it: the two holds give the
        // resistance free of any motion.
        let resistance = resistance(
            &self.kept[NEAR],
            &self.kept[FULL],
            (FULL_SHARE - NEAR_SHARE) * self.plan.abort_a,
        )?;
        let shift = self.kept[NEAR].current().1 - self.kept[FULL].current().1;
        let closed_h = resistance.ohm * self.time_constant(shift).ok_or(Abort::NoDecay)?;
        // The probe's pull moved the armature `x` off the open stop (the ends calibrate
        // the reading): `1/L` is linear in the gap, so the line through the probe's and
        // the closed stop's gives the open stop's.
        let x = (probe_m - open_m) * stroke / travel;
        if x.is_nan() || x >= MIN_TRAVEL_SHARE * stroke {
            return Err(Abort::PulledIn);
        }
        let (inv_p, inv_c) = (1.0 / (resistance.ohm * self.probe_s), 1.0 / closed_h);
        let open_h = 1.0 / (inv_p + (inv_p - inv_c) * x / (stroke - x));
        Ok(Report {
            resistance,
            inductance: Inductance { open_h, closed_h },
            ends: Ends {
                open_m,
                closed_m,
                uncertainty_m: 2.0 * math::sqrt(math::max(var_open, var_closed)),
            },
        })
    }
}
