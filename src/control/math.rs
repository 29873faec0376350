//! Elementary functions that give the same bits on the host and on the Cortex-M4F.
//!
//! `f32::sqrt` is not in `core`. The law needs an exact square root (the desired current is
//! `sqrt(x3d^2)`), so:
//!
//! * on the Cortex-M4F it is one `vsqrt.f32` instruction (IEEE 754 correctly rounded);
//! * elsewhere it is `libm::sqrtf`, also correctly rounded.
//!
//! Both are correctly rounded, so they agree bit for bit on every finite input; this is
//! checked on the emulated target against host-generated golden traces. `micromath`'s fast
//! square root (up to 6 % off) is deliberately not used anywhere in the control path.

/// Correctly rounded square root (`NaN` for negative input, as IEEE 754 requires).
#[inline]
#[must_use]
pub fn sqrt(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_os = "none", target_abi = "eabihf"))]
    {
        let y: f32;
        // SAFETY: the three instructions only touch the two core registers given as operands
        // and `s0`, which is declared clobbered; no memory, no stack, no flags (VSQRT sets
        // FPSCR exception bits only, and FPU exceptions do not trap). The operands go through
        // core registers because the `sreg` class needs a `vfp2` feature that Rust does not
        // enable for this target.
        #[expect(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {y}, s0",
                x = in(reg) x,
                y = lateout(reg) y,
                out("s0") _,
                options(pure, nomem, nostack, preserves_flags),
            );
        }
        y
    }
    #[cfg(not(all(target_arch = "arm", target_os = "none", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// Natural logarithm from the operations IEEE 754 rounds correctly (`+ - * /` and
/// [`sqrt`]), so that it gives the same bits on the host and on the Cortex-M4F, which a
/// library `logf` does not promise: square roots bring the argument within 1/16 of 1
/// (`ln x = 2^k ln x^(1/2^k)`), then four terms of `ln y = 2 atanh((y - 1) / (y + 1))`.
/// Within about 1e-5 of the exact value (the rounding of the roots); for settings and
/// targets only, it is not in the tick. `NaN` for a negative or `NaN` input, `-inf` at 0.
#[must_use]
pub fn ln(x: f32) -> f32 {
    if x.is_nan() || x < 0.0 {
        return f32::NAN;
    }
    if x == 0.0 {
        return f32::NEG_INFINITY;
    }
    if x == f32::INFINITY {
        return f32::INFINITY;
    }
    let mut y = x;
    let mut scale = 2.0;
    // At most 13 roots: every finite f32 lies within 2^(+-150), and 1/16 around 1 holds
    // 2^(+-1/16).
    while !(0.9375..=1.0625).contains(&y) {
        y = sqrt(y);
        scale *= 2.0;
    }
    let z = (y - 1.0) / (y + 1.0);
    let z2 = z * z;
    scale * z * (1.0 + z2 * (1.0 / 3.0 + z2 * (1.0 / 5.0 + z2 * (1.0 / 7.0))))
}

/// Sign with `sign(0) = 0`: `-1`, `0` or `1` (and `NaN` for `NaN`).
#[inline]
#[must_use]
pub fn sign(x: f32) -> f32 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        x * 0.0
    }
}

/// `x` limited to `[-limit, limit]` (`limit >= 0`); `NaN` stays `NaN`.
#[inline]
#[must_use]
pub fn sat(x: f32, limit: f32) -> f32 {
    if x > limit {
        limit
    } else if x < -limit {
        -limit
    } else {
        x
    }
}

/// The larger of `a` and `b`; a `NaN` operand is ignored (as `f32::max`).
///
/// `f32::max` and `f32::min` are library calls on the Cortex-M4F (`fmaxf`/`fminf`: the
/// FPU has no `vmaxnm`), about 11 instructions each with the call; this compiles to a
/// compare and a conditional move. It also fixes the sign of a zero result, which IEEE
/// `maxNum` leaves open: `max(-0.0, 0.0)` is `0.0` on every target.
#[inline]
#[must_use]
pub fn max(a: f32, b: f32) -> f32 {
    if a > b || b.is_nan() {
        a
    } else {
        b
    }
}

/// The smaller of `a` and `b`; a `NaN` operand is ignored (as `f32::min`). See [`max`].
#[inline]
#[must_use]
pub fn min(a: f32, b: f32) -> f32 {
    if a < b || b.is_nan() {
        a
    } else {
        b
    }
}

/// The running maximum `acc` updated with `x`: `x` when it is larger, else `acc`; a `NaN`
/// `x` is skipped. One comparison where [`max`] needs two (its `NaN` test of `b`): for a
/// fold over a set of values, as the fault detectors' corner banks do every tick.
///
/// `acc` must not be `NaN` (start from `-inf` or a value); then this equals
/// `max(acc, x)` bit for bit, zeros included. A `NaN` `acc` is returned as is.
#[inline]
#[must_use]
pub fn running_max(acc: f32, x: f32) -> f32 {
    // `!(acc <= x)`: `acc > x`, or unordered (`x` is `NaN`, as `acc` is not).
    if acc <= x {
        x
    } else {
        acc
    }
}

/// The running minimum `acc` updated with `x`; see [`running_max`].
#[inline]
#[must_use]
pub fn running_min(acc: f32, x: f32) -> f32 {
    if acc >= x {
        x
    } else {
        acc
    }
}

/// `x` limited to `[lo, hi]`, for `lo <= hi`. Unlike `f32::clamp` it has no panic path
/// (`f32::clamp` asserts `lo <= hi` at run time, which the tick cannot afford even when
/// validation guarantees it); `NaN` stays `NaN`.
#[inline]
#[must_use]
pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

/// The whole ticks in `t` ticks' worth of time, rounded down, at least one and at most
/// 4e9 (a count of ticks from a duration times a rate; `NaN` gives one).
#[must_use]
pub fn whole_ticks(t: f32) -> u32 {
    if t >= 4.0e9 {
        4_000_000_000
    } else if t >= 1.0 {
        // In [1, 4e9): the truncation is the intended rounding down.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = t as u32;
        n
    } else {
        1
    }
}

/// `true` when every value is finite.
#[inline]
#[must_use]
pub fn all_finite(values: &[f32]) -> bool {
    values.iter().all(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sqrt_is_exact_on_squares_and_rounding_cases() {
        assert_eq!(sqrt(36.0), 6.0);
        assert_eq!(sqrt(0.0), 0.0);
        assert_eq!(sqrt(2.0).to_bits(), 0x3fb5_04f3);
        assert!(sqrt(-1.0).is_nan());
        assert_eq!(sqrt(f32::INFINITY), f32::INFINITY);
    }

    /// Within 1e-5 (relative, or absolute near 1) of the exact logarithm from the
    /// smallest subnormal to the largest f32, and exact at the special values.
    #[test]
    fn ln_is_within_1e_5_of_the_exact_logarithm_everywhere() {
        // (From 8 subnormal steps, where a factor 1.37 still moves the value.)
        let mut x = f32::from_bits(8);
        let mut worst: f64 = 0.0;
        while x < f32::MAX {
            let exact = f64::from(x).ln();
            let err = (f64::from(ln(x)) - exact).abs() / exact.abs().max(1.0);
            worst = worst.max(err);
            x *= 1.37;
        }
        for x in [
            f32::from_bits(1),
            0.5,
            0.999,
            1.0,
            1.001,
            1.0625,
            1.07,
            2.0,
            10.0,
            f32::MAX,
        ] {
            let exact = f64::from(x).ln();
            worst = worst.max((f64::from(ln(x)) - exact).abs() / exact.abs().max(1.0));
        }
        assert!(worst < 1e-5, "{worst}");
        assert_eq!(ln(1.0), 0.0);
        assert_eq!(ln(0.0), f32::NEG_INFINITY);
        assert_eq!(ln(f32::INFINITY), f32::INFINITY);
        assert!(ln(-1.0).is_nan() && ln(f32::NAN).is_nan());
    }

    #[test]
    fn max_min_clamp_match_core_on_everything_but_the_sign_of_zero() {
        let v = [
            f32::NEG_INFINITY,
            -3.5,
            -0.0,
            0.0,
            1e-40,
            2.0,
            f32::INFINITY,
            f32::NAN,
        ];
        for a in v {
            for b in v {
                let (m, n) = (max(a, b), min(a, b));
                if a == 0.0 && b == 0.0 {
                    assert_eq!(m, 0.0);
                    assert_eq!(m.to_bits(), b.to_bits());
                } else if a.is_nan() && b.is_nan() {
                    assert!(m.is_nan() && n.is_nan());
                } else {
                    assert_eq!(m.to_bits(), a.max(b).to_bits(), "max({a}, {b})");
                    assert_eq!(n.to_bits(), a.min(b).to_bits(), "min({a}, {b})");
                }
            }
        }
        assert_eq!(max(-0.0, 0.0).to_bits(), 0);
        // The running extremes equal max/min bit for bit whenever the accumulator is not
        // NaN, NaN operands and signed zeros included.
        for acc in v.iter().copied().filter(|a| !a.is_nan()) {
            for x in v {
                assert_eq!(
                    running_max(acc, x).to_bits(),
                    max(acc, x).to_bits(),
                    "{acc} {x}"
                );
                assert_eq!(
                    running_min(acc, x).to_bits(),
                    min(acc, x).to_bits(),
                    "{acc} {x}"
                );
            }
        }
        assert!(running_max(f32::NAN, 1.0).is_nan());
        assert_eq!(clamp(5.0, 0.0, 4.0), 4.0);
        assert_eq!(clamp(-1.0, 0.0, 4.0), 0.0);
        assert_eq!(clamp(2.5, 0.0, 4.0), 2.5);
        assert!(clamp(f32::NAN, 0.0, 4.0).is_nan());
        // Where f32::clamp would panic, this one returns a bound.
        assert_eq!(clamp(1.0, 2.0, 0.0), 2.0);
    }

    #[test]
    fn sign_and_sat() {
        assert_eq!(sign(3.0), 1.0);
        assert_eq!(sign(-0.5), -1.0);
        assert_eq!(sign(0.0), 0.0);
        assert!(sign(f32::NAN).is_nan());
        assert_eq!(sat(5.0, 2.0), 2.0);
        assert_eq!(sat(-5.0, 2.0), -2.0);
        assert_eq!(sat(1.5, 2.0), 1.5);
    }
}
