//! Every hardware fact of the reference board, in one place, with its unit.
//!
//! | signal | pin | peripheral | note |
//! |---|---|---|---|
//! | bridge PWM | PA8 | TIM1_CH1 (AF1) | center-aligned, 20 kHz, active high = bridge on |
//! | bridge enable (EN) | PA9 | TIM1_CH2 (AF1) | low = coast; a timer output, so that it drops with the timer's main output (break, debugger halt, fault handlers) |
//! | bridge direction (PH) | PA10 | TIM1_CH3 (AF1) | high = forward; a timer output, so that it changes with the duty at the period boundary |
//! | bridge fault (BKIN) | PB12 | TIM1_BKIN (AF1) | active low: the driver's fault output and the current comparator, open drain, wired together |
//! | position sensor | PC0 | ADC123_IN10 | the span within the range, room left at both ends for the sensor's tolerance ([`ema::control::actuator::Actuator::calibration`]) |
//! | coil current | PC1 | ADC123_IN11 | bidirectional, mid-scale at 0 A ([`ema::control::sense::CURRENT_A_PER_CODE`]) |
//! | bus voltage | PC2 | ADC123_IN12 | 22:1 divider ([`ema::control::sense::VBUS_V_PER_CODE`]) |
//! | bench link TX | PA2 | USART2_TX (AF7), DMA1 stream 6 | [`ema::device::protocol::BAUD`] 8N1, 3.3 V levels, to any USB-serial adapter's RX |
//! | bench link RX | PA3 | USART2_RX (AF7), DMA1 stream 5 | from the adapter's TX; the internal pull-up holds the line idle when nothing is connected |
//! | crystal | PH0/PH1 | HSE | 8 MHz |
//! | debug | PA13/PA14 | SWD | probe-rs, defmt over RTT |
//!
//! What the board must provide (the firmware relies on it):
//!
//! * **Pull-downs on PA8, PA9 and PA10** (10 kOhm): through reset and boot, and whenever a
//!   watchdog reset has released the pins, they float; the pull-down on EN keeps the bridge
//!   coasting then. While the firmware runs, the three lines are timer outputs whose idle
//!   level is low: the timer drives them low whenever its main output is off.
//! * **The break input, PB12, pulled up** (4.7 kOhm to 3.3 V; the internal pull-up is also
//!   on) and pulled low by any of: the driver's fault output (open drain, active low:
//!   over-current, over-temperature, under-voltage) and a comparator on the current shunt
//!   that trips at [`BREAK_CURRENT_A`] in either direction (open drain, active low). The
//!   timer's break acts on the outputs without software and without a clock (RM0090
//!   section 17.3.12): main output off, all three lines driven low; it stays off until a
//!   reset (automatic re-enable is off), and the next tick latches
//!   `Fault::HardwareTrip`.
//! * **A bus that absorbs the coil's energy** (a TVS clamp, a brake chopper, or bulk
//!   capacitance on the bridge's supply). On any fault, `bus_over_voltage` included, the
//!   bridge coasts: all four switches open, and the coil's current returns to the bus
//!   through the body diodes, up to `L I^2 / 2` at the comparator's trip current. Coasting
//!   is the one reaction that needs no switch to work (a brake needs both low sides on,
//!   and an integrated driver's own over-voltage lockout opens them all anyway), so the
//!   bus must take that energy from the over-voltage trip (1.25 times the supply) without
//!   exceeding [`BUS_RATING_V`], which the driver, the bridge and the capacitors must be
//!   rated for: a clamp between the two, or at least [`bulk_capacitance_f`] of bulk
//!   capacitance (266 uF for the product's actuator, 420 uH at 15.8 A: 53 mJ).
//! * **Option bytes** (programmed once, with the probe): `WDG_SW` either way: cleared (the
//!   hardware watchdog option), the independent watchdog runs from reset at LSI / 4 with
//!   the reload 0xFFF, 512 ms nominal and 349 ms at the LSI's fastest, long enough to
//!   reach the first line of start-up, which sets [`IWDG_BOOT`]; read protection at level
//!   0 or 1; sectors 1 and 2 not write-protected (`nWRP1`, `nWRP2` set: the parameter
//!   store writes them); `BOR_LEV` at 2.7 V, so that the flash is only written in the
//!   voltage range whose erase times [`SECTOR_ERASE_MAX_MS`] gives.
//! * **A driver that accepts a direction change while enabled** (its own dead time, as
//!   integrated EN/PH drivers have): the direction changes at the period boundary, in the
//!   middle of the off-time, so the driver is braking then, except at a duty of 100 %.
//!
//! Timing of one control period (50 us, 8400 CPU cycles):
//!
//! ```text
//! TIM1 counter   0 /\ 4200 /\ 0          up/down, 168 MHz: 2 x 4200 counts = 50 us
//! PWM (mode 1)  ‾‾|____|‾‾‾‾|____|‾‾     high while CNT < CCR1: pulses centred on CNT = 0
//! compare 4          ^ CNT = 3632 counting up (PWM mode 2: OC4REF rises) -> TRGO
//!  -> ADC1 injected: position, current, bus, analog set point (4 x 1.9 us), the
//!     current's sampling phase ending exactly at the top of the count, the sequence
//!     3.4 us before to 4.4 us after it
//!  -> JEOC interrupt -> tick -> CCR1..CCR3 (preloaded)
//! update event            ^ top           RCR = 1: one update per period, at the top:
//!                                         duty, direction and enable change together
//! ```
//!
//! Sampling at the top of the count is sampling in the middle of the PWM off-time: with a
//! triangular ripple that is the period's mean current, and it is as far from both
//! switching edges as the period allows. The conversions are placed there by the compare
//! value ([`ADC_TRIGGER_COMPARE`]), not by which overflow the update event lands on; start-up
//! checks both that the update event comes at the top and that the conversions end just
//! after it, and refuses to run otherwise.
//!
//! The sensor scales are the core's constants ([`ema::control::sense`]); only the current
//! zero is measured here, at start, with the bridge off.

use ema::control::actuator::Actuator;
use ema::control::config;
use ema::control::model::Convention;
use ema::control::sense::{Frame, CURRENT_ZERO_CODE};
use ema::control::Settings;
use ema::device::guard::{Watchdog, WATCHDOG_QUIET_PERIODS};

/// The actuator this firmware is built for: the file given as `EMA_ACTUATOR` at build
/// time (validated by `build.rs`, which fails the build with the field named), or the
/// product's default ([`Actuator::PRODUCT`]). Every setting derives from it at start.
pub const ACTUATOR: Actuator = include!(concat!(env!("OUT_DIR"), "/actuator.rs"));

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

/// PWM frequency: the actuator's control rate \[Hz\].
// A rate in Hz is a whole number well inside u32 (checked below).
#[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
pub const PWM_HZ: u32 = ACTUATOR.board.rate_hz as u32;
/// TIM1 auto-reload: center-aligned, one PWM period is `2 * PWM_ARR` timer counts.
pub const PWM_ARR: u32 = TIM1_CLK_HZ / (2 * PWM_HZ);
/// PWM resolution seen by the bridge: the HAL's `max_duty_cycle` is `ARR + 1`, and a
/// compare value above ARR keeps the output on for the whole period (100 %).
// ARR is at most 8400 for the 10 kHz the board goes down to (checked below).
#[expect(clippy::cast_possible_truncation)]
pub const PWM_MAX_DUTY: u16 = (PWM_ARR + 1) as u16;
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
/// ADC channel of the coil current.
pub const CURRENT_CHANNEL: u8 = 11;
/// ADC channel of the position sensor.
pub const POSITION_CHANNEL: u8 = 10;
/// ADC channel of the bus-voltage divider.
pub const VBUS_CHANNEL: u8 = 12;
/// ADC channel of the analog set-point input (PC3, ADC123_IN13): its input stage (divider
/// for 0-10 V, shunt for 4-20 mA) is the board's, its scaling `ema::device::analog`'s.
pub const ANALOG_CHANNEL: u8 = 13;
/// The injected sequence, in conversion order: ADC channel and what it measures; results
/// land in JDR1 to JDR4. The one table both the set-up ([`INJECTED_SEQUENCE`],
/// [`injected_sequence`]) and the readout ([`frame`]) use. The current is converted
/// second, so that the control's three sit around the sampling instant of the current
/// ([`ADC_TRIGGER_COMPARE`]); the analog set point, filtered and least sensitive to a
/// switching edge, last. It is converted whether or not it is used: the sequence, and so
/// the tick's timing, is the same for every set-point source.
pub const INJECTED: [(u8, Signal); 4] = [
    (POSITION_CHANNEL, Signal::Position),
    (CURRENT_CHANNEL, Signal::Current),
    (VBUS_CHANNEL, Signal::Vbus),
    (ANALOG_CHANNEL, Signal::Setpoint),
];
/// The channels of [`INJECTED`], in conversion order.
pub const INJECTED_SEQUENCE: [u8; 4] = [INJECTED[0].0, INJECTED[1].0, INJECTED[2].0, INJECTED[3].0];
/// What an injected conversion measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// Position sensor.
    Position,
    /// Coil current.
    Current,
    /// Bus-voltage divider.
    Vbus,
    /// The analog set-point input.
    Setpoint,
}

/// Where `signal` sits in [`INJECTED`] (the table's length if it is absent).
#[must_use]
pub const fn slot(signal: Signal) -> usize {
    let mut k = 0;
    while k < INJECTED.len() {
        if INJECTED[k].1 as u8 == signal as u8 {
            return k;
        }
        k += 1;
    }
    INJECTED.len()
}

/// The control's frame and the analog set-point code of one sequence, from its results
/// `[JDR1, JDR2, JDR3, JDR4]`, through [`INJECTED`].
#[inline(always)]
#[must_use]
pub fn frame(results: [u16; 4]) -> (Frame, u16) {
    let mut f = Frame::default();
    let mut analog = 0;
    let [(_, a), (_, b), (_, c), (_, d)] = INJECTED;
    let [ra, rb, rc, rd] = results;
    for (signal, code) in [(a, ra), (b, rb), (c, rc), (d, rd)] {
        match signal {
            Signal::Position => f.position = code,
            Signal::Current => f.current = code,
            Signal::Vbus => f.vbus = code,
            Signal::Setpoint => analog = code,
        }
    }
    (f, analog)
}

/// Conversions in the sequence.
pub const CONVERSIONS: u32 = INJECTED.len() as u32;

/// Slot of the current in the sequence.
pub const CURRENT_SLOT: u32 = slot(Signal::Current) as u32;
/// Injected trigger latency, from the trigger edge to the start of the first sampling
/// phase \[ADC cycles\] (datasheet: `t_lat(inj)` at most 3 ADC clock cycles).
pub const ADC_TRIGGER_LATENCY_CYCLES: u32 = 3;
/// TIM1 counts per ADC cycle.
pub const TIM1_COUNTS_PER_ADC_CYCLE: u32 = TIM1_CLK_HZ / ADC_CLK_HZ;
/// TIM1 counts from the trigger to the end of the current's sampling phase (when its
/// sample-and-hold opens): the latency, the conversions before it, its own sampling.
pub const ADC_TRIGGER_LEAD_COUNTS: u32 = (ADC_TRIGGER_LATENCY_CYCLES
    + CURRENT_SLOT * (ADC_SAMPLE_CYCLES + ADC_CONVERSION_CYCLES)
    + ADC_SAMPLE_CYCLES)
    * TIM1_COUNTS_PER_ADC_CYCLE;
/// TIM1 compare 4: its reference rises (PWM mode 2) when the counter passes this value
/// counting up, and on TRGO that edge triggers the sequence; the current's sampling phase
/// then ends exactly at the top of the count, the middle of the off-time.
pub const ADC_TRIGGER_COMPARE: u32 = PWM_ARR - ADC_TRIGGER_LEAD_COUNTS;
/// TIM1 counts from the top of the count to the end of the sequence (the interrupt).
pub const ADC_END_AFTER_TOP_COUNTS: u32 = (ADC_TRIGGER_LATENCY_CYCLES
    + CONVERSIONS * (ADC_SAMPLE_CYCLES + ADC_CONVERSION_CYCLES))
    * TIM1_COUNTS_PER_ADC_CYCLE
    - ADC_TRIGGER_LEAD_COUNTS;
/// Highest duty \[per mille\] whose off-time holds the whole sequence, trigger to last
/// conversion: above it, a switching edge falls inside a conversion. The current's own
/// sample is kept clear by the tick up to 100 % (`ema::control::bridge::max_modulation`:
/// duties between 90.7 % and 100 % at 20 kHz are snapped to one or the other); the position
/// and the bus, converted 1.9 us either side of it, are filtered and far less sensitive.
pub const SEQUENCE_IN_OFF_TIME_MAX_PERMILLE: u32 = 1000
    - ((if ADC_TRIGGER_LEAD_COUNTS > ADC_END_AFTER_TOP_COUNTS {
        ADC_TRIGGER_LEAD_COUNTS
    } else {
        ADC_END_AFTER_TOP_COUNTS
    }) * 1000)
        .div_ceil(PWM_ARR);

/// Time from the trigger to the end of the sequence \[ns\].
pub const ADC_SEQUENCE_NS: u32 =
    CONVERSIONS * (ADC_SAMPLE_CYCLES + ADC_CONVERSION_CYCLES) * 1_000 / (ADC_CLK_HZ / 1_000_000);

/// Port of the bridge PWM pin (TIM1_CH1 in alternate function 1).
pub const PWM_PORT: char = 'A';
/// Pin number of the bridge PWM.
pub const PWM_PIN: u8 = 8;
/// Port of the bridge direction pin (TIM1_CH3 in alternate function 1).
pub const DIR_PORT: char = 'A';
/// Pin number of the bridge direction.
pub const DIR_PIN: u8 = 10;
/// Port of the bridge enable pin (TIM1_CH2 in alternate function 1).
pub const EN_PORT: char = 'A';
/// Pin number of the bridge enable.
pub const EN_PIN: u8 = 9;

/// The independent watchdog's clock, the LSI oscillator \[Hz\]: 32 kHz nominal, 17 to
/// 47 kHz over the chip's range (datasheet, LSI characteristics). Every timeout below is
/// checked at both ends.
pub const LSI_HZ: u32 = 32_000;
/// The LSI's lowest frequency \[Hz\]: the longest a timeout can last.
pub const LSI_MIN_HZ: u32 = 17_000;
/// The LSI's highest frequency \[Hz\]: the shortest a timeout can last.
pub const LSI_MAX_HZ: u32 = 47_000;

/// An independent-watchdog timeout: the prescaler (IWDG_PR, code and divider) and the
/// reload (IWDG_RLR, 12 bits): `(reload + 1) * divider` LSI periods.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IwdgTimeout {
    /// IWDG_PR: `divider = 4 << prescaler_code`.
    pub prescaler_code: u8,
    /// IWDG_RLR.
    pub reload: u16,
}

impl IwdgTimeout {
    /// The timeout of `ms` milliseconds at the nominal LSI with the divider `4 << code`.
    #[must_use]
    pub const fn new(prescaler_code: u8, ms: u32) -> Self {
        let divider = 4u32 << prescaler_code;
        let counts = ms * (LSI_HZ / 1000) / divider;
        assert!(prescaler_code <= 6 && counts >= 1 && counts <= 4096);
        Self {
            prescaler_code,
            reload: (counts - 1) as u16,
        }
    }

    /// LSI periods of the timeout.
    #[must_use]
    pub const fn lsi_periods(self) -> u32 {
        (self.reload as u32 + 1) * (4 << self.prescaler_code)
    }

    /// The shortest it lasts (the LSI at its fastest) \[us\].
    #[must_use]
    pub const fn min_us(self) -> u32 {
        (self.lsi_periods() as u64 * 1_000_000 / LSI_MAX_HZ as u64) as u32
    }

    /// The longest it lasts (the LSI at its slowest) \[us\].
    #[must_use]
    pub const fn max_us(self) -> u32 {
        (self.lsi_periods() as u64 * 1_000_000 / LSI_MIN_HZ as u64) as u32
    }
}

/// The independent watchdog while the controller runs: 2 ms nominal (1.4 to 3.8 ms), 40
/// control periods at 20 kHz, fed by every tick that runs on time while the main loop
/// checks in; the coil's L/R is 0.15-0.44 ms, so a hung tick leaves the last duty on for
/// at most a few milliseconds before the reset coasts the bridge (EN pull-down). The
/// window watchdog acts first (within [`STALL_TO_COAST_MAX_NS`]); this one is the last
/// resort.
pub const IWDG_RUN: IwdgTimeout = IwdgTimeout::new(0, 2);

/// Longest a flash sector erase of the parameter store takes \[ms\] (a 16 KiB sector,
/// datasheet: 400 ms typical, 800 ms at most).
pub const SECTOR_ERASE_MAX_MS: u32 = 800;
/// Longest the crystal may take to start \[ms\]: the datasheet gives 2 ms typical and no
/// maximum; ST's own start-up code waits 100 ms, fifty times the typical.
pub const HSE_STARTUP_TIMEOUT_MS: u32 = 100;
/// Longest the PLL may take to lock, and the system clock to switch to it \[ms\]: the
/// datasheet's lock time is under 0.3 ms; ST's code waits 2 ms.
pub const PLL_LOCK_TIMEOUT_MS: u32 = 2;
/// The internal oscillator the core runs on until the switch to the PLL \[Hz\] (16 MHz,
/// +-1 % at 25 C, a few percent over temperature: the waits below count cycles at it, and
/// a slower oscillator only makes them longer).
pub const HSI_HZ: u32 = 16_000_000;
/// The crystal's wait, in cycles of the cycle counter at [`HSI_HZ`].
pub const HSE_STARTUP_TIMEOUT_CYCLES: u32 = HSE_STARTUP_TIMEOUT_MS * (HSI_HZ / 1000);
/// The PLL's waits, in cycles at [`HSI_HZ`].
pub const PLL_LOCK_TIMEOUT_CYCLES: u32 = PLL_LOCK_TIMEOUT_MS * (HSI_HZ / 1000);
/// Longest wait for an independent-watchdog register update (RM0090 20.4: up to 5 LSI
/// periods at the prescaler's clock, twice that after a write): 20 LSI periods at its
/// slowest, 1.2 ms, in cycles at the fastest core clock (the wait may run before or after
/// the clock set-up; on the internal oscillator it only lasts longer).
pub const IWDG_UPDATE_CYCLES: u32 = 20 * (SYSCLK_HZ / LSI_MIN_HZ);
/// Everything start-up does before the controller's watchdogs run, at its longest \[ms\]:
/// the deferred save (a store may erase both its sectors, when a power cut during the
/// last save left the one it was writing to be repaired), the crystal and the PLL, and
/// the rest of start-up (the current zero's 1088 conversions at the slowest 10 kHz, 109
/// ms; the parameters' validation twice, a few milliseconds: 200 ms in all).
pub const BOOT_MAX_MS: u32 =
    2 * SECTOR_ERASE_MAX_MS + HSE_STARTUP_TIMEOUT_MS + 2 * PLL_LOCK_TIMEOUT_MS + 200;
/// The independent watchdog from the first line of start-up until the controller runs:
/// 4 s nominal (2.7 s at the LSI's fastest), above [`BOOT_MAX_MS`] at its shortest, so
/// that a start on a good board never ends in a watchdog reset; start-up tightens it to
/// [`IWDG_RUN`] just before the control interrupt starts.
pub const IWDG_BOOT: IwdgTimeout = IwdgTimeout::new(6, 4000);

/// The parameter store's flash range, as offsets from the flash's start (0x0800_0000):
/// sectors 1 and 2 (16 KiB each), which `memory.x` keeps out of the image (the code
/// starts after them; its link-time check fails if the two disagree).
pub const STORE_RANGE: core::ops::Range<u32> = 0x0000_4000..0x0000_C000;
/// Size of the store's sectors \[bytes\].
pub const STORE_SECTOR: usize = ema::device::store::SECTOR_BYTES;
const _: () = assert!(
    (STORE_RANGE.end - STORE_RANGE.start) as usize == 2 * STORE_SECTOR
        && (STORE_RANGE.start as usize).is_multiple_of(STORE_SECTOR)
);
/// Port of the bench link's two pins.
pub const LINK_PORT: char = 'A';
/// The bench link's transmit pin (USART2_TX in alternate function 7).
pub const LINK_TX_PIN: u8 = 2;
/// The bench link's receive pin (USART2_RX in alternate function 7).
pub const LINK_RX_PIN: u8 = 3;

/// Port of the break input (TIM1_BKIN in alternate function 1).
pub const BREAK_PORT: char = 'B';
/// Pin number of the break input.
pub const BREAK_PIN: u8 = 12;
/// Trip level the board's comparator on the current shunt must be set to, either direction
/// \[A\]: [`ema::control::actuator::Actuator::break_current_a`], 20 % above the software
/// trip (the actuator's peak current, 13.2 A on the product's), inside the current
/// channel's full scale (the actuator file's validation; checked again below). With the
/// product's actuator, 15.84 A of its +-16.5 A.
pub const BREAK_CURRENT_A: f32 = ACTUATOR.break_current_a();

/// The bus voltage the board must stay below when the coil's energy returns to it \[V\]:
/// half as much again as the supply (the firmware trips at 1.25 times), which the bridge
/// driver, the switches and the bus capacitors must be rated for.
pub const BUS_RATING_V: f32 = 1.5 * ACTUATOR.board.supply_v;

/// The bulk capacitance that takes the coil's largest stored energy (its highest
/// inductance, at the closed stop with the surfaces at their smallest, times the
/// comparator's trip current squared, halved) from the over-voltage trip to
/// [`BUS_RATING_V`] \[F\]: `2 E / (V_rating^2 - V_trip^2)`.
///
/// Host-side (the board's requirement, checked by the tests).
///
/// # Errors
/// The actuator's settings do not derive.
#[cfg(not(target_os = "none"))]
pub fn bulk_capacitance_f() -> Result<f32, config::Error> {
    let s = ACTUATOR.settings()?;
    let closed = s.plant.gap_m(s.plant.stroke_m);
    let l_h = s.plant.envelope()?.l_hi(closed);
    let i_a = BREAK_CURRENT_A;
    let energy_j = 0.5 * l_h * i_a * i_a;
    let trip_v = s.limits.vbus_max_v;
    Ok(2.0 * energy_j / (BUS_RATING_V * BUS_RATING_V - trip_v * trip_v))
}

/// Longest time from a tick that stops to a coasting bridge \[ns\].
pub const STALL_TO_COAST_MAX_NS: u32 = 500_000;
/// One control period \[ns\].
pub const CONTROL_PERIOD_NS: u32 = 1_000_000_000 / CONTROL_RATE_HZ;
/// The window watchdog, on APB1 without prescaler: quiet for
/// [`WATCHDOG_QUIET_PERIODS`] control periods after a feed (on-time ticks feed less than
/// two periods apart), its early-wakeup interrupt (which coasts the bridge) at most
/// 292.6 us after the last feed, its reset at most 390.1 us after it (20 kHz).
pub const WINDOW_WATCHDOG: Watchdog =
    Watchdog::at_least(PCLK1_HZ, WATCHDOG_QUIET_PERIODS * CONTROL_PERIOD_NS);

/// Conversions discarded before measuring the current zero (ADC and sensor settling).
pub const ZERO_SETTLE_SAMPLES: u32 = 64;
/// Conversions averaged for the current zero (51 ms at 20 kHz; the sum stays exact in f32).
pub const ZERO_SAMPLES: u32 = 1024;
/// Largest accepted distance of the measured zero from the nominal one \[codes\]: 100
/// codes, 0.8 A. Further away the sensor or its reference has drifted.
pub const ZERO_TOLERANCE_CODES: f32 = 100.0;
/// Largest accepted peak-to-peak (max - min) of the zero samples \[codes\]: 0.5 A of noise.
pub const ZERO_MAX_PEAK_TO_PEAK_CODES: u16 = 62;

/// Ticks between two status lines (one second).
pub const STATUS_PERIOD_TICKS: u32 = CONTROL_RATE_HZ;

// The arithmetic above, checked by the compiler.
const _: () = {
    // A control rate the timer makes exactly, within the 10 to 50 kHz the board supports.
    assert!(
        ACTUATOR.board.rate_hz == PWM_HZ as f32,
        "the actuator's board.rate_hz must be a whole number of hertz"
    );
    assert!(
        PWM_HZ >= 10_000 && PWM_HZ <= 50_000,
        "the board runs its control between 10 and 50 kHz (board.rate_hz)"
    );
    assert!(
        TIM1_CLK_HZ.is_multiple_of(2 * PWM_HZ),
        "board.rate_hz must divide TIM1's 84 MHz half-clock (10, 20, 25, 40, 50 kHz ...)"
    );
    assert!(PWM_MAX_DUTY as u32 == PWM_ARR + 1);
    // At the product's 20 kHz the timer is the reference board's, the resolution the
    // golden traces are recorded at.
    assert!(PWM_HZ != 20_000 || PWM_ARR == ema::control::bridge::BOARD_PWM_ARR as u32);
    assert!(CONTROL_PERIOD_CYCLES * CONTROL_RATE_HZ == SYSCLK_HZ);
    assert!(ADC_CLK_HZ <= 36_000_000);
    // The core's maximum modulation keeps this board's current sample clear.
    assert!(
        ema::control::bridge::CURRENT_SAMPLING_S == ADC_SAMPLE_CYCLES as f32 / ADC_CLK_HZ as f32,
        "ema::control::bridge::CURRENT_SAMPLING_S must be the current's sampling phase"
    );
    // The conversions end early in the period: the tick has over 40 us left.
    assert!(ADC_SEQUENCE_NS < 10_000);
    assert!(SYSCLK_HZ.is_multiple_of(HSE_HZ));
    // The sequence: every signal in it exactly once, placed around the top of the count.
    assert!(
        slot(Signal::Position) < 4
            && slot(Signal::Current) < 4
            && slot(Signal::Vbus) < 4
            && slot(Signal::Setpoint) < 4
    );
    assert!(slot(Signal::Position) != slot(Signal::Current));
    assert!(slot(Signal::Position) != slot(Signal::Vbus));
    assert!(slot(Signal::Current) != slot(Signal::Vbus));
    assert!(slot(Signal::Setpoint) != slot(Signal::Position));
    assert!(slot(Signal::Setpoint) != slot(Signal::Current));
    assert!(slot(Signal::Setpoint) != slot(Signal::Vbus));
    assert!(TIM1_CLK_HZ.is_multiple_of(ADC_CLK_HZ));
    assert!(ADC_TRIGGER_LEAD_COUNTS < PWM_ARR / 2);
    // The interrupt comes after the top: the tick's writes all wait for the next one.
    assert!(ADC_END_AFTER_TOP_COUNTS > 0 && ADC_END_AFTER_TOP_COUNTS < PWM_ARR / 2);
    // The window watchdog: quiet while on-time ticks feed it, coasting well within the
    // stall limit, by its interrupt or, with interrupts masked, by its reset.
    assert!(WINDOW_WATCHDOG.early_wakeup_min_ns() >= WATCHDOG_QUIET_PERIODS * CONTROL_PERIOD_NS);
    assert!(WINDOW_WATCHDOG.early_wakeup_max_ns() <= STALL_TO_COAST_MAX_NS);
    assert!(WINDOW_WATCHDOG.reset_max_ns() <= STALL_TO_COAST_MAX_NS);
    assert!(WINDOW_WATCHDOG.counts() < Watchdog::MAX_COUNTS);
    // The independent watchdog: a start cannot outlast it; running, it coasts a hung
    // tick within a few milliseconds.
    assert!(IWDG_BOOT.min_us() / 1000 > BOOT_MAX_MS);
    assert!(IWDG_RUN.max_us() < 5_000);
    assert!(IWDG_RUN.min_us() > 2 * CONTROL_PERIOD_NS / 1000);
    // Reset state with WDG_SW cleared: LSI / 4, reload 0xFFF.
    assert!(4096 * 4 * 1000 / LSI_MAX_HZ > 300);
    // The comparator trips inside the current channel's full scale (2047 codes either side
    // of mid-scale), so the converter sees what tripped it.
    assert!(
        BREAK_CURRENT_A <= (2047.0 / 2048.0) * ACTUATOR.board.current_full_scale_a,
        "the break comparator (1.2 x coil.peak_current_a) must trip inside \
         board.current_full_scale_a"
    );
};

/// ADC_JSQR for an injected sequence of four channels. With JL = 3 (four conversions)
/// the ADC converts JSQ1, JSQ2, JSQ3, JSQ4 in that order (RM0090 section 13.13.12: "if
/// JL < 3 the sequence starts at JSQ(4 - JL)", here JSQ1), and the n-th conversion goes
/// to JDRn.
#[must_use]
pub const fn injected_sequence(channels: [u8; 4]) -> u32 {
    let jl = 3;
    (jl << 20)
        | (channels[0] as u32)
        | ((channels[1] as u32) << 5)
        | ((channels[2] as u32) << 10)
        | ((channels[3] as u32) << 15)
}

/// Whether a measured current zero can be trusted.
#[must_use]
pub fn zero_plausible(mean_code: f32, peak_to_peak_codes: u16) -> bool {
    (mean_code - CURRENT_ZERO_CODE).abs() <= ZERO_TOLERANCE_CODES
        && peak_to_peak_codes <= ZERO_MAX_PEAK_TO_PEAK_CODES
}

/// The controller this firmware runs, with the measured current zero (`None`: nominal):
/// every setting derived from [`ACTUATOR`] (the practical law, one sample of measurement
/// delay, which is this firmware's timing, reference shaping and every fault monitor), in
/// the physical convention: settings in the paper's printed convention are refused.
///
/// # Errors
/// An actuator whose settings do not derive; a zero outside the converter range; the
/// paper's convention (named `plant.convention`).
pub fn settings(current_zero_code: Option<f32>) -> Result<Settings, config::Error> {
    let mut s = ACTUATOR.settings()?;
    if s.plant.convention == Convention::Paper {
        return Err(config::Error {
            param: "plant.convention",
            value: 0.0,
            reason: config::Reason::Derived {
                what: "the paper's printed force direction, which no real actuator has",
                derived: 0.0,
            },
        });
    }
    if let Some(code) = current_zero_code {
        s.sense = s.sense.with_current_zero(code)?;
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn injected_sequence_matches_the_reference_manual_layout() {
        // RM0090 13.13.12: JL in bits 21:20, JSQ4 in 19:15, JSQ3 in 14:10, JSQ2 in 9:5,
        // JSQ1 in 4:0; JL = 3 converts JSQ1 to JSQ4. Its example, JSQR = 10 00011 00011
        // 00111 00010 (JL = 2: 7, 3, 3), read with JL = 3, converts 2, 7, 3, 3.
        let rm = 0b10_00011_00011_00111_00010 | (1 << 20);
        assert_eq!(injected_sequence([2, 7, 3, 3]), rm);
        let ours = injected_sequence(INJECTED_SEQUENCE);
        assert_eq!((ours >> 20) & 3, 3);
        assert_eq!(ours & 31, u32::from(POSITION_CHANNEL));
        assert_eq!((ours >> 5) & 31, u32::from(CURRENT_CHANNEL));
        assert_eq!((ours >> 10) & 31, u32::from(VBUS_CHANNEL));
        assert_eq!((ours >> 15) & 31, u32::from(ANALOG_CHANNEL));
    }

    #[test]
    fn the_readout_follows_the_same_table_as_the_set_up() {
        // JDRn holds the n-th conversion: each result lands in the field of the signal
        // the table names for that slot.
        let (f, analog) = frame([100, 2048, 1354, 3000]);
        assert_eq!(INJECTED_SEQUENCE, [10, 11, 12, 13]);
        assert_eq!(
            (f.position, f.current, f.vbus, analog),
            (100, 2048, 1354, 3000)
        );
        for (k, (channel, signal)) in INJECTED.iter().enumerate() {
            let mut results = [0; 4];
            results[k] = 7;
            let (f, analog) = frame(results);
            let got = match signal {
                Signal::Position => f.position,
                Signal::Current => f.current,
                Signal::Vbus => f.vbus,
                Signal::Setpoint => analog,
            };
            assert_eq!(got, 7);
            assert_eq!(
                (injected_sequence(INJECTED_SEQUENCE) >> (5 * k)) & 31,
                u32::from(*channel)
            );
        }
    }

    #[test]
    fn the_conversions_sit_around_the_top_of_the_count() {
        assert_eq!(TIM1_COUNTS_PER_ADC_CYCLE, 8);
        // Current second: 3 + 40 + 28 ADC cycles from the trigger to its hold.
        assert_eq!(CURRENT_SLOT, 1);
        assert_eq!(ADC_TRIGGER_LEAD_COUNTS, 568);
        assert_eq!(ADC_TRIGGER_COMPARE, 3632);
        // 3.4 us before the top to 4.4 us after it: every conversion in the off-time up
        // to a duty of 82.4 % (the control's three up to 86.4 %, as without the analog
        // input; a trigger at the update event would reach 68.9 %).
        assert_eq!(ADC_END_AFTER_TOP_COUNTS, 736);
        assert_eq!(SEQUENCE_IN_OFF_TIME_MAX_PERMILLE, 824);
        // The position and bus samples are 1.9 us either side of the current's.
        let step = (ADC_SAMPLE_CYCLES + ADC_CONVERSION_CYCLES) * TIM1_COUNTS_PER_ADC_CYCLE;
        assert_eq!(step, 320);
    }

    #[test]
    fn the_window_watchdog_coasts_a_stalled_tick_within_half_a_millisecond() {
        assert_eq!(CONTROL_PERIOD_NS, 50_000);
        assert_eq!(WINDOW_WATCHDOG.reload(), 0x43);
        assert_eq!(WINDOW_WATCHDOG.early_wakeup_min_ns(), 195_048);
        assert_eq!(WINDOW_WATCHDOG.early_wakeup_max_ns(), 292_572);
        assert_eq!(WINDOW_WATCHDOG.reset_max_ns(), 390_096);
    }

    #[test]
    fn the_comparator_trips_above_the_software_trip_inside_the_channel() {
        let s = settings(None).unwrap();
        assert!(s.limits.current_trip_a < BREAK_CURRENT_A);
    }

    #[test]
    fn the_bus_takes_the_coils_energy_below_its_rating() {
        assert_eq!(BUS_RATING_V, 36.0);
        let c = bulk_capacitance_f().unwrap();
        assert!((260e-6..270e-6).contains(&c), "{c} F");
    }

    #[test]
    fn timing_constants() {
        assert_eq!(ADC_CLK_HZ, 21_000_000);
        // 4 x 40 ADC cycles at 21 MHz.
        assert_eq!(ADC_SEQUENCE_NS, 7_619);
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
