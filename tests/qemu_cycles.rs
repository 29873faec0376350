//! Instructions per tick on the Cortex-M4F, for every reference case (one per law).
//!
//! Runs each case of `ema::trace::CASES` in closed loop with a small plant stand-in
//! (`common::Loop`) for [`TICKS`] ticks (1 mm at rest, step to 3 mm, then to 2 mm so that
//! the bridge also reverses) and counts, with TIM2 under `-icount shift=0`, the
//! instructions of
//!
//! * the whole tick (`Config::tick`: sense -> observer -> law -> supervisor -> bridge),
//! * the law alone (`ema::law::Law::step` on the same inputs and state),
//! * each stage on its own (sense, observer, law, limits, bridge), to show where the
//!   instructions go.
//!
//! Fails when a whole tick exceeds [`TICK_BUDGET`] (see there why it is not yet the goal
//! of [`TICK_GOAL`]), when a case does not run fault-free,
//! or when the law alone does not reproduce the tick's law output bit for bit.
#![no_std]
#![no_main]

#[macro_use]
mod common;

use core::hint::black_box;

use common::{min_median_max, Bridge, Counter, Loop, FIRMWARE_MAX_DUTY};
use cortex_m_rt::entry;
use ema::control::{Config, State, Status};
use ema::law::{self, Law};
use ema::observer;
use ema::sense::{Frame, Measurement};
use ema::supervisor::Fault;
use ema::trace::CASES;

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    common::on_panic(info)
}

/// Ticks measured per case.
const TICKS: usize = 400;

/// The product's goal for one whole tick \[instructions\]: at 168 MHz and roughly 2
/// cycles per instruction (flash wait states, 14-cycle FPU divides) about 4 us, under a
/// tenth of the 50 us period.
const TICK_GOAL: u32 = 300;

/// Budget for one whole tick \[instructions\]: the run fails above it.
///
/// The tick does not meet [`TICK_GOAL`] today, and this budget does not pretend it does.
/// Measured here (paper law, 400 closed-loop ticks; stage medians with each stage called on
/// its own, call overhead included): whole tick 437/451/476 min/median/max; law alone
/// 127-132 (five divides, one square root, and an `f32::max` that is a library call on this
/// FPU); observer 73; bridge 83-121 (two divides, more when it reverses); sense 55; limits
/// 54; the tick's own glue (status, finiteness checks, call) about 44. The budget sits
/// about 5 % above the measured maximum so that any regression fails the run; reaching the
/// goal needs a cheaper law and observer (fewer divides), not a looser number. The README
/// lists the figures ("Instructions per tick").
const TICK_BUDGET: u32 = 500;

#[inline(never)]
fn whole(cfg: &Config, st: &mut State, b: &mut Bridge, frame: &Frame, setpoint_m: f32) -> Status {
    cfg.tick(st, b, frame, setpoint_m)
}

#[inline(never)]
fn law_alone(law: &law::Config, st: &mut law::State, input: &law::Input) -> law::Output {
    law.step(st, input)
}

#[inline(never)]
fn sense(cfg: &Config, frame: &Frame) -> Result<Measurement, Fault> {
    cfg.sense().convert(frame)
}

#[inline(never)]
fn observe(cfg: &Config, st: &mut observer::State, m: &Measurement) -> observer::Estimate {
    cfg.observer().update(st, m.x_m, m.i_a)
}

#[inline(never)]
fn limits(cfg: &Config, m: &Measurement) -> Option<Fault> {
    cfg.limits().check(m)
}

#[inline(never)]
fn drive(b: &mut Bridge, u_v: f32, vbus_v: f32) -> ema::bridge::Drive {
    match b.apply(u_v, vbus_v) {
        Ok(d) => d,
        Err(e) => match e {
            ema::bridge::Error::Pwm(e) | ema::bridge::Error::Pin(e) => match e {},
        },
    }
}

struct Counts {
    whole: [u32; TICKS],
    law: [u32; TICKS],
    stages: [[u32; TICKS]; 5],
}

static mut COUNTS: Counts = Counts {
    whole: [0; TICKS],
    law: [0; TICKS],
    stages: [[0; TICKS]; 5],
};

const STAGES: [&str; 5] = ["sense", "observer", "law", "limits", "bridge"];

#[entry]
fn main() -> ! {
    let ctr = Counter::start();
    let overhead = ctr.overhead();
    // SAFETY: the only reference to COUNTS, taken once in `main` (no interrupts run).
    let counts = unsafe { &mut *core::ptr::addr_of_mut!(COUNTS) };
    outln!("instructions per tick (TIM2 under -icount shift=0, read overhead {} subtracted), {} ticks per case", overhead, TICKS);
    let mut worst = 0;
    for case in CASES {
        let settings = (case.settings)();
        let cfg = match settings.build() {
            Ok(c) => c,
            Err(e) => common::fail(format_args!("{}: settings do not build: {}", case.name, e)),
        };
        let mut st = cfg.initial_state();
        let mut b = common::bridge(FIRMWARE_MAX_DUTY);
        let mut b2 = common::bridge(FIRMWARE_MAX_DUTY);
        let vbus = settings.limits.vbus_max_v / 1.25;
        let mut plant = Loop::new(settings.plant, settings.sense, cfg.ts_s(), 1e-3, vbus);
        let mut faults = 0;
        for k in 0..TICKS {
            let setpoint = if k < TICKS / 2 { 3e-3 } else { 2e-3 };
            let frame = plant.frame();
            let before = st;

            let t0 = ctr.now();
            let s = whole(
                black_box(&cfg),
                &mut st,
                &mut b,
                black_box(&frame),
                black_box(setpoint),
            );
            let t1 = ctr.now();
            counts.whole[k] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            if let Some(f) = s.fault {
                if faults == 0 {
                    outln!(
                        "{}: first fault at tick {}: {} (x = {} mm, i = {} A)",
                        case.name,
                        k,
                        f,
                        plant.x_m * 1e3,
                        plant.i_a
                    );
                }
                faults += 1;
            }

            // The stages on their own, from the state the tick started from.
            let t0 = ctr.now();
            let m = sense(black_box(&cfg), black_box(&frame));
            let t1 = ctr.now();
            counts.stages[0][k] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            let m = m.unwrap_or_default();
            let mut obs = before.observer;
            let t0 = ctr.now();
            let est = observe(black_box(&cfg), &mut obs, black_box(&m));
            let t1 = ctr.now();
            counts.stages[1][k] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            ensure!(
                s.fault.is_some() || est == s.estimate,
                "{} tick {}: observer alone differs",
                case.name,
                k
            );

            // The tick builds the law's input from these values (control::Config::step).
            #[allow(clippy::needless_update)]
            let input = law::Input {
                x_m: s.estimate.x_m,
                v_mps: s.estimate.v_mps,
                i_a: s.measurement.i_a,
                vbus_v: s.measurement.vbus_v,
                disturbance_mps2: s.estimate.d_mps2,
                reference: s.reference,
                ..Default::default()
            };
            let mut law_state = before.law;
            let t0 = ctr.now();
            let out = law_alone(black_box(cfg.law()), &mut law_state, black_box(&input));
            let t1 = ctr.now();
            let n = t1.wrapping_sub(t0).wrapping_sub(overhead);
            counts.law[k] = n;
            counts.stages[2][k] = n;
            ensure!(
                s.fault.is_some()
                    || (out.u_v.to_bits(), out.i_d_a.to_bits())
                        == (s.output.u_v.to_bits(), s.output.i_d_a.to_bits()),
                "{} tick {}: the law alone gives u = {}, the tick {}",
                case.name,
                k,
                out.u_v,
                s.output.u_v
            );

            let t0 = ctr.now();
            let l = limits(black_box(&cfg), black_box(&m));
            let t1 = ctr.now();
            counts.stages[3][k] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            let _ = black_box(l);

            let t0 = ctr.now();
            let d = drive(&mut b2, black_box(s.output.u_v), black_box(m.vbus_v));
            let t1 = ctr.now();
            counts.stages[4][k] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            ensure!(
                s.fault.is_some() || d == s.drive,
                "{} tick {}: bridge alone differs",
                case.name,
                k
            );

            plant.advance(s.output.i_d_a);
        }
        let (w0, w1, w2) = min_median_max(&mut counts.whole);
        let (l0, l1, l2) = min_median_max(&mut counts.law);
        outln!(
            "{:<12} law {:<10} whole tick min/median/max {}/{}/{}   law alone {}/{}/{}   (x = {} mm at the end, {} faulted ticks)",
            case.name, cfg.law().name(), w0, w1, w2, l0, l1, l2, plant.x_m * 1e3, faults
        );
        let mut sum = 0;
        for (name, v) in STAGES.iter().zip(counts.stages.iter_mut()) {
            let (s0, s1, s2) = min_median_max(v);
            sum += s1;
            outln!("{:<12}   stage {:<9} {}/{}/{}", "", name, s0, s1, s2);
        }
        outln!("{:<12}   sum of stage medians {}, whole-tick median {}: {} for the glue (status, checks, call)", "", sum, w1, w1 as i64 - sum as i64);
        ensure!(
            faults == 0,
            "{}: {} ticks faulted; the measurement must be of the running tick",
            case.name,
            faults
        );
        worst = worst.max(w2);
    }
    ensure!(
        worst <= TICK_BUDGET,
        "a whole tick took {} instructions, budget {}",
        worst,
        TICK_BUDGET
    );
    outln!(
        "PASS: every whole tick <= {} instructions (worst {})",
        TICK_BUDGET,
        worst
    );
    if worst > TICK_GOAL {
        outln!(
            "NOTE: goal of {} instructions per tick not met: worst {} (+{})",
            TICK_GOAL,
            worst,
            worst - TICK_GOAL
        );
    }
    common::exit(true)
}
