//! The link-time proof that the tick cannot panic, shared by `tests/qemu_no_panic.rs` (must
//! link) and `tests/panic_canary.rs` (must not).
//!
//! It also covers the golden-trace reader and replay (`ema::control::trace::Trace::parse`,
//! `ema::control::trace::replay`), which the on-target checker runs on bytes from flash.
//!
//! The program's panic handler calls a function that exists nowhere. The release profile
//! links with fat LTO, so every function that no reachable code calls is gone before the
//! linker resolves symbols: the undefined symbol is only an error when some panic is
//! reachable. `exercise` calls what the firmware's interrupt calls (`Config::tick` through
//! the guard, `guard::Config::run`, and `Config::trip`) with inputs the optimiser cannot
//! see through (`black_box`), for the configuration of every reference case, so every
//! branch of every law, of every stage and of the guard is reachable.

use core::hint::black_box;

use ema::control::supervisor::Fault;
use ema::control::trace::CASES;
use ema::device::guard::{self, End, Start};

#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    extern "Rust" {
        // The symbol's name is the error message the linker prints.
        #[link_name = "\n\nERROR: a panic is reachable from Config::tick, guard::Config::run, Config::trip or the trace replay (see tests/common/no_panic.rs)\n\n"]
        fn a_panic_is_reachable_from_the_tick() -> !;
    }
    // SAFETY: never runs: the program only links when nothing calls the panic handler.
    unsafe { a_panic_is_reachable_from_the_tick() }
}

/// Ticks every reference case on opaque inputs; returns something that depends on all.
pub fn exercise() -> u32 {
    let mut acc = 0u32;
    let mut bridge = crate::common::bridge(black_box(ema::control::bridge::BOARD_MAX_DUTY));
    for case in CASES {
        let Ok(cfg) = (case.settings)().and_then(|s| s.build()) else {
            continue;
        };
        // The optimiser must not know which law, which limits, which calibration.
        let cfg = black_box(cfg);
        let mut state = black_box(cfg.initial_state());
        let guard = black_box(guard::Config::for_period(8400));
        let mut guarded = black_box(guard::State::default());
        for _ in 0..black_box(3) {
            let frame = black_box(ema::control::sense::Frame {
                position: 1000,
                current: 2100,
                vbus: 1354,
            });
            let status = cfg.tick(&mut state, &mut bridge, &frame, black_box(3e-3));
            acc = acc.wrapping_add(u32::from(status.drive.duty));
            let outcome = guard.run(
                &mut guarded,
                &cfg,
                &mut state,
                &mut bridge,
                black_box(Start::default()),
                |st, b| cfg.tick(st, b, &frame, black_box(3e-3)),
                || black_box(End::default()),
            );
            acc = acc.wrapping_add(u32::from(outcome.feed));
        }
        if black_box(false) {
            let _ = cfg.trip(&mut state, &mut bridge, black_box(Fault::Overrun));
        }
        acc = acc.wrapping_add(black_box(state).ticks);
        // The trace reader and replay, on bytes the optimiser cannot see.
        if let Ok(trace) = ema::control::trace::Trace::parse(black_box(&TRACE[..])) {
            if let Err(m) = ema::control::trace::replay(&trace, &cfg, &mut bridge) {
                acc = acc.wrapping_add(m.tick);
            }
        }
    }
    acc
}

/// Bytes for the trace reader: a header and two records' worth.
static TRACE: [u8; ema::control::trace::HEADER_LEN + 2 * ema::control::trace::RECORD_LEN] =
    [0; ema::control::trace::HEADER_LEN + 2 * ema::control::trace::RECORD_LEN];
