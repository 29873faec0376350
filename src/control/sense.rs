//! Raw ADC codes to SI measurements, with plausibility.
//!
//! The converters are 12-bit (codes `0..=4095`). Every channel maps linearly,
//! `value = (code - offset_code) * scale`, and has a plausible code window: a code outside
//! it is a broken sensor (open or shorted input sits on an ADC rail), not a measurement.
//!
//! The hardware constants of the reference board are here, one per fact, with units:
//! [`POSITION_ZERO_CODE`], [`POSITION_M_PER_CODE`], [`CURRENT_ZERO_CODE`],
//! [`CURRENT_A_PER_CODE`], [`VBUS_V_PER_CODE`], [`RAIL_MARGIN_CODES`],
//! [`NOISE_RMS_CODES`].

use crate::control::config::{self, Error};
use crate::control::supervisor::Fault;

/// Largest code of the 12-bit converters.
pub const ADC_MAX_CODE: u16 = 4095;

/// Position sensor: code at `x1 = 0` (5 % of full scale; the sensor's output spans 5-95 %
/// of the ADC range over the 4 mm stroke, so a rail is never a valid position).
pub const POSITION_ZERO_CODE: f32 = 204.8;
/// Position sensor: metres per code (4 mm over 90 % of 4096 codes, 1.085 um).
pub const POSITION_M_PER_CODE: f32 = 4.0e-3 / (0.9 * 4096.0);
/// Current sensor: code at 0 A (bidirectional, mid-scale). Measured at start-up with the
/// bridge off by the firmware, which replaces this nominal value.
pub const CURRENT_ZERO_CODE: f32 = 2048.0;
/// Current sensor: amperes per code (+-16.5 A full scale, 8.06 mA).
pub const CURRENT_A_PER_CODE: f32 = 16.5 / 2048.0;
/// Bus voltage divider: volts per code (72.6 V full scale, 22:1 into 3.3 V).
pub const VBUS_V_PER_CODE: f32 = 72.6 / 4096.0;
/// Codes this close to either rail mean an open or shorted sensor (1 % of full scale).
pub const RAIL_MARGIN_CODES: u16 = 41;
/// Converter noise of every channel, RMS \[code\]: what the fault detectors' noise
/// allowances are built from (`ema::control::actuator`), and what the simulator's typical
/// converter adds.
pub const NOISE_RMS_CODES: f32 = 1.5;

/// One set of simultaneous conversions, as read from the ADC.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Frame {
    /// Position sensor code.
    pub position: u16,
    /// Coil-current sensor code.
    pub current: u16,
    /// Bus-voltage divider code.
    pub vbus: u16,
}

/// Measurements in SI units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Measurement {
    /// Position `x1` \[m\].
    pub x_m: f32,
    /// Coil current `x3` \[A\].
    pub i_a: f32,
    /// Bus voltage \[V\].
    pub vbus_v: f32,
}

/// Linear calibration and plausible window of one converter channel.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Channel {
    /// Code that reads as zero \[code\].
    pub offset_code: f32,
    /// SI units per code.
    pub scale: f32,
    /// Smallest plausible code.
    pub min_code: u16,
    /// Largest plausible code.
    pub max_code: u16,
}

impl Channel {
    /// The SI value of `code`.
    #[inline]
    #[must_use]
    pub fn value(&self, code: u16) -> f32 {
        (f32::from(code) - self.offset_code) * self.scale
    }

    /// `true` when `code` is inside the plausible window.
    #[inline]
    #[must_use]
    pub const fn plausible(&self, code: u16) -> bool {
        code >= self.min_code && code <= self.max_code
    }

    /// The code that reads as `value` (nearest, limited to the converter range): what an
    /// ideal converter would return. Used by simulators and tests.
    #[must_use]
    pub fn code(&self, value: f32) -> u16 {
        let c = value / self.scale + self.offset_code + 0.5;
        if c.is_nan() || c <= 0.0 {
            0
        } else if c >= f32::from(ADC_MAX_CODE) {
            ADC_MAX_CODE
        } else {
            // In (0, 4095): the truncation is the intended rounding.
            #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let code = c as u16;
            code
        }
    }

    fn validate(
        &self,
        name: &'static str,
        scale_name: &'static str,
        min_name: &'static str,
        max_name: &'static str,
    ) -> Result<(), Error> {
        config::within(name, self.offset_code, 0.0, f32::from(ADC_MAX_CODE))?;
        config::finite(scale_name, self.scale)?;
        if self.scale == 0.0 {
            return Err(Error {
                param: scale_name,
                value: self.scale,
                reason: config::Reason::NotPositive,
            });
        }
        config::ordered(
            min_name,
            f32::from(self.min_code),
            max_name,
            f32::from(self.max_code),
        )
    }
}

/// The position sensor's own gain and offset, as a commissioning measures them at the
/// two end stops against the calibration an actuator file gives
/// ([`crate::control::actuator::Actuator::calibration`]).
///
/// A sensor reads `x (1 + e) + o` where the file's calibration expects `x`: a gain error
/// `e` and an offset `o`. With the armature at the open stop (`x = 0`) it reads `o`, at the
/// closed stop (`x` the stroke) `stroke (1 + e) + o`: the two readings give both, and the
/// corrected channel reads the true position at both stops and, the sensor being linear,
/// between them. The file's calibration is [`PositionCorrection::NONE`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[serde(deny_unknown_fields)]
pub struct PositionCorrection {
    /// The sensor's span between the stops over the stroke, `1 + e` \[-\].
    pub gain: f32,
    /// Its reading at the open stop, in the converter's codes \[code\].
    pub offset_codes: f32,
}

impl PositionCorrection {
    /// No correction: the file's calibration.
    pub const NONE: Self = Self {
        gain: 1.0,
        offset_codes: 0.0,
    };

    /// The correction from the mean readings at the open and the closed stop \[m\], taken
    /// with a channel of `scale` metres per code, for a stroke of `stroke_m`.
    #[must_use]
    pub fn from_stops(open_m: f32, closed_m: f32, stroke_m: f32, scale: f32) -> Self {
        Self {
            gain: (closed_m - open_m) / stroke_m,
            offset_codes: open_m / scale,
        }
    }
}

impl Default for PositionCorrection {
    fn default() -> Self {
        Self::NONE
    }
}

impl Channel {
    /// The channel with a sensor's measured gain and offset taken out: reads `x` where the
    /// sensor reads `x (1 + e) + o`.
    #[must_use]
    pub fn corrected(mut self, c: &PositionCorrection) -> Self {
        self.offset_code += c.offset_codes;
        self.scale /= c.gain;
        self
    }
}

/// Calibration of the three channels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Calibration {
    /// Position channel, metres.
    pub position: Channel,
    /// Coil-current channel, amperes.
    pub current: Channel,
    /// Bus-voltage channel, volts.
    pub vbus: Channel,
}

impl Calibration {
    /// The reference board (constants at the top of this module).
    #[must_use]
    pub const fn board() -> Self {
        let window_lo = RAIL_MARGIN_CODES;
        let window_hi = ADC_MAX_CODE - RAIL_MARGIN_CODES;
        Self {
            position: Channel {
                offset_code: POSITION_ZERO_CODE,
                scale: POSITION_M_PER_CODE,
                min_code: window_lo,
                max_code: window_hi,
            },
            current: Channel {
                offset_code: CURRENT_ZERO_CODE,
                scale: CURRENT_A_PER_CODE,
                min_code: window_lo,
                max_code: window_hi,
            },
            vbus: Channel {
                offset_code: 0.0,
                scale: VBUS_V_PER_CODE,
                // A bus reading of 0 is a real (dead) bus, caught as under-voltage.
                min_code: 0,
                max_code: window_hi,
            },
        }
    }

    /// The board with the current-sensor zero replaced by a measured offset \[code\].
    ///
    /// # Errors
    /// An offset that is not finite or outside the converter range.
    pub fn with_current_zero(mut self, offset_code: f32) -> Result<Self, Error> {
        config::within(
            "sense.current.offset_code",
            offset_code,
            0.0,
            f32::from(ADC_MAX_CODE),
        )?;
        self.current.offset_code = offset_code;
        Ok(self)
    }

    /// Checks every channel.
    ///
    /// # Errors
    /// The first bad field, by name.
    pub fn validate(&self) -> Result<(), Error> {
        self.position.validate(
            "sense.position.offset_code",
            "sense.position.scale",
            "sense.position.min_code",
            "sense.position.max_code",
        )?;
        self.current.validate(
            "sense.current.offset_code",
            "sense.current.scale",
            "sense.current.min_code",
            "sense.current.max_code",
        )?;
        self.vbus.validate(
            "sense.vbus.offset_code",
            "sense.vbus.scale",
            "sense.vbus.min_code",
            "sense.vbus.max_code",
        )
    }

    /// Converts a frame, or names the first implausible channel.
    ///
    /// # Errors
    /// [`Fault::PositionSensor`], [`Fault::CurrentSensor`] or [`Fault::VbusSensor`] when
    /// the code sits outside its plausible window (open or shorted sensor).
    #[inline]
    pub fn convert(&self, frame: &Frame) -> Result<Measurement, Fault> {
        if !self.position.plausible(frame.position) {
            return Err(Fault::PositionSensor);
        }
        if !self.current.plausible(frame.current) {
            return Err(Fault::CurrentSensor);
        }
        if !self.vbus.plausible(frame.vbus) {
            return Err(Fault::VbusSensor);
        }
        Ok(Measurement {
            x_m: self.position.value(frame.position),
            i_a: self.current.value(frame.current),
            vbus_v: self.vbus.value(frame.vbus),
        })
    }

    /// The frame an ideal converter would return for `m` (nearest codes).
    #[must_use]
    pub fn frame(&self, m: &Measurement) -> Frame {
        Frame {
            position: self.position.code(m.x_m),
            current: self.current.code(m.i_a),
            vbus: self.vbus.code(m.vbus_v),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_maps_the_stroke_inside_the_plausible_window() {
        let cal = Calibration::board();
        cal.validate().unwrap();
        let lo = cal.position.code(0.0);
        let hi = cal.position.code(4e-3);
        assert_eq!((lo, hi), (205, 3891));
        assert!(cal.position.plausible(lo) && cal.position.plausible(hi));
        assert!((cal.position.value(hi) - 4e-3).abs() < 1e-6);
        assert!((POSITION_M_PER_CODE - 1.085e-6).abs() < 1e-9);
    }

    #[test]
    fn rails_are_faults_not_measurements() {
        let cal = Calibration::board();
        let ok = cal.frame(&Measurement {
            x_m: 1e-3,
            i_a: 2.0,
            vbus_v: 24.0,
        });
        let m = cal.convert(&ok).unwrap();
        assert!((m.x_m - 1e-3).abs() < 1e-6);
        assert!((m.i_a - 2.0).abs() < 0.005);
        assert!((m.vbus_v - 24.0).abs() < 0.01);
        for (frame, fault) in [
            (Frame { position: 0, ..ok }, Fault::PositionSensor),
            (
                Frame {
                    position: 4095,
                    ..ok
                },
                Fault::PositionSensor,
            ),
            (Frame { current: 0, ..ok }, Fault::CurrentSensor),
            (
                Frame {
                    current: 4095,
                    ..ok
                },
                Fault::CurrentSensor,
            ),
            (Frame { vbus: 4095, ..ok }, Fault::VbusSensor),
        ] {
            assert_eq!(cal.convert(&frame), Err(fault));
        }
    }

    #[test]
    fn ideal_codes_round_and_saturate() {
        let ch = Calibration::board().current;
        assert_eq!(ch.code(0.0), 2048);
        assert_eq!(ch.code(100.0), 4095);
        assert_eq!(ch.code(-100.0), 0);
        assert_eq!(ch.code(f32::NAN), 0);
        assert_eq!(ch.code(CURRENT_A_PER_CODE * 0.49), 2048);
        assert_eq!(ch.code(CURRENT_A_PER_CODE * 0.51), 2049);
    }

    #[test]
    fn bad_calibration_is_named() {
        let mut cal = Calibration::board();
        cal.current.scale = f32::NAN;
        assert_eq!(cal.validate().unwrap_err().param, "sense.current.scale");
        let cal = Calibration::board();
        assert_eq!(
            cal.with_current_zero(5000.0).unwrap_err().param,
            "sense.current.offset_code"
        );
        assert_eq!(
            cal.with_current_zero(2051.5).unwrap().current.offset_code,
            2051.5
        );
        // An inverted window names both of its fields.
        let mut cal = Calibration::board();
        cal.vbus.max_code = cal.vbus.min_code;
        let e = cal.validate().unwrap_err();
        assert_eq!(e.param, "sense.vbus.min_code");
        assert_eq!(
            e.reason,
            config::Reason::NotBelow {
                other: "sense.vbus.max_code",
                limit: f32::from(cal.vbus.min_code),
            }
        );
    }
}
