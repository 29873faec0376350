//! Start-up, the control interrupt, the window watchdog's early wake-up, the status line,
//! and the panic and fault handlers.

use core::cell::Cell;
use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::interrupt::{self as irq, Mutex};
use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt_rtt as _;
use ema::control::{Config, State};
use ema::guard::{self, End, Start};
use ema::supervisor::Fault;
use stm32f4xx_hal::pac::{self, interrupt, Interrupt};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::watchdog::IndependentWatchdog;

use crate::board;
use crate::hw::{self, Bridge, Watchdogs};
use crate::regs;
use crate::reset::{self, Cause, Record};
use crate::stats::{self, Cycles, Published, Snapshot};

/// NVIC priority of the window watchdog's early wake-up: the highest, so that it preempts
/// a control interrupt that never ends (4 priority bits, in the high nibble).
const WWDG_PRIORITY: u8 = 0x00;
/// NVIC priority of the control interrupt: one level below.
const ADC_PRIORITY: u8 = 0x10;

// The guard's late-start threshold is the board's documented overrun gap.
const _: () = assert!(
    guard::Config::for_period(board::CONTROL_PERIOD_CYCLES).max_gap() == board::OVERRUN_GAP_CYCLES
);

/// Everything the control interrupt owns.
struct Control {
    cfg: Config,
    state: State,
    bridge: Bridge,
    watchdogs: Watchdogs,
    guard: guard::Config,
    guarded: guard::State,
    cycles: Cycles,
}

/// Start-up hands the controller to the interrupt through this cell, once.
static HANDOFF: Mutex<Cell<Option<Control>>> = Mutex::new(Cell::new(None));
/// Position set point \[m\], as `f32` bits (a future command interface writes it).
static SETPOINT_M: AtomicU32 = AtomicU32::new(board::SETPOINT_M.to_bits());
/// Status for the main loop.
static STATUS: Published = Published::new();

/// Why the last run stopped ([`reset`]): two words of RAM that start-up leaves as they
/// are (cortex-m-rt's `.uninit`), so they survive a reset.
#[link_section = ".uninit.ema_reset_record"]
static mut RECORD: MaybeUninit<[u32; 2]> = MaybeUninit::uninit();

fn record_words() -> *mut [u32; 2] {
    addr_of_mut!(RECORD).cast()
}

/// Records `cause` unless a cause is recorded already (the first one is kept: a panic's
/// `udf` then lands in the hard-fault handler, which must not overwrite it).
fn record(cause: Cause, detail: u8) {
    // SAFETY: a valid, aligned static of two words; single core; accessed only through
    // these volatile operations, by start-up and by handlers that never return to the code
    // they interrupted. After a power-on the RAM holds arbitrary bits, which
    // `Record::decode` rejects.
    unsafe {
        if Record::decode(record_words().read_volatile()).is_none() {
            record_words().write_volatile(Record { cause, detail }.encode());
        }
    }
}

/// The recorded cause, if any; clears it.
fn take_record() -> Option<Record> {
    // SAFETY: as in `record`; start-up runs before any handler that records.
    unsafe {
        let r = Record::decode(record_words().read_volatile());
        record_words().write_volatile([0; 2]);
        r
    }
}

/// Why the controller did not start.
#[derive(Clone, Copy, Debug, defmt::Format)]
enum StartError {
    /// The peripherals were taken before.
    Peripherals,
    /// The clock tree is not the one the timing depends on.
    Clocks,
    /// The PWM's update event is not at the top of the count.
    PwmPhase(hw::PhaseError),
    /// No conversion arrived: TIM1 trigger or ADC dead.
    NoConversions,
    /// The conversions do not end where the trigger places them.
    SamplingInstant {
        /// TIM1_CNT when the end was seen.
        cnt: u32,
        /// Counting down.
        down: bool,
    },
    /// The settings do not build.
    Settings(ema::config::Error),
}

impl StartError {
    /// Code kept across the reset.
    const fn code(&self) -> u8 {
        match self {
            StartError::Peripherals => 1,
            StartError::Clocks => 2,
            StartError::PwmPhase(_) => 3,
            StartError::NoConversions => 4,
            StartError::SamplingInstant { .. } => 5,
            StartError::Settings(_) => 6,
        }
    }
}

#[entry]
fn main() -> ! {
    defmt::info!(
        "ema firmware: STM32F405 at {=u32} MHz, PWM and control at {=u32} Hz",
        board::SYSCLK_HZ / 1_000_000,
        board::CONTROL_RATE_HZ
    );
    if let Err(e) = start() {
        hw::force_coast();
        record(Cause::StartRefused, e.code());
        defmt::error!(
            "not started: {}; bridge off, waiting for the watchdog to restart the chip",
            e
        );
        // The independent watchdog restarts the chip, which then starts again with nothing
        // latched (the record says the controller never drove).
        loop {
            cortex_m::asm::wfi();
        }
    }
    let mut seen = 0;
    loop {
        // Woken by every control interrupt; logs once a second, never from the interrupt.
        cortex_m::asm::wfi();
        if let Some(s) = STATUS.read_new(&mut seen) {
            status_line(&s);
        }
    }
}

fn status_line(s: &Snapshot) {
    let fault = Fault::from_code(s.fault).map_or("none", Fault::name);
    let mode = ema::bridge::Mode::from_code(s.mode).map_or("?", ema::bridge::Mode::name);
    defmt::info!(
        "t={=u32}s {=str} fault={=str} bridge={=str} x={=i32}um i={=i32}mA | cycles/tick mean {=u32} max {=u32} (max since start {=u32}, period {=u32}) | overruns {=u32}",
        s.ticks / board::CONTROL_RATE_HZ,
        if s.fault == 0 { "running" } else { "tripped" },
        fault,
        mode,
        s.x_um,
        s.i_ma,
        s.cycles.mean,
        s.cycles.window_max,
        s.cycles.max,
        board::CONTROL_PERIOD_CYCLES,
        s.overruns
    );
}

/// Logs what the last run's end was, from the reset flags and the record.
fn log_last_stop(flags: reset::Flags, last: Option<Record>, latched: Option<Fault>) {
    let by = if flags.window_watchdog {
        "window watchdog"
    } else if flags.independent_watchdog {
        "independent watchdog"
    } else {
        "power-on, reset pin or software"
    };
    match (last, latched) {
        (Some(r), Some(f)) => defmt::warn!(
            "reset by the {=str} after: {=str} (detail {=u8}); starting with fault {=str} latched",
            by,
            r.cause.name(),
            r.detail,
            f.name()
        ),
        (None, Some(f)) => defmt::warn!(
            "reset by the {=str}, cause not recorded (the tick stopped with interrupts masked); starting with fault {=str} latched",
            by,
            f.name()
        ),
        (Some(r), None) => defmt::info!(
            "reset by the {=str} after: {=str} (detail {=u8}); the controller never drove: starting again",
            by,
            r.cause.name(),
            r.detail
        ),
        (None, None) => defmt::info!("reset by the {=str}", by),
    }
}

/// Watchdog, clocks, PWM (lines low, phase checked), ADC, current-sensor zero with the
/// bridge off (sampling instant checked), settings, main output, then the window watchdog
/// and the control interrupt.
fn start() -> Result<(), StartError> {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        return Err(StartError::Peripherals);
    };
    let flags = hw::take_reset_flags(&dp.RCC);
    let last = take_record();
    let after_reset = reset::latched_after(flags, last);
    log_last_stop(flags, last, after_reset);

    // The independent watchdog first: a crystal that does not start hangs in the clock
    // set-up below, and the watchdog ends that (recorded as such).
    let mut independent = IndependentWatchdog::new(dp.IWDG);
    independent.start(board::WATCHDOG_TIMEOUT_MS.millis());
    hw::freeze_on_debug_halt(&dp.DBGMCU);
    record(Cause::ClockSetup, 0);
    let mut rcc = dp.RCC.freeze(hw::clocks());
    let _ = take_record();
    if !hw::clocks_ok(&rcc) {
        return Err(StartError::Clocks);
    }
    hw::start_clock_security();
    hw::start_cycle_counter(&mut cp.DCB, &mut cp.DWT);

    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);
    let (pwm, direction, enable) = hw::start_pwm(
        dp.TIM1,
        (gpioa.pa8, gpioa.pa9, gpioa.pa10, gpiob.pb12),
        &mut rcc,
    )
    .map_err(StartError::PwmPhase)?;
    let Ok(mut bridge) = Bridge::new(pwm, direction, enable);
    defmt::info!(
        "PWM: update at the top of the count; conversions around it (in the off-time up to a duty of {=u32} per mille); break input: driver fault or |i| > {=f32} A",
        board::SEQUENCE_IN_OFF_TIME_MAX_PERMILLE,
        board::BREAK_CURRENT_A
    );
    if hw::hardware_tripped() {
        defmt::warn!("the bridge's fault input is active: the first tick latches hardware_trip");
    }

    let _position = gpioc.pc0.into_analog();
    let _current = gpioc.pc1.into_analog();
    let _vbus = gpioc.pc2.into_analog();
    hw::start_adc(dp.ADC1, &dp.ADC_COMMON, &mut rcc);

    // Current-sensor zero, bridge coasting since reset.
    let (zero, spread) = measure_current_zero(&mut independent)?;
    let plausible = board::zero_plausible(zero, spread);
    defmt::info!(
        "current zero {=f32} codes (nominal {=f32}), spread {=u16} codes: {=str}",
        zero,
        ema::sense::CURRENT_ZERO_CODE,
        spread,
        if plausible { "used" } else { "REFUSED" }
    );
    let settings = board::settings(plausible.then_some(zero)).map_err(StartError::Settings)?;
    let cfg = settings.build().map_err(StartError::Settings)?;
    defmt::info!(
        "law {=str}, rate {=f32} Hz, set point {=f32} mm",
        cfg.law().name(),
        settings.rate_hz,
        board::SETPOINT_M * 1e3
    );

    let mut state = cfg.initial_state();
    if let Some(fault) = after_reset {
        // The last run stopped while it may have been driving: never drive again without
        // a person looking (power cycle or reset pin).
        cfg.trip(&mut state, &mut bridge, fault);
    }
    if !plausible {
        cfg.trip(&mut state, &mut bridge, Fault::CurrentOffset);
    }

    // Nothing can fail from here on: the window watchdog, once started, only stops with a
    // reset.
    independent.feed();
    hw::enable_outputs();
    let control = Control {
        cfg,
        state,
        bridge,
        watchdogs: Watchdogs::start(independent),
        guard: guard::Config::for_period(board::CONTROL_PERIOD_CYCLES),
        guarded: guard::State::default(),
        cycles: Cycles::new(),
    };
    irq::free(|cs| HANDOFF.borrow(cs).set(Some(control)));
    // Drop a conversion that completed meanwhile, then let the interrupts run.
    let _ = hw::take_frame();
    NVIC::unpend(Interrupt::ADC);
    NVIC::unpend(Interrupt::WWDG);
    // SAFETY: the handlers' state is in HANDOFF and RECORD; unmasking cannot break a
    // critical section (none is open here). The early wake-up outranks the tick.
    unsafe {
        cp.NVIC.set_priority(Interrupt::WWDG, WWDG_PRIORITY);
        cp.NVIC.set_priority(Interrupt::ADC, ADC_PRIORITY);
        NVIC::unmask(Interrupt::WWDG);
        NVIC::unmask(Interrupt::ADC);
    }
    Ok(())
}

/// Mean and spread of the current channel over board::ZERO_SAMPLES conversions, after
/// board::ZERO_SETTLE_SAMPLES discarded ones, polled at the trigger rate with the bridge
/// off. Feeds the watchdog; gives up when a conversion is more than 4 periods late, and
/// refuses conversions that do not end where the trigger places them.
fn measure_current_zero(watchdog: &mut IndependentWatchdog) -> Result<(f32, u16), StartError> {
    let (mut sum, mut lo, mut hi) = (0u32, u16::MAX, 0u16);
    for k in 0..board::ZERO_SETTLE_SAMPLES + board::ZERO_SAMPLES {
        let (cr1, cnt, frame) = hw::wait_conversion(4 * board::CONTROL_PERIOD_CYCLES)
            .ok_or(StartError::NoConversions)?;
        watchdog.feed();
        if !regs::conversions_placed(cr1, cnt) {
            return Err(StartError::SamplingInstant {
                cnt,
                down: regs::update_at_top(cr1),
            });
        }
        if k >= board::ZERO_SETTLE_SAMPLES {
            sum = sum.saturating_add(u32::from(frame.current));
            lo = lo.min(frame.current);
            hi = hi.max(frame.current);
        }
    }
    // sum <= 1024 * 4095 < 2^24: exact in f32, and the division by a power of 2 too.
    let mean = sum as f32 / board::ZERO_SAMPLES as f32;
    Ok((mean, hi.saturating_sub(lo)))
}

/// The control interrupt: end of the injected conversions triggered by TIM1, once per PWM
/// period. Reads the codes and the timer's flags, runs the tick through the guard (which
/// latches a hardware trip or an overrun and says whether to feed), feeds the watchdogs
/// when told, keeps the cycle statistics. No panic path (tests/qemu_no_panic.rs proves it
/// for the tick and the guard; .ci/isr-calls for this handler).
#[interrupt]
fn ADC() {
    static mut CONTROL: Option<Control> = None;
    let start = hw::cycles();
    let hardware_trip = hw::begin_period();
    let frame = hw::take_frame();
    if CONTROL.is_none() {
        *CONTROL = irq::free(|cs| HANDOFF.borrow(cs).take());
    }
    let Some(c) = CONTROL.as_mut() else {
        return;
    };
    let setpoint_m = f32::from_bits(SETPOINT_M.load(Ordering::Relaxed));
    let cfg = &c.cfg;
    let outcome = c.guard.run(
        &mut c.guarded,
        cfg,
        &mut c.state,
        &mut c.bridge,
        Start {
            now: start,
            hardware_trip,
        },
        |state, bridge| cfg.tick(state, bridge, &frame, setpoint_m),
        || End {
            next_due: NVIC::is_pending(Interrupt::ADC) || hw::conversion_pending(),
            boundary_passed: hw::period_boundary_passed(),
        },
    );
    if outcome.feed {
        c.watchdogs.feed();
    }
    let end = hw::cycles();

    if let Some(cycles) = c
        .cycles
        .record(end.wrapping_sub(start), board::STATUS_PERIOD_TICKS)
    {
        let status = outcome.status;
        STATUS.publish(&Snapshot {
            ticks: c.state.ticks,
            cycles,
            overruns: c.guarded.overruns(),
            fault: c.state.supervisor.latched().map_or(0, Fault::code),
            mode: c.bridge.mode().code(),
            x_um: stats::scaled(status.measurement.x_m, 1e6),
            i_ma: stats::scaled(status.measurement.i_a, 1e3),
        });
    }
}

/// The window watchdog's early wake-up: nothing has fed it for at least three periods
/// (the tick stopped or keeps overrunning). Bridge safe at once; the reset follows one
/// count (97.5 us) later, and the next start latches `Fault::Overrun`.
#[interrupt]
fn WWDG() {
    hw::force_coast();
    record(Cause::TickStalled, 0);
    loop {
        cortex_m::asm::wfi();
    }
}

/// The clock security system saw the crystal fail: TIM1 has already broken (outputs off);
/// coast by register writes too, clear the flag, and wait for a watchdog reset.
#[exception]
unsafe fn NonMaskableInt() {
    hw::force_coast();
    record(Cause::ClockFailure, 0);
    hw::clear_clock_failure();
    loop {
        cortex_m::asm::wfi();
    }
}

/// Any interrupt without a handler of its own: bridge safe, then wait for a watchdog
/// reset.
#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    hw::force_coast();
    record(Cause::UnexpectedInterrupt, irqn.to_le_bytes()[0]);
    loop {
        cortex_m::asm::wfi();
    }
}

/// Bridge safe first, by register writes that need no HAL state; then the location on the
/// log; then a fault so that a debugger stops here (`udf`), after which the HardFault
/// handler keeps the bridge safe until the watchdog resets the chip.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::interrupt::disable();
    hw::force_coast();
    record(Cause::Panic, 0);
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    cortex_m::asm::udf()
}

/// A fault (or the panic handler's `udf`): bridge safe, then wait for the watchdog, which
/// keeps running (nothing feeds it now) unless a debugger has halted the core.
#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    hw::force_coast();
    record(Cause::HardFault, 0);
    loop {
        cortex_m::asm::wfi();
    }
}
