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
        #[allow(unsafe_code)]
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
