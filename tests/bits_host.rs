//! The host side of the bit-exactness smoke test: the constants in `tests/common/vectors.rs`
//! are what the host computes (`libm::sqrtf`, and the paper's law). `tests/qemu_bits.rs`
//! checks the Cortex-M4F (one `vsqrt.f32`) against the same constants.

#[path = "common/vectors.rs"]
mod vectors;

use vectors::*;

#[test]
fn host_square_root_is_libm_and_matches_the_saved_sweep() {
    for k in 0..SQRT_SWEEP_COUNT {
        let x = sqrt_input(k);
        assert_eq!(
            ema::control::trace::bits(ema::control::math::sqrt(x)),
            ema::control::trace::bits(libm::sqrtf(x)),
            "sqrt({x:e})"
        );
    }
    let h = sqrt_sweep_hash(ema::control::math::sqrt);
    assert_eq!(h, SQRT_SWEEP_HASH, "SQRT_SWEEP_HASH should be {h:#018x}");
    let cases: Vec<(u32, u32)> = SQRT_CASES
        .iter()
        .map(|&(x, _)| {
            (
                x,
                ema::control::trace::bits(ema::control::math::sqrt(f32::from_bits(x))),
            )
        })
        .collect();
    let rows: Vec<String> = cases
        .iter()
        .map(|(a, b)| format!("    ({a:#010x}, {b:#010x}),\n"))
        .collect();
    assert_eq!(
        cases,
        SQRT_CASES,
        "SQRT_CASES should be &[\n{}]",
        rows.concat()
    );
}

#[test]
fn the_sweep_covers_every_kind_of_input() {
    let (mut neg, mut sub, mut nan, mut inf, mut big, mut small) = (0, 0, 0, 0, 0, 0);
    for k in 0..SQRT_SWEEP_COUNT {
        let x = sqrt_input(k);
        neg += usize::from(x < 0.0);
        sub += usize::from(x.is_subnormal());
        nan += usize::from(x.is_nan());
        inf += usize::from(x.is_infinite());
        big += usize::from(x > 1e30);
        small += usize::from(x > 0.0 && x < 1e-30);
    }
    assert!(neg > 1000 && sub > 100 && nan > 100 && big > 1000 && small > 1000);
    assert_eq!(inf, 0, "the stride skips the two infinities");
}

#[test]
fn paper_law_matches_the_saved_outputs() {
    let now: Vec<(u32, u32, u32)> = law_outputs().collect();
    assert_eq!(now.len(), LAW_INPUTS.len());
    assert_eq!(now, LAW_OUTPUTS, "LAW_OUTPUTS should be {}", literal3(&now));
    // The inputs reach both signs of the command and a clipped desired current.
    let cmd = |k: usize| f32::from_bits(now[k].0);
    assert!((0..now.len()).any(|k| cmd(k) > 0.0) && (0..now.len()).any(|k| cmd(k) < 0.0));
    assert!(now.iter().any(|o| o.1 == 0));
}

fn literal3(v: &[(u32, u32, u32)]) -> String {
    let rows: Vec<String> = v
        .iter()
        .map(|(a, b, c)| format!("    ({a:#010x}, {b:#010x}, {c:#010x}),\n"))
        .collect();
    format!("&[\n{}]", rows.concat())
}
