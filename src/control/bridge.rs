//! H-bridge driver over `embedded-hal` 1.0: one PWM channel for the magnitude, a direction
//! pin and an enable pin (the usual EN/PH/PWM interface of integrated H-bridge drivers).
//!
//! | mode | enable | direction | PWM on | PWM off | coil sees (average) |
//! |---|---|---|---|---|---|
//! | [`Mode::Coast`] | low | - | - | - | all switches open: the current freewheels through the diodes against the bus and decays fast |
//! | [`Mode::Forward`] | high | high | `+Vbus` | 0 V (low sides on) | `+duty Vbus` |
//! | [`Mode::Reverse`] | high | low | `-Vbus` | 0 V (low sides on) | `-duty Vbus` |
//!
//! A voltage command becomes a duty from the measured bus voltage, saturated at the bus
//! voltage.
//!
//! **Maximum modulation.** The coil current is sampled in the middle of the off-time, its
//! converter's sampling phase ending there ([`CURRENT_SAMPLING_S`]); a switching edge
//! inside that phase, or less than [`CURRENT_SETTLE_S`] before it, puts the edge's
//! ringing on the sample. The off-time is `(1 - duty)` of the period, centred on the
//! sample, so every duty up to [`max_modulation`] keeps the sample clear; above it and
//! below 100 % (no edge at all) a duty is snapped to the nearer of the two
//! ([`HBridge::apply_clear`]), and the applied voltage [`Drive::u_v`] is the snapped one,
//! which the law and the detectors see. At 20 kHz that is 90.7 %: duties of 90.7-95.3 %
//! become 90.7 %, those of 95.3-100 % become 100 %. Coast (`duty 0, enable low`) is the safe state; it is also where the bridge
//! starts. Leaving coast is `direction, enable high, duty`; a reversal is
//! `duty 0, direction, duty`: the direction only ever changes right after a zero duty.
//!
//! When each write acts is the implementation's business, and the order above is safe for
//! both kinds:
//!
//! * Writes that act at once (the simulator's lines, the test mocks): the direction changes
//!   while the bridge brakes at zero duty (low sides on), never during a pulse.
//! * The STM32 firmware's timer: the duty, the direction and the enable's rising edge all
//!   take effect together at the next PWM period boundary, the middle of the off-time; only
//!   the enable's falling edge (coast) acts at once. A reversal therefore starts the new
//!   direction and the new duty with the next period, and the period in progress runs to
//!   its end as ordered, which is the voltage the law and the fault detectors assume
//!   ([`Drive::u_v`] applies to exactly one whole period). A reversal does not pass
//!   through coast: with the enable's falling edge acting at once, that would cut the
//!   period in progress short, which no model assumes.
use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

/// Bridge mode.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub enum Mode {
    /// Disabled, all switches open (safe state).
    #[default]
    Coast,
    /// Enabled, positive coil voltage during the PWM on-time.
    Forward,
    /// Enabled, negative coil voltage during the PWM on-time.
    Reverse,
}

impl Mode {
    /// Every mode, in code order.
    pub const ALL: [Mode; 3] = [Mode::Coast, Mode::Forward, Mode::Reverse];

    /// The mode's code in golden traces and the firmware's status snapshot.
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            Mode::Coast => 0,
            Mode::Forward => 1,
            Mode::Reverse => 2,
        }
    }

    /// The mode with `code`, if any.
    #[must_use]
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.iter().copied().find(|m| m.code() == code)
    }

    /// The mode's name in logs and simulator traces: `coast`, `forward`, `reverse`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Mode::Coast => "coast",
            Mode::Forward => "forward",
            Mode::Reverse => "reverse",
        }
    }
}

/// TIM1 auto-reload of the reference board at the product's 20 kHz: a 168 MHz timer
/// clock, center-aligned, one PWM period is `2 * 4200` counts. The firmware derives its
/// own from its clock tree and rate (`board::PWM_ARR`) and checks that at 20 kHz it is
/// this one.
pub const BOARD_PWM_ARR: u16 = 4200;

/// PWM full scale the bridge sees on the reference board at 20 kHz: the HAL's
/// `max_duty_cycle` is `ARR + 1` (a compare value above ARR keeps the output on for the
/// whole period). The golden traces ([`crate::control::trace`]) are recorded at this
/// resolution.
// 4201 fits u16 (checked by the compiler: a const overflow is an error).
pub const BOARD_MAX_DUTY: u16 = BOARD_PWM_ARR + 1;

/// The current's sampling phase on the reference board \[s\]: 28 cycles of the 21 MHz
/// converter clock, ending at the middle of the PWM off-time (the firmware's
/// `board::ADC_SAMPLE_CYCLES` and `board::ADC_CLK_HZ`, which it checks against this).
pub const CURRENT_SAMPLING_S: f32 = 28.0 / 21.0e6;
/// Time the current sensor's output takes to settle after a switching edge \[s\]: a
/// current-sense amplifier with PWM rejection (INA240 class) settles within 1 us of a
/// 48 V edge.
pub const CURRENT_SETTLE_S: f32 = 1.0e-6;

/// The highest duty fraction at `rate_hz` whose off-time keeps the current's sample and
/// the settling before it clear of both switching edges: `1 - 2 (sampling + settling)
/// rate` (see the module documentation).
///
/// Above `1 / (4 (sampling + settling))` (107 kHz) not even a half-duty off-time holds
/// the sampling phase: no board samples the current at such a rate, which only the
/// simulator's near-continuous reproduction of the paper uses, with an ideal sample.
/// There the result is 1: nothing is snapped.
#[must_use]
pub fn max_modulation(rate_hz: f32) -> f32 {
    let m = 1.0 - 2.0 * (CURRENT_SAMPLING_S + CURRENT_SETTLE_S) * rate_hz;
    if m >= 0.5 {
        m
    } else {
        1.0
    }
}

/// What the bridge was set to.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Drive {
    /// Mode.
    pub mode: Mode,
    /// PWM compare value written (0 in coast).
    pub duty: u16,
    /// Average coil voltage this produces at the measured bus voltage \[V\] (0 in coast,
    /// where the coil voltage is set by the freewheeling current, not by the bridge).
    pub u_v: f32,
}

/// A failed PWM or pin operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub enum Error<P, O> {
    /// The PWM channel refused a duty.
    Pwm(P),
    /// A pin could not be set.
    Pin(O),
}

/// An H-bridge: PWM magnitude, direction pin, enable pin.
#[derive(Debug)]
pub struct HBridge<P, O> {
    pwm: P,
    direction: O,
    enable: O,
    mode: Mode,
    max_duty: u16,
}

type BridgeError<P, O> = Error<
    <P as embedded_hal::pwm::ErrorType>::Error,
    <O as embedded_hal::digital::ErrorType>::Error,
>;

impl<P: SetDutyCycle, O: OutputPin> HBridge<P, O> {
    /// Takes the PWM channel and the two pins and puts the bridge in coast
    /// (`duty 0`, `enable low`).
    ///
    /// # Errors
    /// A failed PWM or pin operation.
    pub fn new(pwm: P, direction: O, enable: O) -> Result<Self, BridgeError<P, O>> {
        let max_duty = pwm.max_duty_cycle();
        let mut bridge = Self {
            pwm,
            direction,
            enable,
            mode: Mode::Forward,
            max_duty,
        };
        bridge.coast()?;
        Ok(bridge)
    }

    /// Current mode.
    #[must_use]
    pub const fn mode(&self) -> Mode {
        self.mode
    }

    /// Largest PWM compare value.
    #[must_use]
    pub const fn max_duty(&self) -> u16 {
        self.max_duty
    }

    /// Gives the PWM channel and the pins back (bridge left as it is).
    pub fn release(self) -> (P, O, O) {
        (self.pwm, self.direction, self.enable)
    }

    /// Safe state: duty 0 and enable low. Does the writes even if already coasting, so
    /// that it can be used to force the hardware into the safe state.
    ///
    /// # Errors
    /// A failed PWM or pin operation (both are attempted regardless).
    pub fn coast(&mut self) -> Result<Drive, BridgeError<P, O>> {
        let duty = self.pwm.set_duty_cycle(0).map_err(Error::Pwm);
        let enable = self.enable.set_low().map_err(Error::Pin);
        self.mode = Mode::Coast;
        duty?;
        enable?;
        Ok(Drive::default())
    }

    /// Applies the coil voltage `u_v` at the measured bus voltage `vbus_v`: duty
    /// `|u| / vbus` limited to 1, direction from the sign. A zero command keeps the
    /// present direction at duty 0 (0 V, slow decay; from coast it enables forward). A
    /// non-finite command or a bus voltage that is not positive coasts.
    ///
    /// # Errors
    /// A failed PWM or pin operation; the bridge is then driven to coast (best effort).
    #[inline]
    pub fn apply(&mut self, u_v: f32, vbus_v: f32) -> Result<Drive, BridgeError<P, O>> {
        self.apply_clear(u_v, vbus_v, 1.0)
    }

    /// As [`HBridge::apply`], with every duty between `clear` (a fraction, the
    /// [`max_modulation`] of the rate) and 100 % snapped to the nearer of the two (see
    /// the module documentation).
    ///
    /// # Errors
    /// As [`HBridge::apply`].
    #[inline]
    pub fn apply_clear(
        &mut self,
        u_v: f32,
        vbus_v: f32,
        clear: f32,
    ) -> Result<Drive, BridgeError<P, O>> {
        if !(u_v.is_finite() && vbus_v.is_finite() && vbus_v > 0.0) {
            return self.coast();
        }
        let want = if u_v > 0.0 {
            Mode::Forward
        } else if u_v < 0.0 {
            Mode::Reverse
        } else if self.mode == Mode::Coast {
            Mode::Forward
        } else {
            self.mode
        };
        let duty = snap(
            duty_code(u_v.abs() / vbus_v, self.max_duty),
            clear_code(clear, self.max_duty),
            self.max_duty,
        );
        match self.switch(want, duty) {
            Ok(()) => {
                let u = f32::from(duty) / f32::from(self.max_duty.max(1)) * vbus_v;
                Ok(Drive {
                    mode: want,
                    duty,
                    u_v: if want == Mode::Reverse { -u } else { u },
                })
            }
            Err(e) => {
                // Best effort: the error to report is the first one.
                let _ = self.coast();
                Err(e)
            }
        }
    }

    fn switch(&mut self, want: Mode, duty: u16) -> Result<(), BridgeError<P, O>> {
        if want != self.mode {
            let from_coast = self.mode == Mode::Coast;
            if !from_coast {
                // Reversal: zero duty first, so that the direction never changes during a
                // pulse (see the module documentation for when each write acts).
                self.pwm.set_duty_cycle(0).map_err(Error::Pwm)?;
            }
            match want {
                Mode::Reverse => self.direction.set_low(),
                _ => self.direction.set_high(),
            }
            .map_err(Error::Pin)?;
            if from_coast {
                self.enable.set_high().map_err(Error::Pin)?;
            }
            self.mode = want;
        }
        self.pwm.set_duty_cycle(duty).map_err(Error::Pwm)
    }
}

/// A PWM channel that drives nothing and remembers its last duty: for replaying traces,
/// documentation examples and tests, where the bridge's outputs are read from [`Drive`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NullPwm {
    /// Full-scale compare value it reports.
    pub max_duty: u16,
    /// The last duty written.
    pub duty: u16,
}

impl NullPwm {
    /// A channel with full scale `max_duty`.
    #[must_use]
    pub const fn new(max_duty: u16) -> Self {
        Self { max_duty, duty: 0 }
    }
}

impl embedded_hal::pwm::ErrorType for NullPwm {
    type Error = core::convert::Infallible;
}

impl SetDutyCycle for NullPwm {
    fn max_duty_cycle(&self) -> u16 {
        self.max_duty
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
        self.duty = duty;
        Ok(())
    }
}

/// A pin that drives nothing and remembers its last level (`true` = high); see
/// [`NullPwm`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NullPin(pub bool);

impl embedded_hal::digital::ErrorType for NullPin {
    type Error = core::convert::Infallible;
}

impl OutputPin for NullPin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.0 = false;
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.0 = true;
        Ok(())
    }
}

/// The highest compare value at or below the fraction `clear` of `max` (`max` for 1 and
/// above, 0 for `NaN` and below).
#[inline]
#[must_use]
pub fn clear_code(clear: f32, max: u16) -> u16 {
    let c = clear * f32::from(max);
    if c >= f32::from(max) {
        max
    } else if c >= 0.0 {
        // In [0, max): the truncation is the intended rounding down.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let code = c as u16;
        code
    } else {
        0
    }
}

/// `duty` snapped to the nearer of `clear` and `max` when it lies strictly between them
/// (a tie goes to `max`: no edge).
#[inline]
#[must_use]
pub fn snap(duty: u16, clear: u16, max: u16) -> u16 {
    if duty <= clear || duty >= max {
        duty
    } else if duty.wrapping_sub(clear) >= max.wrapping_sub(duty) {
        max
    } else {
        clear
    }
}

/// PWM compare value for a duty fraction: nearest code, `NaN` and negatives give 0,
/// fractions of 1 and more give `max`.
#[inline]
#[must_use]
pub fn duty_code(fraction: f32, max: u16) -> u16 {
    let max_f = f32::from(max);
    let c = fraction * max_f + 0.5;
    if c.is_nan() || c < 1.0 {
        0
    } else if c >= max_f {
        max
    } else {
        // In [1, max): the truncation is the intended rounding and cannot overflow.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let code = c as u16;
        code
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use core::cell::RefCell;
    use embedded_hal::digital::ErrorType as PinErrorType;
    use embedded_hal::pwm::ErrorType as PwmErrorType;
    use embedded_hal_mock::eh1::digital::{
        Mock as PinMock, State as PinState, Transaction as PinTx,
    };
    use embedded_hal_mock::eh1::pwm::{Mock as PwmMock, Transaction as PwmTx};
    use embedded_hal_mock::eh1::MockError;
    use std::rc::Rc;
    use std::vec;
    use std::vec::Vec;

    // ---------- expectation mocks: exact per-device sequences ----------

    #[test]
    fn start_forward_reverse_and_coast_sequences() {
        let max = 1000;
        let pwm = PwmMock::new(&[
            PwmTx::max_duty_cycle(max),
            PwmTx::set_duty_cycle(0),    // new(): coast
            PwmTx::set_duty_cycle(500),  // +12 V at 24 V
            PwmTx::set_duty_cycle(250),  // +6 V, same direction: duty only
            PwmTx::set_duty_cycle(0),    // reversal: duty 0 first
            PwmTx::set_duty_cycle(1000), // -30 V saturates at -24 V
            PwmTx::set_duty_cycle(0),    // coast
        ]);
        let dir = PinMock::new(&[PinTx::set(PinState::High), PinTx::set(PinState::Low)]);
        let en = PinMock::new(&[
            PinTx::set(PinState::Low),  // new(): coast
            PinTx::set(PinState::High), // enable forward
            PinTx::set(PinState::Low),  // coast (a reversal leaves the enable alone)
        ]);
        let mut b = HBridge::new(pwm, dir, en).unwrap();
        assert_eq!(b.mode(), Mode::Coast);
        let d = b.apply(12.0, 24.0).unwrap();
        assert_eq!((d.mode, d.duty, d.u_v), (Mode::Forward, 500, 12.0));
        let d = b.apply(6.0, 24.0).unwrap();
        assert_eq!((d.mode, d.duty, d.u_v), (Mode::Forward, 250, 6.0));
        let d = b.apply(-30.0, 24.0).unwrap();
        assert_eq!((d.mode, d.duty, d.u_v), (Mode::Reverse, 1000, -24.0));
        let d = b.coast().unwrap();
        assert_eq!((d.mode, d.duty), (Mode::Coast, 0));
        let (mut pwm, mut dir, mut en) = b.release();
        pwm.done();
        dir.done();
        en.done();
    }

    #[test]
    fn bad_commands_coast() {
        let pwm = PwmMock::new(&[
            PwmTx::max_duty_cycle(100),
            PwmTx::set_duty_cycle(0),
            PwmTx::set_duty_cycle(50),
            PwmTx::set_duty_cycle(0), // NaN command
            PwmTx::set_duty_cycle(0), // zero bus voltage
        ]);
        let dir = PinMock::new(&[PinTx::set(PinState::High)]);
        let en = PinMock::new(&[
            PinTx::set(PinState::Low),
            PinTx::set(PinState::High),
            PinTx::set(PinState::Low),
            PinTx::set(PinState::Low),
        ]);
        let mut b = HBridge::new(pwm, dir, en).unwrap();
        b.apply(5.0, 10.0).unwrap();
        assert_eq!(b.apply(f32::NAN, 10.0).unwrap().mode, Mode::Coast);
        assert_eq!(b.apply(5.0, 0.0).unwrap().mode, Mode::Coast);
        let (mut pwm, mut dir, mut en) = b.release();
        pwm.done();
        dir.done();
        en.done();
    }

    #[test]
    fn a_failing_pwm_is_reported_and_the_bridge_coasts() {
        let pwm = PwmMock::new(&[
            PwmTx::max_duty_cycle(100),
            PwmTx::set_duty_cycle(0),
            PwmTx::set_duty_cycle(50).with_error(MockError::Io(std::io::ErrorKind::Other)),
            PwmTx::set_duty_cycle(0), // best-effort coast
        ]);
        let dir = PinMock::new(&[PinTx::set(PinState::High)]);
        let en = PinMock::new(&[
            PinTx::set(PinState::Low),
            PinTx::set(PinState::High),
            PinTx::set(PinState::Low),
        ]);
        let mut b = HBridge::new(pwm, dir, en).unwrap();
        assert!(matches!(b.apply(5.0, 10.0), Err(Error::Pwm(_))));
        assert_eq!(b.mode(), Mode::Coast);
        let (mut pwm, mut dir, mut en) = b.release();
        pwm.done();
        dir.done();
        en.done();
    }

    // ---------- stateful recorder: the global order across devices ----------

    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    enum Op {
        Duty(u16),
        Dir(bool),
        En(bool),
    }

    type Log = Rc<RefCell<Vec<Op>>>;

    struct Pwm(Log);
    impl PwmErrorType for Pwm {
        type Error = core::convert::Infallible;
    }
    impl SetDutyCycle for Pwm {
        fn max_duty_cycle(&self) -> u16 {
            4200
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
            self.0.borrow_mut().push(Op::Duty(duty));
            Ok(())
        }
    }

    struct Pin(Log, bool);
    impl PinErrorType for Pin {
        type Error = core::convert::Infallible;
    }
    impl OutputPin for Pin {
        fn set_low(&mut self) -> Result<(), Self::Error> {
            let op = if self.1 {
                Op::Dir(false)
            } else {
                Op::En(false)
            };
            self.0.borrow_mut().push(op);
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Self::Error> {
            let op = if self.1 { Op::Dir(true) } else { Op::En(true) };
            self.0.borrow_mut().push(op);
            Ok(())
        }
    }

    #[test]
    fn reversal_order_across_devices() {
        let log: Log = Rc::default();
        let mut b = HBridge::new(
            Pwm(log.clone()),
            Pin(log.clone(), true),
            Pin(log.clone(), false),
        )
        .unwrap();
        b.apply(10.0, 42.0).unwrap();
        b.apply(-21.0, 42.0).unwrap();
        assert_eq!(
            *log.borrow(),
            vec![
                Op::Duty(0),
                Op::En(false), // new(): coast
                Op::Dir(true),
                Op::En(true),
                Op::Duty(1000), // 10/42 * 4200
                Op::Duty(0),    // reversal: zero duty, then the direction
                Op::Dir(false),
                Op::Duty(2100),
            ]
        );
    }

    /// Over any sequence of commands, the direction pin only ever changes right after a zero
    /// duty (the bridge brakes, no pulse runs), the duty is zero whenever the bridge is
    /// enabled, and every coast disables the bridge.
    #[test]
    fn direction_changes_only_at_zero_duty() {
        let log: Log = Rc::default();
        let mut b = HBridge::new(
            Pwm(log.clone()),
            Pin(log.clone(), true),
            Pin(log.clone(), false),
        )
        .unwrap();
        let mut x = 0x1234_5678_u32;
        let (mut reversals, mut coasts) = (0, 0);
        let mut last = Mode::Coast;
        for _ in 0..10_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let u = (x % 2001) as f32 * 0.05 - 50.0;
            if x.is_multiple_of(97) {
                b.coast().unwrap();
                coasts += 1;
            } else {
                let d = b.apply(u, 24.0).unwrap();
                assert!(d.u_v.abs() <= 24.0);
                assert!(d.duty <= 4200);
                if last != Mode::Coast && d.mode != last {
                    reversals += 1;
                }
            }
            last = b.mode();
        }
        assert!(reversals > 1000 && coasts > 50, "{reversals} {coasts}");
        let (mut enabled, mut duty, mut dir) = (false, 0, None);
        for op in log.borrow().iter() {
            match *op {
                Op::Dir(d) => {
                    if enabled && dir != Some(d) {
                        assert_eq!(duty, 0, "direction changed during a pulse");
                    }
                    dir = Some(d);
                }
                Op::En(true) => {
                    assert_eq!(duty, 0, "enabled with a non-zero duty");
                    enabled = true;
                }
                Op::En(false) => {
                    assert_eq!(duty, 0, "coast left a duty behind");
                    enabled = false;
                }
                Op::Duty(d) => duty = d,
            }
        }
    }

    #[test]
    fn duty_codes_round_and_saturate() {
        assert_eq!(duty_code(0.5, 1000), 500);
        assert_eq!(duty_code(0.0004, 1000), 0);
        assert_eq!(duty_code(0.0006, 1000), 1);
        assert_eq!(duty_code(1.5, 1000), 1000);
        assert_eq!(duty_code(-0.5, 1000), 0);
        assert_eq!(duty_code(f32::NAN, 1000), 0);
        assert_eq!(duty_code(f32::INFINITY, 1000), 1000);
    }

    #[test]
    fn the_maximum_modulation_keeps_the_current_sample_clear_of_the_edges() {
        // 20 kHz: 2.33 us of the 25 us half period before the sample, either side.
        let m = max_modulation(20_000.0);
        assert!((m - 0.906_67).abs() < 1e-4, "{m}");
        // The off-time, centred on the sample, is `(1 - m)` of the period: each half
        // holds the sampling phase and the settling exactly.
        let half_off_s = (1.0 - m) / 20_000.0 / 2.0;
        assert!((half_off_s - (CURRENT_SAMPLING_S + CURRENT_SETTLE_S)).abs() < 1e-9);
        assert!((max_modulation(50_000.0) - 0.766_67).abs() < 1e-4);
        // Past 107 kHz no converter samples; the near-continuous model is left unsnapped.
        assert!((max_modulation(100_000.0) - 0.533_33).abs() < 1e-4);
        assert_eq!(max_modulation(110_000.0), 1.0);
        assert_eq!(max_modulation(1.0e6), 1.0);
        // On the reference board's timer: the highest clear compare value, and the snap.
        let max = BOARD_MAX_DUTY;
        let clear = clear_code(m, max);
        assert_eq!(clear, 3808);
        assert_eq!(snap(3808, clear, max), 3808);
        assert_eq!(snap(3809, clear, max), 3808);
        assert_eq!(snap(4004, clear, max), 3808);
        assert_eq!(snap(4005, clear, max), max);
        assert_eq!(snap(4200, clear, max), max);
        assert_eq!(snap(max, clear, max), max);
        assert_eq!(snap(100, clear, max), 100);
        assert_eq!(clear_code(1.0, max), max);
        assert_eq!(clear_code(f32::NAN, max), 0);
        // Through the bridge: 95 % of the bus becomes 90.7 %, 97 % becomes 100 %, and the
        // drive reports the voltage applied.
        let mut b = HBridge::new(NullPwm::new(max), NullPin(false), NullPin(false)).unwrap();
        let d = b.apply_clear(0.95 * 24.0, 24.0, m).unwrap();
        assert_eq!(d.duty, clear);
        assert!((d.u_v - 24.0 * f32::from(clear) / f32::from(max)).abs() < 1e-5);
        let d = b.apply_clear(-0.97 * 24.0, 24.0, m).unwrap();
        assert_eq!((d.mode, d.duty, d.u_v), (Mode::Reverse, max, -24.0));
        let d = b.apply_clear(0.5 * 24.0, 24.0, m).unwrap();
        assert_eq!(d.duty, duty_code(0.5, max));
    }
}
