//! The optional analog set point: a 0-10 V or 4-20 mA signal, scaled to the stroke and
//! filtered, as industrial proportional-valve drivers take it.
//!
//! The board converts the input on one more ADC channel, in the same injected sequence as
//! the control's three (the firmware's `board::ANALOG_CHANNEL`), once per tick:
//!
//! | source | input stage (the board's) | code to signal | signal to set point |
//! |---|---|---|---|
//! | `voltage_0_10v` | divider, 11 V at full scale | [`VOLTAGE_V_PER_CODE`] | 0 V -> 0, 10 V -> stroke |
//! | `current_4_20ma` | 150 ohm shunt, 22 mA at full scale | [`CURRENT_A_PER_CODE`] | 4 mA -> 0, 20 mA -> stroke |
//!
//! The scaled value is clamped to the stroke and low-pass filtered (first order, time
//! constant `setpoint.filter_s`); the set point follows the filtered value only when it
//! moves by more than [`BAND_CODES`] input codes' worth of stroke, so converter noise does
//! not replan a move every tick.
//!
//! **Broken wire.** A 4-20 mA loop carries current at zero: 3.6-21 mA is the live range
//! (NAMUR NE 43); below, the wire is open, above it is shorted. A reading outside that
//! window for [`BREAK_CONFIRM_S`] latches `Fault::AnalogWireBreak` while armed, and refuses
//! arming while disarmed. A 0-10 V input cannot tell a broken wire from 0 V: a broken wire
//! reads as the open end stop, where the spring holds the armature anyway.
//!
//! ```
//! use ema::device::analog::{Settings, Source, CURRENT_A_PER_CODE};
//! let cfg = Settings { source: Source::Current, filter_s: 0.0 }.build(4e-3, 50e-6).unwrap();
//! let mut st = Default::default();
//! // 12 mA: mid-stroke.
//! let code = (12e-3 / CURRENT_A_PER_CODE) as u16;
//! let r = cfg.step(&mut st, code);
//! assert!((r.setpoint_m - 2e-3).abs() < 3e-6);
//! assert_eq!(r.fault, None);
//! // 2 mA for 1 ms: an open loop.
//! let open = (2e-3 / CURRENT_A_PER_CODE) as u16;
//! let faults = (0..20).filter_map(|_| cfg.step(&mut st, open).fault).count();
//! assert_eq!(faults, 1);
//! ```

use serde::{Deserialize, Serialize};

use crate::control::config::{self, Error};
use crate::control::math;
use crate::control::sense::ADC_MAX_CODE;
use crate::control::supervisor::Fault;

/// Codes of the 12-bit converter.
const FULL_SCALE_CODES: f32 = 4096.0;
/// Volts at the input per converter code: an 11 V full scale (a 10 V signal reads 3724).
pub const VOLTAGE_V_PER_CODE: f32 = 11.0 / FULL_SCALE_CODES;
/// Amperes in the loop per converter code: a 150 ohm shunt into 3.3 V, 22 mA at full
/// scale (20 mA reads 3724).
pub const CURRENT_A_PER_CODE: f32 = 3.3 / 150.0 / FULL_SCALE_CODES;
/// Signal at the open end stop (`x = 0`) and its span to the closed one: 0-10 V.
pub const VOLTAGE_ZERO_V: f32 = 0.0;
/// Span of the voltage signal over the stroke \[V\].
pub const VOLTAGE_SPAN_V: f32 = 10.0;
/// Loop current at the open end stop \[A\].
pub const CURRENT_ZERO_A: f32 = 4e-3;
/// Span of the loop current over the stroke \[A\].
pub const CURRENT_SPAN_A: f32 = 16e-3;
/// Lowest loop current of a healthy 4-20 mA loop \[A\] (NAMUR NE 43).
pub const CURRENT_MIN_A: f32 = 3.6e-3;
/// Highest loop current of a healthy 4-20 mA loop \[A\].
pub const CURRENT_MAX_A: f32 = 21e-3;
/// How long the loop current must stay outside its window to be a broken wire \[s\]: a
/// millisecond, twenty ticks at 20 kHz, so one disturbed conversion is not.
pub const BREAK_CONFIRM_S: f32 = 1e-3;
/// Input codes the filtered value must move before the set point follows it.
pub const BAND_CODES: f32 = 4.0;
/// Longest filter time constant \[s\].
pub const FILTER_MAX_S: f32 = 1.0;

/// Where the set point comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub enum Source {
    /// From the link ([`crate::device::protocol::Command::Move`]).
    #[default]
    Link,
    /// From a 0-10 V input.
    Voltage,
    /// From a 4-20 mA loop.
    Current,
}

impl Source {
    /// The names of the choices, in choice order (`setpoint.source`).
    pub const NAMES: [&'static str; 3] = ["link", "voltage_0_10v", "current_4_20ma"];

    /// The choice's index.
    #[must_use]
    pub const fn index(self) -> u8 {
        match self {
            Source::Link => 0,
            Source::Voltage => 1,
            Source::Current => 2,
        }
    }

    /// The choice with index `i`.
    #[must_use]
    pub const fn from_index(i: u8) -> Option<Self> {
        match i {
            0 => Some(Source::Link),
            1 => Some(Source::Voltage),
            2 => Some(Source::Current),
            _ => None,
        }
    }
}

/// The analog set point's parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Settings {
    /// Where the set point comes from.
    pub source: Source,
    /// Time constant of the first-order filter on the input \[s\] (0: none).
    pub filter_s: f32,
}

impl Default for Settings {
    /// From the link; a 5 ms filter for when an analog source is chosen.
    fn default() -> Self {
        Self {
            source: Source::Link,
            filter_s: 5e-3,
        }
    }
}

impl Settings {
    /// Validates and builds for a stroke `stroke_m` and tick period `ts_s`.
    ///
    /// # Errors
    /// `setpoint.filter_s` outside `[0, 1]` s.
    pub fn build(&self, stroke_m: f32, ts_s: f32) -> Result<Config, Error> {
        config::within("setpoint.filter_s", self.filter_s, 0.0, FILTER_MAX_S)?;
        config::positive("setpoint.stroke_m", stroke_m)?;
        config::sample_period(ts_s)?;
        // Code -> metre: x = (code * per_code - zero) / span * stroke.
        let (per_code, zero, span) = match self.source {
            Source::Voltage | Source::Link => (VOLTAGE_V_PER_CODE, VOLTAGE_ZERO_V, VOLTAGE_SPAN_V),
            Source::Current => (CURRENT_A_PER_CODE, CURRENT_ZERO_A, CURRENT_SPAN_A),
        };
        let m_per_code = per_code / span * stroke_m;
        let (lo, hi) = if self.source == Source::Current {
            (
                code_at(CURRENT_MIN_A / CURRENT_A_PER_CODE, true),
                code_at(CURRENT_MAX_A / CURRENT_A_PER_CODE, false),
            )
        } else {
            (0, ADC_MAX_CODE)
        };
        // Ticks that make BREAK_CONFIRM_S, at least one.
        let confirm = math::max(1.0, BREAK_CONFIRM_S / ts_s + 0.5);
        Ok(Config {
            source: self.source,
            m_per_code,
            zero_m: zero / span * stroke_m,
            stroke_m,
            gain: ts_s / (self.filter_s + ts_s),
            band_m: BAND_CODES * m_per_code,
            lo_code: lo,
            hi_code: hi,
            confirm_ticks: if confirm < 60_000.0 {
                // In [1, 60000): exact.
                #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let c = confirm as u16;
                c
            } else {
                60_000
            },
        })
    }
}

/// The code nearest `x` codes, rounded inward (`up`: towards higher codes) so that the
/// window never admits a current outside it.
fn code_at(x: f32, up: bool) -> u16 {
    let c = if up { x + 0.999 } else { x };
    if c <= 0.0 {
        0
    } else if c >= f32::from(ADC_MAX_CODE) {
        ADC_MAX_CODE
    } else {
        // In (0, 4095): the truncation is the intended rounding.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let k = c as u16;
        k
    }
}

/// A validated analog input.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    source: Source,
    m_per_code: f32,
    zero_m: f32,
    stroke_m: f32,
    gain: f32,
    band_m: f32,
    lo_code: u16,
    hi_code: u16,
    confirm_ticks: u16,
}

/// The filter and the wire check's memory.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    filtered_m: f32,
    setpoint_m: f32,
    outside: u16,
    primed: bool,
}

/// One reading.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reading {
    /// The set point the input asks for \[m\].
    pub setpoint_m: f32,
    /// The filtered input, scaled \[m\].
    pub filtered_m: f32,
    /// `Fault::AnalogWireBreak` at the tick the loop has been outside its window long
    /// enough, and at every tick after while it stays outside.
    pub fault: Option<Fault>,
}

impl Config {
    /// Where the set point comes from.
    #[must_use]
    pub const fn source(&self) -> Source {
        self.source
    }

    /// Takes one conversion.
    #[inline]
    pub fn step(&self, st: &mut State, code: u16) -> Reading {
        let x = math::clamp(
            f32::from(code) * self.m_per_code - self.zero_m,
            0.0,
            self.stroke_m,
        );
        if st.primed {
            st.filtered_m += self.gain * (x - st.filtered_m);
        } else {
            st.filtered_m = x;
            st.setpoint_m = x;
            st.primed = true;
        }
        let d = st.filtered_m - st.setpoint_m;
        if d > self.band_m || d < -self.band_m {
            st.setpoint_m = st.filtered_m;
        }
        let outside = code < self.lo_code || code > self.hi_code;
        st.outside = if outside {
            st.outside.saturating_add(1)
        } else {
            0
        };
        Reading {
            setpoint_m: st.setpoint_m,
            filtered_m: st.filtered_m,
            fault: (st.outside >= self.confirm_ticks).then_some(Fault::AnalogWireBreak),
        }
    }

    /// The window of healthy codes `[lo, hi]`.
    #[must_use]
    pub const fn window(&self) -> (u16, u16) {
        (self.lo_code, self.hi_code)
    }
}

#[cfg(test)]
// Codes from volts and milliamps: small, positive, rounded on purpose.
#[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
mod tests {
    use super::*;

    const TS: f32 = 50e-6;

    fn cfg(source: Source, filter_s: f32) -> Config {
        Settings { source, filter_s }.build(4e-3, TS).unwrap()
    }

    #[test]
    fn both_signals_scale_to_the_stroke() {
        let v = cfg(Source::Voltage, 0.0);
        for (volts, x) in [(0.0, 0.0), (5.0, 2e-3), (10.0, 4e-3), (10.9, 4e-3)] {
            let code = (volts / VOLTAGE_V_PER_CODE + 0.5) as u16;
            let r = v.step(&mut State::default(), code);
            assert!(
                (r.setpoint_m - x).abs() < 2e-6,
                "{volts} V: {}",
                r.setpoint_m
            );
            assert_eq!(r.fault, None);
        }
        let c = cfg(Source::Current, 0.0);
        for (ma, x) in [(4.0, 0.0), (8.0, 1e-3), (20.0, 4e-3)] {
            let code = (ma * 1e-3 / CURRENT_A_PER_CODE + 0.5) as u16;
            let r = c.step(&mut State::default(), code);
            assert!((r.setpoint_m - x).abs() < 2e-6, "{ma} mA: {}", r.setpoint_m);
        }
    }

    #[test]
    fn the_loop_window_is_3_6_to_21_ma() {
        let c = cfg(Source::Current, 0.0);
        let (lo, hi) = c.window();
        assert!(f32::from(lo) * CURRENT_A_PER_CODE >= CURRENT_MIN_A);
        assert!(f32::from(lo - 1) * CURRENT_A_PER_CODE < CURRENT_MIN_A);
        assert!(f32::from(hi) * CURRENT_A_PER_CODE <= CURRENT_MAX_A);
        assert!(f32::from(hi + 1) * CURRENT_A_PER_CODE > CURRENT_MAX_A);
        assert_eq!((lo, hi), (671, 3909));
        // A 0-10 V input has no window.
        assert_eq!(cfg(Source::Voltage, 0.0).window(), (0, 4095));
    }

    #[test]
    fn a_broken_wire_latches_after_a_millisecond_and_not_before() {
        let c = cfg(Source::Current, 5e-3);
        let mut st = State::default();
        let ok = (12e-3 / CURRENT_A_PER_CODE) as u16;
        for _ in 0..100 {
            assert_eq!(c.step(&mut st, ok).fault, None);
        }
        // 19 ticks outside, one inside: no fault.
        for _ in 0..19 {
            assert_eq!(c.step(&mut st, 0).fault, None);
        }
        assert_eq!(c.step(&mut st, ok).fault, None);
        // 20 in a row (1 ms at 20 kHz): the fault.
        let seen: usize = (0..20)
            .filter(|_| c.step(&mut st, 0).fault.is_some())
            .count();
        assert_eq!(seen, 1);
        // Shorted (above 21 mA) too.
        let mut st = State::default();
        let short = (21.5e-3 / CURRENT_A_PER_CODE) as u16;
        let first = (1..=40).find(|_| c.step(&mut st, short).fault.is_some());
        assert_eq!(first, Some(20));
    }

    #[test]
    fn the_filter_and_the_band_keep_noise_from_moving_the_set_point() {
        let c = cfg(Source::Voltage, 5e-3);
        let mut st = State::default();
        let mid = (5.0 / VOLTAGE_V_PER_CODE) as u16;
        let first = c.step(&mut st, mid).setpoint_m;
        // +-2 codes of noise for 1000 ticks: the set point never moves.
        for k in 0..1000u16 {
            let r = c.step(&mut st, mid - 2 + (k * 7) % 5);
            assert_eq!(r.setpoint_m, first);
        }
        // A 1 V step: the filtered value reaches 63 % after one time constant (100 ticks).
        let step = mid + (1.0 / VOLTAGE_V_PER_CODE) as u16;
        let mut r = Reading::default();
        for _ in 0..100 {
            r = c.step(&mut st, step);
        }
        let rise = (r.filtered_m - first) / 0.4e-3;
        assert!((rise - 0.632).abs() < 0.01, "{rise}");
        assert!(r.setpoint_m > first);
    }

    #[test]
    fn a_bad_filter_is_refused_by_name() {
        let e = Settings {
            source: Source::Voltage,
            filter_s: -1.0,
        }
        .build(4e-3, TS)
        .unwrap_err();
        assert_eq!(e.param, "setpoint.filter_s");
        let e = Settings {
            source: Source::Voltage,
            filter_s: f32::NAN,
        }
        .build(4e-3, TS)
        .unwrap_err();
        assert_eq!(e.param, "setpoint.filter_s");
    }
}
