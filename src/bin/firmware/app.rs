//! Start-up, the control interrupt, the main loop (the bench link and the status line),
//! the window watchdog's early wake-up, and the panic and fault handlers.

use core::mem::MaybeUninit;
use core::ptr::{addr_of, addr_of_mut};
use core::sync::atomic::{compiler_fence, Ordering};

use cortex_m::peripheral::{NVIC, SCB};
use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt_rtt as _;
use ema::control::supervisor::Fault;
use ema::device::guard::{self, End, Start};
use ema::device::params::{Board, Params};
use ema::device::protocol::{Build, Sample, Source};
use ema::device::store::{self, Store};
use ema::device::{
    Action, Controller, Dispatcher, Inputs, IsrEnds, MainEnds, Queues, ANSWER_SLOTS,
    CAPTURE_CAPACITY, ORDER_SLOTS, SAMPLE_SLOTS,
};
use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use stm32f4xx_hal::flash::{FlashExt, LockedFlash};
use stm32f4xx_hal::gpio::{Alternate, Pin};
use stm32f4xx_hal::pac::{self, interrupt, Interrupt};
use stm32f4xx_hal::prelude::*;

use crate::board;
use crate::hw::{self, Bridge, Watchdogs};
use crate::link::{self, Link};
use crate::regs;
use crate::reset::{self, Cause, Record};
use crate::stats::{self, Published, Snapshot};

/// NVIC priority of the window watchdog's early wake-up: the highest, so that it preempts
/// a control interrupt that never ends (4 priority bits, in the high nibble).
const WWDG_PRIORITY: u8 = 0x00;
/// NVIC priority of the control interrupt: one level below.
const ADC_PRIORITY: u8 = 0x10;

// The guard's late-start threshold is the board's documented overrun gap.
const _: () = assert!(
    guard::Config::for_period(board::CONTROL_PERIOD_CYCLES).max_gap() == board::OVERRUN_GAP_CYCLES
);

/// The capture buffer the controller fills in the interrupt.
type Capture = &'static mut [Sample; CAPTURE_CAPACITY];

/// Everything the control interrupt owns.
struct Control {
    controller: Controller<Capture>,
    bridge: Bridge,
    watchdogs: Watchdogs,
    /// Taken out for the tick (see `ADC`), always put back.
    ends: Option<IsrEnds<'static>>,
}

/// Everything the main loop owns: the dispatcher, its ends of the queues, the link and
/// the store's read-only view.
struct MainLoop {
    dispatcher: Dispatcher,
    ends: MainEnds<'static>,
    link: Link,
    /// Read-only from here on (see [`ChipFlash`]).
    store: Store<ChipFlash>,
}

/// What the control interrupt owns: written once by start-up, before the interrupt is
/// unmasked, and then only touched by the interrupt. All zeros at reset (`.bss`): an
/// `Option<Control>` would be in `.data` (its `None` is not all zeros), its initial value
/// costing flash, and a hand-over cell would hold a second copy in RAM.
static mut CONTROL: Slot = Slot {
    ready: false,
    control: MaybeUninit::uninit(),
};

/// [`CONTROL`]: `ready` once `control` holds the controller.
struct Slot {
    ready: bool,
    control: MaybeUninit<Control>,
}
/// The buffers start-up hands out (capture, queues, the link's): empty, all zeros at reset
/// (`.bss`: no initial values in flash, no copy through the stack, no fill loop).
struct Buffers {
    capture: [Sample; CAPTURE_CAPACITY],
    queues: Queues,
    rx: [u8; link::RX_RING],
    tx: [u8; link::TX_BUFFER],
}

/// `Sample::default()`, as a constant.
const NO_SAMPLE: Sample = Sample {
    r_m: 0.0,
    x_m: 0.0,
    v_mps: 0.0,
    i_a: 0.0,
    u_v: 0.0,
    duty: 0.0,
    vbus_v: 0.0,
    analog_m: 0.0,
    fault: 0,
    mode: 0,
};

/// Taken once, by `start`.
static mut BUFFERS: Buffers = Buffers {
    capture: [NO_SAMPLE; CAPTURE_CAPACITY],
    queues: Queues::new(),
    rx: [0; link::RX_RING],
    tx: [0; link::TX_BUFFER],
};

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
fn record(cause: Cause, detail: u8, attempt: u8) {
    // SAFETY: a valid, aligned static of two words; single core; accessed only through
    // these volatile operations, by start-up and by handlers that never return to the code
    // they interrupted. After a power-on the RAM holds arbitrary bits, which
    // `Record::decode` rejects.
    unsafe {
        if Record::decode(record_words().read_volatile()).is_none() {
            record_words().write_volatile(
                Record {
                    cause,
                    detail,
                    attempt,
                }
                .encode(),
            );
        }
    }
}

/// A parameter set to save at the next start, before the control and its watchdog timeout
/// run (a save erases a 16 KiB sector: 400 ms typical, 800 ms at most, within the boot
/// timeout `board::IWDG_BOOT`, far beyond the running one): a marker, the record's length and the record as the store encodes it (its own
/// CRC covers it), in RAM that start-up leaves as it is.
#[repr(C)]
struct PendingSave {
    marker: u32,
    len: u32,
    record: [u8; store::MAX_RECORD],
}

/// "SAVE": a pending save follows.
const SAVE_MARKER: u32 = 0x5341_5645;

#[link_section = ".uninit.ema_pending_save"]
static mut PENDING_SAVE: MaybeUninit<PendingSave> = MaybeUninit::uninit();

/// Leaves `params` for the next start to save; false if the set does not encode.
fn leave_save(params: &Params) -> bool {
    let mut record = [0u8; store::MAX_RECORD];
    let Ok(len) = store::encode(params, &mut record) else {
        return false;
    };
    // SAFETY: a valid, aligned static; single core; only the main loop (here, just before
    // a reset) and start-up (before any interrupt) touch it. Field by field (one volatile
    // copy of the whole struct is unrolled into hundreds of bytes of code): the record and
    // its length first, the marker that makes them valid last.
    unsafe {
        let p = addr_of_mut!(PENDING_SAVE).cast::<PendingSave>();
        addr_of_mut!((*p).record).write(record);
        addr_of_mut!((*p).len).write_volatile(len as u32);
        compiler_fence(Ordering::SeqCst);
        addr_of_mut!((*p).marker).write_volatile(SAVE_MARKER);
    }
    true
}

/// The set left to save, if any (its record decodes: marker and CRC); clears it first, so
/// that a save cut short by a reset is not tried again.
fn take_save() -> Option<Params> {
    // SAFETY: as in `leave_save`; after a power-on the RAM holds arbitrary bits, which the
    // marker and the record's CRC reject.
    let (marker, len, record) = unsafe {
        let p = addr_of_mut!(PENDING_SAVE).cast::<PendingSave>();
        let marker = addr_of!((*p).marker).read_volatile();
        let len = addr_of!((*p).len).read_volatile();
        addr_of_mut!((*p).marker).write_volatile(0);
        compiler_fence(Ordering::SeqCst);
        (marker, len, addr_of!((*p).record).read())
    };
    if marker != SAVE_MARKER {
        return None;
    }
    let record = record.get(..len as usize)?;
    store::decode(record).ok()
}

/// The recorded cause, if any; clears it.
#[inline(never)]
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
    /// The crystal, the PLL or the switch to it did not come in time.
    ClockSetup(hw::ClockError),
    /// The clock tree is not the one the timing depends on.
    Clocks,
    /// The independent watchdog did not take its running timeout.
    Watchdog,
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
    Settings(ema::control::config::Error),
    /// The parameter store's range is not whole sectors.
    Store,
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
            StartError::Store => 7,
            StartError::ClockSetup(hw::ClockError::Crystal) => 8,
            StartError::ClockSetup(hw::ClockError::Pll) => 9,
            StartError::ClockSetup(hw::ClockError::Switch) => 10,
            StartError::Watchdog => 11,
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
    let mut app = match start() {
        Ok(app) => app,
        Err((e, attempt)) => refused(e, attempt),
    };
    let mut seen = 0;
    loop {
        // Woken by every control interrupt: the link is served every 50 us; the status
        // line once a second, never from the interrupt.
        cortex_m::asm::wfi();
        serve(&mut app);
        if let Some(s) = STATUS.read_new(&mut seen) {
            status_line(&s);
        }
    }
}

/// Bytes in to the dispatcher, its orders to the interrupt, the answers and telemetry out,
/// and the save or restart it asks for once its answer has left the line.
#[inline(never)]
fn serve(app: &mut MainLoop) {
    let taken = app
        .dispatcher
        .receive(app.link.received(), &mut app.ends, &mut app.store);
    app.link.consume(taken);
    app.dispatcher.poll(&mut app.ends);
    let sent = app.link.send(app.dispatcher.tx());
    app.dispatcher.sent(sent);
    if let Some(action) = app.dispatcher.take_action() {
        app.link.flush();
        if let Action::Save(params) = action {
            if !leave_save(&params) {
                defmt::error!("the set to save does not encode: restarting without saving");
            }
        }
        // The interrupt keeps feeding the watchdogs up to here; the reset stops the
        // watchdogs, and the bridge coasts through it (pull-downs).
        hw::force_coast();
        SCB::sys_reset();
    }
}

/// Start refused, the `attempt`-th time in a row: bridge off, the reason recorded. The
/// independent watchdog restarts the chip, which then starts again with nothing latched
/// (the record says the controller never drove), up to [`reset::START_ATTEMPTS`] times in
/// a row; then the board stays refused, feeding the watchdog, the bridge off and the
/// reason logged every few seconds, until a person resets or powers it: a board that
/// cannot start does not cycle through resets.
fn refused(e: StartError, attempt: u8) -> ! {
    hw::force_coast();
    record(Cause::StartRefused, e.code(), attempt);
    if attempt < reset::START_ATTEMPTS {
        defmt::error!(
            "not started: {} (attempt {=u8} of {=u8}); bridge off, the watchdog restarts the chip",
            e,
            attempt,
            reset::START_ATTEMPTS
        );
        loop {
            cortex_m::asm::wfi();
        }
    }
    loop {
        defmt::error!(
            "not started: {} ({=u8} attempts); bridge off; reset or power the board to try again",
            e,
            attempt
        );
        // Fed every 16 M cycles: 1 s on the internal oscillator (a failed clock set-up),
        // 0.1 s on the PLL; the boot timeout is at least 2.7 s.
        for _ in 0..4 {
            hw::feed_independent_watchdog();
            cortex_m::asm::delay(16_000_000);
        }
    }
}

fn status_line(s: &Snapshot) {
    let fault = Fault::from_code(s.fault);
    let mode = ema::control::bridge::Mode::from_code(s.mode);
    defmt::info!(
        "t={=u32}s {=str} fault={} bridge={} x={=i32}um i={=i32}mA | cycles/tick mean {=u32} max {=u32} (max since start {=u32}, period {=u32}) | overruns {=u32}",
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
        By::WindowWatchdog
    } else if flags.independent_watchdog {
        By::IndependentWatchdog
    } else {
        By::Person
    };
    match (last, latched) {
        (Some(r), Some(f)) => defmt::warn!(
            "reset by the {} after: {} (detail {=u8}); starting with fault {} latched",
            by,
            r.cause,
            r.detail,
            f
        ),
        (None, Some(f)) => defmt::warn!(
            "reset by the {}, cause not recorded (the tick stopped with interrupts masked); starting with fault {} latched",
            by,
            f
        ),
        (Some(r), None) => defmt::info!(
            "reset by the {} after: {} (detail {=u8}); the controller never drove: starting again",
            by,
            r.cause,
            r.detail
        ),
        (None, None) => defmt::info!("reset by the {}", by),
    }
}

/// What reset the chip, as the log says it (the texts stay in the log's symbols, not in
/// flash).
#[derive(Clone, Copy)]
enum By {
    WindowWatchdog,
    IndependentWatchdog,
    Person,
}

impl defmt::Format for By {
    fn format(&self, f: defmt::Formatter<'_>) {
        match self {
            By::WindowWatchdog => defmt::write!(f, "window watchdog"),
            By::IndependentWatchdog => defmt::write!(f, "independent watchdog"),
            By::Person => defmt::write!(f, "power-on, reset pin or software"),
        }
    }
}

/// The parameters (a pending save written first, then the stored set loaded, before any
/// watchdog runs), watchdog, clocks, PWM (lines low, phase checked), ADC, current-sensor
/// zero with the bridge off (sampling instant checked), settings, the link, main output,
/// then the window watchdog and the control interrupt.
fn start() -> Result<MainLoop, (StartError, u8)> {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        return Err((StartError::Peripherals, 1));
    };
    // First of all: the cycle counter (every wait of start-up is bounded by it) and the
    // independent watchdog with its boot timeout, long enough for everything start-up
    // does (`board::BOOT_MAX_MS`) and short enough to end a hang.
    hw::start_cycle_counter(&mut cp.DCB, &mut cp.DWT);
    let watchdog_ok = hw::start_independent_watchdog(board::IWDG_BOOT);
    hw::freeze_on_debug_halt(&dp.DBGMCU);
    let flags = hw::take_reset_flags(&dp.RCC);
    let last = take_record();
    let attempt = reset::attempt(flags, last);
    let after_reset = reset::latched_after(flags, last);
    log_last_stop(flags, last, after_reset);
    if !watchdog_ok {
        return Err((StartError::Watchdog, attempt));
    }
    bring_up(dp, &mut cp.NVIC, after_reset).map_err(|e| (e, attempt))
}

/// Start-up after the watchdog: see [`start`].
fn bring_up(
    dp: pac::Peripherals,
    nvic: &mut NVIC,
    after_reset: Option<Fault>,
) -> Result<MainLoop, StartError> {
    // The parameters: a save (and a repair of a store a power cut damaged) erases 16 KiB
    // sectors, 400 ms each (800 ms at most), within the boot timeout. The bridge coasts
    // meanwhile (the board's pull-downs; TIM1 is not started yet). The set is built here
    // for the nominal current zero and again below for the measured one.
    let defaults = Params::new(board::ACTUATOR);
    let rate_hz = board::ACTUATOR.board.rate_hz;
    let save = take_save();
    let flash = ChipFlash {
        flash: LockedFlash::new(dp.FLASH),
        writable: true,
    };
    let mut store = Store::new(flash, board::STORE_RANGE).map_err(|_| StartError::Store)?;
    let nominal = Board {
        rate_hz,
        current_zero_code: None,
    };
    let mut boot = ema::device::boot(&mut store, &defaults, &nominal, save.as_ref())
        .map_err(StartError::Settings)?;
    store.flash().writable = false;
    log_boot(&boot.source, boot.saved);

    // Every wait of the clock set-up is bounded; a hang there anyway (the watchdog's boot
    // timeout ends it) is recorded as such.
    record(Cause::ClockSetup, 0, 0);
    let clocks = hw::start_clocks(dp.RCC);
    let _ = take_record();
    let mut rcc = clocks.map_err(StartError::ClockSetup)?;
    if !hw::clocks_ok() {
        return Err(StartError::Clocks);
    }
    hw::start_clock_security();

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
    defmt::info!(
        "bus: coasts on every fault; the board must keep the coil's returned energy below {=f32} V (its rating)",
        board::BUS_RATING_V
    );
    if hw::hardware_tripped() {
        defmt::warn!("the bridge's fault input is active: the first tick latches hardware_trip");
    }

    let _position = gpioc.pc0.into_analog();
    let _current = gpioc.pc1.into_analog();
    let _vbus = gpioc.pc2.into_analog();
    let _analog_setpoint = gpioc.pc3.into_analog();
    hw::start_adc(dp.ADC1, &dp.ADC_COMMON, &mut rcc);

    // Current-sensor zero, bridge coasting since reset.
    let (zero, peak_to_peak) = measure_current_zero()?;
    let plausible = board::zero_plausible(zero, peak_to_peak);
    if plausible {
        defmt::info!(
            "current zero {=f32} codes (nominal {=f32}), peak-to-peak {=u16} codes: used",
            zero,
            ema::control::sense::CURRENT_ZERO_CODE,
            peak_to_peak
        );
    } else {
        defmt::info!(
            "current zero {=f32} codes (nominal {=f32}), peak-to-peak {=u16} codes: REFUSED",
            zero,
            ema::control::sense::CURRENT_ZERO_CODE,
            peak_to_peak
        );
    }
    // The board's own refusals (the paper's force convention) still apply.
    board::settings(None).map_err(StartError::Settings)?;
    let board_now = Board {
        rate_hz,
        current_zero_code: plausible.then_some(zero),
    };
    boot.install = boot
        .params
        .build(&board_now)
        .map_err(StartError::Settings)?;
    defmt::info!(
        "law {=str}, rate {=f32} Hz; disarmed: the bench link arms and moves ({=u32} baud on USART2)",
        boot.install.control.law().name(),
        rate_hz,
        ema::device::protocol::BAUD
    );

    // SAFETY: `start` gets here at most once (`pac::Peripherals::take` above succeeds only
    // once), so these are the only references to BUFFERS ever made.
    let Buffers {
        capture,
        queues,
        rx,
        tx,
    } = unsafe { &mut *addr_of_mut!(BUFFERS) };
    let mut controller = Controller::new(boot.install, board::CONTROL_PERIOD_CYCLES, capture);
    if let Some(fault) = after_reset {
        // The last run stopped while it may have been driving: never drive again without
        // a person looking (power cycle or reset pin).
        controller.trip(&mut bridge, fault);
    }
    if !plausible {
        controller.trip(&mut bridge, Fault::CurrentOffset);
    }
    let capacity = u16::try_from(CAPTURE_CAPACITY).unwrap_or(u16::MAX);
    let dispatcher = Dispatcher::new(board_now, Build::THIS, defaults, &boot, capacity);
    let (main_ends, isr_ends) = queues.split();

    let _tx_pin: Pin<{ board::LINK_PORT }, { board::LINK_TX_PIN }, Alternate<7>> =
        gpioa.pa2.into_alternate();
    let _rx_pin: Pin<{ board::LINK_PORT }, { board::LINK_RX_PIN }, Alternate<7>> =
        gpioa.pa3.into_alternate().internal_pull_up(true);
    let link = Link::start(dp.USART2, dp.DMA1, rx, tx, &mut rcc);

    // The independent watchdog's running timeout, now that every long step is over.
    if !hw::start_independent_watchdog(board::IWDG_RUN) {
        return Err(StartError::Watchdog);
    }
    // Nothing can fail from here on: the window watchdog, once started, only stops with a
    // reset.
    hw::enable_outputs();
    let control = Control {
        controller,
        bridge,
        watchdogs: Watchdogs::start(),
        ends: Some(isr_ends),
    };
    // SAFETY: the control interrupt is masked (never unmasked yet) and nothing else touches
    // CONTROL; `ready` is set after the write, and the fences keep both before the
    // unmasking below.
    unsafe {
        let slot = addr_of_mut!(CONTROL);
        (*slot).control.write(control);
        compiler_fence(Ordering::SeqCst);
        (*slot).ready = true;
    }
    compiler_fence(Ordering::SeqCst);
    // Drop a conversion that completed meanwhile, then let the interrupts run.
    let _ = hw::take_frame();
    NVIC::unpend(Interrupt::ADC);
    NVIC::unpend(Interrupt::WWDG);
    // SAFETY: the handlers' state is in CONTROL and RECORD; unmasking cannot break a
    // critical section (none is open here). The early wake-up outranks the tick.
    unsafe {
        nvic.set_priority(Interrupt::WWDG, WWDG_PRIORITY);
        nvic.set_priority(Interrupt::ADC, ADC_PRIORITY);
        NVIC::unmask(Interrupt::WWDG);
        NVIC::unmask(Interrupt::ADC);
    }
    Ok(MainLoop {
        dispatcher,
        ends: main_ends,
        link,
        store,
    })
}

/// Logs where the parameters came from and what the save this start made did.
fn log_boot(source: &Source<'_>, saved: Option<Result<(), ema::device::protocol::StoreError>>) {
    match saved {
        None => defmt::info!("parameters: {}", From(source)),
        Some(Ok(())) => defmt::info!("parameters saved; in use: {}", From(source)),
        Some(Err(_)) => defmt::error!("parameters NOT saved; in use: {}", From(source)),
    }
}

/// Where the parameters in use came from, as the log says it (the texts stay in the
/// log's symbols, not in flash).
struct From<'a, 'b>(&'a Source<'b>);

impl defmt::Format for From<'_, '_> {
    fn format(&self, f: defmt::Formatter<'_>) {
        match self.0 {
            Source::Stored => defmt::write!(f, "the stored set"),
            Source::Defaults => defmt::write!(f, "the built-in defaults (nothing stored)"),
            Source::Fallback(_) => {
                defmt::write!(f, "the built-in defaults (the stored set was refused)");
            }
        }
    }
}

/// The chip's flash as the parameter store sees it: writable at start (a pending save, a
/// repair), then read-only for the main loop while the control interrupt runs (an erase
/// stalls the bus for hundreds of milliseconds; a load that would need a repair fails
/// instead). One type for both, so the store's code is in the image once.
struct ChipFlash {
    flash: LockedFlash,
    writable: bool,
}

impl ErrorType for ChipFlash {
    type Error = stm32f4xx_hal::flash::Error;
}

impl ReadNorFlash for ChipFlash {
    const READ_SIZE: usize = 1;

    #[inline(never)]
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        ReadNorFlash::read(&mut self.flash, offset, bytes)
    }

    fn capacity(&self) -> usize {
        ReadNorFlash::capacity(&self.flash)
    }
}

impl NorFlash for ChipFlash {
    const WRITE_SIZE: usize = 1;
    /// Sectors 1 and 2 (`board::STORE_RANGE`).
    const ERASE_SIZE: usize = board::STORE_SECTOR;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if !self.writable {
            return Err(stm32f4xx_hal::flash::Error::WriteProtection);
        }
        NorFlash::erase(&mut self.flash.unlocked(), from, to)
    }

    #[inline(never)]
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if !self.writable {
            return Err(stm32f4xx_hal::flash::Error::WriteProtection);
        }
        NorFlash::write(&mut self.flash.unlocked(), offset, bytes)
    }
}

/// Mean and peak-to-peak of the current channel over board::ZERO_SAMPLES conversions, after
/// board::ZERO_SETTLE_SAMPLES discarded ones, polled at the trigger rate with the bridge
/// off. Feeds the watchdog; gives up when a conversion is more than 4 periods late, and
/// refuses conversions that do not end where the trigger places them.
fn measure_current_zero() -> Result<(f32, u16), StartError> {
    let (mut sum, mut lo, mut hi) = (0u32, u16::MAX, 0u16);
    for k in 0..board::ZERO_SETTLE_SAMPLES + board::ZERO_SAMPLES {
        let (cr1, cnt, frame) = hw::wait_conversion(4 * board::CONTROL_PERIOD_CYCLES)
            .ok_or(StartError::NoConversions)?;
        hw::feed_independent_watchdog();
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
/// period. Reads the codes and the timer's flags, runs the application's tick
/// (`ema::device::Controller`: at most one order from the main loop, the operating state,
/// `Config::tick` through the guard when armed, telemetry and capture), restores the
/// timer's main output when a hardware trip was cleared, feeds the watchdogs when told,
/// keeps the cycle statistics. No panic path (tests/qemu_no_panic.rs and
/// tests/qemu_device.rs for the tick; .ci/isr-calls for this handler).
#[interrupt]
fn ADC() {
    let start = hw::cycles();
    let hardware_trip = hw::begin_period();
    let (frame, analog) = hw::take_frame();
    // SAFETY: `ready` is set only after start-up has written `control`, and start-up never
    // touches CONTROL again; this handler does not re-enter itself, and nothing else uses
    // CONTROL.
    let slot = unsafe { &mut *addr_of_mut!(CONTROL) };
    if !slot.ready {
        return;
    }
    // SAFETY: as above: `ready`, so `control` is initialised.
    let c = unsafe { slot.control.assume_init_mut() };
    let inputs = Inputs {
        frame,
        analog,
        start: Start {
            now: start,
            hardware_trip,
        },
        break_active: hw::break_input_active(),
    };
    // The queues' ends are `heapless` views, whose capacity is a length in memory: their
    // index arithmetic divides by it. Taken into a local and checked against the
    // constants they were made with, the compiler knows every divisor and no division by
    // zero (a panic path) remains; .ci/isr-calls checks that on the image. A mismatch
    // cannot happen; if it did, the bridge coasts and nothing feeds the watchdogs.
    let Some(mut ends) = c.ends.take() else {
        hw::force_coast();
        return;
    };
    if ends.orders.capacity() != ORDER_SLOTS - 1
        || ends.answers.capacity() != ANSWER_SLOTS - 1
        || ends.samples.capacity() != SAMPLE_SLOTS - 1
    {
        hw::force_coast();
        c.ends = Some(ends);
        return;
    }
    let ticked = c
        .controller
        .tick(&mut c.bridge, &inputs, &mut ends, || End {
            next_due: NVIC::is_pending(Interrupt::ADC) || hw::conversion_pending(),
            boundary_passed: hw::period_boundary_passed(),
        });
    c.ends = Some(ends);
    if ticked.restore_outputs {
        // The tick consumed the flag it read: clear it, or the next tick latches the
        // trip again.
        hw::clear_break_flag();
        hw::enable_outputs();
    }
    if ticked.feed {
        c.watchdogs.feed();
    } else if c.controller.state().supervisor.latched() == Some(Fault::MainLoopStalled) {
        // The window watchdog ends this run within a few periods; the next start names
        // the cause.
        record(Cause::MainLoopStalled, 0, 0);
    }
    let end = hw::cycles();
    let cycles = end.wrapping_sub(start);
    // One accumulator for the link's status and the status line.
    if let Some(cycles) = c
        .controller
        .record_cycles(cycles, board::STATUS_PERIOD_TICKS)
    {
        let status = ticked.status;
        let state = c.controller.state();
        STATUS.publish(&Snapshot {
            ticks: state.ticks,
            cycles,
            overruns: c.controller.guarded().overruns(),
            fault: state.supervisor.latched().map_or(0, Fault::code),
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
    record(Cause::TickStalled, 0, 0);
    loop {
        cortex_m::asm::wfi();
    }
}

/// The clock security system saw the crystal fail: TIM1 has already broken (outputs off);
/// coast by register writes too, clear the flag, and wait for a watchdog reset.
#[exception]
unsafe fn NonMaskableInt() {
    hw::force_coast();
    record(Cause::ClockFailure, 0, 0);
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
    record(Cause::UnexpectedInterrupt, irqn.to_le_bytes()[0], 0);
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
    record(Cause::Panic, 0, 0);
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
    record(Cause::HardFault, 0, 0);
    loop {
        cortex_m::asm::wfi();
    }
}
