//! STM32F405 glue at register level: clocks, TIM1 PWM and its ADC trigger, ADC1 injected
//! conversions, the cycle counter, reset cause, debug freeze, and the safe state that
//! needs no HAL object (for the panic and fault handlers).
//!
//! Everything here runs before the control interrupt is enabled, except [`take_frame`],
//! [`conversion_pending`], [`cycles`] and the [`Pwm`] channel, which the interrupt uses,
//! and [`force_coast`], which the panic and fault handlers use.

use core::convert::Infallible;

use cortex_m::peripheral::{DCB, DWT};
use ema::sense::Frame;
use stm32f4xx_hal::gpio::{self, Output, PushPull};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{self, Enable, Rcc, Reset};
use stm32f4xx_hal::timer::{PwmChannel, PwmExt};

use crate::board;

/// The bridge enable pin (board::EN_PORT, board::EN_PIN): start-up must hand over exactly
/// this pin, so the constants and the code cannot disagree.
pub type EnablePin = gpio::Pin<{ board::EN_PORT }, { board::EN_PIN }, Output<PushPull>>;
/// The bridge direction pin (board::DIR_PORT, board::DIR_PIN).
pub type DirectionPin = gpio::Pin<{ board::DIR_PORT }, { board::DIR_PIN }, Output<PushPull>>;
/// The bridge PWM pin before it is given to TIM1 (board::PWM_PORT, board::PWM_PIN).
pub type PwmPin = gpio::Pin<{ board::PWM_PORT }, { board::PWM_PIN }>;

// force_coast writes these pins through the GPIOC and GPIOA register blocks.
const _: () = assert!(board::EN_PORT == 'C' && board::PWM_PORT == 'A' && board::EN_PIN < 16);
const _: () = assert!(board::PWM_PIN < 16);

/// The bridge's direction or enable pin. The core's bridge takes both pins as one type;
/// the HAL's erased pin types would do, but they index the pin number at run time, which
/// links a bounds-check panic into the interrupt. With the pins kept typed, every pin
/// write is one store to BSRR with a constant.
pub enum Pin {
    /// Bridge direction.
    Direction(DirectionPin),
    /// Bridge enable.
    Enable(EnablePin),
}

impl embedded_hal::digital::ErrorType for Pin {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for Pin {
    #[inline]
    fn set_low(&mut self) -> Result<(), Infallible> {
        match self {
            Pin::Direction(p) => p.set_low(),
            Pin::Enable(p) => p.set_low(),
        }
        Ok(())
    }

    #[inline]
    fn set_high(&mut self) -> Result<(), Infallible> {
        match self {
            Pin::Direction(p) => p.set_high(),
            Pin::Enable(p) => p.set_high(),
        }
        Ok(())
    }
}

/// The H-bridge as the firmware drives it.
pub type Bridge = ema::bridge::HBridge<Pwm, Pin>;

/// The clock tree: 168 MHz from the 8 MHz crystal, APB1 42 MHz, APB2 84 MHz.
pub fn clocks() -> rcc::Config {
    rcc::Config::hse(board::HSE_HZ.Hz())
        .sysclk(board::SYSCLK_HZ.Hz())
        .hclk(board::SYSCLK_HZ.Hz())
        .pclk1(board::PCLK1_HZ.Hz())
        .pclk2(board::PCLK2_HZ.Hz())
}

/// `true` when the clock tree came out as [`clocks`] asked.
pub fn clocks_ok(rcc: &Rcc) -> bool {
    let c = &rcc.clocks;
    c.sysclk().raw() == board::SYSCLK_HZ
        && c.pclk1().raw() == board::PCLK1_HZ
        && c.pclk2().raw() == board::PCLK2_HZ
}

/// Whether the last reset was the independent watchdog's; clears the reset flags.
pub fn take_watchdog_reset(rcc: &pac::RCC) -> bool {
    let by_watchdog = rcc.csr().read().wdgrstf().bit_is_set();
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    by_watchdog
}

/// While a debugger halts the core: TIM1 stops with its outputs disabled (as if MOE were
/// cleared: the PWM pin goes inactive, no pulse is frozen on), and the watchdog pauses.
pub fn freeze_on_debug_halt(dbg: &pac::DBGMCU) {
    dbg.apb2_fz().modify(|_, w| w.dbg_tim1_stop().set_bit());
    dbg.apb1_fz().modify(|_, w| w.dbg_iwdg_stop().set_bit());
}

/// Starts the DWT cycle counter.
pub fn start_cycle_counter(dcb: &mut DCB, dwt: &mut DWT) {
    dcb.enable_trace();
    dwt.enable_cycle_counter();
}

/// The cycle counter.
#[inline(always)]
pub fn cycles() -> u32 {
    DWT::cycle_count()
}

/// TIM1 channel 1 for the bridge. A duty of 0 takes effect at once, any other duty at the
/// next update event (the compare preload keeps the pulses symmetric).
///
/// Why zero is special: the core's bridge coasts and reverses as `duty 0, enable low,
/// direction, enable high, duty` within one tick, assuming each step acts at once. Enable
/// and direction are GPIO writes and do; a preloaded compare value would only change at
/// the next update, leaving the old duty running for the rest of the period with the
/// bridge enabled in the new direction. Writing 0 with the preload briefly off makes the
/// output inactive immediately, so the bridge is only ever enabled at zero duty, as the
/// core intends; the new duty then starts with the next period.
pub struct Pwm(PwmChannel<pac::TIM1, 0>);

impl embedded_hal::pwm::ErrorType for Pwm {
    type Error = Infallible;
}

impl embedded_hal::pwm::SetDutyCycle for Pwm {
    fn max_duty_cycle(&self) -> u16 {
        self.0.get_max_duty()
    }

    #[inline]
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        if duty == 0 {
            // SAFETY: CCMR1 of TIM1 is only ever written here and by the set-up below (which
            // has finished before the bridge exists); the interrupt that calls this is the
            // only one touching TIM1, so the read-modify-writes cannot interleave.
            let tim = unsafe { &*pac::TIM1::ptr() };
            tim.ccmr1_output().modify(|_, w| w.oc1pe().clear_bit());
            self.0.set_duty(0);
            tim.ccmr1_output().modify(|_, w| w.oc1pe().set_bit());
        } else {
            self.0.set_duty(duty);
        }
        Ok(())
    }
}

/// TIM1 at 20 kHz center-aligned on the PWM pin, its update event once per period on TRGO
/// (the ADC trigger), main output enabled, channel enabled at duty 0.
pub fn pwm(tim1: pac::TIM1, pin: PwmPin, rcc: &mut Rcc) -> Pwm {
    // Prescaler 0 (the timer counts at TIM1_CLK_HZ), ARR = PWM_ARR, compare preload on,
    // PWM mode 1, counter running edge-aligned for now.
    let (_manager, (ch1, ..)) = tim1.pwm::<{ board::TIM1_CLK_HZ }>(
        fugit::TimerDurationU32::from_ticks(board::PWM_ARR + 1),
        rcc,
    );
    let mut ch1 = ch1.with(pin);
    ch1.set_duty(0);
    // SAFETY: TIM1 belongs to this function (the HAL objects above own it and only write
    // CCR1 and CCER from now on); nothing else runs yet.
    let tim = unsafe { &*pac::TIM1::ptr() };
    // RM0090 17.3.3: the counting mode may only change while the counter is stopped.
    tim.cr1().modify(|_, w| w.cen().clear_bit());
    tim.cnt().reset();
    tim.cr1().modify(|_, w| w.cms().center_aligned1());
    // Written before the counter starts: the update event falls on the overflow (top).
    tim.rcr().write(|w| w.rep().set(board::PWM_REPETITION));
    // Load prescaler, ARR, CCR1 and the repetition counter now. MMS is still "reset", so
    // this UG also pulses TRGO, harmlessly: the ADC's trigger is not enabled yet.
    tim.egr().write(|w| w.ug().set_bit());
    tim.cr2().modify(|_, w| w.mms().update());
    tim.bdtr().modify(|_, w| w.moe().set_bit());
    ch1.enable();
    tim.cr1().modify(|_, w| w.cen().set_bit());
    Pwm(ch1)
}

/// ADC1 converting current, position and bus voltage (board::INJECTED_SEQUENCE) as an
/// injected sequence on every rising edge of TIM1 TRGO, JEOC interrupt enabled (the NVIC
/// line stays masked until the controller is handed over).
pub fn start_adc(adc1: pac::ADC1, common: &pac::ADC_COMMON, rcc: &mut Rcc) {
    pac::ADC1::enable(rcc);
    pac::ADC1::reset(rcc);
    common.ccr().modify(|_, w| w.adcpre().div4());
    adc1.cr1().write(|w| w.scan().set_bit().jeocie().set_bit());
    adc1.smpr1().write(|w| {
        w.smp10().cycles28();
        w.smp11().cycles28();
        w.smp12().cycles28()
    });
    // SAFETY: JSQR takes any 22-bit value; this one is built by board::injected_sequence
    // from channel numbers below 19 (checked in its unit test).
    adc1.jsqr()
        .write(|w| unsafe { w.bits(board::injected_sequence(board::INJECTED_SEQUENCE)) });
    adc1.cr2().write(|w| w.adon().set_bit());
    // tSTAB (3 us, datasheet) before the first trigger is honoured.
    cortex_m::asm::delay(board::SYSCLK_HZ / 1_000_000 * 5);
    adc1.cr2()
        .modify(|_, w| w.jexten().rising_edge().jextsel().tim1trgo());
}

fn adc1() -> &'static pac::adc1::RegisterBlock {
    // SAFETY: after start_adc, ADC1's status and injected data registers are only read (and
    // JEOC cleared) by the one context that consumes conversions: the start-up code, then
    // the control interrupt.
    unsafe { &*pac::ADC1::ptr() }
}

/// Clears the end-of-injected-conversion flag and returns the three codes.
#[inline(always)]
pub fn take_frame() -> Frame {
    let adc = adc1();
    adc.sr().write(|w| w.jeoc().clear());
    Frame {
        current: adc.jdr1().read().jdata().bits(),
        position: adc.jdr2().read().jdata().bits(),
        vbus: adc.jdr3().read().jdata().bits(),
    }
}

/// `true` when a sequence has completed since the last [`take_frame`].
#[inline(always)]
pub fn conversion_pending() -> bool {
    adc1().sr().read().jeoc().bit_is_set()
}

/// The safe state, forced by register writes that need no HAL object and no lock: bridge
/// enable low (coast), TIM1 main output off, compare 0, and the PWM pin turned into a GPIO
/// output driven low. Safe to call at any time, any number of times, from any context
/// (a write to a peripheral whose clock is still off is ignored, and then the pins are
/// still in their reset state: inputs, EN pulled down by the board).
pub fn force_coast() {
    // Raw bit values, not the PAC's indexed field writers: those check the index at run
    // time, and a panic handler must not be able to panic.
    let en_reset = 1u32 << (16 + board::EN_PIN);
    let pwm_reset = 1u32 << (16 + board::PWM_PIN);
    let pwm_mode_mask = 0b11u32 << (2 * board::PWM_PIN);
    let pwm_mode_output = 0b01u32 << (2 * board::PWM_PIN);
    // SAFETY: fixed register blocks of this chip. A single 32-bit write to BSRR is atomic
    // with respect to every other pin operation; the read-modify-writes of TIM1 and GPIOA
    // can only race with code that the caller has stopped (it runs with interrupts masked
    // or as the hard-fault handler), and they only move the outputs towards the safe state.
    // Every value written is valid for its register (BSRR: the reset bit of one pin;
    // MODER: general-purpose output for one pin; CCR1: 0).
    unsafe {
        let gpioc = &*pac::GPIOC::ptr();
        gpioc.bsrr().write(|w| w.bits(en_reset));
        let tim = &*pac::TIM1::ptr();
        tim.bdtr()
            .modify(|_, w| w.moe().clear_bit().aoe().clear_bit());
        tim.ccr1().write(|w| w.ccr().set(0));
        let gpioa = &*pac::GPIOA::ptr();
        gpioa.bsrr().write(|w| w.bits(pwm_reset));
        gpioa
            .moder()
            .modify(|r, w| w.bits((r.bits() & !pwm_mode_mask) | pwm_mode_output));
    }
}
