//! Instructions per tick on the Cortex-M4F, for every reference case (one per law).
//!
//! Runs each case of `ema::control::trace::CASES` in closed loop with a small actuator
//! model (`common::plant`) for [`TICKS`] ticks (1 mm at rest, step to 3 mm, then to 2 mm)
//! and counts, with TIM2 under `-icount shift=0`, the instructions of
//!
//! * the whole tick (`Config::tick`: sense -> observer -> law -> supervisor -> bridge),
//! * the law alone (`ema::control::law::Law::step` on the same inputs and state),
//! * each stage on its own (sense, observer, law, limits, bridge), to show where the
//!   instructions go.
//!
//! A tick that latches a fault is followed by `Config::rearm`, as an operator would: the
//! paper's law, sampled at 20 kHz from 24 V, trips the current checks every few ticks
//! (its chattering current outruns the limits), and the statistics are of the ticks that ran the whole path
//! ("running"); the ticks that latched are counted and also held to the budget.
//!
//! Fails when any tick exceeds [`TICK_BUDGET`] (see there why it is not yet the goal of
//! [`TICK_GOAL`]), when a case has fewer than [`MIN_RUNNING`] running ticks, or when the
//! law or a stage alone does not reproduce the tick's result bit for bit.
#![no_std]
#![no_main]

#[macro_use]
mod common;
use ema::control::bridge::BOARD_MAX_DUTY;

use core::hint::black_box;

use common::plant::Plant;
use common::{min_median_max, Bridge, Counter};
use cortex_m_rt::entry;
use ema::control::bridge::Drive;
use ema::control::law::{self, Law, Reference};
use ema::control::observer;
use ema::control::sense::{Frame, Measurement};
use ema::control::shaping;
use ema::control::supervisor::monitor;
use ema::control::supervisor::Fault;
use ema::control::trace::CASES;
use ema::control::{Config, State, Status};

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    common::on_panic(info)
}

/// Ticks per case.
const TICKS: usize = 400;
/// Fewest ticks per case that must run the whole path (no fault latched).
const MIN_RUNNING: usize = 200;

/// The product's goal for one whole tick \[instructions\]: at 168 MHz and roughly 2
/// cycles per instruction (flash wait states, 14-cycle FPU divides) about 4 us, under a
/// tenth of the 50 us period.
const TICK_GOAL: u32 = 300;

/// Budget for one whole tick \[instructions\]: the run fails above it.
///
/// The tick does not meet [`TICK_GOAL`], and this budget does not pretend it does: it
/// sits about 5 % above the worst tick measured (1525, the practical law on the first
/// tick of a shaped move, which plans the trajectory, since the electrical residual
/// learns the coil's resistance), so that any regression fails the run. The count is of the code the board runs: the firmware profile, built for speed
/// (opt-level 3; built for size, as the image once had to be to fit 64 KiB, the same tick
/// took 1625 at most, median 1218 against 1124). The run prints the measured figures per
/// case and per stage; the goal is out of reach of a single-rate tick: sense, limits, law
/// and bridge alone take more than 300.
const TICK_BUDGET: u32 = 1_600;

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

/// The tick's reference shaping step (control::Config::step does the same).
#[inline(never)]
fn shape(cfg: &Config, st: &mut shaping::State, x_m: f32, setpoint_m: f32) -> Reference {
    let stroke = cfg.stroke_m();
    let setpoint_m = ema::control::math::clamp(setpoint_m, 0.0, stroke);
    match cfg.shaping() {
        Some(shaping) => {
            if !st.is_primed() {
                shaping.start(st, ema::control::math::clamp(x_m, 0.0, stroke));
            }
            shaping.step(st, setpoint_m)
        }
        None => Reference::hold(setpoint_m),
    }
}

/// The tick's fault detectors: the check, and the record of the drive that follows.
#[inline(never)]
fn monitor(
    cfg: &Config,
    st: &mut monitor::State,
    inputs: &monitor::Inputs,
    d: &Drive,
) -> Option<Fault> {
    let f = cfg.monitors().check(st, inputs);
    cfg.monitors()
        .record_drive(st, d.u_v, d.mode != ema::control::bridge::Mode::Coast);
    f
}

#[inline(never)]
fn drive(b: &mut Bridge, u_v: f32, vbus_v: f32, clear: f32) -> ema::control::bridge::Drive {
    match b.apply_clear(u_v, vbus_v, clear) {
        Ok(d) => d,
        Err(e) => match e {
            ema::control::bridge::Error::Pwm(e) | ema::control::bridge::Error::Pin(e) => match e {},
        },
    }
}

/// The stages of the tick, in its order.
const STAGES: [&str; 7] = [
    "sense", "limits", "shaping", "observer", "law", "monitors", "bridge",
];

struct Counts {
    whole: [u32; TICKS],
    law: [u32; TICKS],
    stages: [[u32; TICKS]; STAGES.len()],
}

static mut COUNTS: Counts = Counts {
    whole: [0; TICKS],
    law: [0; TICKS],
    stages: [[0; TICKS]; STAGES.len()],
};

#[entry]
fn main() -> ! {
    measure()
}

/// Counts every case's ticks and stages and reports them (`#[entry]` puts no attribute on
/// the function that carries its body, so the body is here).
#[expect(
    clippy::too_many_lines,
    reason = "the counted loop: each stage timed and checked in the tick's order on the \
              state the tick started from; split, each helper would take that whole state"
)]
fn measure() -> ! {
    let ctr = Counter::start();
    let overhead = ctr.overhead();
    // SAFETY: the only reference to COUNTS, taken once in `main` (no interrupts run).
    let counts = unsafe { &mut *core::ptr::addr_of_mut!(COUNTS) };
    outln!(
        "instructions per tick (TIM2 under -icount shift=0, read overhead {} subtracted), {} closed-loop ticks per case",
        overhead,
        TICKS
    );
    let mut worst = 0;
    for case in CASES {
        let settings = match (case.settings)() {
            Ok(s) => s,
            Err(e) => common::fail(format_args!("{}: settings do not derive: {}", case.name, e)),
        };
        let cfg = match settings.build() {
            Ok(c) => c,
            Err(e) => common::fail(format_args!("{}: settings do not build: {}", case.name, e)),
        };
        let mut st = cfg.initial_state();
        let mut b = common::bridge(BOARD_MAX_DUTY);
        let mut b2 = common::bridge(BOARD_MAX_DUTY);
        let mut plant = Plant::new(&settings, 1e-3, 24.0);
        let (mut running, mut tripped, mut tripped_max) = (0usize, 0u32, 0u32);
        let mut first_fault = None;
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
            let n_whole = t1.wrapping_sub(t0).wrapping_sub(overhead);
            worst = worst.max(n_whole);
            plant.advance(&s.drive);
            if let Some(f) = s.fault {
                first_fault.get_or_insert((k, f));
                tripped += 1;
                tripped_max = tripped_max.max(n_whole);
                cfg.rearm(&mut st);
                continue;
            }
            let n = running;
            running += 1;
            counts.whole[n] = n_whole;

            // The stages on their own, from the state the tick started from, each checked
            // against what the tick produced.
            let t0 = ctr.now();
            let m = sense(black_box(&cfg), black_box(&frame));
            let t1 = ctr.now();
            counts.stages[0][n] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            let m = m.unwrap_or_default();
            ensure!(
                m == s.measurement,
                "{} tick {}: sense alone differs",
                case.name,
                k
            );

            let t0 = ctr.now();
            let l = limits(black_box(&cfg), black_box(&m));
            let t1 = ctr.now();
            counts.stages[1][n] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            ensure!(l.is_none(), "{} tick {}: limits alone trip", case.name, k);

            let mut traj = before.shaping;
            let t0 = ctr.now();
            let r = shape(
                black_box(&cfg),
                &mut traj,
                black_box(m.x_m),
                black_box(setpoint),
            );
            let t1 = ctr.now();
            counts.stages[2][n] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            ensure!(
                r == s.reference,
                "{} tick {}: shaping alone differs",
                case.name,
                k
            );

            let mut obs = before.observer;
            let t0 = ctr.now();
            let est = observe(black_box(&cfg), &mut obs, black_box(&m));
            let t1 = ctr.now();
            counts.stages[3][n] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            ensure!(
                est == s.estimate,
                "{} tick {}: the observer alone differs",
                case.name,
                k
            );

            // The tick builds the law's input from these values (control::Config::step).
            let input = law::Input {
                x_m: s.estimate.x_m,
                v_mps: s.estimate.v_mps,
                i_a: s.measurement.i_a,
                vbus_v: s.measurement.vbus_v,
                disturbance_mps2: s.estimate.d_mps2,
                reference: s.reference,
                u_prev_v: before.u_prev_v,
                ..Default::default()
            };
            let mut law_state = before.law;
            let t0 = ctr.now();
            let out = law_alone(black_box(cfg.law()), &mut law_state, black_box(&input));
            let t1 = ctr.now();
            let n_law = t1.wrapping_sub(t0).wrapping_sub(overhead);
            counts.law[n] = n_law;
            counts.stages[4][n] = n_law;
            ensure!(
                (out.u_v.to_bits(), out.i_d_a.to_bits())
                    == (s.output.u_v.to_bits(), s.output.i_d_a.to_bits()),
                "{} tick {}: the law alone gives u = {}, the tick {}",
                case.name,
                k,
                out.u_v,
                s.output.u_v
            );

            let mut mon = before.monitor;
            let seen = monitor::Inputs {
                x_m: m.x_m,
                i_a: m.i_a,
                r_m: s.reference.x_m,
                target_m: setpoint,
                v_mps: s.estimate.v_mps,
            };
            let t0 = ctr.now();
            let f = monitor(
                black_box(&cfg),
                &mut mon,
                black_box(&seen),
                black_box(&s.drive),
            );
            let t1 = ctr.now();
            counts.stages[5][n] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            ensure!(
                f.is_none() && mon == st.monitor,
                "{} tick {}: the monitors alone differ",
                case.name,
                k
            );

            // The voltage the tick lets the bridge apply (zero after a current jump).
            let u_v = cfg.monitors().drive_v(&st.monitor, s.output.u_v);
            let t0 = ctr.now();
            let d = drive(
                &mut b2,
                black_box(u_v),
                black_box(m.vbus_v),
                cfg.max_modulation(),
            );
            let t1 = ctr.now();
            counts.stages[6][n] = t1.wrapping_sub(t0).wrapping_sub(overhead);
            ensure!(
                d == s.drive,
                "{} tick {}: the bridge alone differs",
                case.name,
                k
            );
        }
        ensure!(
            running >= MIN_RUNNING,
            "{}: only {} of {} ticks ran the whole path",
            case.name,
            running,
            TICKS
        );
        let (w0, w1, w2) = min_median_max(&mut counts.whole[..running]);
        let (l0, l1, l2) = min_median_max(&mut counts.law[..running]);
        outln!(
            "{:<15} law {:<15} whole tick min/median/max {}/{}/{}   law alone {}/{}/{}   ({} running ticks, x = {} mm at the end)",
            case.name, cfg.law().name(), w0, w1, w2, l0, l1, l2, running, plant.x_m * 1e3
        );
        if let Some((k, f)) = first_fault {
            outln!(
                "{:<15}   {} ticks latched a fault and were re-armed (first: {} at tick {}), at most {} instructions",
                "", tripped, f, k, tripped_max
            );
        }
        let mut sum = 0;
        for (name, v) in STAGES.iter().zip(counts.stages.iter_mut()) {
            let (s0, s1, s2) = min_median_max(&mut v[..running]);
            sum += s1;
            outln!("{:<15}   stage {:<9} {}/{}/{}", "", name, s0, s1, s2);
        }
        outln!(
            "{:<15}   sum of stage medians {}, whole-tick median {}: {} for the glue (status, checks, call)",
            "", sum, w1, w1 as i64 - sum as i64
        );
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
