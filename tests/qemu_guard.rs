//! The guard (`ema::device::guard`) as the firmware's control interrupt runs it, on the
//! Cortex-M4F.
//!
//! SysTick fires at the control rate (20 kHz) and runs the product's tick (the practical
//! law, closed loop with the plant stand-in) through `guard::Config::run`, with what the
//! hardware says: the start time from TIM2 (one count per instruction, 1 ns, under
//! `-icount shift=0`), "next tick due" from SysTick's pending bit and "period boundary
//! passed" from its COUNTFLAG (read at the start, which clears it, and at the end). Ticks
//! are made late and long on purpose:
//!
//! 1. **On time**: [`TICKS`] ticks: every one feeds, nothing latches, and two feeds are
//!    never further apart than the window watchdog's quiet time.
//! 2. **Long ticks**: tick [`AT`] burns [`LONG_NS`], more than a period:
//!    `overrun` latches, that tick does not feed, the bridge coasts; the ticks after it
//!    feed again and keep it coasting.
//! 3. **A late tick**: the main loop masks interrupts for [`LATE_NS`] (1.6 periods) after
//!    tick [`AT`]: the next tick starts late, `overrun` latches, it does not feed.
//! 4. **Every tick long**: no tick feeds; the time without a feed passes the window
//!    watchdog's latest early wake-up, which on the board coasts the bridge then.
//! 5. **Hardware trip**: the break flag reads set at tick [`AT`]: `hardware_trip` latches,
//!    the bridge coasts, and the ticks keep feeding.
//!
//! It also counts what the guard adds to a tick: the guarded tick against the bare tick on
//! the same inputs (which must give the same bits).
#![no_std]
#![no_main]

#[macro_use]
mod common;
use ema::control::bridge::BOARD_MAX_DUTY;

use core::cell::RefCell;
use core::hint::black_box;

use common::plant::Plant;
use common::{min_median_max, Bridge, Counter};
use cortex_m::interrupt::{self, Mutex};
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use cortex_m_rt::{entry, exception};
use ema::control::bridge::Mode;
use ema::control::supervisor::Fault;
use ema::control::{Config, Settings, State};
use ema::device::guard::{self, End, Start, Watchdog, WATCHDOG_QUIET_PERIODS};

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    common::on_panic(info)
}

/// Ticks per run.
const TICKS: u32 = 400;
/// The tick at which each run's event happens.
const AT: u32 = 200;
/// Ticks of the run where every tick is long.
const LONG_TICKS: u32 = 12;
/// What a long tick burns on top of its work \[ns\] (1.2 periods: the next tick is due
/// before it ends, yet starts within 1.5 periods of it).
const LONG_NS: u32 = 60_000;
/// How long the main loop masks interrupts to make a tick late \[ns\] (1.6 periods).
const LATE_NS: u32 = 80_000;

/// Burns `ns` nanoseconds: `cortex_m::asm::delay(n)` runs `n` two-instruction iterations,
/// 2 ns each under `-icount shift=0`.
fn burn(ns: u32) {
    cortex_m::asm::delay(ns / 2);
}
/// The control period under QEMU \[ns\] (= TIM2 counts).
const PERIOD_NS: u32 = 50_000;
/// The reference board's APB1 clock, which counts the window watchdog \[Hz\].
const APB1_HZ: u32 = 42_000_000;
/// Samples of the guard's own cost.
const COST_TICKS: usize = 200;

#[derive(Clone, Copy, PartialEq, Eq)]
enum Event {
    None,
    LongTick,
    EveryTickLong,
    HardwareTrip,
}

#[derive(Clone, Copy, Default)]
struct Tick {
    fed: bool,
    fault: Option<Fault>,
    coasting: bool,
}

struct Run {
    cfg: Config,
    state: State,
    bridge: Bridge,
    plant: Plant,
    ctr: Counter,
    guard: guard::Config,
    guarded: guard::State,
    event: Event,
    target: u32,
    done: u32,
    ticks: [Tick; TICKS as usize],
    first_start: Option<u32>,
    last_feed: Option<u32>,
    max_feed_gap: u32,
    end: u32,
}

static RUN: Mutex<RefCell<Option<Run>>> = Mutex::new(RefCell::new(None));

/// SysTick's COUNTFLAG: the counter wrapped since the last read (the read clears it).
fn wrapped() -> bool {
    // SAFETY: a read of SYST_CSR; its only side effect is clearing COUNTFLAG, which only
    // this program's tick reads.
    unsafe { (*SYST::PTR).csr.read() & (1 << 16) != 0 }
}

#[exception]
fn SysTick() {
    interrupt::free(|cs| {
        let mut guard = RUN.borrow(cs).borrow_mut();
        let Some(r) = guard.as_mut() else { return };
        if r.done >= r.target {
            return;
        }
        let now = r.ctr.now();
        let _ = wrapped();
        r.first_start.get_or_insert(now);
        let k = r.done;
        let slow = match r.event {
            Event::LongTick => k == AT,
            Event::EveryTickLong => true,
            _ => false,
        };
        let start = Start {
            now,
            hardware_trip: r.event == Event::HardwareTrip && k == AT,
        };
        let cfg = r.cfg;
        let frame = r.plant.frame();
        let o = r.guard.run(
            &mut r.guarded,
            &cfg,
            &mut r.state,
            &mut r.bridge,
            start,
            |st, b| {
                let s = cfg.tick(st, b, &frame, 3e-3);
                if slow {
                    burn(LONG_NS);
                }
                s
            },
            || End {
                next_due: SCB::is_pendst_pending(),
                boundary_passed: wrapped(),
            },
        );
        let end = r.ctr.now();
        r.plant.advance(&o.status.drive);
        if o.feed {
            if let Some(last) = r.last_feed {
                r.max_feed_gap = r.max_feed_gap.max(end.wrapping_sub(last));
            }
            r.last_feed = Some(end);
        }
        if let Some(t) = r.ticks.get_mut(k as usize) {
            *t = Tick {
                fed: o.feed,
                fault: o.status.fault,
                coasting: r.bridge.mode() == Mode::Coast,
            };
        }
        r.end = end;
        r.done += 1;
    });
}

fn done() -> u32 {
    interrupt::free(|cs| RUN.borrow(cs).borrow().as_ref().map_or(0, |r| r.done))
}

/// Runs `target` ticks of `settings` in SysTick at the control rate, with `event`.
fn run(syst: &mut SYST, settings: &Settings, event: Event, target: u32, late: bool) -> Run {
    let cfg = match settings.build() {
        Ok(c) => c,
        Err(e) => common::fail(format_args!("settings do not build: {}", e)),
    };
    let r = Run {
        cfg,
        state: cfg.initial_state(),
        bridge: common::bridge(BOARD_MAX_DUTY),
        plant: Plant::new(settings, 1e-3, 24.0),
        ctr: Counter::start(),
        guard: guard::Config::for_period(PERIOD_NS),
        guarded: guard::State::default(),
        event,
        target,
        done: 0,
        ticks: [Tick::default(); TICKS as usize],
        first_start: None,
        last_feed: None,
        max_feed_gap: 0,
        end: 0,
    };
    interrupt::free(|cs| *RUN.borrow(cs).borrow_mut() = Some(r));
    // SysTick runs on the 168 MHz processor clock under QEMU (tests/qemu_systick.rs
    // measures it): 8400 counts per 20 kHz period.
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(168_000_000 / 20_000 - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
    let mut masked = false;
    // Busy-wait, not `wfi` (see tests/qemu_systick.rs).
    loop {
        cortex_m::asm::nop();
        let d = done();
        if late && !masked && d == AT {
            // Something holds the processor for 1.6 periods right after a tick.
            masked = true;
            interrupt::free(|_| burn(LATE_NS));
        }
        if d >= target {
            break;
        }
    }
    syst.disable_interrupt();
    syst.disable_counter();
    SCB::clear_pendst();
    match interrupt::free(|cs| RUN.borrow(cs).borrow_mut().take()) {
        Some(r) => r,
        None => common::fail(format_args!("the run vanished")),
    }
}

fn tick(r: &Run, k: u32) -> Tick {
    r.ticks.get(k as usize).copied().unwrap_or_default()
}

/// Every tick from `from` on feeds, with `fault` latched and the bridge coasting.
fn fed_and_coasting_from(r: &Run, from: u32, fault: Fault) -> bool {
    (from..r.done).all(|k| {
        let t = tick(r, k);
        t.fed && t.fault == Some(fault) && t.coasting
    })
}

#[entry]
fn main() -> ! {
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        common::fail(format_args!("core peripherals taken twice"))
    };
    let Some(case) = ema::control::trace::case("practical") else {
        common::fail(format_args!("no practical case"))
    };
    let settings = match (case.settings)() {
        Ok(s) => s,
        Err(e) => common::fail(format_args!("practical settings do not derive: {}", e)),
    };
    let wwdg = Watchdog::at_least(APB1_HZ, WATCHDOG_QUIET_PERIODS * PERIOD_NS);

    // What the guard costs: guarded and bare tick on the same inputs, bit for bit.
    guard_cost(&settings);

    // 1. On time.
    let r = run(&mut cp.SYST, &settings, Event::None, TICKS, false);
    let fed = (0..r.done).filter(|&k| tick(&r, k).fed).count() as u32;
    outln!(
        "on time: {} ticks, {} fed, {} overruns, fault {:?}; longest gap between two feeds {} ns (window watchdog quiet for {} ns, early wake-up {}..{} ns after a feed)",
        r.done, fed, r.guarded.overruns(), r.state.supervisor.latched(), r.max_feed_gap,
        WATCHDOG_QUIET_PERIODS * PERIOD_NS, wwdg.early_wakeup_min_ns(), wwdg.early_wakeup_max_ns()
    );
    ensure!(
        r.done == TICKS && fed == TICKS,
        "{} of {} ticks fed",
        fed,
        r.done
    );
    ensure!(r.state.supervisor.latched().is_none(), "a fault latched");
    ensure!(
        r.max_feed_gap < 2 * PERIOD_NS,
        "feeds {} ns apart: more than two periods",
        r.max_feed_gap
    );
    ensure!(
        r.max_feed_gap < wwdg.early_wakeup_min_ns(),
        "the window watchdog would bite an on-time loop"
    );

    // 2. One long tick.
    let r = run(&mut cp.SYST, &settings, Event::LongTick, TICKS, false);
    let t = tick(&r, AT);
    outln!(
        "long tick {} (+{} ns): fed {}, fault {:?}, coasting {}; {} overruns; the {} ticks after it fed and coasting: {}",
        AT, LONG_NS, t.fed, t.fault, t.coasting, r.guarded.overruns(), r.done - AT - 1,
        fed_and_coasting_from(&r, AT + 1, Fault::Overrun)
    );
    ensure!(
        (0..AT).all(|k| tick(&r, k).fed),
        "a tick before the long one was not fed"
    );
    ensure!(
        !t.fed && t.fault == Some(Fault::Overrun) && t.coasting,
        "the long tick: fed {}, fault {:?}, coasting {}",
        t.fed,
        t.fault,
        t.coasting
    );
    ensure!(
        r.guarded.overruns() == 1,
        "{} overruns",
        r.guarded.overruns()
    );
    ensure!(
        fed_and_coasting_from(&r, AT + 1, Fault::Overrun),
        "after the long tick: not all fed and coasting with the overrun latched"
    );

    // 3. A late tick.
    let r = run(&mut cp.SYST, &settings, Event::None, TICKS, true);
    let t = tick(&r, AT);
    outln!(
        "late tick {} (interrupts masked {} ns after tick {}): fed {}, fault {:?}, coasting {}; {} overruns",
        AT, LATE_NS, AT - 1, t.fed, t.fault, t.coasting, r.guarded.overruns()
    );
    ensure!(
        (0..AT).all(|k| tick(&r, k).fed),
        "a tick before the late one was not fed"
    );
    ensure!(
        !t.fed && t.fault == Some(Fault::Overrun) && t.coasting,
        "the late tick: fed {}, fault {:?}, coasting {}",
        t.fed,
        t.fault,
        t.coasting
    );
    ensure!(
        r.guarded.overruns() == 1,
        "{} overruns",
        r.guarded.overruns()
    );
    ensure!(
        fed_and_coasting_from(&r, AT + 1, Fault::Overrun),
        "after the late tick: not all fed and coasting with the overrun latched"
    );

    // 4. Every tick long: nothing feeds.
    let r = run(
        &mut cp.SYST,
        &settings,
        Event::EveryTickLong,
        LONG_TICKS,
        false,
    );
    let fed = (0..r.done).filter(|&k| tick(&r, k).fed).count();
    let unfed_ns = r.end.wrapping_sub(r.first_start.unwrap_or(r.end));
    outln!(
        "every tick long: {} ticks, {} fed, fault {:?}; {} ns without a feed: the window watchdog's early wake-up coasts the bridge by {} ns after the last feed",
        r.done, fed, r.state.supervisor.latched(), unfed_ns, wwdg.early_wakeup_max_ns()
    );
    ensure!(fed == 0, "{} long ticks fed the watchdog", fed);
    ensure!(
        r.state.supervisor.latched() == Some(Fault::Overrun),
        "no overrun latched"
    );
    ensure!(
        unfed_ns > wwdg.early_wakeup_max_ns(),
        "the run ended before the watchdog would have bitten"
    );

    // 5. Hardware trip.
    let r = run(&mut cp.SYST, &settings, Event::HardwareTrip, TICKS, false);
    let t = tick(&r, AT);
    outln!(
        "hardware trip at tick {}: fed {}, fault {:?}, coasting {}; the {} ticks after it fed and coasting: {}",
        AT, t.fed, t.fault, t.coasting, r.done - AT - 1,
        fed_and_coasting_from(&r, AT + 1, Fault::HardwareTrip)
    );
    ensure!(
        t.fed && t.fault == Some(Fault::HardwareTrip) && t.coasting,
        "the tripped tick: fed {}, fault {:?}, coasting {}",
        t.fed,
        t.fault,
        t.coasting
    );
    ensure!(
        fed_and_coasting_from(&r, AT + 1, Fault::HardwareTrip),
        "after the trip: not all fed and coasting"
    );
    ensure!(
        r.guarded.overruns() == 0,
        "{} overruns",
        r.guarded.overruns()
    );

    outln!("PASS");
    common::exit(true)
}

/// Instructions the guard adds to a tick: [`COST_TICKS`] closed-loop ticks, each run once
/// through the guard and once bare from the same state, with the same result.
fn guard_cost(settings: &Settings) {
    let cfg = match settings.build() {
        Ok(c) => c,
        Err(e) => common::fail(format_args!("settings do not build: {}", e)),
    };
    let ctr = Counter::start();
    let overhead = ctr.overhead();
    let guard = guard::Config::for_period(PERIOD_NS);
    let mut g = guard::State::default();
    let (mut st1, mut st2) = (cfg.initial_state(), cfg.initial_state());
    let (mut b1, mut b2) = (
        common::bridge(BOARD_MAX_DUTY),
        common::bridge(BOARD_MAX_DUTY),
    );
    let mut plant = Plant::new(settings, 1e-3, 24.0);
    let mut guarded = [0u32; COST_TICKS];
    let mut bare = [0u32; COST_TICKS];
    let mut extra = [0u32; COST_TICKS];
    for k in 0..COST_TICKS {
        let frame = plant.frame();
        let now = ctr.now();
        let t0 = ctr.now();
        let o = guard.run(
            &mut g,
            black_box(&cfg),
            &mut st1,
            &mut b1,
            Start {
                now: black_box(now),
                hardware_trip: black_box(false),
            },
            |st, b| cfg.tick(st, b, black_box(&frame), black_box(3e-3)),
            || black_box(End::default()),
        );
        let t1 = ctr.now();
        let s = cfg.tick(&mut st2, &mut b2, black_box(&frame), black_box(3e-3));
        let t2 = ctr.now();
        ensure!(o.feed, "cost run: tick {} not fed", k);
        ensure!(
            o.status == s && st1 == st2,
            "cost run: the guarded tick {} differs from the bare one",
            k
        );
        plant.advance(&s.drive);
        let (a, b) = (
            t1.wrapping_sub(t0).wrapping_sub(overhead),
            t2.wrapping_sub(t1).wrapping_sub(overhead),
        );
        guarded[k] = a;
        bare[k] = b;
        extra[k] = a.saturating_sub(b);
    }
    let (g0, g1, g2) = min_median_max(&mut guarded);
    let (b0, b1_, b2_) = min_median_max(&mut bare);
    let (e0, e1, e2) = min_median_max(&mut extra);
    outln!(
        "instructions per tick, practical law, {} closed-loop ticks (min/median/max): guarded {}/{}/{}, bare {}/{}/{}, the guard adds {}/{}/{}",
        COST_TICKS, g0, g1, g2, b0, b1_, b2_, e0, e1, e2
    );
}
