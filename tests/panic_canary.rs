//! Negative control for the link-time no-panic proof (`tests/qemu_no_panic.rs`): the same
//! program plus one reachable panic (an index the optimiser cannot check). It must FAIL to
//! link, with the proof's message; `.ci/run` builds it and fails when it links, so a
//! silently blind proof (LTO off, a changed panic strategy) cannot pass unnoticed.
#![no_std]
#![no_main]

mod common;
#[path = "common/no_panic.rs"]
mod no_panic;

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::debug;

#[entry]
fn main() -> ! {
    let acc = no_panic::exercise();
    let table = black_box([1u32, 2, 3]);
    // A bounds check the optimiser cannot remove: the panic the proof must catch.
    #[expect(clippy::indexing_slicing)]
    let canary = table[black_box(7usize)];
    debug::exit(if acc.wrapping_add(canary) == 0 {
        debug::EXIT_FAILURE
    } else {
        debug::EXIT_SUCCESS
    });
    loop {
        cortex_m::asm::wfi();
    }
}
