//! Start-up, the control interrupt, the status line, and the panic and fault handlers.

use core::cell::Cell;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::interrupt::{self as irq, Mutex};
use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt_rtt as _;
use ema::control::{Config, State};
use ema::supervisor::Fault;
use stm32f4xx_hal::gpio::PinState;
use stm32f4xx_hal::pac::{self, interrupt, Interrupt};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::watchdog::IndependentWatchdog;

use crate::board;
use crate::hw::{self, Bridge, Pin};
use crate::stats::{self, Cycles, Published, Snapshot};

/// Everything the control interrupt owns.
struct Control {
    cfg: Config,
    state: State,
    bridge: Bridge,
    watchdog: IndependentWatchdog,
    cycles: Cycles,
    last_start: Option<u32>,
    overruns: u32,
}

/// Start-up hands the controller to the interrupt through this cell, once.
static HANDOFF: Mutex<Cell<Option<Control>>> = Mutex::new(Cell::new(None));
/// Position set point \[m\], as `f32` bits (a future command interface writes it).
static SETPOINT_M: AtomicU32 = AtomicU32::new(board::SETPOINT_M.to_bits());
/// Status for the main loop.
static STATUS: Published = Published::new();

/// Why the controller did not start.
#[derive(Clone, Copy, Debug, defmt::Format)]
enum StartError {
    /// The peripherals were taken before.
    Peripherals,
    /// The clock tree is not the one the timing depends on.
    Clocks,
    /// No conversion arrived: TIM1 trigger or ADC dead.
    NoConversions,
    /// The settings do not build.
    Settings(ema::config::Error),
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
        defmt::error!("not started: {}; bridge off, waiting for the watchdog", e);
        // The watchdog (if it runs) resets the chip, which then starts with a latched fault.
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
    let mode = match s.mode {
        0 => "coast",
        1 => "forward",
        2 => "reverse",
        _ => "?",
    };
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

/// Clocks, pins (bridge off first), PWM, ADC, watchdog, current-sensor zero with the
/// bridge off, settings, then the control interrupt.
fn start() -> Result<(), StartError> {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        return Err(StartError::Peripherals);
    };
    let after_watchdog = hw::take_watchdog_reset(&dp.RCC);
    let mut rcc = dp.RCC.freeze(hw::clocks());
    if !hw::clocks_ok(&rcc) {
        return Err(StartError::Clocks);
    }
    hw::freeze_on_debug_halt(&dp.DBGMCU);

    // Bridge pins: enable low before anything else drives.
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);
    let enable = Pin::Enable(gpioc.pc9.into_push_pull_output_in_state(PinState::Low));
    let direction = Pin::Direction(gpioc.pc8.into_push_pull_output_in_state(PinState::Low));
    let pwm = hw::pwm(dp.TIM1, gpioa.pa8, &mut rcc);
    let Ok(mut bridge) = Bridge::new(pwm, direction, enable);

    let mut watchdog = IndependentWatchdog::new(dp.IWDG);
    watchdog.start(board::WATCHDOG_TIMEOUT_MS.millis());

    let _position = gpioc.pc0.into_analog();
    let _current = gpioc.pc1.into_analog();
    let _vbus = gpioc.pc2.into_analog();
    hw::start_adc(dp.ADC1, &dp.ADC_COMMON, &mut rcc);
    hw::start_cycle_counter(&mut cp.DCB, &mut cp.DWT);

    // Current-sensor zero, bridge coasting since reset.
    let (zero, spread) = measure_current_zero(&mut watchdog)?;
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
    if after_watchdog {
        // The tick stopped long enough for the watchdog to bite: never drive again
        // without a person looking (power cycle or reset pin).
        cfg.trip(&mut state, &mut bridge, Fault::Overrun);
        defmt::warn!("reset by the watchdog: starting with fault overrun latched");
    }
    if !plausible {
        cfg.trip(&mut state, &mut bridge, Fault::CurrentOffset);
    }

    // The interrupt feeds from now on; this covers the time since the last zero sample.
    watchdog.feed();
    let control = Control {
        cfg,
        state,
        bridge,
        watchdog,
        cycles: Cycles::new(),
        last_start: None,
        overruns: 0,
    };
    irq::free(|cs| HANDOFF.borrow(cs).set(Some(control)));
    // Drop a conversion that completed meanwhile, then let the interrupt run.
    let _ = hw::take_frame();
    NVIC::unpend(Interrupt::ADC);
    // SAFETY: the handler's state is in HANDOFF; unmasking cannot break a critical section
    // (none is open here). Priority: the only enabled interrupt, at the highest level.
    unsafe {
        cp.NVIC.set_priority(Interrupt::ADC, 0);
        NVIC::unmask(Interrupt::ADC);
    }
    Ok(())
}

/// Mean and spread of the current channel over board::ZERO_SAMPLES conversions, after
/// board::ZERO_SETTLE_SAMPLES discarded ones, polled at the trigger rate with the bridge
/// off. Feeds the watchdog; gives up when a conversion is more than 4 periods late.
fn measure_current_zero(watchdog: &mut IndependentWatchdog) -> Result<(f32, u16), StartError> {
    let (mut sum, mut lo, mut hi) = (0u32, u16::MAX, 0u16);
    for k in 0..board::ZERO_SETTLE_SAMPLES + board::ZERO_SAMPLES {
        let t0 = hw::cycles();
        while !hw::conversion_pending() {
            if hw::cycles().wrapping_sub(t0) > 4 * board::CONTROL_PERIOD_CYCLES {
                return Err(StartError::NoConversions);
            }
        }
        let frame = hw::take_frame();
        watchdog.feed();
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
/// period. Reads the codes, runs the tick, checks for an overrun, feeds the watchdog when
/// healthy, keeps the cycle statistics. No panic path (tests/qemu_no_panic.rs proves it for
/// the tick; everything else here is saturating or checked).
#[interrupt]
fn ADC() {
    static mut CONTROL: Option<Control> = None;
    let start = hw::cycles();
    let frame = hw::take_frame();
    if CONTROL.is_none() {
        *CONTROL = irq::free(|cs| HANDOFF.borrow(cs).take());
    }
    let Some(c) = CONTROL.as_mut() else {
        return;
    };
    let setpoint_m = f32::from_bits(SETPOINT_M.load(Ordering::Relaxed));
    let status = c.cfg.tick(&mut c.state, &mut c.bridge, &frame, setpoint_m);
    let end = hw::cycles();

    let gap = c.last_start.map(|last| start.wrapping_sub(last));
    c.last_start = Some(start);
    let pending_again = NVIC::is_pending(Interrupt::ADC) || hw::conversion_pending();
    if stats::overran(pending_again, gap, board::OVERRUN_GAP_CYCLES) {
        c.overruns = c.overruns.saturating_add(1);
        c.cfg.trip(&mut c.state, &mut c.bridge, Fault::Overrun);
    } else {
        // Healthy: the tick ran on time. A latched fault does not stop the feeding: the
        // tick is what holds the bridge in coast, and a reset would lose the latch.
        c.watchdog.feed();
    }

    if let Some(cycles) = c
        .cycles
        .record(end.wrapping_sub(start), board::STATUS_PERIOD_TICKS)
    {
        STATUS.publish(&Snapshot {
            ticks: c.state.ticks,
            cycles,
            overruns: c.overruns,
            fault: c.state.supervisor.latched().map_or(0, Fault::code),
            mode: ema::trace::mode_code(c.bridge.mode()),
            x_um: stats::scaled(status.measurement.x_m, 1e6),
            i_ma: stats::scaled(status.measurement.i_a, 1e3),
        });
    }
}

/// Bridge safe first, by register writes that need no HAL state; then the location on the
/// log; then a fault so that a debugger stops here (`udf`), after which the HardFault
/// handler keeps the bridge safe until the watchdog resets the chip.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::interrupt::disable();
    hw::force_coast();
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
    loop {
        cortex_m::asm::wfi();
    }
}
