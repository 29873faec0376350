//! STM32F405 glue at register level: TIM1 with the three bridge lines and the ADC trigger,
//! ADC1 injected conversions, the watchdogs, the clock security system, the cycle
//! counter, reset flags, debug freeze, and the safe state that needs no HAL object (for
//! the fault handlers). Register values come from [`crate::regs`].
//!
//! Everything here runs before the control interrupt is enabled, except [`take_frame`],
//! [`begin_period`], [`period_boundary_passed`], [`conversion_pending`], [`cycles`],
//! [`break_input_active`], [`enable_outputs`] (after a cleared hardware trip), [`Pwm`],
//! [`Line`] and [`Watchdogs::feed`], which the interrupt uses, and
//! [`force_coast`] and [`clear_clock_failure`], which the fault handlers use.

use core::convert::Infallible;

use cortex_m::peripheral::{DCB, DWT};
use ema::control::sense::Frame;
use stm32f4xx_hal::gpio;
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Enable, Rcc, Reset};

use crate::board;
use crate::regs;
use crate::reset;

/// The bridge PWM pin before it is given to TIM1 (board::PWM_PORT, board::PWM_PIN).
pub type PwmPin = gpio::Pin<{ board::PWM_PORT }, { board::PWM_PIN }>;
/// The bridge enable pin before it is given to TIM1 (board::EN_PORT, board::EN_PIN).
pub type EnablePin = gpio::Pin<{ board::EN_PORT }, { board::EN_PIN }>;
/// The bridge direction pin before it is given to TIM1 (board::DIR_PORT, board::DIR_PIN).
pub type DirectionPin = gpio::Pin<{ board::DIR_PORT }, { board::DIR_PIN }>;
/// The break input before it is given to TIM1 (board::BREAK_PORT, board::BREAK_PIN).
pub type BreakPin = gpio::Pin<{ board::BREAK_PORT }, { board::BREAK_PIN }>;

// force_coast writes the three bridge pins through the GPIOA register block.
const _: () = assert!(board::PWM_PORT == 'A' && board::EN_PORT == 'A' && board::DIR_PORT == 'A');
const _: () = assert!(board::PWM_PIN < 16 && board::EN_PIN < 16 && board::DIR_PIN < 16);
/// The three bridge pins in a GPIO port's 16-bit pin mask.
const BRIDGE_PINS: u32 = (1 << board::PWM_PIN) | (1 << board::EN_PIN) | (1 << board::DIR_PIN);
/// GPIOx_MODER bits of the three pins (two per pin).
const BRIDGE_MODE_MASK: u32 =
    (0b11 << (2 * board::PWM_PIN)) | (0b11 << (2 * board::EN_PIN)) | (0b11 << (2 * board::DIR_PIN));
/// GPIOx_MODER value of the three pins as general-purpose outputs (01).
const BRIDGE_MODE_OUTPUT: u32 =
    (0b01 << (2 * board::PWM_PIN)) | (0b01 << (2 * board::EN_PIN)) | (0b01 << (2 * board::DIR_PIN));

fn tim1() -> &'static pac::tim1::RegisterBlock {
    // SAFETY: after `start_pwm`, TIM1 is written only by the control interrupt (compare
    // registers, the enable's preload bit, the update flag) and by `force_coast` (the main
    // output bit), which only moves the outputs to their safe level; see each use.
    unsafe { &*pac::TIM1::ptr() }
}

/// TIM1 channel 1: the bridge PWM. Every duty is preloaded: it takes effect at the next
/// update event, the top of the count, together with the direction and the enable.
pub struct Pwm(());

impl embedded_hal::pwm::ErrorType for Pwm {
    type Error = Infallible;
}

impl embedded_hal::pwm::SetDutyCycle for Pwm {
    fn max_duty_cycle(&self) -> u16 {
        board::PWM_MAX_DUTY
    }

    #[inline]
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        tim1().ccr1().write(|w| w.ccr().set(duty));
        Ok(())
    }
}

/// The bridge's direction or enable line, each a TIM1 output whose compare value keeps it
/// high ([`regs::LINE_HIGH`]) or low all period. Writes are preloaded (they take effect at
/// the next period boundary, with the duty), except the enable's fall, which acts at once:
/// that is the coast.
pub enum Line {
    /// Bridge direction, TIM1 channel 3.
    Direction,
    /// Bridge enable, TIM1 channel 2.
    Enable,
}

impl embedded_hal::digital::ErrorType for Line {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for Line {
    #[inline]
    fn set_low(&mut self) -> Result<(), Infallible> {
        match self {
            Line::Direction => {
                tim1().ccr3().write(|w| w.ccr().set(regs::LINE_LOW));
            }
            Line::Enable => enable_off_now(),
        }
        Ok(())
    }

    #[inline]
    fn set_high(&mut self) -> Result<(), Infallible> {
        let ccr = match self {
            Line::Direction => tim1().ccr3(),
            Line::Enable => tim1().ccr2(),
        };
        ccr.write(|w| w.ccr().set(regs::LINE_HIGH));
        Ok(())
    }
}

/// The enable low now, and from the next update event on: compare 2 written with its
/// preload briefly off (RM0090 17.3.10: without preload a compare write takes effect at
/// once), so the active and the preloaded value are both 0.
#[inline]
fn enable_off_now() {
    let tim = tim1();
    // SAFETY: CCMR1 takes any value with the channel bits kept as set up; only OC2PE
    // changes. The read-modify-writes run in the control interrupt (or before it exists)
    // and can only be preempted by a fault handler, which never writes CCMR1.
    tim.ccmr1_output()
        .modify(|r, w| unsafe { w.bits(r.bits() & !regs::CCMR1_OC2PE) });
    tim.ccr2().write(|w| w.ccr().set(regs::LINE_LOW));
    tim.ccmr1_output()
        .modify(|r, w| unsafe { w.bits(r.bits() | regs::CCMR1_OC2PE) });
}

/// The H-bridge as the firmware drives it.
pub type Bridge = ema::control::bridge::HBridge<Pwm, Line>;

/// Why the clock tree did not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum ClockError {
    /// The crystal was not ready within [`board::HSE_STARTUP_TIMEOUT_CYCLES`].
    Crystal,
    /// The PLL did not lock within [`board::PLL_LOCK_TIMEOUT_CYCLES`].
    Pll,
    /// The system clock did not switch to the PLL within [`board::PLL_LOCK_TIMEOUT_CYCLES`].
    Switch,
}

/// Polls `ready` until it holds or `timeout` cycles of the cycle counter have passed.
fn wait_for(timeout: u32, ready: impl Fn() -> bool) -> bool {
    let t0 = cycles();
    while !ready() {
        if cycles().wrapping_sub(t0) > timeout {
            return false;
        }
    }
    true
}

/// The clock tree: 168 MHz from the 8 MHz crystal, APB1 42 MHz, APB2 84 MHz, by register
/// writes ([`regs::RCC_PLLCFGR`] and its neighbours), in the order the HAL's `Rcc::freeze`
/// makes them. Each wait is bounded (the cycle counter must run: [`start_cycle_counter`]
/// first; the core runs on the 16 MHz internal oscillator until the switch) and a wait
/// that runs out is a named failure, with the crystal and the PLL left as they are. The
/// returned `Rcc` enables and resets the peripherals; its `clocks` field is the HAL's
/// default and means nothing here (nothing reads it: the timer, ADC and USART values come
/// from `board`).
///
/// # Errors
/// The crystal not ready, the PLL not locked or the switch to it not done in time.
pub fn start_clocks(rcc: pac::RCC) -> Result<Rcc, ClockError> {
    let cr = |bit: u32| move || rcc_now().cr().read().bits() & bit != 0;
    // SAFETY: register values from RM0090 (see `regs`); start-up owns RCC and FLASH here,
    // nothing else runs yet.
    unsafe {
        let flash = &*pac::FLASH::ptr();
        flash
            .acr()
            .modify(|r, w| w.bits((r.bits() & !regs::FLASH_ACR_MASK) | regs::FLASH_ACR));
        rcc.cr()
            .modify(|r, w| w.bits(r.bits() | regs::RCC_CR_HSEON));
    }
    if !wait_for(board::HSE_STARTUP_TIMEOUT_CYCLES, cr(regs::RCC_CR_HSERDY)) {
        return Err(ClockError::Crystal);
    }
    // SAFETY: as above.
    unsafe {
        rcc.pllcfgr().write(|w| w.bits(regs::RCC_PLLCFGR));
        rcc.cr()
            .modify(|r, w| w.bits(r.bits() | regs::RCC_CR_PLLON));
    }
    if !wait_for(board::PLL_LOCK_TIMEOUT_CYCLES, cr(regs::RCC_CR_PLLRDY)) {
        return Err(ClockError::Pll);
    }
    // SAFETY: as above.
    unsafe {
        rcc.cfgr()
            .modify(|r, w| w.bits(r.bits() & !regs::RCC_CFGR_I2SSRC));
        rcc.cfgr()
            .modify(|r, w| w.bits((r.bits() & !regs::RCC_CFGR_PRE_MASK) | regs::RCC_CFGR_PRE));
        // "The clocks are divided with the new prescaler factor from 1 to 16 AHB cycles
        // after write" (RM0090 7.3.3).
        cortex_m::asm::delay(16);
        rcc.cfgr()
            .modify(|r, w| w.bits((r.bits() & !regs::RCC_CFGR_SW_MASK) | regs::RCC_CFGR_SW_PLL));
    }
    let switched =
        || rcc_now().cfgr().read().bits() & regs::RCC_CFGR_SWS_MASK == regs::RCC_CFGR_SWS_PLL;
    if !wait_for(board::PLL_LOCK_TIMEOUT_CYCLES, switched) {
        return Err(ClockError::Switch);
    }
    Ok(rcc.constrain())
}

fn rcc_now() -> &'static pac::rcc::RegisterBlock {
    // SAFETY: reads only (the waits of `start_clocks`, which owns RCC).
    unsafe { &*pac::RCC::ptr() }
}

/// The independent watchdog, at register level (RM0090 section 20): started, or its
/// timeout changed while it runs, to `timeout`; waits (at most
/// [`board::IWDG_UPDATE_CYCLES`]) until the new values are in force, then reloads the
/// counter with them. Returns whether they took. Safe at any time: the first write starts
/// it (if the option bytes have not already), and from then on only the timeout changes.
pub fn start_independent_watchdog(timeout: board::IwdgTimeout) -> bool {
    // SAFETY: IWDG's key, prescaler and reload registers take these values (RM0090 20.4:
    // the prescaler code 3 bits, the reload 12, checked by `board::IwdgTimeout`); only
    // start-up writes them, before the interrupts run, and the tick's feed writes the key
    // only.
    let iwdg = unsafe { &*pac::IWDG::ptr() };
    iwdg.kr()
        .write(|w| unsafe { w.key().bits(regs::IWDG_KEY_START) });
    // The prescaler and reload registers are written only when no earlier update is in
    // progress (PVU, RVU clear).
    let idle = || iwdg.sr().read().bits() & regs::IWDG_SR_UPDATING == 0;
    if !wait_for(board::IWDG_UPDATE_CYCLES, idle) {
        return false;
    }
    iwdg.kr()
        .write(|w| unsafe { w.key().bits(regs::IWDG_KEY_ACCESS) });
    iwdg.pr()
        .write(|w| unsafe { w.pr().bits(timeout.prescaler_code) });
    iwdg.rlr().write(|w| w.rl().set(timeout.reload));
    let took = wait_for(board::IWDG_UPDATE_CYCLES, idle);
    feed_independent_watchdog();
    took
}

/// Reloads the independent watchdog's counter (a feed).
#[inline(always)]
pub fn feed_independent_watchdog() {
    // SAFETY: a write of the reload key to IWDG_KR, which only reloads the counter.
    let iwdg = unsafe { &*pac::IWDG::ptr() };
    iwdg.kr()
        .write(|w| unsafe { w.key().bits(regs::IWDG_KEY_RELOAD) });
}

/// `true` when the clock tree is the one [`start_clocks`] set: read back from the
/// registers (PLL configuration and lock, prescalers, system clock source, flash wait
/// states).
pub fn clocks_ok() -> bool {
    // SAFETY: reads only.
    let (rcc, flash) = unsafe { (&*pac::RCC::ptr(), &*pac::FLASH::ptr()) };
    let cfgr = rcc.cfgr().read().bits();
    rcc.pllcfgr().read().bits() == regs::RCC_PLLCFGR
        && rcc.cr().read().bits() & regs::RCC_CR_PLLRDY != 0
        && cfgr & regs::RCC_CFGR_PRE_MASK == regs::RCC_CFGR_PRE
        && cfgr & regs::RCC_CFGR_SWS_MASK == regs::RCC_CFGR_SWS_PLL
        && flash.acr().read().bits() & regs::FLASH_ACR_MASK == regs::FLASH_ACR
}

/// The watchdog reset flags of the last reset; clears all reset flags.
pub fn take_reset_flags(rcc: &pac::RCC) -> reset::Flags {
    let csr = rcc.csr().read();
    let flags = reset::Flags {
        independent_watchdog: csr.wdgrstf().bit_is_set(),
        window_watchdog: csr.wwdgrstf().bit_is_set(),
    };
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    flags
}

/// Turns the clock security system on (RM0090 7.2.7): if the crystal fails, the chip
/// switches to its internal oscillator, TIM1 breaks (outputs off, like its break input)
/// and the non-maskable interrupt runs.
pub fn start_clock_security() {
    // SAFETY: RCC_CR takes CSSON with every other bit as read; the clock set-up is over
    // and nothing else writes RCC_CR.
    let rcc = unsafe { &*pac::RCC::ptr() };
    rcc.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | regs::RCC_CR_CSSON) });
}

/// Clears the clock-security flag (without it the non-maskable interrupt would re-enter
/// forever).
pub fn clear_clock_failure() {
    // SAFETY: RCC_CIR: CSSC is write-1-to-clear; the enable bits are written back as
    // read, the flags are read-only. Called from the non-maskable interrupt only.
    let rcc = unsafe { &*pac::RCC::ptr() };
    rcc.cir()
        .modify(|r, w| unsafe { w.bits(r.bits() | regs::RCC_CIR_CSSC) });
}

/// While a debugger halts the core: TIM1 stops with its outputs at their idle level (its
/// main output acts as off and OSSI = 1: all three bridge lines low, the bridge coasts,
/// RM0090 17.3.21), and both watchdogs pause.
pub fn freeze_on_debug_halt(dbg: &pac::DBGMCU) {
    dbg.apb2_fz().modify(|_, w| w.dbg_tim1_stop().set_bit());
    dbg.apb1_fz()
        .modify(|_, w| w.dbg_iwdg_stop().set_bit().dbg_wwdg_stop().set_bit());
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

/// Why the PWM did not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum PhaseError {
    /// No update event came within three periods.
    NoUpdate,
    /// The update event fell at the bottom of the count (in the middle of the pulses).
    UpdateAtBottom,
}

/// TIM1 from [`regs`]: the break pin handed to it first (its pull-up holding it high, so
/// that enabling the break does not see the reset state of a floating input), the bridge
/// lines driven low (main output off), the pins handed to it, the counter running; then checks that the update event falls at the top of the
/// count (RM0090 17.3.3: with an odd repetition count in center-aligned mode, whether it
/// lands on the overflow or the underflow depends on when RCR was written and the counter
/// started). The main output stays off until [`enable_outputs`].
///
/// # Errors
/// The update event does not come, or comes at the bottom: the compare values would
/// change in the middle of a pulse.
pub fn start_pwm(
    timer: pac::TIM1,
    pins: (PwmPin, EnablePin, DirectionPin, BreakPin),
    rcc: &mut Rcc,
) -> Result<(Pwm, Line, Line), PhaseError> {
    pac::TIM1::enable(rcc);
    pac::TIM1::reset(rcc);
    let (pwm, en, dir, brk) = pins;
    let _brk = brk.into_alternate::<1>().internal_pull_up(true);
    // The board's pull-up (4.7 kOhm, tens of picofarads: well under a microsecond) has
    // settled the pin before the break is enabled.
    cortex_m::asm::delay(board::SYSCLK_HZ / 1_000_000);
    let tim = &timer;
    // SAFETY: TIM1 is owned here, clocked and reset, its counter stopped. Every value
    // comes from `regs`, where it is checked against the reference manual's bit positions;
    // prescaler 0, ARR and the compares fit their 16-bit registers (board asserts).
    unsafe {
        tim.cr1().write(|w| w.bits(regs::CR1));
        tim.cr2().write(|w| w.bits(regs::CR2));
        tim.psc().write(|w| w.bits(0));
        tim.arr().write(|w| w.bits(board::PWM_ARR));
        tim.rcr().write(|w| w.bits(regs::RCR));
        tim.ccmr1_output().write(|w| w.bits(regs::CCMR1));
        tim.ccmr2_output().write(|w| w.bits(regs::CCMR2));
        tim.ccr1().write(|w| w.bits(0));
        tim.ccr2().write(|w| w.bits(u32::from(regs::LINE_LOW)));
        tim.ccr3().write(|w| w.bits(u32::from(regs::LINE_LOW)));
        tim.ccr4().write(|w| w.bits(board::ADC_TRIGGER_COMPARE));
        tim.ccer().write(|w| w.bits(regs::CCER));
        // One write, lock included: the break and off-state settings cannot change again
        // before a reset.
        tim.bdtr().write(|w| w.bits(regs::BDTR));
    }
    // BKE takes one APB clock to act (RM0090 17.3.12); then a flag the enabling may have
    // raised goes, unless the break input really is active.
    cortex_m::asm::delay(8);
    tim.sr().write(|w| unsafe { w.bits(0) });
    // UG loads the prescaler, ARR, the compares and the repetition counter and clears the
    // counter; RCR is written before the counter starts. TRGO is compare 4, so this does
    // not trigger a conversion.
    tim.egr().write(|w| w.ug().set_bit());
    tim.sr().write(|w| w.uif().clear());
    // The bridge pins go to the timer now: its outputs are enabled at their idle level
    // (low).
    let _pwm = pwm.into_alternate::<1>();
    let _en = en.into_alternate::<1>();
    let _dir = dir.into_alternate::<1>();
    tim.cr1()
        .modify(|r, w| unsafe { w.bits(r.bits() | regs::CR1_CEN) });

    let cr1 = wait_update(3 * board::CONTROL_PERIOD_CYCLES).ok_or(PhaseError::NoUpdate)?;
    if !regs::update_at_top(cr1) {
        return Err(PhaseError::UpdateAtBottom);
    }
    Ok((Pwm(()), Line::Direction, Line::Enable))
}

/// Waits for the next update event, at most `timeout` cycles; returns TIM1_CR1 read as
/// soon as it is seen, and clears the flag.
fn wait_update(timeout: u32) -> Option<u32> {
    let tim = tim1();
    tim.sr().write(|w| w.uif().clear());
    let t0 = cycles();
    while tim.sr().read().bits() & regs::SR_UIF == 0 {
        if cycles().wrapping_sub(t0) > timeout {
            return None;
        }
    }
    let cr1 = tim.cr1().read().bits();
    tim.sr().write(|w| w.uif().clear());
    Some(cr1)
}

/// Turns TIM1's main output on: the lines follow their compare values (the bridge still
/// coasts: the enable's compare is 0). Has no effect while the break input is active.
pub fn enable_outputs() {
    // SAFETY: only MOE changes (the other BDTR bits are written back; the locked ones
    // ignore writes anyway). Runs before the control interrupt is enabled.
    tim1()
        .bdtr()
        .modify(|r, w| unsafe { w.bits(r.bits() | regs::BDTR_MOE) });
}

/// Clears the break flag (the record of a hardware trip) once a clear has accepted the
/// trip with its cause gone; the other flags are written 1 (no change).
pub fn clear_break_flag() {
    tim1().sr().write(|w| w.bif().clear());
}

/// The break flag is set: the bridge's hardware protection switched the outputs off (at
/// start: its input is active).
pub fn hardware_tripped() -> bool {
    tim1().sr().read().bits() & regs::SR_BIF != 0
}

/// The break input is active now (its cause is still there: the pin is low), as opposed to
/// the break flag, which records that it was.
#[inline(always)]
pub fn break_input_active() -> bool {
    // SAFETY: a read of GPIOB's input data register, which has no side effect.
    let gpiob = unsafe { &*pac::GPIOB::ptr() };
    gpiob.idr().read().bits() & (1 << board::BREAK_PIN) == 0
}

/// At the interrupt's start: whether the bridge's hardware protection has switched the
/// outputs off (break flag), and clears the update flag of the top that began this
/// period, so that [`period_boundary_passed`] sees only the next one.
#[inline(always)]
pub fn begin_period() -> bool {
    let tim = tim1();
    let sr = tim.sr().read().bits();
    // Only UIF: the other flags are written 1 (no change), BIF stays as a record.
    tim.sr().write(|w| w.uif().clear());
    sr & regs::SR_BIF != 0
}

/// Whether an update event (the period boundary at which the tick's writes take effect)
/// came since [`begin_period`].
#[inline(always)]
pub fn period_boundary_passed() -> bool {
    tim1().sr().read().bits() & regs::SR_UIF != 0
}

/// ADC1 converting board::INJECTED as an injected sequence on every rising edge of TIM1
/// TRGO (compare 4), JEOC interrupt enabled (the NVIC line stays masked until the
/// controller is handed over).
pub fn start_adc(adc1: pac::ADC1, common: &pac::ADC_COMMON, rcc: &mut Rcc) {
    pac::ADC1::enable(rcc);
    pac::ADC1::reset(rcc);
    common.ccr().modify(|_, w| w.adcpre().div4());
    adc1.cr1().write(|w| w.scan().set_bit().jeocie().set_bit());
    adc1.smpr1().write(|w| {
        w.smp10().cycles28();
        w.smp11().cycles28();
        w.smp12().cycles28();
        w.smp13().cycles28()
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

/// Clears the end-of-injected-conversion flag and returns the control's frame and the
/// analog set-point code, each from the slot board::INJECTED names.
#[inline(always)]
pub fn take_frame() -> (Frame, u16) {
    let adc = adc1();
    adc.sr().write(|w| w.jeoc().clear());
    board::frame([
        adc.jdr1().read().jdata().bits(),
        adc.jdr2().read().jdata().bits(),
        adc.jdr3().read().jdata().bits(),
        adc.jdr4().read().jdata().bits(),
    ])
}

/// `true` when a sequence has completed since the last [`take_frame`].
#[inline(always)]
pub fn conversion_pending() -> bool {
    adc1().sr().read().jeoc().bit_is_set()
}

/// Waits for the next sequence, at most `timeout` cycles; returns TIM1_CR1 and TIM1_CNT
/// read as soon as its end is seen (for [`regs::conversions_placed`]) and the frame.
pub fn wait_conversion(timeout: u32) -> Option<(u32, u32, Frame)> {
    let t0 = cycles();
    while !conversion_pending() {
        if cycles().wrapping_sub(t0) > timeout {
            return None;
        }
    }
    let tim = tim1();
    let cnt = tim.cnt().read().bits();
    let cr1 = tim.cr1().read().bits();
    Some((cr1, cnt, take_frame().0))
}

/// Both watchdogs; the tick feeds them when the guard says it ran on time and the main
/// loop has checked in.
pub struct Watchdogs(());

impl Watchdogs {
    /// Starts the window watchdog (board::WINDOW_WATCHDOG, early-wakeup interrupt on; its
    /// NVIC line is unmasked by the caller) beside the running independent one, which
    /// start-up has tightened to its running timeout. Once started, only a reset stops it:
    /// every step that can fail comes before.
    #[inline(never)]
    pub fn start() -> Self {
        // SAFETY: RCC_APB1ENR: one more clock enable bit, written back as read otherwise;
        // the WWDG values come from `regs` (checked against RM0090 21.6).
        unsafe {
            let rcc = &*pac::RCC::ptr();
            rcc.apb1enr().modify(|_, w| w.wwdgen().set_bit());
            let wwdg = &*pac::WWDG::ptr();
            wwdg.cfr().write(|w| w.bits(regs::WWDG_CFR));
            wwdg.sr().write(|w| w.bits(0));
            wwdg.cr().write(|w| w.bits(regs::WWDG_CR));
        }
        Self(())
    }

    /// Feeds both.
    #[inline(always)]
    pub fn feed(&mut self) {
        feed_independent_watchdog();
        // SAFETY: WWDG_CR takes WDGA (already set) and the counter reload from `regs`;
        // the window is open (W = 0x7F), so a feed is never early.
        unsafe { (*pac::WWDG::ptr()).cr().write(|w| w.bits(regs::WWDG_CR)) };
    }
}

/// The safe state, forced by register writes that need no HAL object and no lock: TIM1's
/// main output off (with OSSI = 1 the three bridge lines go to their idle level, low: the
/// bridge coasts), the enable's compare 0, and the three pins turned into GPIO outputs
/// driven low, so that they no longer depend on the timer at all. Safe to call at any
/// time, any number of times, from any context (a write to a peripheral whose clock is
/// still off is ignored, and then the pins are still in their reset state: inputs, pulled
/// down by the board).
pub fn force_coast() {
    // Raw bit values, not the PAC's indexed field writers: those check the index at run
    // time, and a fault handler must not be able to panic.
    // SAFETY: fixed register blocks of this chip. Each write only moves the outputs towards
    // the safe state: BDTR loses MOE (the locked bits ignore the write-back), CCR2 gets 0,
    // BSRR gets the reset bits of the three pins (a single, atomic write), MODER makes them
    // outputs. A read-modify-write here can only race with code this handler preempted;
    // that code writes neither BDTR nor MODER.
    unsafe {
        let tim = &*pac::TIM1::ptr();
        tim.bdtr().modify(|r, w| w.bits(r.bits() & !regs::BDTR_MOE));
        tim.ccr2().write(|w| w.bits(u32::from(regs::LINE_LOW)));
        let gpioa = &*pac::GPIOA::ptr();
        gpioa.bsrr().write(|w| w.bits(BRIDGE_PINS << 16));
        gpioa
            .moder()
            .modify(|r, w| w.bits((r.bits() & !BRIDGE_MODE_MASK) | BRIDGE_MODE_OUTPUT));
    }
}
