//! Bit-exactness vectors shared by the host test `tests/bits_host.rs` and the on-target test
//! `tests/qemu_bits.rs`: both compute the same values and compare them with the constants
//! below, which were computed on the host. If the host and the Cortex-M4F disagree, one of
//! the two tests fails.
#![allow(dead_code)]

use ema::control::law::{self, Law};
use ema::control::model::Plant;

/// Number of `f32` bit patterns in the square-root sweep.
pub const SQRT_SWEEP_COUNT: u32 = 1 << 18;

/// Step between bit patterns of the sweep: odd and close to `2^32 / SQRT_SWEEP_COUNT`, so
/// the sweep covers every exponent of both signs, subnormals, zeros, infinities and NaNs.
pub const SQRT_SWEEP_STRIDE: u32 = (1 << 14) + 1;

/// The `k`-th input of the sweep.
pub fn sqrt_input(k: u32) -> f32 {
    f32::from_bits(k.wrapping_mul(SQRT_SWEEP_STRIDE))
}

/// One step of 64-bit FNV-1a over the four bytes of `bits`.
pub fn fnv(mut h: u64, bits: u32) -> u64 {
    for b in bits.to_le_bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// FNV-1a offset basis.
pub const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// Hash of `ema::control::math::sqrt` over the sweep (NaN results canonical), computed on
/// the host with `libm::sqrtf` (what `ema::control::math::sqrt` is there).
pub const SQRT_SWEEP_HASH: u64 = 0xd297_55d4_6b41_ecc7;

/// The hash of `sqrt` over the sweep.
pub fn sqrt_sweep_hash(sqrt: impl Fn(f32) -> f32) -> u64 {
    (0..SQRT_SWEEP_COUNT).fold(FNV_OFFSET, |h, k| {
        fnv(h, ema::control::trace::bits(sqrt(sqrt_input(k))))
    })
}

/// Square roots checked one by one: `(input bits, output bits)`.
pub const SQRT_CASES: &[(u32, u32)] = &[
    (0x00000000, 0x00000000),
    (0x80000000, 0x80000000),
    (0x3f800000, 0x3f800000),
    (0x40000000, 0x3fb504f3),
    (0x3f000000, 0x3f3504f3),
    (0x40400000, 0x3fddb3d7),
    (0x3dcccccd, 0x3ea1e89b),
    (0x47f12065, 0x43afae9e),
    (0x006ce3ee, 0x1fec1e4a),
    (0x7f7fffff, 0x5f7fffff),
    (0x7f800000, 0x7f800000),
    (0xbf800000, 0x7fc00000),
    (0x00000001, 0x1a3504f3),
    (0x007fffff, 0x1fffffff),
];

/// The paper's law (paper actuator, 20 kHz) stepped through these states in order, from a
/// fresh state, so that the `x3d'` term (difference of successive desired currents) is
/// exercised too: `(x_m, v_mps, i_a, r_m)`.
pub const LAW_INPUTS: &[(f32, f32, f32, f32)] = &[
    (3e-3, -1e-4, 6.0, 3e-3),
    (2.99e-3, -2e-4, 5.5, 3e-3),
    (1e-3, 0.0, 0.0, 3e-3),
    (1.01e-3, 0.01, 2.0, 3e-3),
    (2.2e-3, 0.013, 4.7, 3e-3),
    (3.5e-3, 0.02, 7.5, 3e-3),
    (0.4e-3, -0.05, -1.2, 2e-3),
];

/// Expected `(u_v, i_d_a, s_a)` bits after each step of [`LAW_INPUTS`].
pub const LAW_OUTPUTS: &[(u32, u32, u32)] = &[
    (0xc1898ebc, 0x40a245a8, 0x3f6dd2c0),
    (0x41caf7e4, 0x410c1041, 0xc0504104),
    (0x433796d2, 0x41bf3de7, 0xc1bf3de7),
    (0x42f7784c, 0x4187e562, 0xc16fcac4),
    (0xc23a09f4, 0x00000000, 0x40966666),
    (0xc1492ebe, 0x00000000, 0x40f00000),
    (0x442bb439, 0x418af789, 0xc1949123),
];

/// The outputs of the paper's law for [`LAW_INPUTS`] (all zeros if it does not build).
pub fn law_outputs() -> impl Iterator<Item = (u32, u32, u32)> {
    let cfg = law::paper::Gains::paper().build(&Plant::paper(), 1.0 / 20_000.0);
    let mut st = law::paper::State::default();
    LAW_INPUTS.iter().map(move |&(x_m, v_mps, i_a, r_m)| {
        let Ok(cfg) = &cfg else {
            return (0, 0, 0);
        };
        // Any input the law gains later stays at its default (zero).
        let input = law::Input {
            x_m,
            v_mps,
            i_a,
            vbus_v: 24.0,
            disturbance_mps2: 0.0,
            reference: law::Reference::hold(r_m),
            ..law::Input::default()
        };
        let y = cfg.step(&mut st, &input);
        (y.u_v.to_bits(), y.i_d_a.to_bits(), y.s_a.to_bits())
    })
}
