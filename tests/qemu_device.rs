//! The board's application (`ema::device`) on the Cortex-M4F: the scripted bench session
//! of `tests/common/session.rs` (arm, a refused set, a stream, a capture triggered by a
//! move, the capture read back, a damaged frame rejected, disarm, a set, a commissioning,
//! a heartbeat, a silent host, a hung main loop) sends byte for byte the frames the
//! host's run sends (`tests/device_host.rs`); the silent host disarms the board, and the
//! hung main loop stops the watchdogs' feed, at the ticks the host's run sees; the
//! instructions of `Controller::tick` (TIM2 under `-icount shift=0`) stay within
//! [`DEVICE_BUDGET`] in every phase: disarmed, armed and holding, armed with telemetry
//! streaming and a capture recording; and the main loop's longest pass stays far within
//! its deadline ([`MAIN_PASS_BUDGET`]).
#![no_std]
#![no_main]

#[macro_use]
mod common;
use ema::control::bridge::BOARD_MAX_DUTY;

use common::session::{Session, FRAMES_HASH, FRAMES_LEN, LINK_TIMEOUT_TICKS, MAIN_LOOP_TICKS};
use common::Counter;
use cortex_m_rt::entry;
use ema::device::Queues;

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    common::on_panic(info)
}

/// Budget of one `Controller::tick` \[instructions\]: the run fails above it. The largest
/// is a tick that takes an order carrying a new configuration (a set, a load: it copies
/// the whole controller configuration), measured 2747 (the firmware profile, built for
/// speed; the order read where it lies in the queue); about 5 % above.
const DEVICE_BUDGET: u32 = 2_885;
/// Budget of what the application (guard, queue poll, liveness checks, operating state)
/// adds to the control tick's largest \[instructions\]: measured 127.
const WRAP_BUDGET: u32 = 135;
/// Budget of what a telemetry sample and a capture sample add on top \[instructions\]:
/// measured 102 (a sample built from the tick's status, queued, and copied to the
/// buffer).
const RECORD_BUDGET: u32 = 110;

/// Budget of the main loop's longest pass \[instructions\]: a tenth of its deadline
/// (`ema::device::liveness::MAIN_LOOP_DEADLINE_S`, 20 ms: 3.36 M cycles at 168 MHz), so
/// that the deadline holds with ten times the margin even where an instruction takes
/// several cycles (flash wait states, divisions).
const MAIN_PASS_BUDGET: u32 = 336_000;

#[entry]
fn main() -> ! {
    let ctr = Counter::start();
    let overhead = ctr.overhead();
    let mut q = Queues::new();
    let (main, isr) = q.split();
    let bridges = (
        common::bridge(BOARD_MAX_DUTY),
        common::bridge(BOARD_MAX_DUTY),
    );
    let s = match Session::new(main, isr, bridges.0, bridges.1) {
        Ok(s) => s,
        Err(e) => common::fail(format_args!("session: {}", e)),
    };
    let mut clock = || ctr.now().wrapping_sub(overhead);
    let out = match s.run(&mut clock) {
        Ok(o) => o,
        Err(e) => common::fail(format_args!("session: {}", e)),
    };
    outln!(
        "session: {} bytes sent, hash {:#018x} (host {} bytes, {:#018x}); {} telemetry frames, {} capture samples read back, at {} um",
        out.len,
        out.hash,
        FRAMES_LEN,
        FRAMES_HASH,
        out.telemetry,
        out.captured,
        (out.x_m * 1e6) as i32
    );
    ensure!(
        out.hash == FRAMES_HASH && out.len == FRAMES_LEN,
        "the frames differ from the host's"
    );
    outln!(
        "silent host: disarmed with link_timeout {} ticks after the arming request (timeout {}); hung main loop: no feed {} ticks after its last pass (deadline {})",
        out.link_lost_after,
        LINK_TIMEOUT_TICKS,
        out.main_stalled_after,
        MAIN_LOOP_TICKS
    );
    ensure!(
        (LINK_TIMEOUT_TICKS + 1..=LINK_TIMEOUT_TICKS + 2).contains(&out.link_lost_after)
            && (MAIN_LOOP_TICKS + 1..=MAIN_LOOP_TICKS + 2).contains(&out.main_stalled_after),
        "liveness: not at the host's ticks"
    );
    let c = out.cost;
    for (what, app, bare) in [
        ("disarmed", c.disarmed, None),
        ("armed, holding", c.armed, Some(c.armed_bare)),
        (
            "armed, streaming and capturing",
            c.recording,
            Some(c.recording_bare),
        ),
        ("carrying an order", c.with_order, None),
        ("commissioning", c.commissioning, None),
    ] {
        match bare {
            Some(b) => outln!(
                "{}: Controller::tick mean {} max {}; Config::tick alone mean {} max {} ({} ticks)",
                what,
                app.mean(),
                app.max,
                b.mean(),
                b.max,
                app.n
            ),
            None => outln!(
                "{}: Controller::tick mean {} max {} ({} ticks)",
                what,
                app.mean(),
                app.max,
                app.n
            ),
        }
    }
    ensure!(
        c.disarmed.n >= 40 && c.armed.n >= 200 && c.recording.n > 3_000 && c.commissioning.n >= 200,
        "too few ticks measured"
    );
    // What the application adds to the control tick, and what telemetry and the capture
    // add to that: each held to its budget.
    let wrap = c.armed.max.saturating_sub(c.armed_bare.max);
    let recording = c
        .recording
        .max
        .saturating_sub(c.recording_bare.max)
        .saturating_sub(wrap);
    outln!(
        "the application adds at most {} instructions to the control tick; telemetry and capture {} more",
        wrap,
        recording
    );
    ensure!(
        wrap <= WRAP_BUDGET,
        "application: {} > {}",
        wrap,
        WRAP_BUDGET
    );
    ensure!(
        recording <= RECORD_BUDGET,
        "telemetry and capture: {} > {}",
        recording,
        RECORD_BUDGET
    );
    for (what, n) in [
        ("disarmed", c.disarmed.max),
        ("armed", c.armed.max),
        ("recording", c.recording.max),
        ("order", c.with_order.max),
        ("commissioning", c.commissioning.max),
    ] {
        ensure!(
            n <= DEVICE_BUDGET,
            "{}: {} instructions > {}",
            what,
            n,
            DEVICE_BUDGET
        );
    }
    outln!(
        "main loop: longest pass {} instructions (mean {}, {} passes), budget {}",
        c.main_pass.max,
        c.main_pass.mean(),
        c.main_pass.n,
        MAIN_PASS_BUDGET
    );
    ensure!(
        c.main_pass.max <= MAIN_PASS_BUDGET,
        "main loop: {} instructions > {}",
        c.main_pass.max,
        MAIN_PASS_BUDGET
    );
    outln!("PASS");
    common::exit(true)
}
