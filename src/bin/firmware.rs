//! STM32F405 firmware: the control core in a fixed-rate interrupt.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use cortex_m_rt::entry;
    use defmt_rtt as _;
    use panic_probe as _;
    use stm32f4xx_hal as _;

    #[entry]
    fn main() -> ! {
        defmt::info!("ema firmware");
        loop {
            cortex_m::asm::wfi();
        }
    }
}

/// The firmware only runs on the STM32; on the host this binary explains itself.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "the firmware runs on the STM32F405: build it with `cargo fw`, flash it with `cargo flash`"
    );
}
