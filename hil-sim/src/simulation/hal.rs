//! Mock hardware: the PWM channel and pins the core's [`ema::control::bridge::HBridge`]
//! drives, the bridge and supply they switch, the converter that produces raw ADC codes,
//! and the firmware's window watchdog.
//!
//! The mock PWM and pins share their state with a [`Lines`] handle through
//! `Rc<Cell<..>>`; the runner reads [`Lines::switches`] after each tick to know what voltage
//! the coil sees over the next period:
//!
//! | enable | direction | PWM on-time | PWM off-time |
//! |---|---|---|---|
//! | low | - | coast: `u = -sign(i) (Vbus + 2 V_diode)` until `i = 0`, then open (`i` stays 0) | same |
//! | high | high | `u = +Vbus` | `u = 0` (low sides on) |
//! | high | low | `u = -Vbus` | `u = 0` |
//!
//! This is when the STM32 firmware's writes act, too: its timer takes the duty, the
//! direction and the enable's rising edge at the period boundary, together, so every
//! period runs one whole drive, as here (a reversal included: the bridge does not pass
//! through coast). One difference remains, on the safe side: when a tick latches a fault,
//! the firmware's enable falls at once, during the period the previous tick ordered, while
//! here the coast starts with the next period; the currents simulated after a fault are
//! the firmware's or higher.
//!
//! The [`Supply`] is a source `V_s` behind an internal resistance: `Vbus = V_s - R_int I_bus`.
//!
//! The [`Watchdog`] is fed by the ticks the guard ([`ema::device::guard`]) finds on time;
//! when nothing feeds it for its early-wakeup time, it coasts the bridge, as the firmware's
//! window-watchdog interrupt does.

use std::cell::Cell;
use std::collections::VecDeque;
use std::convert::Infallible;
use std::rc::Rc;

use ema::control::sense::{Calibration, Channel, Frame, ADC_MAX_CODE};
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

use crate::simulation::plant::{non_negative, Input};
use crate::simulation::Error;

/// A PWM channel implementing `embedded_hal::pwm::SetDutyCycle`. Duties above the maximum
/// are clamped to it (as a timer compare register saturates).
#[derive(Debug)]
pub struct Pwm {
    duty: Rc<Cell<u16>>,
    max_duty: u16,
}

impl PwmErrorType for Pwm {
    type Error = Infallible;
}

impl SetDutyCycle for Pwm {
    fn max_duty_cycle(&self) -> u16 {
        self.max_duty
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.duty.set(duty.min(self.max_duty));
        Ok(())
    }
}

/// An output pin implementing `embedded_hal::digital::OutputPin`.
#[derive(Debug)]
pub struct Pin {
    level: Rc<Cell<bool>>,
}

impl PinErrorType for Pin {
    type Error = Infallible;
}

impl OutputPin for Pin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.level.set(false);
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.level.set(true);
        Ok(())
    }
}

/// The plant's view of the bridge's control lines.
#[derive(Clone, Debug)]
pub struct Lines {
    duty: Rc<Cell<u16>>,
    direction: Rc<Cell<bool>>,
    enable: Rc<Cell<bool>>,
    max_duty: u16,
}

/// What the bridge's switches do with the lines as they are (the core's
/// [`ema::control::bridge::Drive`] is what the tick set the bridge to; this is what the
/// plant sees).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Switches {
    /// Enable low: all switches open.
    Coast,
    /// Enable high.
    Driven {
        /// Direction pin high.
        forward: bool,
        /// On-time fraction of the PWM period, `duty / max_duty` \[-\].
        fraction: f64,
    },
}

impl Switches {
    /// The drive a bridge in `mode` with compare value `duty` out of `max_duty` produces
    /// (for replaying a recorded trace).
    #[must_use]
    pub fn from_mode(mode: ema::control::bridge::Mode, duty: u16, max_duty: u16) -> Self {
        let fraction = f64::from(duty.min(max_duty)) / f64::from(max_duty.max(1));
        match mode {
            ema::control::bridge::Mode::Coast => Switches::Coast,
            ema::control::bridge::Mode::Forward => Switches::Driven {
                forward: true,
                fraction,
            },
            ema::control::bridge::Mode::Reverse => Switches::Driven {
                forward: false,
                fraction,
            },
        }
    }
}

impl Lines {
    /// The switch state the lines select.
    #[must_use]
    pub fn switches(&self) -> Switches {
        if self.enable.get() {
            Switches::Driven {
                forward: self.direction.get(),
                fraction: f64::from(self.duty.get()) / f64::from(self.max_duty.max(1)),
            }
        } else {
            Switches::Coast
        }
    }

    /// Raw PWM compare value.
    #[must_use]
    pub fn duty(&self) -> u16 {
        self.duty.get()
    }
}

/// A PWM channel (`max_duty` counts full scale), a direction pin and an enable pin, all
/// low, and the [`Lines`] that read them.
#[must_use]
pub fn bridge_io(max_duty: u16) -> (Pwm, Pin, Pin, Lines) {
    let lines = Lines {
        duty: Rc::default(),
        direction: Rc::default(),
        enable: Rc::default(),
        max_duty,
    };
    (
        Pwm {
            duty: lines.duty.clone(),
            max_duty,
        },
        Pin {
            level: lines.direction.clone(),
        },
        Pin {
            level: lines.enable.clone(),
        },
        lines,
    )
}

/// The supply: a source behind an internal resistance.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Supply {
    /// Source (open-circuit) voltage `V_s` \[V\].
    pub voltage_v: f64,
    /// Internal resistance `R_int` \[ohm\].
    #[serde(default)]
    pub internal_resistance_ohm: f64,
}

impl Supply {
    /// An ideal source of `voltage_v`.
    #[must_use]
    pub const fn ideal(voltage_v: f64) -> Self {
        Self {
            voltage_v,
            internal_resistance_ohm: 0.0,
        }
    }

    /// Checks the parameters.
    ///
    /// # Errors
    /// A voltage that is not positive, a negative resistance.
    pub fn validate(&self) -> Result<(), Error> {
        crate::simulation::plant::positive("supply.voltage_v", self.voltage_v)?;
        non_negative(
            "supply.internal_resistance_ohm",
            self.internal_resistance_ohm,
        )
    }

    /// The coil input with the bridge enabled in direction `sign` (`+1` or `-1`) for an
    /// on-time `fraction` of the time (`fraction = 1` during a switching-level on-phase,
    /// the duty in the averaged model, 0 during an off-phase): `u = f s V_s - R_int f^2 i`,
    /// bus current `f s i`.
    #[must_use]
    pub fn driven(&self, sign: f64, fraction: f64) -> Input {
        Input {
            u0_v: fraction * sign * self.voltage_v,
            r_ohm: self.internal_resistance_ohm * fraction * fraction,
            bus_gain: fraction * sign,
            vs_v: self.voltage_v,
            freewheel: false,
        }
    }

    /// The coil input with the bridge disabled and current `i_a` in the coil: the two
    /// opposite diodes conduct back into the supply, `u = -sign(i) (V_s + R_int |i| + 2
    /// V_d)`, bus current `-|i|`; with no current the coil is open (`u = 0`).
    #[must_use]
    pub fn coast(&self, i_a: f64, diode_drop_v: f64) -> Input {
        if i_a == 0.0 {
            return Input {
                vs_v: self.voltage_v,
                ..Input::default()
            };
        }
        let s = i_a.signum();
        Input {
            u0_v: -s * (self.voltage_v + 2.0 * diode_drop_v),
            r_ohm: self.internal_resistance_ohm,
            bus_gain: -s,
            vs_v: self.voltage_v,
            freewheel: true,
        }
    }

    /// Bus (terminal) voltage \[V\] with coil current `i_a` under `input`.
    #[must_use]
    pub fn bus_voltage_v(&self, input: &Input, i_a: f64) -> f64 {
        self.voltage_v - self.internal_resistance_ohm * input.bus_gain * i_a
    }
}

/// The reference board's APB1 clock, which counts the window watchdog \[Hz\] (the
/// firmware's `board::PCLK1_HZ`).
pub const REFERENCE_APB1_HZ: u32 = 42_000_000;

/// The firmware's window watchdog as the loop sees it: fed by on-time ticks, it coasts
/// the bridge at the latest moment its early-wakeup interrupt can come after the last
/// feed ([`ema::device::guard::Watchdog::early_wakeup_max_ns`]), checked at each sample
/// instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Watchdog {
    bite_after_ns: u64,
    last_feed_ns: u64,
}

impl Watchdog {
    /// The reference board's window watchdog for ticks at `rate_hz`: quiet for
    /// [`ema::device::guard::WATCHDOG_QUIET_PERIODS`] periods after a feed (the firmware's
    /// choice, `board::WINDOW_WATCHDOG`), fed at time 0.
    #[must_use]
    pub fn reference(rate_hz: f64) -> Self {
        let quiet_ns = f64::from(ema::device::guard::WATCHDOG_QUIET_PERIODS) * 1e9 / rate_hz;
        // Bounded to [0, u32::MAX] before the cast.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let quiet_ns = quiet_ns.round().clamp(0.0, f64::from(u32::MAX)) as u32;
        let w = ema::device::guard::Watchdog::at_least(REFERENCE_APB1_HZ, quiet_ns);
        Self {
            bite_after_ns: u64::from(w.early_wakeup_max_ns()),
            last_feed_ns: 0,
        }
    }

    /// Time from a feed to the bite \[ns\].
    #[must_use]
    pub const fn bite_after_ns(&self) -> u64 {
        self.bite_after_ns
    }

    /// An on-time tick fed it at `now_ns`.
    pub fn feed(&mut self, now_ns: u64) {
        self.last_feed_ns = now_ns;
    }

    /// Whether it has bitten by `now_ns`.
    #[must_use]
    pub const fn bitten(&self, now_ns: u64) -> bool {
        now_ns.saturating_sub(self.last_feed_ns) >= self.bite_after_ns
    }
}

/// A calibration on the reference board's position channel with the current and bus
/// channels rescaled: current `+-current_full_scale_a` around mid-scale, bus
/// `0..vbus_full_scale_v`. The board's own (`Calibration::board()`) is +-16.5 A and 72.6 V;
/// a 150 V scenario with the paper's 21 A start-up needs about 225 V and +-40 A.
#[must_use]
#[expect(clippy::cast_possible_truncation)]
pub fn calibration(vbus_full_scale_v: f64, current_full_scale_a: f64) -> Calibration {
    let board = Calibration::board();
    Calibration {
        current: Channel {
            scale: (current_full_scale_a / 2048.0) as f32,
            ..board.current
        },
        vbus: Channel {
            scale: (vbus_full_scale_v / 4096.0) as f32,
            ..board.vbus
        },
        ..board
    }
}

/// The largest value \[SI\] a channel reads before its plausible window ends.
#[must_use]
pub fn channel_span(ch: &Channel) -> (f64, f64) {
    let a = f64::from(ch.value(ch.min_code));
    let b = f64::from(ch.value(ch.max_code));
    (a.min(b), a.max(b))
}

/// Errors of one converter channel, in codes of the 12-bit scale.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelError {
    /// Relative gain error: the signal part of the code is multiplied by `1 + gain_error`.
    #[serde(default)]
    pub gain_error: f64,
    /// Offset added to the code \[code\].
    #[serde(default)]
    pub offset_code: f64,
    /// RMS of the Gaussian noise added before quantisation \[code\].
    #[serde(default)]
    pub noise_rms_code: f64,
}

/// A calibration class: how far a production board's converter channels may be from the
/// calibration its firmware carries. Each channel's gain error is uniform within
/// `+-gain_rel` and its offset uniform within `+-offset_code` codes, drawn independently
/// per channel. The defaults, +-0.5 % and +-2 codes on the position, current and bus
/// channels, are the class the Monte Carlo's `--sensor-errors` draws from.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationClass {
    /// Largest relative gain error of a channel \[-\].
    pub gain_rel: f64,
    /// Largest offset of a channel \[code\].
    pub offset_code: f64,
}

/// The largest relative gain error of a production board's converter channel: the
/// [`CalibrationClass::default`] every channel is drawn from \[-\].
pub const CONVERTER_GAIN_CLASS: f64 = 0.005;

impl Default for CalibrationClass {
    /// +-0.5 % gain ([`CONVERTER_GAIN_CLASS`]), +-2 codes offset (the board's class,
    /// [`ema::control::actuator::OFFSET_CLASS_CODES`], which the residual allows for).
    fn default() -> Self {
        Self {
            gain_rel: CONVERTER_GAIN_CLASS,
            offset_code: f64::from(ema::control::actuator::OFFSET_CLASS_CODES),
        }
    }
}

impl CalibrationClass {
    /// One channel's gain and offset drawn from the class (noise zero).
    pub fn draw_channel<R: rand::Rng + ?Sized>(&self, rng: &mut R) -> ChannelError {
        let g = self.gain_rel.abs();
        let o = self.offset_code.abs();
        ChannelError {
            gain_error: rng.random_range(-g..=g),
            offset_code: rng.random_range(-o..=o),
            noise_rms_code: 0.0,
        }
    }

    /// `adc` with every channel's gain and offset drawn from the class (position, current,
    /// bus, in that order) by a PCG64 generator seeded by `seed`; the noise, resolution and
    /// delay are kept.
    #[must_use]
    pub fn apply(&self, adc: &Adc, seed: u64) -> Adc {
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut out = *adc;
        for ch in [&mut out.position, &mut out.current, &mut out.vbus] {
            let e = self.draw_channel(&mut rng);
            ch.gain_error = e.gain_error;
            ch.offset_code = e.offset_code;
        }
        out
    }
}

/// The sensor's share of the steady position error at `x_ref_m` \[m\]: where the true
/// position is when the converter's mean reading (noise and quantisation averaged out) is
/// exactly `x_ref_m`, minus `x_ref_m`. A channel with gain error `g` and offset `e` codes
/// reads `x (1 + g) + e * scale`, so a controller that holds the reading on the reference
/// holds the armature at `(x_ref - e * scale) / (1 + g)`: no controller acting on this
/// reading can remove it.
#[must_use]
pub fn sensor_position_error_m(ch: &Channel, err: &ChannelError, x_ref_m: f64) -> f64 {
    (x_ref_m - err.offset_code * f64::from(ch.scale)) / (1.0 + err.gain_error) - x_ref_m
}

/// The analog front end and converter: the ideal transfer is the controller's calibration
/// (`code = value / scale + offset`); this adds gain error, offset, Gaussian noise,
/// quantisation to `resolution_bits` and a delay of whole samples.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Adc {
    /// Converter resolution, 1 to 12 bits; codes are always on the 12-bit scale the
    /// calibration uses (a 10-bit converter gives multiples of 4) \[bit\].
    #[serde(default = "default_bits")]
    pub resolution_bits: u8,
    /// Position channel errors.
    #[serde(default)]
    pub position: ChannelError,
    /// Current channel errors.
    #[serde(default)]
    pub current: ChannelError,
    /// Bus channel errors.
    #[serde(default)]
    pub vbus: ChannelError,
    /// The frame the tick sees was converted this many ISR periods earlier (0 or 1 typical).
    #[serde(default)]
    pub delay_samples: u32,
    /// Seed of the noise generator (PCG64).
    #[serde(default)]
    pub seed: u64,
}

fn default_bits() -> u8 {
    12
}

impl Default for Adc {
    /// 12 bits, no errors, no noise, no delay: only quantisation.
    fn default() -> Self {
        Self {
            resolution_bits: 12,
            position: ChannelError::default(),
            current: ChannelError::default(),
            vbus: ChannelError::default(),
            delay_samples: 0,
            seed: 0,
        }
    }
}

impl Adc {
    /// A typical converter: 12 bits, the board's noise
    /// ([`ema::control::sense::NOISE_RMS_CODES`], 1.5 codes RMS) on every channel, one
    /// sample of delay, seed 1.
    #[must_use]
    pub fn typical() -> Self {
        let noise = ChannelError {
            noise_rms_code: f64::from(ema::control::sense::NOISE_RMS_CODES),
            ..ChannelError::default()
        };
        Self {
            position: noise,
            current: noise,
            vbus: noise,
            delay_samples: 1,
            seed: 1,
            ..Self::default()
        }
    }

    /// Checks the parameters.
    ///
    /// # Errors
    /// A resolution outside 1..=12 bits, a non-finite error term, a negative noise, a
    /// delay above 1000 samples.
    pub fn validate(&self) -> Result<(), Error> {
        if !(1..=12).contains(&self.resolution_bits) {
            return Err(Error::param(
                "sensors.resolution_bits",
                f64::from(self.resolution_bits),
                "must be 1 to 12 (codes are on the core's 12-bit scale)",
            ));
        }
        for (name, ch) in [
            ("position", &self.position),
            ("current", &self.current),
            ("vbus", &self.vbus),
        ] {
            for (field, v) in [
                ("gain_error", ch.gain_error),
                ("offset_code", ch.offset_code),
            ] {
                if !v.is_finite() {
                    return Err(Error::param(
                        format!("sensors.{name}.{field}"),
                        v,
                        "must be finite",
                    ));
                }
            }
            non_negative(&format!("sensors.{name}.noise_rms_code"), ch.noise_rms_code)?;
        }
        if self.delay_samples > 1000 {
            return Err(Error::param(
                "sensors.delay_samples",
                f64::from(self.delay_samples),
                "must be at most 1000",
            ));
        }
        Ok(())
    }

    /// A converter with this model on the analog front end described by `calibration`.
    #[must_use]
    pub fn start(&self, calibration: &Calibration) -> Converter {
        Converter {
            model: *self,
            calibration: *calibration,
            rng: Pcg64::seed_from_u64(self.seed),
            queue: VecDeque::with_capacity(self.delay_samples as usize + 1),
        }
    }
}

/// A running converter (noise generator and delay line).
#[derive(Clone, Debug)]
pub struct Converter {
    model: Adc,
    calibration: Calibration,
    rng: Pcg64,
    queue: VecDeque<Frame>,
}

impl Converter {
    /// Sets the position channel's gain error and offset \[code\] (an injected sensor
    /// fault, or one off its calibration); its noise is kept.
    pub fn set_position_error(&mut self, gain_error: f64, offset_code: f64) {
        self.model.position.gain_error = gain_error;
        self.model.position.offset_code = offset_code;
    }

    /// Converts the true position \[m\], current \[A\] and bus voltage \[V\] now and returns
    /// the frame converted `delay_samples` periods ago (the first frame until then).
    pub fn sample(&mut self, x_m: f64, i_a: f64, vbus_v: f64) -> Frame {
        let (cal, model) = (self.calibration, self.model);
        let frame = Frame {
            position: self.code(&cal.position, &model.position, x_m),
            current: self.code(&cal.current, &model.current, i_a),
            vbus: self.code(&cal.vbus, &model.vbus, vbus_v),
        };
        if self.queue.is_empty() {
            for _ in 0..self.model.delay_samples {
                self.queue.push_back(frame);
            }
        }
        self.queue.push_back(frame);
        self.queue.pop_front().unwrap_or(frame)
    }

    fn code(&mut self, ch: &Channel, err: &ChannelError, value: f64) -> u16 {
        let mut c = value * (1.0 + err.gain_error) / f64::from(ch.scale)
            + f64::from(ch.offset_code)
            + err.offset_code;
        if err.noise_rms_code > 0.0 {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            c += err.noise_rms_code * n;
        }
        let step = f64::from(1_u16 << (12 - self.model.resolution_bits.min(12)));
        let q = (c / step).round() * step;
        if q.is_nan() || q <= 0.0 {
            0
        } else if q >= f64::from(ADC_MAX_CODE) {
            ADC_MAX_CODE
        } else {
            // In (0, 4095): exact integer value, the cast cannot truncate.
            #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let code = q as u16;
            code
        }
    }
}

/// The PWM full-scale compare value at `rate_hz` for a centre-aligned timer clocked at
/// [`TIMER_CLOCK_HZ`]: half a period in counts, plus one for 100 %.
#[must_use]
#[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
pub fn pwm_full_scale(rate_hz: f64) -> u16 {
    let counts = (TIMER_CLOCK_HZ / (2.0 * rate_hz)).round();
    (counts.clamp(1.0, f64::from(u16::MAX - 1)) as u16) + 1
}

/// The firmware's PWM timer clock (TIM1 at 168 MHz) \[Hz\].
pub const TIMER_CLOCK_HZ: f64 = 168e6;

#[cfg(test)]
mod tests {
    use super::*;
    use ema::control::bridge::{HBridge, Mode};

    #[test]
    fn the_core_bridge_drives_the_mock_lines() {
        let (pwm, dir, en, lines) = bridge_io(1000);
        let mut b = HBridge::new(pwm, dir, en).unwrap();
        assert_eq!(lines.switches(), Switches::Coast);
        b.apply(12.0, 24.0).unwrap();
        assert_eq!(
            lines.switches(),
            Switches::Driven {
                forward: true,
                fraction: 0.5
            }
        );
        b.apply(-30.0, 24.0).unwrap();
        assert_eq!(b.mode(), Mode::Reverse);
        assert_eq!(
            lines.switches(),
            Switches::Driven {
                forward: false,
                fraction: 1.0
            }
        );
        assert_eq!(lines.duty(), 1000);
        b.coast().unwrap();
        assert_eq!(lines.switches(), Switches::Coast);
    }

    #[test]
    fn the_calibration_class_stays_within_its_limits_and_its_share_is_exact() {
        let class = CalibrationClass::default();
        let adc = class.apply(&Adc::typical(), 7);
        for ch in [adc.position, adc.current, adc.vbus] {
            assert!(
                ch.gain_error.abs() <= 0.005 && ch.offset_code.abs() <= 2.0,
                "{ch:?}"
            );
            assert_eq!(
                ch.noise_rms_code,
                f64::from(ema::control::sense::NOISE_RMS_CODES)
            );
        }
        assert_ne!(adc.position, adc.current);
        // Without noise, a reading held on the reference puts the armature at the
        // reference plus the share: the converter reads the reference there.
        let cal = Calibration::board().position;
        let err = ChannelError {
            gain_error: 0.004,
            offset_code: -1.5,
            noise_rms_code: 0.0,
        };
        let x_ref = 2e-3;
        let x = x_ref + sensor_position_error_m(&cal, &err, x_ref);
        let read = (x * (1.0 + err.gain_error) / f64::from(cal.scale) + err.offset_code)
            * f64::from(cal.scale);
        assert!((read - x_ref).abs() < 1e-12, "{read} {x_ref}");
        // 0.4 % gain alone: about 0.4 % of the reference.
        let gain_only = ChannelError {
            offset_code: 0.0,
            ..err
        };
        let share = sensor_position_error_m(&cal, &gain_only, x_ref) / x_ref;
        assert!((share + 0.004 / 1.004).abs() < 1e-12, "{share}");
    }

    #[test]
    fn the_watchdog_bites_its_early_wakeup_time_after_the_last_feed() {
        let mut w = Watchdog::reference(20e3);
        // 3 counts of 4096 cycles at 42 MHz.
        assert_eq!(w.bite_after_ns(), 292_572);
        w.feed(1_000_000);
        assert!(!w.bitten(1_292_571));
        assert!(w.bitten(1_292_572));
        // At 10 kHz: 5 counts, still within half a millisecond.
        assert_eq!(Watchdog::reference(10e3).bite_after_ns(), 487_620);
    }

    #[test]
    fn supply_resistance_and_freewheel() {
        let s = Supply {
            voltage_v: 100.0,
            internal_resistance_ohm: 0.5,
        };
        // Averaged at duty 0.5 forward with 4 A: u = 50 - 0.5 * 0.25 * 4 = 49.5 V.
        let d = s.driven(1.0, 0.5);
        assert!((d.coil_voltage_v(4.0) - 49.5).abs() < 1e-12);
        assert!((s.bus_voltage_v(&d, 4.0) - 99.0).abs() < 1e-12);
        // Coasting with +4 A: -(100 + 0.5 * 4 + 1.4) = -103.4 V, the bus rises by 2 V.
        let c = s.coast(4.0, 0.7);
        assert!((c.coil_voltage_v(4.0) + 103.4).abs() < 1e-12);
        assert!((s.bus_voltage_v(&c, 4.0) - 102.0).abs() < 1e-12);
        let c = s.coast(-4.0, 0.7);
        assert!((c.coil_voltage_v(-4.0) - 103.4).abs() < 1e-12);
        assert_eq!(s.coast(0.0, 0.7).coil_voltage_v(0.0), 0.0);
    }

    #[test]
    fn ideal_converter_matches_the_calibration() {
        let cal = calibration(225.0, 40.0);
        let mut adc = Adc::default().start(&cal);
        let f = adc.sample(2e-3, 6.0, 150.0);
        let m = cal.convert(&f).unwrap();
        assert!((f64::from(m.x_m) - 2e-3).abs() <= 0.55e-6 * 4.0 / 3.6);
        assert!((f64::from(m.i_a) - 6.0).abs() <= 0.5 * 40.0 / 2048.0 + 1e-6);
        assert!((f64::from(m.vbus_v) - 150.0).abs() <= 0.5 * 225.0 / 4096.0 + 1e-4);
        assert_eq!(
            f,
            cal.frame(&ema::control::sense::Measurement {
                x_m: 2e-3,
                i_a: 6.0,
                vbus_v: 150.0
            })
        );
    }

    #[test]
    fn errors_noise_resolution_and_delay() {
        let cal = calibration(225.0, 40.0);
        let model = Adc {
            resolution_bits: 10,
            current: ChannelError {
                gain_error: 0.01,
                offset_code: 3.0,
                noise_rms_code: 0.0,
            },
            delay_samples: 1,
            ..Adc::default()
        };
        let mut adc = model.start(&cal);
        let first = adc.sample(1e-3, 10.0, 150.0);
        let second = adc.sample(3e-3, 10.0, 150.0);
        // One sample of delay: the first frame twice.
        assert_eq!(first, second);
        let third = adc.sample(3e-3, 10.0, 150.0);
        assert!(third.position > first.position);
        // 10 bits: multiples of 4 codes.
        assert_eq!(third.position % 4, 0);
        // 10 A * 1.01 / (40/2048) + 2048 + 3 = 2568.1 -> 2568 on the 10-bit grid.
        assert_eq!(third.current, 2568);

        // Noise: seeded, reproducible, about the requested RMS.
        let noisy = Adc {
            position: ChannelError {
                noise_rms_code: 2.0,
                ..ChannelError::default()
            },
            seed: 7,
            ..Adc::default()
        };
        let codes = |m: &Adc| {
            let mut a = m.start(&cal);
            (0..4000)
                .map(|_| f64::from(a.sample(2e-3, 0.0, 150.0).position))
                .collect::<Vec<_>>()
        };
        let c1 = codes(&noisy);
        assert_eq!(c1, codes(&noisy));
        let mean = c1.iter().sum::<f64>() / c1.len() as f64;
        let rms = (c1.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / c1.len() as f64).sqrt();
        assert!(rms > 1.9 && rms < 2.2, "{rms}");
        assert!(Adc {
            resolution_bits: 14,
            ..Adc::default()
        }
        .validate()
        .is_err());
    }
}
