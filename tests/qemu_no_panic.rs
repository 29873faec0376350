//! Link-time proof that `Config::tick`, `guard::Config::run`, `Config::trip` and the
//! golden-trace replay cannot panic: this program only links when no panic is reachable from them (`tests/common/no_panic.rs`). Under QEMU it
//! then just runs the calls once and exits successfully; the proof is that it was built.
//! Output goes through `hio` without `core::fmt`, whose own panic paths would otherwise
//! count against the tick.
#![no_std]
#![no_main]

mod common;
#[path = "common/no_panic.rs"]
mod no_panic;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hio};

#[entry]
fn main() -> ! {
    let acc = no_panic::exercise();
    if let Ok(mut out) = hio::hstdout() {
        let _ = out.write_all(b"linked with an undefined panic handler: no panic is reachable from Config::tick, guard::Config::run, Config::trip or the trace replay\n");
    }
    debug::exit(if acc == 0 {
        debug::EXIT_FAILURE
    } else {
        debug::EXIT_SUCCESS
    });
    loop {
        cortex_m::asm::wfi();
    }
}
