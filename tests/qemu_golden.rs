//! Golden traces replayed on the Cortex-M4F: every output bit of every tick must equal what
//! the host recorded (`ema::control::trace`, format in `src/control/trace.rs`). The traces
//! sit in flash (`include_bytes!`); the bridge is the RAM bridge with the trace's PWM
//! resolution. On a mismatch the run prints the first differing tick and field and fails.
//!
//! `tests/golden_host.rs` checks on the host that every reference case has a trace listed
//! here and that none is stale.
#![no_std]
#![no_main]

#[macro_use]
mod common;

use cortex_m_rt::entry;
use ema::control::trace;

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    common::on_panic(info)
}

/// Every golden trace, by case name.
const TRACES: &[(&str, &[u8])] = &[
    ("paper", include_bytes!("golden/paper.emat")),
    (
        "boundary_layer",
        include_bytes!("golden/boundary_layer.emat"),
    ),
    ("practical", include_bytes!("golden/practical.emat")),
];

#[entry]
fn main() -> ! {
    let ctr = common::Counter::start();
    let mut total = 0u32;
    for &(name, bytes) in TRACES {
        let (trace, case, cfg) = match trace::open(bytes) {
            Ok(t) => t,
            Err(e) => common::fail(format_args!("{}: cannot replay: {:?}", name, e)),
        };
        ensure!(
            case.name == name,
            "{}: the trace is of case {}",
            name,
            case.name
        );
        let ticks = trace.header().ticks;
        ensure!(
            ticks >= trace::MIN_GOLDEN_TICKS,
            "{}: only {} ticks",
            name,
            ticks
        );
        let mut bridge = common::bridge(trace.header().max_duty);
        let t0 = ctr.now();
        match trace::replay(&trace, &cfg, &mut bridge) {
            Ok(n) => {
                ensure!(n == ticks, "{}: replayed {} of {} ticks", name, n, ticks);
            }
            Err(m) => common::fail(format_args!("{} (law {}): {}", name, cfg.law().name(), m)),
        }
        let instr = ctr.now().wrapping_sub(t0);
        let (mut modes, mut faulted) = ([0u32; 3], 0u32);
        for r in trace.records() {
            if let Some(m) = modes.get_mut(usize::from(r.output.mode)) {
                *m += 1;
            }
            faulted += u32::from(r.output.fault != 0);
        }
        outln!(
            "{} (law {}): {} ticks bit-exact (coast {}, forward {}, reverse {}, latched fault {}), {} bytes in flash, {} instructions per replayed tick",
            name, cfg.law().name(), ticks, modes[0], modes[1], modes[2], faulted, bytes.len(), instr / ticks
        );
        total += ticks;
    }
    ensure!(total > 0, "no trace replayed");
    outln!(
        "PASS: {} ticks of {} trace(s) reproduce the host bit for bit",
        total,
        TRACES.len()
    );
    common::exit(true)
}
