//! The control layer: everything the control tick computes, and the tick itself.
//!
//! The tick runs sense -> limits -> set point -> shaping -> observer -> law -> supervisor
//! -> bridge (each step in the crate docs' architecture section). Its stages are the
//! submodules ([`sense`], [`shaping`], [`observer`], [`law`], [`supervisor`], [`bridge`]),
//! with what they share ([`model`], [`actuator`], [`config`], [`math`]) and the golden
//! traces that record and replay it ([`trace`]). The tick is this module's root, not a
//! submodule of its own: [`Config`] is the layer's configuration, made of each stage's
//! `Config` (`law::Config`, `observer::Config`, ...), so `control::Config::tick` names it
//! as the stages are named, and a `control::tick::Config::tick` would say "tick" twice.
//! The layer uses nothing else in the crate: the build script compiles it alone.
//!
//! [`Settings`] is the plain description (what a configuration file holds);
//! [`Settings::build`] validates it into an immutable [`Config`], the only thing the tick
//! reads. [`State`] is the small mutable part. The firmware interrupt, the simulator and
//! the QEMU tests all call [`Config::tick`] (or [`Config::tick_measured`] when a simulator
//! supplies ideal SI measurements instead of converter codes).
//!
//! ```
//! use ema::control::bridge::{HBridge, NullPin, NullPwm, BOARD_MAX_DUTY};
//! use ema::control::Settings;
//! use ema::control::sense::Measurement;
//! let cfg = Settings::paper(20_000.0, 24.0).build().unwrap();
//! let mut state = cfg.initial_state();
//! let mut bridge = HBridge::new(NullPwm::new(BOARD_MAX_DUTY), NullPin(false), NullPin(false)).unwrap();
//!
//! // Armature at 1 mm, no current, 24 V bus, target 3 mm: the law drives current in.
//! let frame = cfg.sense().frame(&Measurement { x_m: 1e-3, i_a: 0.0, vbus_v: 24.0 });
//! let status = cfg.tick(&mut state, &mut bridge, &frame, 3e-3);
//! assert_eq!(status.fault, None);
//! assert!(status.drive.u_v > 23.9); // saturated at the bus voltage
//!
//! // A position sensor on the ADC rail is a fault: the bridge coasts, nothing panics.
//! let broken = ema::control::sense::Frame { position: 0, ..frame };
//! let status = cfg.tick(&mut state, &mut bridge, &broken, 3e-3);
//! assert_eq!(status.fault, Some(ema::control::supervisor::Fault::PositionSensor));
//! assert_eq!(status.drive.mode, ema::control::bridge::Mode::Coast);
//! ```

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

pub mod actuator;
pub mod bridge;
pub mod config;
pub mod law;
pub mod math;
pub mod model;
pub mod observer;
pub mod sense;
pub mod shaping;
pub mod supervisor;
pub mod trace;

use actuator::Actuator;
use bridge::{Drive, HBridge};
use config::Error;
use law::{Law, Reference};
use model::Plant;
use observer::Estimate;
use sense::{Calibration, Frame, Measurement};
use supervisor::{monitor, Fault, Limits, Monitors};

/// Everything needed to build a controller, before validation.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Settings {
    /// Control (ISR) rate \[Hz\].
    pub rate_hz: f32,
    /// The actuator as the controller knows it (nominal values and bounds).
    pub plant: Plant,
    /// Converter calibration.
    pub sense: Calibration,
    /// Velocity observer.
    pub observer: observer::Settings,
    /// Control law and its gains.
    pub law: law::Settings,
    /// Trip limits.
    pub limits: Limits,
    /// Age of the measurements when the tick runs, in samples (0 or 1). With 1, the
    /// observer and the current loop predict across the delay.
    #[cfg_attr(feature = "serde", serde(default))]
    pub delay_ticks: u8,
    /// Reference shaping; `None` passes the set point through as a step.
    #[cfg_attr(feature = "serde", serde(default))]
    pub shaping: Option<shaping::Settings>,
    /// Fault detectors that need history (all off by default in files).
    #[cfg_attr(feature = "serde", serde(default))]
    pub monitors: Monitors,
}

impl Settings {
    /// The paper's actuator and law at `rate_hz` on a `vbus_v` supply, on the reference
    /// board, in the paper's printed convention (for reproducing the paper only: the
    /// product and the firmware run [`Actuator`]-derived settings in the physical one);
    /// observer bandwidth 2000 rad/s; current trip 16 A, just inside the board's +-16.5 A
    /// current channel (the paper's law asks for about 21 A at start-up: a reproduction of
    /// its example needs a wider channel and trip, as the simulator's paper scenario
    /// sets); bus window 0.5 to 1.25 times the supply; the sensor and coil detectors of
    /// the product, but no I^2 t (the paper's law asks for 21 A at start-up) and no
    /// tracking detector (its step response takes 0.4 s).
    #[cfg(feature = "paper")]
    #[must_use]
    pub fn paper(rate_hz: f32, vbus_v: f32) -> Self {
        let plant = Plant::paper();
        let sense = Calibration::board();
        Self {
            rate_hz,
            plant,
            sense,
            observer: observer::Settings {
                bandwidth_rad_s: 2_000.0,
                disturbance: false,
                model: observer::Model::Nominal,
                force_scaled_above_a: 0.0,
            },
            law: law::Settings::Paper(law::paper::Gains::paper()),
            limits: Limits::for_stroke(plant.stroke_m, 16.0, 0.5 * vbus_v, 1.25 * vbus_v),
            delay_ticks: 0,
            shaping: None,
            monitors: Monitors {
                thermal: None,
                stuck: Some(actuator::stuck_detector(&sense.position)),
                residual: Some(actuator::residual_detector(&sense.current, rate_hz)),
                tracking: None,
            },
        }
    }

    /// The product's default ([`Actuator::PRODUCT`], every setting derived from it) at
    /// `rate_hz` on a `vbus_v` supply: the practical law ([`law::practical`]) with one
    /// sample of measurement delay, an extended-state observer, reference shaping and every
    /// fault detector, in the physical convention.
    ///
    /// # Errors
    /// A rate or supply the derivation refuses, by name.
    pub fn practical(rate_hz: f32, vbus_v: f32) -> Result<Self, Error> {
        Actuator::PRODUCT
            .with_rate_hz(rate_hz)
            .with_supply_v(vbus_v)
            .settings()
    }

    /// Validates everything and builds the immutable configuration.
    ///
    /// # Errors
    /// The first invalid parameter, by name, with its value and the reason.
    pub fn build(&self) -> Result<Config, Error> {
        config::positive("rate_hz", self.rate_hz)?;
        let ts_s = config::sample_period(1.0 / self.rate_hz)?;
        self.plant.validate()?;
        self.sense.validate()?;
        self.limits.validate()?;
        Ok(Config {
            ts_s,
            observer: self.observer.build(&self.plant, ts_s, self.delay_ticks)?,
            law: self.law.build(&self.plant, ts_s, self.delay_ticks)?,
            shaping: match &self.shaping {
                Some(s) => Some(s.build(&self.plant, ts_s)?),
                None => None,
            },
            monitors: self
                .monitors
                .build(&self.plant, &self.sense, ts_s, self.delay_ticks)?,
            sense: self.sense,
            limits: self.limits,
            stroke_m: self.plant.stroke_m,
            max_modulation: bridge::max_modulation(self.rate_hz),
        })
    }
}

/// A validated controller configuration. Immutable; the tick only reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    ts_s: f32,
    sense: Calibration,
    observer: observer::Config,
    law: law::Config,
    shaping: Option<shaping::Config>,
    monitors: monitor::Config,
    limits: Limits,
    stroke_m: f32,
    /// The highest duty that keeps the current's sample clear of the switching edges
    /// ([`bridge::max_modulation`]).
    max_modulation: f32,
}

/// The controller's mutable state.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    /// Observer state.
    pub observer: observer::State,
    /// Law state.
    pub law: law::State,
    /// Latched fault and counters.
    pub supervisor: supervisor::State,
    /// History of the fault detectors.
    pub monitor: monitor::State,
    /// Reference-shaping state.
    pub shaping: shaping::State,
    /// Average voltage the bridge applied over the last period \[V\].
    pub u_prev_v: f32,
    /// Ticks since start (wrapping).
    pub ticks: u32,
    /// The inductance probe, when one runs.
    pub probe: Probe,
}

/// The inductance probe: a square wave of `+-amplitude_a` added to the law's desired
/// current for `ticks_left` ticks, switching every `half_ticks`, starting up (the
/// practical law follows it; the others do not use a desired current this way).
///
/// Where the loop holds the armature between the stops, the magnet's stiffness exceeds
/// the spring's on most actuators and no open-loop step can leave it there: the loop
/// keeps holding it, and the current loop steps the coil's current by `2 amplitude_a`
/// every half period, well faster than the armature can follow (the mean pull is that
/// of the hold). The flux the steps take, the voltage's integral less the resistive
/// drop, over the current's change is the inductance at the hold's position
/// (`hil_sim::identification::commissioning`). A stopped probe adds nothing, bit for bit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Probe {
    /// Half the step of the desired current \[A\].
    pub amplitude_a: f32,
    /// Ticks at each level (0: stopped).
    pub half_ticks: u16,
    /// Ticks the probe still runs.
    pub ticks_left: u32,
}

impl Probe {
    /// A probe of `cycles` cycles, `half_ticks` at each level, `+-amplitude_a`, started.
    #[must_use]
    pub fn new(amplitude_a: f32, half_ticks: u16, cycles: u16) -> Self {
        Self {
            amplitude_a,
            half_ticks,
            ticks_left: u32::from(half_ticks).saturating_mul(2 * u32::from(cycles)),
        }
    }

    /// What the probe adds to the desired current at this tick \[A\], and one tick on.
    fn next(&mut self) -> f32 {
        let Some(left) = self.ticks_left.checked_sub(1) else {
            return 0.0;
        };
        let Some(level) = left.checked_div(u32::from(self.half_ticks)) else {
            return 0.0;
        };
        self.ticks_left = left;
        if level & 1 == 1 {
            self.amplitude_a
        } else {
            -self.amplitude_a
        }
    }
}

/// What one tick did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Status {
    /// Latched fault (the bridge coasts while there is one).
    pub fault: Option<Fault>,
    /// Converted measurement (zero when the frame was implausible).
    pub measurement: Measurement,
    /// Observer estimate.
    pub estimate: Estimate,
    /// Reference used.
    pub reference: Reference,
    /// Law output (before saturation).
    pub output: law::Output,
    /// What the bridge was set to.
    pub drive: Drive,
}

impl Config {
    /// Sample period \[s\].
    #[must_use]
    pub const fn ts_s(&self) -> f32 {
        self.ts_s
    }

    /// The highest duty fraction that keeps the current's sample clear of the switching
    /// edges at this rate (the bridge snaps those above it: [`HBridge::apply_clear`]).
    #[must_use]
    pub const fn max_modulation(&self) -> f32 {
        self.max_modulation
    }

    /// Converter calibration.
    #[must_use]
    pub const fn sense(&self) -> &Calibration {
        &self.sense
    }

    /// Trip limits.
    #[must_use]
    pub const fn limits(&self) -> &Limits {
        &self.limits
    }

    /// The stroke the set point and the reference's start are clamped to \[m\].
    #[must_use]
    pub const fn stroke_m(&self) -> f32 {
        self.stroke_m
    }

    /// The law.
    #[must_use]
    pub const fn law(&self) -> &law::Config {
        &self.law
    }

    /// The observer.
    #[must_use]
    pub const fn observer(&self) -> &observer::Config {
        &self.observer
    }

    /// The reference shaping, if any.
    #[must_use]
    pub const fn shaping(&self) -> Option<&shaping::Config> {
        self.shaping.as_ref()
    }

    /// The fault detectors.
    #[must_use]
    pub const fn monitors(&self) -> &monitor::Config {
        &self.monitors
    }

    /// A fresh state for this configuration.
    #[must_use]
    pub fn initial_state(&self) -> State {
        State {
            observer: observer::State::default(),
            law: self.law.initial_state(),
            supervisor: supervisor::State::default(),
            monitor: monitor::State::default(),
            shaping: shaping::State::default(),
            u_prev_v: 0.0,
            ticks: 0,
            probe: Probe::default(),
        }
    }

    /// One control period from converter codes. Infallible and panic-free: an implausible
    /// frame, a limit violation, a non-finite value or a failed bridge operation latches a
    /// fault and leaves the bridge coasting.
    #[inline]
    pub fn tick<P: SetDutyCycle, O: OutputPin>(
        &self,
        state: &mut State,
        bridge: &mut HBridge<P, O>,
        frame: &Frame,
        setpoint_m: f32,
    ) -> Status {
        let measurement = self.sense.convert(frame);
        self.step(state, bridge, measurement, setpoint_m)
    }

    /// One control period from SI measurements (ideal sensors in a simulator). Same path
    /// as [`Config::tick`] after the conversion.
    #[inline]
    pub fn tick_measured<P: SetDutyCycle, O: OutputPin>(
        &self,
        state: &mut State,
        bridge: &mut HBridge<P, O>,
        measurement: &Measurement,
        setpoint_m: f32,
    ) -> Status {
        self.step(state, bridge, Ok(*measurement), setpoint_m)
    }

    /// Latches a fault detected outside the tick (for example an interrupt overrun seen by
    /// the firmware) and coasts the bridge.
    pub fn trip<P: SetDutyCycle, O: OutputPin>(
        &self,
        state: &mut State,
        bridge: &mut HBridge<P, O>,
        fault: Fault,
    ) -> Fault {
        let latched = state.supervisor.trip(fault);
        // Coast is already the outcome we want; a failing pin cannot make it safer.
        let _ = bridge.coast();
        latched
    }

    /// Clears a latched fault, stops an inductance probe and restarts the observer, the
    /// law and the detectors from scratch; fault counters and the coil's I^2 t (it is
    /// still warm) are kept. The next tick checks everything again before driving.
    pub fn rearm(&self, state: &mut State) {
        state.supervisor.clear();
        state.monitor.rearm();
        state.observer = observer::State::default();
        state.law = self.law.initial_state();
        state.shaping = shaping::State::default();
        state.u_prev_v = 0.0;
        state.probe = Probe::default();
    }

    fn step<P: SetDutyCycle, O: OutputPin>(
        &self,
        state: &mut State,
        bridge: &mut HBridge<P, O>,
        measurement: Result<Measurement, Fault>,
        setpoint_m: f32,
    ) -> Status {
        state.ticks = state.ticks.wrapping_add(1);
        let mut status = Status {
            fault: state.supervisor.latched(),
            ..Status::default()
        };
        if status.fault.is_some() {
            return self.safe(state, bridge, status);
        }
        let m = match measurement {
            Ok(m) => m,
            Err(fault) => {
                status.fault = Some(state.supervisor.trip(fault));
                return self.safe(state, bridge, status);
            }
        };
        status.measurement = m;
        if let Some(fault) = self.limits.check(&m) {
            status.fault = Some(state.supervisor.trip(fault));
            return self.safe(state, bridge, status);
        }
        if !setpoint_m.is_finite() {
            status.fault = Some(state.supervisor.trip(Fault::Setpoint));
            return self.safe(state, bridge, status);
        }
        let setpoint_m = math::clamp(setpoint_m, 0.0, self.stroke_m);
        status.reference = match &self.shaping {
            Some(shaping) => {
                if !state.shaping.is_primed() {
                    shaping.start(&mut state.shaping, math::clamp(m.x_m, 0.0, self.stroke_m));
                }
                shaping.step(&mut state.shaping, setpoint_m)
            }
            None => Reference::hold(setpoint_m),
        };

        status.estimate = self.observer.update(&mut state.observer, m.x_m, m.i_a);
        status.output = self.law.step(
            &mut state.law,
            &law::Input {
                x_m: status.estimate.x_m,
                v_mps: status.estimate.v_mps,
                i_a: m.i_a,
                vbus_v: m.vbus_v,
                disturbance_mps2: status.estimate.d_mps2,
                reference: status.reference,
                u_prev_v: state.u_prev_v,
                probe_a: state.probe.next(),
            },
        );
        if !(status.output.u_v.is_finite()
            && status.estimate.x_m.is_finite()
            && status.estimate.v_mps.is_finite()
            && status.estimate.d_mps2.is_finite())
        {
            status.fault = Some(state.supervisor.trip(Fault::NonFinite));
            return self.safe(state, bridge, status);
        }
        let seen = monitor::Inputs {
            x_m: m.x_m,
            i_a: m.i_a,
            r_m: status.reference.x_m,
            target_m: setpoint_m,
            v_mps: status.estimate.v_mps,
        };
        if let Some(fault) = self.monitors.check(&mut state.monitor, &seen) {
            status.fault = Some(state.supervisor.trip(fault));
            return self.safe(state, bridge, status);
        }
        // A reading that jumped beyond every admissible coil is a shorted coil or a
        // reading that stepped, and the next step tells which. Until it does, the bridge
        // applies zero volts: a short runs the current on by the same jump every period
        // the law keeps driving it, and the period until the verdict would carry it
        // past the trip. On a stepped reading the period costs the coil one period's
        // decay.
        let u_v = self.monitors.drive_v(&state.monitor, status.output.u_v);
        match bridge.apply_clear(u_v, m.vbus_v, self.max_modulation) {
            Ok(drive) => {
                status.drive = drive;
                state.u_prev_v = drive.u_v;
                self.monitors.record_drive(
                    &mut state.monitor,
                    drive.u_v,
                    drive.mode != bridge::Mode::Coast,
                );
            }
            Err(_) => {
                status.fault = Some(state.supervisor.trip(Fault::BridgeIo));
                return self.safe(state, bridge, status);
            }
        }
        status
    }

    fn safe<P: SetDutyCycle, O: OutputPin>(
        &self,
        state: &mut State,
        bridge: &mut HBridge<P, O>,
        mut status: Status,
    ) -> Status {
        if bridge.coast().is_err() {
            status.fault = Some(state.supervisor.trip(Fault::BridgeIo));
        }
        status.drive = Drive::default();
        state.u_prev_v = 0.0;
        self.monitors.record_drive(&mut state.monitor, 0.0, false);
        status
    }
}

#[cfg(test)]
mod properties;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::bridge::{Mode, NullPin, NullPwm, BOARD_MAX_DUTY};

    fn setup() -> (Config, State, HBridge<NullPwm, NullPin>) {
        let cfg = Settings::paper(20_000.0, 24.0).build().unwrap();
        let st = cfg.initial_state();
        let b = HBridge::new(NullPwm::new(BOARD_MAX_DUTY), NullPin(false), NullPin(false)).unwrap();
        (cfg, st, b)
    }

    fn meas(x_m: f32, i_a: f32) -> Measurement {
        Measurement {
            x_m,
            i_a,
            vbus_v: 24.0,
        }
    }

    #[test]
    fn drives_toward_the_target_and_saturates_at_the_bus() {
        let (cfg, mut st, mut b) = setup();
        let s = cfg.tick_measured(&mut st, &mut b, &meas(1e-3, 0.0), 3e-3);
        assert_eq!(s.fault, None);
        assert_eq!(s.drive.mode, Mode::Forward);
        assert_eq!(s.drive.duty, BOARD_MAX_DUTY);
        assert_eq!(s.drive.u_v, 24.0);
        assert!(
            s.output.u_v > 24.0,
            "the paper law asks for more than the bus"
        );
        // On target and at rest the law wants no current (z2 = 0): with 10 A in the coil it
        // reverses (a fresh start: a jump from 0 to 10 A in one period is itself a fault,
        // see the residual monitor).
        let mut st = cfg.initial_state();
        let s = cfg.tick_measured(&mut st, &mut b, &meas(3e-3, 10.0), 3e-3);
        assert_eq!(s.output.i_d_a, 0.0);
        assert_eq!(s.drive.mode, Mode::Reverse);
    }

    #[test]
    fn the_inductance_probe_steps_up_then_down_and_stops() {
        let mut p = Probe {
            amplitude_a: 0.25,
            half_ticks: 3,
            ticks_left: 12,
        };
        let seen: [f32; 14] = core::array::from_fn(|_| p.next());
        let (u, d) = (0.25, -0.25);
        assert_eq!(seen, [u, u, u, d, d, d, u, u, u, d, d, d, 0.0, 0.0]);
        let mut stopped = Probe { half_ticks: 0, ..p };
        stopped.ticks_left = 5;
        assert_eq!(stopped.next(), 0.0);
        // A re-arm stops a running probe.
        let (cfg, mut st, _) = setup();
        st.probe = Probe {
            amplitude_a: 0.25,
            half_ticks: 3,
            ticks_left: 12,
        };
        cfg.rearm(&mut st);
        assert_eq!(st.probe, Probe::default());
    }

    #[test]
    fn invalid_inputs_latch_a_fault_and_coast() {
        let cases = [
            (meas(f32::NAN, 0.0), 3e-3, Fault::NonFinite),
            (meas(1e-3, f32::INFINITY), 3e-3, Fault::NonFinite),
            (meas(9e-3, 0.0), 3e-3, Fault::PositionRange),
            (meas(1e-3, 31.0), 3e-3, Fault::OverCurrent),
            (
                Measurement {
                    vbus_v: 5.0,
                    ..meas(1e-3, 0.0)
                },
                3e-3,
                Fault::BusUnderVoltage,
            ),
            (meas(1e-3, 0.0), f32::NAN, Fault::Setpoint),
        ];
        for (m, sp, fault) in cases {
            let (cfg, mut st, mut b) = setup();
            // One good tick first so the bridge is enabled.
            cfg.tick_measured(&mut st, &mut b, &meas(1e-3, 0.0), 3e-3);
            assert_eq!(b.mode(), Mode::Forward);
            let s = cfg.tick_measured(&mut st, &mut b, &m, sp);
            assert_eq!(s.fault, Some(fault));
            assert_eq!(b.mode(), Mode::Coast);
            assert_eq!(s.drive, Drive::default());
            // Latched: good inputs do not restart the bridge.
            let s = cfg.tick_measured(&mut st, &mut b, &meas(1e-3, 0.0), 3e-3);
            assert_eq!(s.fault, Some(fault));
            assert_eq!(b.mode(), Mode::Coast);
            // Re-arm: driving again.
            cfg.rearm(&mut st);
            let s = cfg.tick_measured(&mut st, &mut b, &meas(1e-3, 0.0), 3e-3);
            assert_eq!(s.fault, None);
            assert_eq!(b.mode(), Mode::Forward);
            assert_eq!(st.supervisor.count(fault), 1);
        }
    }

    #[test]
    fn converter_rails_are_sensor_faults() {
        let (cfg, mut st, mut b) = setup();
        let good = cfg.sense().frame(&meas(1e-3, 0.0));
        let s = cfg.tick(&mut st, &mut b, &good, 3e-3);
        assert_eq!(s.fault, None);
        assert!((s.measurement.x_m - 1e-3).abs() < 1e-6);
        let s = cfg.tick(
            &mut st,
            &mut b,
            &Frame {
                current: 4095,
                ..good
            },
            3e-3,
        );
        assert_eq!(s.fault, Some(Fault::CurrentSensor));
        assert_eq!(b.mode(), Mode::Coast);
    }

    #[test]
    fn an_external_overrun_latches() {
        let (cfg, mut st, mut b) = setup();
        cfg.tick_measured(&mut st, &mut b, &meas(1e-3, 0.0), 3e-3);
        assert_eq!(cfg.trip(&mut st, &mut b, Fault::Overrun), Fault::Overrun);
        assert_eq!(b.mode(), Mode::Coast);
        let s = cfg.tick_measured(&mut st, &mut b, &meas(1e-3, 0.0), 3e-3);
        assert_eq!(s.fault, Some(Fault::Overrun));
    }

    #[test]
    fn set_points_are_limited_to_the_stroke() {
        let (cfg, mut st, mut b) = setup();
        let s = cfg.tick_measured(&mut st, &mut b, &meas(1e-3, 0.0), 9.0);
        assert_eq!(s.reference.x_m, 4e-3);
        let s = cfg.tick_measured(&mut st, &mut b, &meas(1e-3, 0.0), -1.0);
        assert_eq!(s.reference.x_m, 0.0);
    }

    #[test]
    fn bad_settings_are_refused_by_name() {
        let mut s = Settings::paper(20_000.0, 24.0);
        s.rate_hz = 0.0;
        assert_eq!(s.build().unwrap_err().param, "rate_hz");
        let mut s = Settings::paper(20_000.0, 24.0);
        s.rate_hz = -5.0;
        assert_eq!(s.build().unwrap_err().param, "rate_hz");
        // So slow that its period is not finite: still named as the rate.
        let mut s = Settings::paper(20_000.0, 24.0);
        s.rate_hz = 1e-39;
        assert_eq!(s.build().unwrap_err().param, "rate_hz");
        let mut s = Settings::paper(20_000.0, 24.0);
        s.law = law::Settings::Paper(law::paper::Gains {
            alpha2: 10.0,
            ..law::paper::Gains::paper()
        });
        assert_eq!(s.build().unwrap_err().param, "alpha2");
        let mut s = Settings::paper(20_000.0, 24.0);
        s.plant.bounds.s_hi_m2 = 0.5 * s.plant.bounds.s_lo_m2;
        assert_eq!(s.build().unwrap_err().param, "bounds.s_lo_m2");
    }
}
