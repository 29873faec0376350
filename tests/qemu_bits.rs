//! Bit-exactness smoke test on the Cortex-M4F: `ema::control::math::sqrt` (one `vsqrt.f32`)
//! and the paper's law give the very bits the host computed (`tests/common/vectors.rs`,
//! checked on the host by `tests/bits_host.rs`), and `vsqrt` agrees with `libm::sqrtf` run
//! on the target itself over a sweep of 2^18 bit patterns of every kind.
#![no_std]
#![no_main]

#[macro_use]
mod common;
#[path = "common/vectors.rs"]
mod vectors;

use core::hint::black_box;

use cortex_m_rt::entry;
use ema::control::trace::bits;
use vectors::*;

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    common::on_panic(info)
}

#[entry]
fn main() -> ! {
    // 1. Square roots one by one.
    for &(x, want) in SQRT_CASES {
        let got = bits(ema::control::math::sqrt(black_box(f32::from_bits(x))));
        ensure!(
            got == want,
            "sqrt({:#010x}) = {:#010x}, host {:#010x}",
            x,
            got,
            want
        );
    }
    outln!(
        "sqrt: {} hand-picked cases match the host",
        SQRT_CASES.len()
    );

    // 2. The sweep: vsqrt against libm on the target, and the hash against the host's.
    let mut differ = 0u32;
    for k in 0..SQRT_SWEEP_COUNT {
        let x = black_box(sqrt_input(k));
        let (a, b) = (bits(ema::control::math::sqrt(x)), bits(libm::sqrtf(x)));
        if a != b {
            if differ == 0 {
                outln!(
                    "first difference: sqrt({:#010x}): vsqrt {:#010x}, libm {:#010x}",
                    x.to_bits(),
                    a,
                    b
                );
            }
            differ += 1;
        }
    }
    ensure!(
        differ == 0,
        "vsqrt and libm::sqrtf differ on {} of {} inputs",
        differ,
        SQRT_SWEEP_COUNT
    );
    let h = sqrt_sweep_hash(|x| ema::control::math::sqrt(black_box(x)));
    ensure!(
        h == SQRT_SWEEP_HASH,
        "sweep hash {:#018x}, host {:#018x}",
        h,
        SQRT_SWEEP_HASH
    );
    outln!(
        "sqrt: vsqrt.f32 == libm::sqrtf on all {} sweep inputs; hash {:#018x} == host",
        SQRT_SWEEP_COUNT,
        h
    );

    // 3. The paper's law.
    let mut n = 0;
    for (k, (got, want)) in law_outputs().zip(LAW_OUTPUTS.iter().copied()).enumerate() {
        ensure!(
            got == want,
            "paper law step {}: (u, i_d, s) bits {:#010x?}, host {:#010x?}",
            k,
            got,
            want
        );
        n += 1;
    }
    ensure!(
        n == LAW_INPUTS.len() && n == LAW_OUTPUTS.len(),
        "{} law outputs compared",
        n
    );
    outln!("paper law: {} steps match the host bit for bit", n);
    outln!("PASS");
    common::exit(true)
}
