//! Limits, fault detection, latched fault codes and the safe state.
//!
//! Every check runs inside the tick. The first fault latches: from then on the tick only
//! keeps the bridge in its safe state (coast: all switches open, the coil current decays
//! through the freewheel diodes against the bus) until the application re-arms explicitly
//! ([`crate::control::Config::rearm`]). Each fault code also has a counter that survives
//! re-arming, for diagnostics.

use core::fmt;

use crate::control::config::{self, Error};
use crate::control::sense::Measurement;

pub mod monitor;
pub use monitor::Monitors;

/// The product's requirement: every fault is named within this time of becoming
/// observable \[s\]. The fault detectors' windows are sized from it
/// ([`crate::control::actuator::residual_detector`]).
pub const DEADLINE_S: f32 = 1e-3;

/// Fault codes. The numeric value is stable (logged, stored, compared in golden traces).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[repr(u8)]
pub enum Fault {
    /// Position-sensor code on an ADC rail: sensor open or shorted.
    PositionSensor = 1,
    /// Current-sensor code on an ADC rail: sensor open or shorted.
    CurrentSensor = 2,
    /// Bus-voltage code on the upper rail: divider open.
    VbusSensor = 3,
    /// A non-finite value in a measurement, an estimate or a command.
    NonFinite = 4,
    /// Position outside the stroke (plus margin).
    PositionRange = 5,
    /// Coil current above the instantaneous trip level.
    OverCurrent = 6,
    /// Coil current above its continuous rating for too long (I^2 t).
    OverCurrentI2t = 7,
    /// Bus voltage below the minimum.
    BusUnderVoltage = 8,
    /// Bus voltage above the maximum.
    BusOverVoltage = 9,
    /// Position reading does not change while the current (force) does.
    PositionStuck = 10,
    /// The current changes less than any admissible coil would under the applied voltage,
    /// with a non-zero reading: current sensor stuck.
    CurrentStuck = 11,
    /// The current reading stepped by more than any admissible coil allows in one period:
    /// current-sensor offset step (or a glitch).
    CurrentOffset = 12,
    /// Position error too large for too long.
    Tracking = 13,
    /// Set point not finite.
    Setpoint = 14,
    /// The tick was still running when the next one was due.
    Overrun = 15,
    /// A PWM or pin operation of the bridge failed.
    BridgeIo = 16,
    /// Voltage applied, current stays near zero: coil (or its wiring) open.
    CoilOpen = 17,
    /// The current rises far more than any admissible coil allows: shorted turns (the
    /// resistance or the inductance far below its bound).
    CoilShort = 18,
    /// The coil responds outside what the configured bounds admit, moderately: the plant
    /// is not the one the controller was designed for.
    ModelBounds = 19,
    /// The bridge's hardware protection switched it off without software: the driver's
    /// fault output or the comparator on the current shunt pulled the PWM timer's break
    /// input (over-current, driver over-temperature or under-voltage).
    HardwareTrip = 20,
    /// The 4-20 mA set-point loop reads outside 3.6-21 mA for a millisecond: a broken or
    /// shorted wire (only with the analog set point, `setpoint.source = current_4_20ma`).
    AnalogWireBreak = 21,
    /// The host fell silent for longer than `link.timeout_s` while the board drove the
    /// coil for it ([`crate::device::liveness`]).
    LinkTimeout = 22,
    /// The main loop stopped checking in: the link is not served and the watchdogs are no
    /// longer fed ([`crate::device::liveness`]).
    MainLoopStalled = 23,
}

/// Number of fault codes (codes run `1..=FAULT_COUNT`).
pub const FAULT_COUNT: usize = 23;

impl Fault {
    /// Raised by the detectors that run behind the law ([`monitor`]): a tick that ends
    /// with one of these (or with none) has passed sense, the limits and the law.
    #[must_use]
    pub const fn from_detectors(self) -> bool {
        matches!(
            self,
            Fault::OverCurrentI2t
                | Fault::PositionStuck
                | Fault::CurrentStuck
                | Fault::CurrentOffset
                | Fault::Tracking
                | Fault::CoilOpen
                | Fault::CoilShort
                | Fault::ModelBounds
        )
    }

    /// Every fault, in code order.
    pub const ALL: [Fault; FAULT_COUNT] = [
        Fault::PositionSensor,
        Fault::CurrentSensor,
        Fault::VbusSensor,
        Fault::NonFinite,
        Fault::PositionRange,
        Fault::OverCurrent,
        Fault::OverCurrentI2t,
        Fault::BusUnderVoltage,
        Fault::BusOverVoltage,
        Fault::PositionStuck,
        Fault::CurrentStuck,
        Fault::CurrentOffset,
        Fault::Tracking,
        Fault::Setpoint,
        Fault::Overrun,
        Fault::BridgeIo,
        Fault::CoilOpen,
        Fault::CoilShort,
        Fault::ModelBounds,
        Fault::HardwareTrip,
        Fault::AnalogWireBreak,
        Fault::LinkTimeout,
        Fault::MainLoopStalled,
    ];

    /// The stable numeric code.
    #[must_use]
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The fault with numeric code `code`, if any.
    #[must_use]
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.iter().copied().find(|f| f.code() == code)
    }

    /// Short stable name (`snake_case`), as in logs and configuration files.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Fault::PositionSensor => "position_sensor",
            Fault::CurrentSensor => "current_sensor",
            Fault::VbusSensor => "vbus_sensor",
            Fault::NonFinite => "non_finite",
            Fault::PositionRange => "position_range",
            Fault::OverCurrent => "over_current",
            Fault::OverCurrentI2t => "over_current_i2t",
            Fault::BusUnderVoltage => "bus_under_voltage",
            Fault::BusOverVoltage => "bus_over_voltage",
            Fault::PositionStuck => "position_stuck",
            Fault::CurrentStuck => "current_stuck",
            Fault::CurrentOffset => "current_offset",
            Fault::Tracking => "tracking",
            Fault::Setpoint => "setpoint",
            Fault::Overrun => "overrun",
            Fault::BridgeIo => "bridge_io",
            Fault::CoilOpen => "coil_open",
            Fault::CoilShort => "coil_short",
            Fault::ModelBounds => "model_bounds",
            Fault::HardwareTrip => "hardware_trip",
            Fault::AnalogWireBreak => "analog_wire_break",
            Fault::LinkTimeout => "link_timeout",
            Fault::MainLoopStalled => "main_loop_stalled",
        }
    }

    fn index(self) -> usize {
        usize::from(self.code().saturating_sub(1))
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (code {})", self.name(), self.code())
    }
}

/// Trip limits.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Limits {
    /// Instantaneous over-current trip level \[A\].
    pub current_trip_a: f32,
    /// Lowest plausible position \[m\].
    pub position_min_m: f32,
    /// Highest plausible position \[m\].
    pub position_max_m: f32,
    /// Bus under-voltage trip level \[V\].
    pub vbus_min_v: f32,
    /// Bus over-voltage trip level \[V\].
    pub vbus_max_v: f32,
}

impl Limits {
    /// Limits for a stroke `0..=stroke_m`: position margin 10 % of the stroke, current trip
    /// `current_trip_a`, bus window `vbus_min_v..=vbus_max_v`.
    #[must_use]
    pub fn for_stroke(
        stroke_m: f32,
        current_trip_a: f32,
        vbus_min_v: f32,
        vbus_max_v: f32,
    ) -> Self {
        Self {
            current_trip_a,
            position_min_m: -0.1 * stroke_m,
            position_max_m: 1.1 * stroke_m,
            vbus_min_v,
            vbus_max_v,
        }
    }

    /// Checks that every limit is finite and the windows are ordered.
    ///
    /// # Errors
    /// The first bad limit, by name.
    pub fn validate(&self) -> Result<(), Error> {
        config::positive("limits.current_trip_a", self.current_trip_a)?;
        config::finite("limits.position_min_m", self.position_min_m)?;
        config::finite("limits.position_max_m", self.position_max_m)?;
        config::ordered(
            "limits.position_min_m",
            self.position_min_m,
            "limits.position_max_m",
            self.position_max_m,
        )?;
        config::positive("limits.vbus_min_v", self.vbus_min_v)?;
        config::finite("limits.vbus_max_v", self.vbus_max_v)?;
        config::ordered(
            "limits.vbus_min_v",
            self.vbus_min_v,
            "limits.vbus_max_v",
            self.vbus_max_v,
        )
    }

    /// The first limit a measurement violates, if any. Non-finite values are caught here
    /// too (every comparison with `NaN` is false, so they are tested explicitly first).
    #[inline]
    #[must_use]
    pub fn check(&self, m: &Measurement) -> Option<Fault> {
        if !(m.x_m.is_finite() && m.i_a.is_finite() && m.vbus_v.is_finite()) {
            return Some(Fault::NonFinite);
        }
        if m.x_m < self.position_min_m || m.x_m > self.position_max_m {
            return Some(Fault::PositionRange);
        }
        if m.i_a.abs() > self.current_trip_a {
            return Some(Fault::OverCurrent);
        }
        if m.vbus_v < self.vbus_min_v {
            return Some(Fault::BusUnderVoltage);
        }
        if m.vbus_v > self.vbus_max_v {
            return Some(Fault::BusOverVoltage);
        }
        None
    }
}

/// Latched fault and per-fault counters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    latched: Option<Fault>,
    counts: [u16; FAULT_COUNT],
}

impl State {
    /// The latched fault, if any.
    #[inline]
    #[must_use]
    pub const fn latched(&self) -> Option<Fault> {
        self.latched
    }

    /// Latches `fault` unless one is already latched (the first cause is kept) and counts
    /// it. Returns the latched fault.
    #[inline]
    pub fn trip(&mut self, fault: Fault) -> Fault {
        match self.latched {
            Some(first) => first,
            None => {
                self.note(fault);
                self.latched = Some(fault);
                fault
            }
        }
    }

    /// Counts `fault` without latching it: an event the board reacts to without
    /// stopping (a link timeout when `link.on_timeout = hold`).
    pub fn note(&mut self, fault: Fault) {
        if let Some(c) = self.counts.get_mut(fault.index()) {
            *c = c.saturating_add(1);
        }
    }

    /// How many times `fault` has latched (or been noted) since power-up (saturating).
    #[must_use]
    pub fn count(&self, fault: Fault) -> u16 {
        self.counts.get(fault.index()).copied().unwrap_or(0)
    }

    /// Clears the latch; counters are kept.
    pub fn clear(&mut self) {
        self.latched = None;
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    fn limits() -> Limits {
        Limits::for_stroke(4e-3, 13.2, 10.0, 60.0)
    }

    fn m(x_m: f32, i_a: f32, vbus_v: f32) -> Measurement {
        Measurement { x_m, i_a, vbus_v }
    }

    #[test]
    fn every_limit_trips_with_its_code() {
        let l = limits();
        l.validate().unwrap();
        assert_eq!(l.check(&m(2e-3, 6.0, 24.0)), None);
        assert_eq!(l.check(&m(5e-3, 6.0, 24.0)), Some(Fault::PositionRange));
        assert_eq!(l.check(&m(-1e-3, 6.0, 24.0)), Some(Fault::PositionRange));
        assert_eq!(l.check(&m(2e-3, 13.3, 24.0)), Some(Fault::OverCurrent));
        assert_eq!(l.check(&m(2e-3, -13.3, 24.0)), Some(Fault::OverCurrent));
        assert_eq!(l.check(&m(2e-3, 6.0, 9.0)), Some(Fault::BusUnderVoltage));
        assert_eq!(l.check(&m(2e-3, 6.0, 61.0)), Some(Fault::BusOverVoltage));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(l.check(&m(bad, 6.0, 24.0)), Some(Fault::NonFinite));
            assert_eq!(l.check(&m(2e-3, bad, 24.0)), Some(Fault::NonFinite));
            assert_eq!(l.check(&m(2e-3, 6.0, bad)), Some(Fault::NonFinite));
        }
    }

    #[test]
    fn the_first_fault_latches_and_is_counted() {
        let mut s = State::default();
        assert_eq!(s.trip(Fault::OverCurrent), Fault::OverCurrent);
        assert_eq!(s.trip(Fault::NonFinite), Fault::OverCurrent);
        assert_eq!(s.latched(), Some(Fault::OverCurrent));
        assert_eq!(s.count(Fault::OverCurrent), 1);
        assert_eq!(s.count(Fault::NonFinite), 0);
        s.clear();
        assert_eq!(s.latched(), None);
        s.trip(Fault::OverCurrent);
        assert_eq!(s.count(Fault::OverCurrent), 2);
        // Noted: counted, not latched.
        s.clear();
        s.note(Fault::LinkTimeout);
        assert_eq!(s.latched(), None);
        assert_eq!(s.count(Fault::LinkTimeout), 1);
    }

    #[test]
    fn codes_are_stable_and_named() {
        for (k, f) in Fault::ALL.iter().enumerate() {
            assert_eq!(usize::from(f.code()), k + 1);
            assert_eq!(Fault::from_code(f.code()), Some(*f));
        }
        assert_eq!(Fault::from_code(0), None);
        assert_eq!(Fault::from_code(24), None);
        assert_eq!(
            Fault::MainLoopStalled.to_string(),
            "main_loop_stalled (code 23)"
        );
        assert_eq!(Fault::OverCurrent.to_string(), "over_current (code 6)");
        assert_eq!(Fault::HardwareTrip.to_string(), "hardware_trip (code 20)");
        // Names are unique (logs and files name faults by them).
        for (k, f) in Fault::ALL.iter().enumerate() {
            for g in &Fault::ALL[k + 1..] {
                assert_ne!(f.name(), g.name());
            }
        }
    }

    #[test]
    fn bad_limits_are_named() {
        let mut l = limits();
        l.vbus_min_v = 70.0;
        assert_eq!(l.validate().unwrap_err().param, "limits.vbus_min_v");
        let mut l = limits();
        l.current_trip_a = f32::NAN;
        assert_eq!(l.validate().unwrap_err().param, "limits.current_trip_a");
    }
}
