//! Every hardware fact of the reference board, in one place, with its unit.
//!
//! | signal | pin | peripheral | note |
//! |---|---|---|---|
//! | bridge PWM | PA8 | TIM1_CH1 (AF1) | center-aligned, 20 kHz, active high = bridge on |
//! | bridge direction (PH) | PC8 | GPIO push-pull | high = forward |
//! | bridge enable (EN) | PC9 | GPIO push-pull | low = coast; **the board must pull it down** so the bridge coasts through reset, boot and a watchdog reset, while the pin floats |
//! | position sensor | PC0 | ADC123_IN10 | 5-95 % of the range over the stroke ([`ema::sense::POSITION_M_PER_CODE`]) |
//! | coil current | PC1 | ADC123_IN11 | bidirectional, mid-scale at 0 A ([`ema::sense::CURRENT_A_PER_CODE`]) |
//! | bus voltage | PC2 | ADC123_IN12 | 22:1 divider ([`ema::sense::VBUS_V_PER_CODE`]) |
//! | crystal | PH0/PH1 | HSE | 8 MHz |
//! | debug | PA13/PA14 | SWD | probe-rs, defmt over RTT |
//!
//! Timing of one control period (50 us, 8400 CPU cycles):
//!
//! ```text
//! TIM1 counter   0 /\ 4200 /\ 0          up/down, 168 MHz: 2 x 4200 counts = 50 us
//! PWM (mode 1)  ‾‾|____|‾‾‾‾|____|‾‾     high while CNT < CCR1: pulses centred on CNT = 0
//! update event        ^ top               RCR = 1: one update per period, at the top
//!  -> TRGO -> ADC1 injected: current, position, bus (3 x 1.9 us)
//!  -> JEOC interrupt -> tick -> CCR1 (preloaded: applies at the next top)
//! ```
//!
//! Sampling at the top of the count is sampling in the middle of the PWM off-time: with a
//! triangular ripple that is the period's mean current, and it is as far from both
//! switching edges as the period allows.
//!
//! The sensor scales are the core's constants ([`ema::sense`]); only the current zero is
//! measured here, at start, with the bridge off.

use ema::config;
use ema::control::Settings;
use ema::sense::CURRENT_ZERO_CODE;

/// Crystal \[Hz\].
pub const HSE_HZ: u32 = 8_000_000;
/// Core clock (PLL from the HSE) \[Hz\].
pub const SYSCLK_HZ: u32 = 168_000_000;
/// APB1 clock (at most 42 MHz) \[Hz\].
pub const PCLK1_HZ: u32 = 42_000_000;
/// APB2 clock (at most 84 MHz) \[Hz\].
pub const PCLK2_HZ: u32 = 84_000_000;
/// TIM1 kernel clock: twice PCLK2, because the APB2 prescaler is not 1 \[Hz\].
pub const TIM1_CLK_HZ: u32 = 2 * PCLK2_HZ;

/// PWM frequency \[Hz\].
pub const PWM_HZ: u32 = 20_000;
/// TIM1 auto-reload: center-aligned, one PWM period is `2 * PWM_ARR` timer counts.
pub const PWM_ARR: u32 = TIM1_CLK_HZ / (2 * PWM_HZ);
/// PWM resolution seen by the bridge: the HAL's `max_duty_cycle` is `ARR + 1`, and a
/// compare value above ARR keeps the output on for the whole period (100 %).
pub const PWM_MAX_DUTY: u16 = 4201;
/// TIM1 repetition counter: center-aligned mode has two over/underflows per period; with
/// RCR = 1 only every second one is an update event (one ADC trigger and one compare
/// reload per period). Written before the counter starts, the update falls on the
/// overflow (top): RM0090 section 17.3.3.
pub const PWM_REPETITION: u8 = 1;

/// Control rate: one tick per PWM period \[Hz\].
pub const CONTROL_RATE_HZ: u32 = PWM_HZ;
/// Core cycles per control period.
pub const CONTROL_PERIOD_CYCLES: u32 = SYSCLK_HZ / CONTROL_RATE_HZ;
/// A tick that starts this long after the previous one means at least one conversion
/// went unserved (an overrun, even if nothing was pending when a tick ended) \[cycles\].
pub const OVERRUN_GAP_CYCLES: u32 = CONTROL_PERIOD_CYCLES + CONTROL_PERIOD_CYCLES / 2;

/// ADC clock divider (ADC_CCR.ADCPRE): PCLK2 / 4.
pub const ADC_PRESCALER: u32 = 4;
/// ADC clock (at most 36 MHz at 3.3 V) \[Hz\].
pub const ADC_CLK_HZ: u32 = PCLK2_HZ / ADC_PRESCALER;
/// Sampling time of every channel \[ADC cycles\] (SMPx = 0b010). 1.33 us, enough for a
/// sensor output impedance of a few kilo-ohms (datasheet R_AIN table).
pub const ADC_SAMPLE_CYCLES: u32 = 28;
/// Conversion time of a 12-bit result after sampling \[ADC cycles\].
pub const ADC_CONVERSION_CYCLES: u32 = 12;
/// ADC channel of the coil current (converted first: nearest the sampling instant).
pub const CURRENT_CHANNEL: u8 = 11;
/// ADC channel of the position sensor.
pub const POSITION_CHANNEL: u8 = 10;
/// ADC channel of the bus-voltage divider.
pub const VBUS_CHANNEL: u8 = 12;
/// The injected sequence, in conversion order; results land in JDR1, JDR2, JDR3.
pub const INJECTED_SEQUENCE: [u8; 3] = [CURRENT_CHANNEL, POSITION_CHANNEL, VBUS_CHANNEL];
/// Time from the trigger to the end of the sequence \[ns\].
pub const ADC_SEQUENCE_NS: u32 =
    3 * (ADC_SAMPLE_CYCLES + ADC_CONVERSION_CYCLES) * 1_000 / (ADC_CLK_HZ / 1_000_000);

/// Port of the bridge PWM pin (TIM1_CH1 in alternate function 1).
pub const PWM_PORT: char = 'A';
/// Pin number of the bridge PWM.
pub const PWM_PIN: u8 = 8;
/// Port of the bridge direction pin.
pub const DIR_PORT: char = 'C';
/// Pin number of the bridge direction.
pub const DIR_PIN: u8 = 8;
/// Port of the bridge enable pin.
pub const EN_PORT: char = 'C';
/// Pin number of the bridge enable.
pub const EN_PIN: u8 = 9;

/// Independent-watchdog timeout \[ms\] (LSI 32 kHz nominal, 17-47 kHz over the chip's
/// range: 1.4 to 3.8 ms). 40 control periods; the coil's L/R is 0.15-0.44 ms, so a hung
/// tick leaves the last duty on for at most a few milliseconds before the reset coasts
/// the bridge (EN pull-down).
pub const WATCHDOG_TIMEOUT_MS: u32 = 2;

/// Conversions discarded before measuring the current zero (ADC and sensor settling).
pub const ZERO_SETTLE_SAMPLES: u32 = 64;
/// Conversions averaged for the current zero (51 ms at 20 kHz; the sum stays exact in f32).
pub const ZERO_SAMPLES: u32 = 1024;
/// Largest accepted distance of the measured zero from the nominal one \[codes\]: 100
/// codes, 0.8 A. Further away the sensor or its reference has drifted.
pub const ZERO_TOLERANCE_CODES: f32 = 100.0;
/// Largest accepted spread (max - min) of the zero samples \[codes\]: 0.5 A of noise.
pub const ZERO_MAX_SPREAD_CODES: u16 = 62;

/// Nominal bus voltage \[V\]: sets the bus under/over-voltage window of the settings.
pub const VBUS_NOMINAL_V: f32 = 24.0;
/// Position set point at start \[m\] (the paper's step to 3 mm).
pub const SETPOINT_M: f32 = 3.0e-3;
/// Ticks between two status lines (one second).
pub const STATUS_PERIOD_TICKS: u32 = CONTROL_RATE_HZ;

// The arithmetic above, checked by the compiler.
const _: () = {
    assert!(PWM_ARR == 4200);
    assert!(TIM1_CLK_HZ / (2 * PWM_ARR) == PWM_HZ);
    assert!(PWM_MAX_DUTY as u32 == PWM_ARR + 1);
    assert!(CONTROL_PERIOD_CYCLES == 8400);
    assert!(ADC_CLK_HZ <= 36_000_000);
    // The conversions end early in the period: the tick has over 40 us left.
    assert!(ADC_SEQUENCE_NS < 10_000);
    assert!(SYSCLK_HZ % HSE_HZ == 0);
};

/// ADC_JSQR for an injected sequence of three channels. With JL = 2 (three conversions)
/// the ADC converts JSQ2, JSQ3, JSQ4 in that order (RM0090 section 13.13.12: "if JL < 3
/// the sequence starts at JSQ(4 - JL)"), and the n-th conversion goes to JDRn.
#[must_use]
pub const fn injected_sequence(channels: [u8; 3]) -> u32 {
    let jl = 2;
    (jl << 20)
        | ((channels[0] as u32) << 5)
        | ((channels[1] as u32) << 10)
        | ((channels[2] as u32) << 15)
}

/// Whether a measured current zero can be trusted.
#[must_use]
pub fn zero_plausible(mean_code: f32, spread_codes: u16) -> bool {
    (mean_code - CURRENT_ZERO_CODE).abs() <= ZERO_TOLERANCE_CODES
        && spread_codes <= ZERO_MAX_SPREAD_CODES
}

/// The controller this firmware runs, with the measured current zero (`None`: nominal):
/// the product's default (`Settings::practical`: the practical discrete-time law, one
/// sample of measurement delay, which is this firmware's timing, reference shaping and
/// every fault monitor). The law, gains and limits are chosen here and nowhere else.
///
/// # Errors
/// A zero outside the converter range.
pub fn settings(current_zero_code: Option<f32>) -> Result<Settings, config::Error> {
    let mut s = Settings::practical(CONTROL_RATE_HZ as f32, VBUS_NOMINAL_V)?;
    if let Some(code) = current_zero_code {
        s.sense = s.sense.with_current_zero(code)?;
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn injected_sequence_matches_the_reference_manual_example() {
        // RM0090: JSQR = 10 00011 00011 00111 00010 converts 7, 3, 3 (JSQ1 = 2 unused).
        let rm = 0b10_00011_00011_00111_00010;
        assert_eq!(injected_sequence([7, 3, 3]) | 0b00010, rm);
        let ours = injected_sequence(INJECTED_SEQUENCE);
        assert_eq!((ours >> 20) & 3, 2);
        assert_eq!((ours >> 5) & 31, u32::from(CURRENT_CHANNEL));
        assert_eq!((ours >> 10) & 31, u32::from(POSITION_CHANNEL));
        assert_eq!((ours >> 15) & 31, u32::from(VBUS_CHANNEL));
    }

    #[test]
    fn timing_constants() {
        assert_eq!(ADC_CLK_HZ, 21_000_000);
        // 3 x 40 ADC cycles at 21 MHz.
        assert_eq!(ADC_SEQUENCE_NS, 5_714);
        assert_eq!(OVERRUN_GAP_CYCLES, 12_600);
    }

    #[test]
    fn current_zero_window() {
        assert!(zero_plausible(2048.0, 10));
        assert!(zero_plausible(2147.5, 10));
        assert!(!zero_plausible(2149.0, 10));
        assert!(!zero_plausible(1900.0, 10));
        assert!(!zero_plausible(2048.0, 63));
        assert!(!zero_plausible(f32::NAN, 0));
    }

    #[test]
    fn settings_build_with_a_measured_zero_and_refuse_a_wild_one() {
        let s = settings(Some(2051.25)).unwrap();
        assert_eq!(s.sense.current.offset_code, 2051.25);
        assert_eq!(s.rate_hz, 20_000.0);
        // The firmware's sample-to-duty delay is one period.
        assert_eq!(s.delay_ticks, 1);
        s.build().unwrap();
        settings(None).unwrap().build().unwrap();
        assert!(settings(Some(9000.0)).is_err());
    }
}
