//! The closed loop: at every ISR instant the true plant is sampled (ideal or through the
//! converter model), the core's `Config::tick` runs and drives the mock bridge, and the plant
//! is integrated over the period with the voltage the bridge's lines select.
//!
//! Timing: sample at `t_k = k / rate`, tick, the new bridge state holds over
//! `[t_k, t_k+1)` (zero-order hold, no computation delay; a converter delay is set in the
//! sensor model).
//!
//! Every tick runs through the firmware's guard ([`ema::device::guard::Config::run`]) at
//! the simulated time `t_k` in nanoseconds, and the ticks it finds on time feed a model of
//! the firmware's window watchdog ([`hal::Watchdog`]). A missed deadline
//! ([`Injected::MissedDeadlines`]) is a tick that does not run: the bridge keeps its last
//! state, the guard sees the gap when the interrupt runs again and latches the overrun, and
//! if the stall outlasts the watchdog, the watchdog coasts the bridge first (the firmware
//! then resets and starts with the overrun latched, which is what the run records).
//!
//! The board's over-current comparator on the timer's break input
//! ([`crate::simulation::scenario::Bridge::break_current_a`]) is checked at every substep: once the
//! coil current reaches its level the bridge coasts for the rest of the run, whatever the
//! lines select, and the next tick starts with the break flag set (`hardware_trip`), as
//! the firmware's does. Between two samples it is the only protection: the sampled trip
//! sees the current once a period.

use ema::control::bridge::{Drive, HBridge};
use ema::control::sense::Measurement;
use ema::control::supervisor::Fault;
use ema::device::guard::{self, End, Start};
use serde::{Deserialize, Serialize};

use crate::simulation::hal::{self, Supply, Switches};
use crate::simulation::metrics::{self, Metrics};
use crate::simulation::plant::{Input, Params, State};
use crate::simulation::scenario::{BridgeMode, Injected, Scenario, Sensors};
use crate::simulation::Error;

pub use crate::simulation::trace::{fault_name, mode_name, ImpactAt, Sample};

/// The result of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// One sample per ISR period (the simulation's record, not a golden trace).
    pub samples: Vec<Sample>,
    /// End-stop impacts.
    pub impacts: Vec<ImpactAt>,
    /// The true plant that was simulated.
    pub plant: Params,
    /// Metrics ([`metrics`]).
    pub metrics: Metrics,
}

impl Run {
    /// The sample at or just before `t_s` (the first one before the run starts).
    #[must_use]
    pub fn sample_at(&self, t_s: f64) -> Option<&Sample> {
        let k = self.samples.partition_point(|s| s.t_s <= t_s);
        self.samples.get(k.saturating_sub(1))
    }
}

/// Runs a scenario.
///
/// # Errors
/// An invalid scenario, true plant or controller configuration, by name.
pub fn run(scenario: &Scenario) -> Result<Run, Error> {
    run_with(scenario, None)
}

/// What [`run_with`] records for golden traces: every tick's frame, set point and outputs
/// in the `ema::control::trace` format; a latched fault is re-armed at the next tick when
/// `rearm_after_fault` (so that a trace keeps exercising the whole path).
#[derive(Debug, Default)]
pub struct Recording {
    /// Re-arm the controller at the tick after a latched fault.
    pub rearm_after_fault: bool,
    /// The records, one per tick.
    pub records: Vec<ema::control::trace::Record>,
}

/// As [`run`], recording every tick into `recording` when given.
///
/// # Errors
/// As [`run`]; recording needs converter codes ([`Sensors::Adc`]) and no missed
/// deadlines (a trace has one record per tick).
pub fn run_with(scenario: &Scenario, recording: Option<&mut Recording>) -> Result<Run, Error> {
    simulate(scenario, recording, Vec::new(), Until::End)
}

std::thread_local! {
    /// The samples' buffer [`with_run`] lends each run on this thread: a long run's record
    /// is tens of megabytes, which a fresh allocation per run would map, fault in page by
    /// page and unmap again.
    static SAMPLES: core::cell::Cell<Vec<Sample>> = const { core::cell::Cell::new(Vec::new()) };
}

/// Runs a scenario, as [`run`], and hands the run to `f`, which only borrows it: its
/// samples live in a buffer this thread keeps for the next run. The same bits as [`run`];
/// what a search or a Monte Carlo runs thousands of times.
///
/// # Errors
/// As [`run`].
pub fn with_run<T>(scenario: &Scenario, f: impl FnOnce(&Run) -> T) -> Result<T, Error> {
    with_run_until(scenario, Until::End, f)
}

/// Where a run stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Until {
    /// At the scenario's end.
    End,
    /// At the scenario's end or at the tick a fault latches, whichever is first: for a
    /// search that rejects any run in which a fault latched, whatever the rest of it
    /// does. The run's metrics then cover only the ticks up to the fault.
    Fault,
    /// As [`Until::Fault`], and also at the first sample that makes a step segment miss
    /// its settling target ([`crate::simulation::targets::Targets::for_scenario`]): a
    /// sample outside the segment's 2 % band once its target has passed. The segment's
    /// settling time is then longer than the target whatever follows (it ends no earlier
    /// than the next sample), and the stopped run's reads as never settled: for a search
    /// that rejects a run missing any target and needs no more of it.
    Miss,
}

/// A step segment's settling deadline, for [`Until::Miss`].
struct Deadline {
    /// Past this time \[s\], a sample outside the band is a certain miss.
    after_s: f64,
    /// The segment's end \[s\].
    end_s: f64,
    to_m: f64,
    band_m: f64,
}

impl Deadline {
    /// The step segments of `scenario`, in time order.
    fn of(scenario: &Scenario) -> Vec<Self> {
        let t = crate::simulation::targets::Targets::for_scenario(scenario);
        scenario
            .reference
            .segments(scenario.duration_s)
            .iter()
            .enumerate()
            .filter(|(_, s)| s.to_m != s.from_m)
            .map(|(k, s)| Self {
                after_s: s.start_s + t.settling_of(k),
                end_s: s.end_s,
                to_m: s.to_m,
                band_m: metrics::SETTLING_BAND * (s.to_m - s.from_m).abs(),
            })
            .collect()
    }

    /// Whether the sample at `t_s`, at `x_m`, makes its segment's settling miss.
    fn missed(deadlines: &[Self], t_s: f64, x_m: f64) -> bool {
        // Segments are contiguous and few: the one holding `t_s`, if a step.
        deadlines
            .iter()
            .find(|d| t_s < d.end_s)
            .is_some_and(|d| t_s > d.after_s && (x_m - d.to_m).abs() > d.band_m)
    }
}

/// [`with_run`], stopped as `until` says.
///
/// # Errors
/// As [`run`].
pub fn with_run_until<T>(
    scenario: &Scenario,
    until: Until,
    f: impl FnOnce(&Run) -> T,
) -> Result<T, Error> {
    let run = simulate(scenario, None, SAMPLES.take(), until)?;
    let out = f(&run);
    SAMPLES.set(run.samples);
    Ok(out)
}

/// [`run_with`] into `samples`, cleared first (its capacity is kept).
fn simulate(
    scenario: &Scenario,
    mut recording: Option<&mut Recording>,
    mut samples: Vec<Sample>,
    until: Until,
) -> Result<Run, Error> {
    if recording.is_some() {
        if let Sensors::Ideal = scenario.sensors {
            return Err(Error::param(
                "sensors",
                f64::NAN,
                "a recorded run needs converter codes (sensors.kind = \"adc\")",
            ));
        }
        if scenario
            .faults
            .iter()
            .any(|f| matches!(f.fault, Injected::MissedDeadlines { .. }))
        {
            return Err(Error::param(
                "faults",
                f64::NAN,
                "a recorded run has one record per tick: no missed deadlines",
            ));
        }
    }
    scenario.validate()?;
    let config = scenario.controller.build()?;
    let plant = scenario.plant.resolve(&scenario.controller.plant);
    plant.validate()?;
    let bounds = metrics::bounds_check(&scenario.controller.plant, &plant)?;
    let mut stepper = Stepper::for_scenario(scenario, plant, scenario.integration.substeps)?;

    let n = scenario.ticks();
    let (pwm, dir, en, lines) = hal::bridge_io(scenario.bridge.max_duty);
    let mut bridge = match HBridge::new(pwm, dir, en) {
        Ok(b) => b,
        Err(e) => match e {},
    };
    let mut ctl = config.initial_state();
    let mut converter = match &scenario.sensors {
        Sensors::Ideal => None,
        Sensors::Adc(adc) => Some(adc.start(config.sense())),
    };
    samples.clear();
    samples.reserve_exact(n);
    let mut faults = scenario.faults.clone();
    faults.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    let mut faults = faults.into_iter().peekable();
    let mut probes = scenario.inductance_probes.clone();
    probes.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    let mut probes = probes.into_iter().peekable();
    let mut sensing = SensorFaults::default();
    let mut missed = 0_u32;
    let mut last = ema::control::Status::default();
    let period_ns = 1e9 / scenario.rate_hz();
    // The guard counts nanoseconds; one period is far inside its 32-bit range.
    #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let guard = guard::Config::for_period(period_ns.round() as u32);
    let mut guarded = guard::State::default();
    let mut watchdog = hal::Watchdog::reference(scenario.rate_hz());
    let deadlines = if until == Until::Miss {
        Deadline::of(scenario)
    } else {
        Vec::new()
    };

    for _ in 0..n {
        let now = stepper.sample();
        // Non-negative and far below 2^64 ns; the guard's counter wraps at 2^32.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let now_ns = (now.t_s * 1e9).round() as u64;
        let r = scenario.reference.position_m(now.t_s);
        // Faults whose time has come (a period's worth of slack for the f64 clock).
        while let Some(f) = faults.next_if(|f| f.at_s <= now.t_s + 1e-9) {
            match f.fault {
                Injected::CoilOpen => stepper.set_coil_open(true),
                Injected::CoilShort { resistance_ohm } => {
                    stepper.set_resistance_ohm(resistance_ohm)
                }
                Injected::Supply { voltage_v } => stepper.set_supply_v(voltage_v),
                Injected::MissedDeadlines { ticks } => missed = missed.saturating_add(ticks),
                other => sensing.inject(other, &now),
            }
        }
        while let Some(p) = probes.next_if(|p| p.at_s <= now.t_s + 1e-9) {
            ctl.probe = p.start();
        }
        let status = if missed > 0 {
            // The interrupt does not run: the bridge keeps whatever it was set to, until
            // the watchdog's early-wakeup interrupt coasts it.
            missed -= 1;
            if watchdog.bitten(now_ns) && last.fault.is_none() {
                last.fault = Some(config.trip(&mut ctl, &mut bridge, Fault::Overrun));
                last.drive = Drive::default();
            }
            last
        } else {
            let start = Start {
                #[expect(clippy::cast_possible_truncation)]
                now: now_ns as u32,
                hardware_trip: stepper.broken(),
            };
            let (x_m, i_a) = sensing.read(&now);
            let outcome = guard.run(
                &mut guarded,
                &config,
                &mut ctl,
                &mut bridge,
                start,
                |ctl, bridge| {
                    #[expect(clippy::cast_possible_truncation)]
                    match converter.as_mut() {
                        None => config.tick_measured(
                            ctl,
                            bridge,
                            &Measurement {
                                x_m: x_m as f32,
                                i_a: i_a as f32,
                                vbus_v: now.vbus_v as f32,
                            },
                            r as f32,
                        ),
                        Some(c) => {
                            let frame = c.sample(x_m, i_a, now.vbus_v);
                            match recording.as_deref_mut() {
                                None => config.tick(ctl, bridge, &frame, r as f32),
                                Some(rec) => {
                                    let rearm = rec.rearm_after_fault && last.fault.is_some();
                                    let (status, record) = ema::control::trace::tick_record(
                                        &config, ctl, bridge, &frame, r as f32, rearm,
                                    );
                                    rec.records.push(record);
                                    status
                                }
                            }
                        }
                    }
                },
                // The simulated tick takes no time: it always ends on time.
                End::default,
            );
            if outcome.feed {
                watchdog.feed(now_ns);
            }
            outcome.status
        };
        last = status;
        let period = stepper.advance(lines.switches(), scenario.bridge.mode);
        samples.push(Sample {
            t_s: now.t_s,
            r_m: r,
            x_m: now.x_m,
            v_mps: now.v_mps,
            i_a: now.i_a,
            psi_wb: now.psi_wb,
            vbus_v: now.vbus_v,
            x_meas_m: f64::from(status.measurement.x_m),
            i_meas_a: f64::from(status.measurement.i_a),
            u_drive_v: f64::from(status.drive.u_v),
            vbus_meas_v: f64::from(status.measurement.vbus_v),
            x_est_m: f64::from(status.estimate.x_m),
            v_est_mps: f64::from(status.estimate.v_mps),
            d_est_mps2: f64::from(status.estimate.d_mps2),
            r_shaped_m: f64::from(status.reference.x_m),
            u_cmd_v: f64::from(status.output.u_v),
            i_d_a: f64::from(status.output.i_d_a),
            duty: status.drive.duty,
            mode: status.drive.mode,
            fault: status.fault,
            u_mean_v: period.u_mean_v,
            u_rms_v: period.u_rms_v,
            u_abs_max_v: period.u_abs_max_v,
            i_abs_max_a: period.i_abs_max_a,
            energy_j: period.energy_j,
        });
        if until != Until::End && status.fault.is_some() {
            break;
        }
        if until == Until::Miss && Deadline::missed(&deadlines, now.t_s, now.x_m) {
            break;
        }
    }
    let (plant, impacts) = stepper.finish();
    let metrics = metrics::compute(scenario, bounds, &samples, &impacts);
    Ok(Run {
        samples,
        impacts,
        plant,
        metrics,
    })
}

/// What the injected sensor faults do to the analog values the converter sees.
#[derive(Clone, Copy, Debug, Default)]
struct SensorFaults {
    position: Option<PositionFault>,
    current_stuck: Option<f64>,
    current_offset_a: f64,
}

#[derive(Clone, Copy, Debug)]
enum PositionFault {
    /// Output at 0 V: a value far below the range, which the converter reads as its low
    /// rail.
    Open,
    /// Output at the sensor's supply: far above the range, the high rail.
    Shorted,
    /// Frozen at this value \[m\].
    Stuck(f64),
}

impl SensorFaults {
    fn inject(&mut self, fault: Injected, now: &Truth) {
        match fault {
            Injected::PositionOpen => self.position = Some(PositionFault::Open),
            Injected::PositionShorted => self.position = Some(PositionFault::Shorted),
            Injected::PositionStuck => self.position = Some(PositionFault::Stuck(now.x_m)),
            Injected::CurrentStuck => {
                self.current_stuck = Some(now.i_a + self.current_offset_a);
            }
            Injected::CurrentOffset { offset_a } => self.current_offset_a += offset_a,
            _ => {}
        }
    }

    /// Position and current as the sensors report them.
    fn read(&self, now: &Truth) -> (f64, f64) {
        let x = match self.position {
            None => now.x_m,
            Some(PositionFault::Open) => -1.0,
            Some(PositionFault::Shorted) => 1.0,
            Some(PositionFault::Stuck(x)) => x,
        };
        let i = self
            .current_stuck
            .unwrap_or(now.i_a + self.current_offset_a);
        (x, i)
    }
}

/// The true state at a sample instant.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Time \[s\].
    pub t_s: f64,
    /// Position \[m\].
    pub x_m: f64,
    /// Velocity \[m/s\].
    pub v_mps: f64,
    /// Coil current \[A\].
    pub i_a: f64,
    /// Flux linkage \[Wb\].
    pub psi_wb: f64,
    /// Bus voltage at the supply terminals \[V\].
    pub vbus_v: f64,
}

/// What the coil saw over one period.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Period {
    /// Mean coil voltage \[V\].
    pub u_mean_v: f64,
    /// RMS coil voltage \[V\].
    pub u_rms_v: f64,
    /// Largest `|u|` at the substep boundaries \[V\].
    pub u_abs_max_v: f64,
    /// Largest `|i|` at the substep boundaries, start included \[A\].
    pub i_abs_max_a: f64,
    /// Energy drawn from the supply's source \[J\].
    pub energy_j: f64,
}

/// The plant side of the loop, without a controller: the true plant, the supply and the
/// bridge, advanced one ISR period at a time under a given [`Switches`]. [`run`] uses it
/// between ticks; it is public for open-loop replays (integrator convergence, golden
/// traces, injected drive sequences).
#[derive(Clone, Debug)]
pub struct Stepper {
    plant: Params,
    supply: Supply,
    diode_drop_v: f64,
    substeps: u32,
    ts_s: f64,
    k: u64,
    state: State,
    impacts: Vec<ImpactAt>,
    /// The input in force at the end of the last period (for the bus voltage at the next
    /// sample instant).
    last: Input,
    /// The coil circuit is open (an injected fault): no current flows.
    coil_open: bool,
    /// The armature is jammed where it is (an injected fault).
    jammed: bool,
    /// The board's over-current comparator's level \[A\] (`None`: no comparator).
    break_a: Option<f64>,
    /// The comparator has tripped: the bridge coasts, whatever the lines select.
    broken: bool,
}

impl Stepper {
    /// A plant at `initial`, with the bridge coasting, at time 0.
    ///
    /// # Errors
    /// An invalid plant, supply, rate or substep count, by name.
    pub fn new(
        plant: Params,
        supply: Supply,
        bridge: &crate::simulation::scenario::Bridge,
        substeps: u32,
        rate_hz: f64,
        initial: &crate::simulation::scenario::Initial,
    ) -> Result<Self, Error> {
        plant.validate()?;
        supply.validate()?;
        crate::simulation::plant::positive("controller.rate_hz", rate_hz)?;
        crate::simulation::plant::non_negative("bridge.diode_drop_v", bridge.diode_drop_v)?;
        if let Some(b) = bridge.break_current_a {
            crate::simulation::plant::positive("bridge.break_current_a", f64::from(b))?;
        }
        if substeps == 0 {
            return Err(Error::param(
                "integration.substeps",
                0.0,
                "must be positive",
            ));
        }
        let state = plant.state(initial.x_m, initial.v_mps, initial.i_a);
        let last = supply.coast(plant.current_a(&state), bridge.diode_drop_v);
        let substeps = substeps.max(stable_substeps(&plant, rate_hz));
        Ok(Self {
            plant,
            supply,
            diode_drop_v: bridge.diode_drop_v,
            substeps,
            ts_s: 1.0 / rate_hz,
            k: 0,
            state,
            impacts: Vec::new(),
            last,
            coil_open: false,
            jammed: false,
            break_a: bridge.break_current_a.map(f64::from),
            broken: false,
        })
    }

    /// Jams the armature where it is (a foreign body, a seized guide), or frees it.
    pub fn set_jammed(&mut self, jammed: bool) {
        self.jammed = jammed;
        if jammed {
            self.state.y[1] = 0.0;
        }
    }

    /// Opens the coil circuit (an injected fault: from then on no current flows, whatever
    /// the bridge applies), or closes it again.
    pub fn set_coil_open(&mut self, open: bool) {
        self.coil_open = open;
        if open {
            self.state.y[2] = 0.0;
        }
    }

    /// The board's over-current comparator has tripped: the bridge's outputs are off until
    /// [`Stepper::release_break`] (the firmware's break input, read by the next tick).
    #[must_use]
    pub const fn broken(&self) -> bool {
        self.broken
    }

    /// The comparator's output now: the current is at or above its level (the cause of a
    /// trip is still there).
    #[must_use]
    pub fn break_input_active(&self) -> bool {
        let i = self.plant.current_a(&self.state);
        self.break_a.is_some_and(|b| i.abs() >= b)
    }

    /// Switches the outputs off as the break input does (the driver's fault output).
    pub fn trip_break(&mut self) {
        self.broken = true;
    }

    /// Re-enables the outputs after a comparator trip (a re-arm).
    pub fn release_break(&mut self) {
        self.broken = false;
    }

    /// The plant, to change (an injected fault, or a part off its datasheet): it takes
    /// effect from the next period.
    pub fn plant_mut(&mut self) -> &mut Params {
        &mut self.plant
    }

    /// Changes the coil resistance (an injected short of turns) \[ohm\].
    pub fn set_resistance_ohm(&mut self, resistance_ohm: f64) {
        self.plant.resistance_ohm = resistance_ohm;
    }

    /// Changes the supply's source voltage (an injected sag or over-voltage) \[V\].
    pub fn set_supply_v(&mut self, voltage_v: f64) {
        self.supply.voltage_v = voltage_v;
    }

    /// The plant side of `scenario` with `plant` (the scenario's true plant, resolved)
    /// and `substeps` RK4 substeps per period.
    ///
    /// # Errors
    /// As [`Stepper::new`].
    pub fn for_scenario(scenario: &Scenario, plant: Params, substeps: u32) -> Result<Self, Error> {
        Self::new(
            plant,
            scenario.supply,
            &scenario.bridge,
            substeps,
            scenario.rate_hz(),
            &scenario.initial,
        )
    }

    /// The true state now.
    #[must_use]
    pub fn sample(&self) -> Truth {
        let s = &self.state;
        let i = self.plant.current_a(s);
        #[expect(clippy::cast_precision_loss)]
        let t_s = self.k as f64 * self.ts_s;
        Truth {
            t_s,
            x_m: s.x_m(),
            v_mps: s.v_mps(),
            i_a: i,
            psi_wb: self.plant.flux_linkage_of(s),
            vbus_v: self.supply.bus_voltage_v(&self.last, i),
        }
    }

    /// Puts the plant in the state of `sample` (position, velocity and current or flux
    /// linkage, as the force model carries it) at the start of period `k`: for measuring
    /// the error of one period alone.
    pub fn resync(&mut self, k: u64, sample: &Sample) {
        let e = match self.plant.force {
            crate::simulation::plant::ForceModel::Frozen => sample.i_a,
            crate::simulation::plant::ForceModel::EnergyConsistent => sample.psi_wb,
        };
        self.state.y = [sample.x_m, sample.v_mps, e, 0.0, 0.0, 0.0];
        self.k = k;
        self.last = self.supply.coast(sample.i_a, self.diode_drop_v);
    }

    /// The true plant.
    #[must_use]
    pub const fn plant(&self) -> &Params {
        &self.plant
    }

    /// End-stop impacts so far.
    #[must_use]
    pub fn impacts(&self) -> &[ImpactAt] {
        &self.impacts
    }

    /// The plant and the impacts.
    #[must_use]
    pub fn finish(self) -> (Params, Vec<ImpactAt>) {
        (self.plant, self.impacts)
    }

    /// Advances one ISR period with the bridge lines selecting `drive`.
    pub fn advance(&mut self, drive: Switches, mode: BridgeMode) -> Period {
        let ts = self.ts_s;
        #[expect(clippy::cast_precision_loss)]
        let mut t = self.k as f64 * ts;
        let i0 = self.plant.current_a(&self.state);
        // Running integrals restart every period.
        self.state.y[3] = 0.0;
        self.state.y[4] = 0.0;
        self.state.y[5] = 0.0;
        let mut p = Period {
            i_abs_max_a: i0.abs(),
            ..Period::default()
        };
        let n = f64::from(self.substeps);
        match (drive, mode) {
            (Switches::Coast, _) => self.phase(Phase::Coast, ts, self.substeps, &mut t, &mut p),
            (Switches::Driven { forward, fraction }, BridgeMode::Averaged) => {
                let sign = if forward { 1.0 } else { -1.0 };
                self.phase(
                    Phase::Driven { sign, fraction },
                    ts,
                    self.substeps,
                    &mut t,
                    &mut p,
                );
            }
            (Switches::Driven { forward, fraction }, BridgeMode::Switching) => {
                let sign = if forward { 1.0 } else { -1.0 };
                let on = Phase::Driven {
                    sign,
                    fraction: 1.0,
                };
                let off = Phase::Driven {
                    sign,
                    fraction: 0.0,
                };
                let f = fraction.clamp(0.0, 1.0);
                if f <= 0.0 {
                    self.phase(off, ts, self.substeps, &mut t, &mut p);
                } else if f >= 1.0 {
                    self.phase(on, ts, self.substeps, &mut t, &mut p);
                } else {
                    let half_off = 0.5 * (1.0 - f) * ts;
                    let n_off = count(n * 0.5 * (1.0 - f));
                    let n_on = count(n * f);
                    self.phase(off, half_off, n_off, &mut t, &mut p);
                    self.phase(on, f * ts, n_on, &mut t, &mut p);
                    self.phase(off, half_off, n_off, &mut t, &mut p);
                }
            }
        }
        self.k += 1;
        let s = &self.state;
        p.u_mean_v = s.volt_seconds() / ts;
        p.u_rms_v = (s.volt_sq_seconds() / ts).max(0.0).sqrt();
        p.energy_j = s.energy_j();
        p
    }

    fn phase(&mut self, phase: Phase, len_s: f64, n: u32, t: &mut f64, p: &mut Period) {
        let h = len_s / f64::from(n);
        let mut i = self.plant.current_a(&self.state);
        for _ in 0..n {
            let input = match phase {
                Phase::Driven { sign, fraction } if !self.broken => {
                    self.supply.driven(sign, fraction)
                }
                Phase::Driven { .. } | Phase::Coast => self.supply.coast(i, self.diode_drop_v),
            };
            let u0 = input.coil_voltage_v(i).abs();
            let x0 = self.state.y[0];
            let hit = self.plant.step(&mut self.state, &input, h);
            if self.jammed {
                self.state.y[0] = x0;
                self.state.y[1] = 0.0;
            }
            if self.coil_open {
                // i = 0 exactly in both electrical states (current, or flux linkage).
                self.state.y[2] = 0.0;
            }
            *t += h;
            i = self.plant.current_a(&self.state);
            p.u_abs_max_v = p.u_abs_max_v.max(u0).max(input.coil_voltage_v(i).abs());
            p.i_abs_max_a = p.i_abs_max_a.max(i.abs());
            // The comparator acts at the end of the substep it is crossed in.
            self.broken |= self.break_a.is_some_and(|b| i.abs() >= b);
            if let Some(impact) = hit {
                self.impacts.push(ImpactAt { t_s: *t, impact });
            }
            self.last = input;
        }
        if matches!(phase, Phase::Coast) || self.broken {
            // The bus voltage at the next sample follows the state the coil ends in.
            self.last = self.supply.coast(i, self.diode_drop_v);
        }
    }
}

/// A stretch of constant bridge state within a period.
#[derive(Clone, Copy)]
enum Phase {
    /// Bridge enabled: `driven(sign, fraction)`.
    Driven { sign: f64, fraction: f64 },
    /// Bridge disabled.
    Coast,
}

/// Longest RK4 substep, in the plant's fastest electrical time constant (the coil's L/R
/// at its largest gap, unsaturated) \[-\]. RK4 is stable on a decay only while a step is
/// under 2.785 of its time constants; over one of them it moves the current by 1.1 % less
/// than the coil does (at 1.5, 6.5 %), well inside the monitors' relative margin
/// ([`ema::control::actuator::RESIDUAL_MARGIN`]). A coil whose time constant is under
/// half the period, integrated in one substep per period (as `tune` screens), grew
/// instead of decaying: its current ran the wrong way under the drive, and the monitors
/// named a fault the coil does not have.
pub const MAX_SUBSTEP_TIME_CONSTANTS: f64 = 1.0;

/// The fewest RK4 substeps per period at `rate_hz` that keep every substep within
/// [`MAX_SUBSTEP_TIME_CONSTANTS`] of `plant`'s fastest electrical time constant: the
/// substeps a run takes whatever it is asked for.
#[must_use]
pub fn stable_substeps(plant: &Params, rate_hz: f64) -> u32 {
    let (_, widest) = plant.gap_range_m();
    let tau_s = plant.inductance_h(widest) / plant.resistance_ohm;
    count(1.0 / (rate_hz * MAX_SUBSTEP_TIME_CONSTANTS * tau_s))
}

/// Substeps for a phase that lasts `x` substeps of the period: `ceil(x)`, at least 1, so
/// that no substep is longer than `T / substeps`.
fn count(x: f64) -> u32 {
    // Bounded to [1, 1e6] before the cast.
    #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let n = (x - 1e-9).ceil().clamp(1.0, 1e6) as u32;
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulation::scenario::{Bridge, Initial};
    use ema::control::bridge::Mode;

    fn stepper(mode_supply: Supply, initial: Initial) -> Stepper {
        Stepper::new(
            Params::paper(),
            mode_supply,
            &Bridge::default(),
            10,
            20_000.0,
            &initial,
        )
        .unwrap()
    }

    /// Armature held on the stroke-end stop (4 mm, L = 43.75 uH, tau = L/R = 109.4 us),
    /// 20 V, duty 0.5 at 20 kHz. Switching-level, the periodic solution is made of
    /// exponential arcs towards 50 A (on, 25 us) and 0 A (off, 2 x 12.5 us): with
    /// `a = exp(-25/109.375)`, valley `i_v = 50 a (1 - a) / (1 - a^2) = 22.155 A`, peak
    /// `50 - i_v = 27.845 A` (5.69 A peak to peak), and the sample, mid-way down the off
    /// time, `27.845 exp(-12.5/109.375) = 24.838 A`. Averaged, the current sits at 25 A.
    #[test]
    fn switching_level_ripple_is_the_pwm_triangle() {
        let initial = Initial {
            x_m: 4e-3,
            v_mps: 0.0,
            i_a: 25.0,
        };
        let drive = Switches::Driven {
            forward: true,
            fraction: 0.5,
        };
        let a = (-25.0_f64 / 109.375).exp();
        let valley = 50.0 * a * (1.0 - a) / (1.0 - a * a);
        let peak = 50.0 - valley;
        let mid_off = peak * (-12.5_f64 / 109.375).exp();
        for (mode, sample_a, peak_a) in [
            (BridgeMode::Switching, mid_off, peak),
            (BridgeMode::Averaged, 25.0, 25.0),
        ] {
            let mut st = stepper(Supply::ideal(20.0), initial);
            let mut last = Period::default();
            let mut sample = st.sample();
            for _ in 0..400 {
                sample = st.sample();
                last = st.advance(drive, mode);
            }
            assert_eq!(sample.x_m, 4e-3);
            assert!(
                (sample.i_a - sample_a).abs() < 1e-3,
                "{mode:?}: {}",
                sample.i_a
            );
            assert!(
                (last.i_abs_max_a - peak_a).abs() < 1e-3,
                "{mode:?}: {}",
                last.i_abs_max_a
            );
            assert!((last.u_mean_v - 10.0).abs() < 1e-9, "{}", last.u_mean_v);
            // RMS of a 0/20 V square wave at duty 0.5 is 14.14 V; averaged it is 10 V.
            let rms = if mode == BridgeMode::Switching {
                200.0_f64.sqrt()
            } else {
                10.0
            };
            assert!((last.u_rms_v - rms).abs() < 1e-9, "{}", last.u_rms_v);
        }
    }

    /// A coil whose time constant is a third of the period, asked for one substep: the
    /// armature on the stroke-end stop (4 mm, tau = 109.4 us) at 3.05 kHz, 10 V averaged
    /// from 0 A. RK4 over the whole period multiplies the distance to 25 A by 1.375 each
    /// period (it diverges); the run takes the substeps [`stable_substeps`] asks and
    /// follows the coil: `25 (1 - e^-3) = 23.76 A` after a period, 25 A after twenty.
    #[test]
    fn a_coil_faster_than_the_period_is_integrated_stably() {
        let tau = 109.375e-6;
        let rate = 1.0 / (3.0 * tau);
        let initial = Initial {
            x_m: 4e-3,
            v_mps: 0.0,
            i_a: 0.0,
        };
        let mut st = Stepper::new(
            Params::paper(),
            Supply::ideal(20.0),
            &Bridge::default(),
            1,
            rate,
            &initial,
        )
        .unwrap();
        assert!(stable_substeps(&Params::paper(), rate) >= 3);
        let drive = Switches::Driven {
            forward: true,
            fraction: 0.5,
        };
        st.advance(drive, BridgeMode::Averaged);
        let first = st.sample().i_a;
        let exact = 25.0 * (1.0 - (-3.0_f64).exp());
        assert!(
            (first / exact - 1.0).abs() < 0.02,
            "{first} A, exactly {exact} A"
        );
        for _ in 0..19 {
            st.advance(drive, BridgeMode::Averaged);
        }
        let last = st.sample().i_a;
        assert!((last / 25.0 - 1.0).abs() < 1e-3, "{last} A");
    }

    /// Coasting from 5 A at 3 mm into a 150 V supply with 1 ohm inside: the diodes put
    /// -(150 + 5 + 1.4) V on the coil, the current reaches 0 within 2 us and stays there
    /// exactly; the energy goes back into the supply, whose terminals rise while it flows.
    #[test]
    fn coasting_current_freewheels_into_the_supply_and_stops() {
        let supply = Supply {
            voltage_v: 150.0,
            internal_resistance_ohm: 1.0,
        };
        let mut st = stepper(
            supply,
            Initial {
                x_m: 3e-3,
                v_mps: 0.0,
                i_a: 5.0,
            },
        );
        assert!((st.sample().vbus_v - 155.0).abs() < 1e-9);
        let p = st.advance(Switches::Coast, BridgeMode::Averaged);
        // L di/dt = -(151.4 + 1.4 i): with tau = L/1.4 = 41.67 us the current reaches 0 at
        // t0 = tau ln(113.14/108.14) = 1.883 us, int i dt = 4.66e-6 C, and the source takes
        // back 150 V * 4.66e-6 C = 0.699 mJ (of the 0.729 mJ stored).
        assert!((p.energy_j + 0.699e-3).abs() < 0.005e-3, "{}", p.energy_j);
        assert!(p.u_abs_max_v > 156.0);
        for _ in 0..10 {
            let now = st.sample();
            assert_eq!(now.i_a, 0.0);
            assert_eq!(now.vbus_v, 150.0);
            let p = st.advance(Switches::Coast, BridgeMode::Switching);
            assert_eq!(p.u_abs_max_v, 0.0);
        }
    }

    /// The trace and the metrics are what CSV and report writers will serialise: a flat
    /// sample with the mode and the fault by name, and metrics that read back unchanged.
    #[test]
    fn samples_and_metrics_round_trip_through_serde() {
        let sample = Sample {
            t_s: 1e-3,
            mode: Mode::Reverse,
            fault: Some(Fault::OverCurrent),
            ..Sample::default()
        };
        let text = toml::to_string(&sample).unwrap();
        assert!(text.contains("mode = \"reverse\""), "{text}");
        assert!(text.contains("fault = \"over_current\""), "{text}");
        assert_eq!(toml::from_str::<Sample>(&text).unwrap(), sample);
        let clean = Sample::default();
        assert_eq!(
            toml::from_str::<Sample>(&toml::to_string(&clean).unwrap()).unwrap(),
            clean
        );

        let mut sc = crate::simulation::scenario::Scenario::paper(20_000.0).with_duration_s(0.01);
        sc.controller.limits.vbus_min_v = 200.0;
        sc.controller.limits.vbus_max_v = 300.0;
        let m = run(&sc).unwrap().metrics;
        assert!(m.first_fault.is_some());
        let back: Metrics = toml::from_str(&toml::to_string(&m).unwrap()).unwrap();
        assert_eq!(back, m);
    }

    /// A run stopped at the fault is the full run up to the tick the fault latched, bit
    /// for bit, and ends there; without a fault it is the full run.
    #[test]
    fn a_run_until_the_fault_is_the_full_run_up_to_it() {
        use crate::simulation::scenario::{Injected, Injection, Scenario};
        let mut sc = Scenario::product(20e3, 24.0).unwrap().with_duration_s(0.05);
        let healthy = run(&sc).unwrap();
        let same = with_run_until(&sc, Until::Fault, |r| r.samples.clone()).unwrap();
        assert_eq!(same, healthy.samples);
        sc.faults.push(Injection {
            at_s: 0.02,
            fault: Injected::CoilOpen,
        });
        let full = run(&sc).unwrap();
        let k = full.samples.iter().position(|s| s.fault.is_some()).unwrap();
        assert!(k + 1 < full.samples.len(), "the fault latched at the end");
        let (samples, first) = with_run_until(&sc, Until::Fault, |r| {
            (r.samples.clone(), r.metrics.first_fault)
        })
        .unwrap();
        assert_eq!(samples.len(), k + 1);
        assert_eq!(samples.as_slice(), full.samples.get(..=k).unwrap());
        assert_eq!(first, full.metrics.first_fault);
    }

    /// A run stopped at a settling miss is the full run up to a sample outside the band
    /// after the move's target has passed, and the full run misses that target; a run
    /// that meets its targets is not stopped.
    #[test]
    fn a_run_until_the_miss_stops_only_where_the_settling_is_missed() {
        use crate::analysis::tune::{condition, Candidate};
        use crate::simulation::targets::{Targets, Worst};
        let act = ema::control::actuator::Actuator::PRODUCT;
        let sc = crate::simulation::actuator::scenario("product", &act).unwrap();
        let met = run(&sc).unwrap();
        let t = Targets::for_scenario(&sc);
        assert!(Worst::of([&met.metrics], &t).settling_ratio < 1.0);
        let same = with_run_until(&sc, Until::Miss, |r| r.samples.clone()).unwrap();
        assert_eq!(same, met.samples);

        // Moves shaped four times gentler than the product's.
        let tuning = act.tuning.unwrap();
        let slow = Candidate {
            alpha: f64::from(tuning.alpha_per_s),
            observer_rad_s: f64::from(tuning.observer_rad_s),
            margin: f64::from(tuning.margin) / 4.0,
            follows_force: tuning.disturbance_follows_force,
        };
        let sc = condition("slow", &act, &slow, f64::from(act.board.rate_hz), 1).unwrap();
        let full = run(&sc).unwrap();
        let t = Targets::for_scenario(&sc);
        let w = Worst::of([&full.metrics], &t);
        assert!(w.settling_ratio > 1.0 && w.faulted_runs == 0, "{w:?}");
        let (samples, ratio) = with_run_until(&sc, Until::Miss, |r| {
            (
                r.samples.clone(),
                Worst::of([&r.metrics], &t).settling_ratio,
            )
        })
        .unwrap();
        assert!(samples.len() < full.samples.len());
        assert_eq!(
            samples.as_slice(),
            full.samples.get(..samples.len()).unwrap()
        );
        assert!(ratio > 1.0, "{ratio}");
        // It stopped at the first sample that proves the miss: outside the band of its
        // move, after the move's target.
        let last = samples.last().unwrap();
        let (k, seg) = full
            .metrics
            .segments
            .iter()
            .enumerate()
            .find(|(_, s)| s.spec.start_s <= last.t_s && last.t_s < s.spec.end_s)
            .unwrap();
        let band = metrics::SETTLING_BAND * (seg.spec.to_m - seg.spec.from_m).abs();
        assert!((last.x_m - seg.spec.to_m).abs() > band);
        assert!(last.t_s - seg.spec.start_s > t.settling_of(k));
        assert!(seg.settling_time_s.is_none_or(|s| s > t.settling_of(k)));
    }

    #[test]
    fn an_invalid_true_plant_is_refused_by_name() {
        let mut p = Params::paper();
        p.gaps.clear();
        let sc = crate::simulation::scenario::Scenario::paper(20_000.0)
            .with_plant(crate::simulation::scenario::TruePlant::Given(p));
        assert_eq!(run(&sc).unwrap_err().name(), "plant.gaps");
    }

    #[test]
    fn drives_replay_from_a_recorded_mode_and_duty() {
        assert_eq!(Switches::from_mode(Mode::Coast, 100, 4200), Switches::Coast);
        assert_eq!(
            Switches::from_mode(Mode::Reverse, 2100, 4200),
            Switches::Driven {
                forward: false,
                fraction: 0.5
            }
        );
    }
}
