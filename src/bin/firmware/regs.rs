//! The register values the set-up writes, computed from the board's facts ([`crate::board`])
//! and checked on the host against the bit positions of the reference manual (RM0090).
//! `hw` writes them; nothing here touches a register.
//!
//! TIM1 (RM0090 section 17.4) drives the three bridge lines and triggers the conversions:
//!
//! | channel | pin | mode | compare | idle (main output off) |
//! |---|---|---|---|---|
//! | 1: PWM | PA8 | PWM mode 1, preloaded | the duty | low |
//! | 2: enable | PA9 | PWM mode 1, preloaded | 0 (low) or [`LINE_HIGH`] (high) | low |
//! | 3: direction | PA10 | PWM mode 1, preloaded | 0 (low) or [`LINE_HIGH`] (high) | low |
//! | 4: ADC trigger | none | PWM mode 2, its reference on TRGO | [`board::ADC_TRIGGER_COMPARE`] | - |
//!
//! Every compare value is preloaded: what the tick writes takes effect together at the
//! next update event, the top of the count, in the middle of the off-time. The break input
//! is on (active low), the off-state levels are driven (OSSI = OSSR = 1) with every idle
//! level low, automatic re-enable after a break is off, and the lock (level 2) freezes
//! all of that until the next reset.

use crate::board;

// ---------- TIM1 (RM0090 section 17.4) ----------

/// TIM1_CR1.DIR, bit 4 (17.4.1): the counter counts down (read-only in center-aligned mode).
pub const CR1_DIR: u32 = 1 << 4;
/// TIM1_CR1.CEN, bit 0: counter enabled.
pub const CR1_CEN: u32 = 1;
/// TIM1_CR1 while configuring: center-aligned mode 1 (CMS = 01, bits 6:5), auto-reload
/// preloaded (ARPE, bit 7), counter stopped.
pub const CR1: u32 = (1 << 7) | (0b01 << 5);

/// TIM1_CR2 (17.4.2): master mode "compare, OC4REF is TRGO" (MMS = 111, bits 6:4), every
/// output idle state low (OIS1..OIS4 and OIS1N..OIS3N, bits 8..14, all 0), compare
/// control bits not preloaded (CCPC = 0).
pub const CR2: u32 = 0b111 << 4;

/// TIM1_SR.UIF, bit 0 (17.4.5): an update event happened.
pub const SR_UIF: u32 = 1;
/// TIM1_SR.BIF, bit 7: a break happened (stays set while the break input is active).
pub const SR_BIF: u32 = 1 << 7;

/// Output compare mode PWM mode 1 (OCxM = 110): active while CNT < CCRx counting up,
/// while CNT <= CCRx counting down (17.4.7).
const PWM_MODE_1: u32 = 0b110;
/// PWM mode 2 (OCxM = 111): inactive while CNT < CCRx counting up, active above.
const PWM_MODE_2: u32 = 0b111;
/// OCxPE: compare preload (bit 3 of each channel's byte).
const PRELOAD: u32 = 1 << 3;

/// One output channel's byte of CCMRx: CCxS = 00 (output), OCxPE, OCxM (bits 6:4).
const fn output(mode: u32) -> u32 {
    (mode << 4) | PRELOAD
}

/// TIM1_CCMR1 (17.4.7): channel 1 (PWM) and channel 2 (enable) in PWM mode 1, preloaded.
pub const CCMR1: u32 = output(PWM_MODE_1) | (output(PWM_MODE_1) << 8);
/// TIM1_CCMR1.OC2PE, bit 11: the enable's compare preload, switched off for the one write
/// that makes the enable fall at once.
pub const CCMR1_OC2PE: u32 = PRELOAD << 8;
/// TIM1_CCMR2 (17.4.8): channel 3 (direction) in PWM mode 1, channel 4 (ADC trigger) in
/// PWM mode 2, both preloaded.
pub const CCMR2: u32 = output(PWM_MODE_1) | (output(PWM_MODE_2) << 8);

/// TIM1_CCER (17.4.9): outputs 1, 2 and 3 enabled (CC1E bit 0, CC2E bit 4, CC3E bit 8),
/// active high (CCxP = 0), no complementary output; channel 4 has no pin (CC4E = 0: its
/// reference still reaches TRGO).
pub const CCER: u32 = 1 | (1 << 4) | (1 << 8);

/// TIM1_BDTR.MOE, bit 15 (17.4.18): main output enable.
pub const BDTR_MOE: u32 = 1 << 15;
/// TIM1_BDTR.AOE, bit 14: automatic output enable after a break (kept off: named for the
/// test that checks it).
#[allow(dead_code)]
pub const BDTR_AOE: u32 = 1 << 14;
/// TIM1_BDTR.BKP, bit 13: break polarity (1 = active high; kept 0, active low: named for
/// the test that checks it).
#[allow(dead_code)]
pub const BDTR_BKP: u32 = 1 << 13;
/// TIM1_BDTR.BKE, bit 12: break enable.
pub const BDTR_BKE: u32 = 1 << 12;
/// TIM1_BDTR.OSSR, bit 11: off-state selection in run mode (outputs enabled at their
/// inactive level rather than released).
pub const BDTR_OSSR: u32 = 1 << 11;
/// TIM1_BDTR.OSSI, bit 10: off-state selection in idle mode: with the main output off,
/// the enabled outputs are driven to their idle level (OISx) instead of floating.
pub const BDTR_OSSI: u32 = 1 << 10;
/// TIM1_BDTR.LOCK = 10 (bits 9:8): level 2, which freezes BKE, BKP, AOE, the idle levels,
/// the polarities, OSSI and OSSR until the next reset. (Level 3 would also freeze the
/// output compare modes and preloads, which the enable's immediate fall needs.)
pub const BDTR_LOCK_2: u32 = 0b10 << 8;
/// TIM1_BDTR as the set-up writes it, once: break on, active low (the driver's fault
/// output and the comparator pull it low), off-states driven, no automatic re-enable
/// (a break stays until a reset), no dead time (the driver has its own), locked; the main
/// output still off (`MOE` is set last, on its own).
pub const BDTR: u32 = BDTR_LOCK_2 | BDTR_OSSI | BDTR_OSSR | BDTR_BKE;

/// TIM1_RCR (17.4.13): one update event per period (two over/underflows).
pub const RCR: u32 = board::PWM_REPETITION as u32;

/// A compare value that keeps a PWM-mode-1 output high all period (above ARR).
pub const LINE_HIGH: u16 = board::PWM_MAX_DUTY;
/// A compare value that keeps it low all period.
pub const LINE_LOW: u16 = 0;

// ---------- Window watchdog (RM0090 section 21.6) ----------

/// WWDG_CFR (21.6.2): window W = 0x7F (bits 6:0; a feed is always allowed: the watchdog
/// counts about two periods per count, too coarse for a window the tick could keep),
/// prescaler WDGTB = 0 (bits 8:7, /4096), early-wakeup interrupt on (EWI, bit 9).
pub const WWDG_CFR: u16 = (1 << 9) | 0x7F;
/// WWDG_CR (21.6.1) as a feed writes it: activation (WDGA, bit 7, stays set until reset)
/// and the counter reload (T, bits 6:0).
pub const WWDG_CR: u16 = (1 << 7) | board::WINDOW_WATCHDOG.reload() as u16;

// ---------- Independent watchdog (RM0090 section 20.4) ----------

/// IWDG_KR: starts the watchdog (a no-op once it runs).
pub const IWDG_KEY_START: u16 = 0xCCCC;
/// IWDG_KR: opens IWDG_PR and IWDG_RLR to writes (until the next reload).
pub const IWDG_KEY_ACCESS: u16 = 0x5555;
/// IWDG_KR: reloads the counter (a feed).
pub const IWDG_KEY_RELOAD: u16 = 0xAAAA;
/// IWDG_SR.PVU (bit 0) and RVU (bit 1): a prescaler or reload update in progress.
pub const IWDG_SR_UPDATING: u16 = 0b11;

// ---------- Clock security system (RM0090 sections 7.2.7, 7.3.1, 7.3.3) ----------

/// RCC_CR.CSSON, bit 19: clock security system on.
pub const RCC_CR_CSSON: u32 = 1 << 19;
/// RCC_CIR.CSSC, bit 23: clears the clock-security flag (and with it the NMI).
pub const RCC_CIR_CSSC: u32 = 1 << 23;

// ---------- Clock tree (RM0090 sections 3.9, 7.3.1 to 7.3.3) ----------
//
// 168 MHz from the 8 MHz crystal through the main PLL, APB1 at a quarter, APB2 at half:
// the values the HAL's `Rcc::freeze` computed for this request (its PLL search is 2.7 KiB
// of flash), written directly.

/// PLLM: the PLL's input, HSE / 4 = 2 MHz (1 to 2 MHz; 2 MHz for the least jitter).
pub const PLL_M: u32 = 4;
/// PLLN: the VCO, 2 MHz x 168 = 336 MHz (100 to 432 MHz).
pub const PLL_N: u32 = 168;
/// PLLP: the system clock, 336 MHz / 2 = 168 MHz.
pub const PLL_P: u32 = 2;
/// PLLQ: the 48 MHz clock, 336 MHz / 7 (unused; the HAL's choice, the lowest divider that
/// keeps it at or below 48 MHz).
pub const PLL_Q: u32 = 7;
/// RCC_PLLCFGR (7.3.2): PLLM (bits 5:0), PLLN (14:6), PLLP (17:16, 00 = /2), PLLSRC
/// (bit 22, HSE), PLLQ (27:24); bit 29 is reserved and kept at its reset value 1.
pub const RCC_PLLCFGR: u32 =
    (1 << 29) | (PLL_Q << 24) | (1 << 22) | ((PLL_P / 2 - 1) << 16) | (PLL_N << 6) | PLL_M;
/// RCC_CR.HSEON, bit 16 (7.3.1).
pub const RCC_CR_HSEON: u32 = 1 << 16;
/// RCC_CR.HSERDY, bit 17.
pub const RCC_CR_HSERDY: u32 = 1 << 17;
/// RCC_CR.PLLON, bit 24.
pub const RCC_CR_PLLON: u32 = 1 << 24;
/// RCC_CR.PLLRDY, bit 25.
pub const RCC_CR_PLLRDY: u32 = 1 << 25;
/// RCC_CFGR prescaler fields (7.3.3): HPRE (bits 7:4), PPRE1 (12:10), PPRE2 (15:13).
pub const RCC_CFGR_PRE_MASK: u32 = (0b111 << 13) | (0b111 << 10) | (0b1111 << 4);
/// RCC_CFGR prescalers: AHB /1 (HPRE = 0), APB1 /4 (PPRE1 = 101), APB2 /2 (PPRE2 = 100).
pub const RCC_CFGR_PRE: u32 = (0b100 << 13) | (0b101 << 10);
/// RCC_CFGR.SW (bits 1:0).
pub const RCC_CFGR_SW_MASK: u32 = 0b11;
/// RCC_CFGR.SW = 10: the PLL drives the system clock.
pub const RCC_CFGR_SW_PLL: u32 = 0b10;
/// RCC_CFGR.SWS (bits 3:2): what drives the system clock.
pub const RCC_CFGR_SWS_MASK: u32 = 0b11 << 2;
/// RCC_CFGR.SWS = 10: the PLL.
pub const RCC_CFGR_SWS_PLL: u32 = 0b10 << 2;
/// RCC_CFGR.I2SSRC, bit 23 (0: the I2S PLL; the HAL clears it).
pub const RCC_CFGR_I2SSRC: u32 = 1 << 23;
/// FLASH_ACR.LATENCY (bits 2:0, 3.9): wait states, one per 30 MHz started at 2.7 to 3.6 V.
pub const FLASH_LATENCY: u32 = (board::SYSCLK_HZ - 1) / 30_000_000;
/// FLASH_ACR fields the set-up writes: LATENCY and the prefetch, instruction and data
/// caches (PRFTEN, ICEN, DCEN: bits 8, 9, 10).
pub const FLASH_ACR_MASK: u32 = 0b111 | (0b111 << 8);
/// FLASH_ACR as the set-up writes those fields.
pub const FLASH_ACR: u32 = FLASH_LATENCY | (0b111 << 8);

// The clock tree these values give is the one `board` documents.
const _: () = assert!(board::HSE_HZ / PLL_M >= 1_000_000);
const _: () = assert!(board::HSE_HZ / PLL_M <= 2_000_000);
const _: () = assert!(board::HSE_HZ / PLL_M * PLL_N >= 100_000_000);
const _: () = assert!(board::HSE_HZ / PLL_M * PLL_N <= 432_000_000);
const _: () = assert!(board::HSE_HZ.is_multiple_of(PLL_M));
const _: () = assert!(board::HSE_HZ / PLL_M * PLL_N / PLL_P == board::SYSCLK_HZ);
const _: () = assert!(board::HSE_HZ / PLL_M * PLL_N / PLL_Q <= 48_000_000);
const _: () =
    assert!(board::SYSCLK_HZ / 4 == board::PCLK1_HZ && board::SYSCLK_HZ / 2 == board::PCLK2_HZ);

// ---------- Checks of the PWM's phase at start ----------

/// Whether the update event falls at the top of the count: read just after an update, the
/// counter counts down (`TIM1_CR1.DIR`). With the update at the bottom, the preloaded
/// compare values would change in the middle of a pulse.
#[must_use]
pub const fn update_at_top(cr1: u32) -> bool {
    cr1 & CR1_DIR != 0
}

/// Whether a sequence of conversions, its end seen at once by a polling loop, ended where
/// the trigger places it: counting down, [`board::ADC_END_AFTER_TOP_COUNTS`] after the top
/// (two ADC cycles early for the trigger latency, an eighth of a half period late for the
/// polling).
#[must_use]
pub const fn conversions_placed(cr1: u32, cnt: u32) -> bool {
    let early = 2 * board::TIM1_COUNTS_PER_ADC_CYCLE;
    let late = board::PWM_ARR / 8;
    if !update_at_top(cr1) || cnt > board::PWM_ARR {
        return false;
    }
    let since_top = board::PWM_ARR - cnt;
    since_top + early >= board::ADC_END_AFTER_TOP_COUNTS
        && since_top <= board::ADC_END_AFTER_TOP_COUNTS + late
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timer_registers_match_the_reference_manual_bits() {
        // CR1: ARPE | CMS = 01.
        assert_eq!(CR1, 0b1010_0000);
        // CR2: MMS = 111 (OC4REF on TRGO); OIS1..OIS4 (bits 8, 10, 12, 14) all low.
        assert_eq!(CR2, 0x70);
        assert_eq!(CR2 & 0x7F00, 0);
        // CCMR1: OC1M = 110, OC1PE; OC2M = 110, OC2PE.
        assert_eq!(CCMR1, 0x6868);
        assert_eq!(CCMR1_OC2PE, 1 << 11);
        // CCMR2: OC3M = 110, OC3PE; OC4M = 111, OC4PE.
        assert_eq!(CCMR2, 0x7868);
        // CCER: CC1E, CC2E, CC3E; no polarity inversion, no CC4E.
        assert_eq!(CCER, 0x0111);
        // BDTR: LOCK = 2, OSSI, OSSR, BKE; active low (no BKP), no AOE, MOE later.
        assert_eq!(BDTR, 0x1E00);
        assert_eq!(BDTR & (BDTR_BKP | BDTR_AOE | BDTR_MOE), 0);
        assert_eq!(BDTR & 0xFF, 0, "no dead time");
        assert_eq!(RCR, 1);
        assert_eq!((SR_UIF, SR_BIF), (1, 0x80));
    }

    #[test]
    fn enable_and_direction_compares_span_the_period() {
        // Above ARR a PWM-mode-1 output never goes inactive; at 0 it never goes active.
        assert!(u32::from(LINE_HIGH) > board::PWM_ARR);
        assert_eq!(LINE_LOW, 0);
    }

    #[test]
    fn window_watchdog_registers() {
        // EWI, WDGTB = 0, W = 0x7F; feed: WDGA | 0x43.
        assert_eq!(WWDG_CFR, 0x27F);
        assert_eq!(WWDG_CR, 0xC3);
        assert_eq!((RCC_CR_CSSON, RCC_CIR_CSSC), (0x8_0000, 0x80_0000));
    }

    #[test]
    fn clock_registers_match_the_reference_manual_bits() {
        // PLLCFGR: reserved bit 29, Q = 7, HSE, P = 00, N = 168, M = 4.
        assert_eq!(RCC_PLLCFGR, 0x2740_2A04);
        assert_eq!((RCC_CR_HSEON, RCC_CR_HSERDY), (0x1_0000, 0x2_0000));
        assert_eq!((RCC_CR_PLLON, RCC_CR_PLLRDY), (0x100_0000, 0x200_0000));
        assert_eq!(RCC_CFGR_PRE, 0x9400);
        assert_eq!(RCC_CFGR_PRE_MASK, 0xFCF0);
        assert_eq!((RCC_CFGR_SW_PLL, RCC_CFGR_SWS_PLL), (2, 8));
        // Five wait states at 168 MHz (RM0090 table 10), prefetch and both caches on.
        assert_eq!(FLASH_LATENCY, 5);
        assert_eq!(FLASH_ACR, 0x705);
    }

    #[test]
    fn the_pwm_phase_checks() {
        let top = board::PWM_ARR;
        // Counting down just after an update: the update was at the top.
        assert!(update_at_top(CR1 | CR1_CEN | CR1_DIR));
        assert!(!update_at_top(CR1 | CR1_CEN));
        // The sequence ends 736 counts after the top: seen there, or up to 525 later.
        let end = board::ADC_END_AFTER_TOP_COUNTS;
        let down = CR1 | CR1_CEN | CR1_DIR;
        assert!(conversions_placed(down, top - end));
        assert!(conversions_placed(down, top - end - 525));
        assert!(!conversions_placed(down, top - end - 526));
        assert!(conversions_placed(down, top - end + 16));
        assert!(!conversions_placed(down, top - end + 17));
        // Triggered by the update at the top (TRGO on the update event instead of compare
        // 4): the conversions end 1304 counts after the top (3 ADC cycles of latency and
        // 4 x 40 to convert, 8 counts each), outside the window.
        assert!(!conversions_placed(down, top - 1304));
        // Counting up (the conversions around the bottom): refused.
        assert!(!conversions_placed(CR1 | CR1_CEN, top - end));
        assert!(!conversions_placed(down, top + 1));
    }
}
