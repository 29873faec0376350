//! Shared by the on-target test binaries (`tests/qemu_*.rs`): semihosting output and exit,
//! the TIM2 instruction counter and RAM-backed bridge pins; `plant` is the small
//! closed-loop actuator that gives the tick realistic inputs.
//!
//! These binaries run on QEMU `-machine netduinoplus2 -cpu cortex-m4` (an STM32F405), see
//! the `qemu` alias in `.cargo/config.toml`. QEMU's GPIO, ADC and RCC are not usable, so
//! the bridge writes RAM "registers" with volatile stores instead of the STM32 HAL.
#![allow(dead_code, unused_macros)]

pub mod plant;
pub mod session;

use core::convert::Infallible;
use core::fmt;

use cortex_m_semihosting::debug;
use ema::control::bridge::HBridge;
// The STM32F405 vector table (cortex-m-rt's `device` feature is on in this package).
use stm32f4xx_hal as _;

/// Prints a line on the host's stdout through semihosting.
macro_rules! outln {
    ($($arg:tt)*) => { cortex_m_semihosting::hprintln!($($arg)*) };
}

/// Fails the test with a message unless `cond` holds.
macro_rules! ensure {
    ($cond:expr, $($arg:tt)*) => {
        if !$cond {
            $crate::common::fail(format_args!($($arg)*));
        }
    };
}

/// Prints `FAIL: <msg>` and ends QEMU with a failure exit code.
pub fn fail(msg: fmt::Arguments<'_>) -> ! {
    cortex_m_semihosting::hprintln!("FAIL: {}", msg);
    exit(false)
}

/// Ends QEMU: exit code 0 when `ok`, 1 otherwise.
pub fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    // Not reached under QEMU; on a board without a debugger, stay here.
    loop {
        cortex_m::asm::bkpt();
    }
}

/// What a test's panic handler calls: report and exit with failure.
pub fn on_panic(info: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m_semihosting::hprintln!("FAIL: panic: {}", info);
    exit(false)
}

/// TIM2 as a free-running 32-bit counter. Under `qemu-system-arm -icount shift=0` the
/// virtual clock advances 1 ns per executed instruction and QEMU's STM32 timers count at
/// 1 GHz, so with prescaler 0 a raw count difference is the exact number of instructions
/// executed in between (QEMU models neither the Cortex-M4's pipeline nor flash wait
/// states). On silicon it would count timer clocks.
pub struct Counter(());

const TIM2: usize = 0x4000_0000;
const RCC_APB1ENR: usize = 0x4002_3840;

impl Counter {
    /// Enables TIM2 (prescaler 0, period 2^32) and starts it.
    pub fn start() -> Self {
        // SAFETY: fixed STM32F405 register addresses (RM0090: RCC at 0x4002_3800, TIM2 at
        // 0x4000_0000), written once before any counting; nothing else in these test
        // programs touches RCC or TIM2.
        unsafe {
            let apb1enr = RCC_APB1ENR as *mut u32;
            apb1enr.write_volatile(apb1enr.read_volatile() | 1); // TIM2EN
            ((TIM2 + 0x28) as *mut u32).write_volatile(0); // PSC
            ((TIM2 + 0x2c) as *mut u32).write_volatile(u32::MAX); // ARR
            ((TIM2 + 0x14) as *mut u32).write_volatile(1); // EGR.UG: load PSC
            (TIM2 as *mut u32).write_volatile(1); // CR1.CEN
        }
        Self(())
    }

    /// The raw count.
    #[inline(always)]
    pub fn now(&self) -> u32 {
        // SAFETY: TIM2_CNT, a read-only-in-effect register of an enabled timer.
        unsafe { ((TIM2 + 0x24) as *const u32).read_volatile() }
    }

    /// Counts between two back-to-back reads: subtract it from every measurement.
    pub fn overhead(&self) -> u32 {
        let mut best = u32::MAX;
        for _ in 0..8 {
            let a = self.now();
            let b = self.now();
            best = best.min(b.wrapping_sub(a));
        }
        best
    }
}

/// A RAM word written like a peripheral register (volatile stores only).
pub struct Reg(core::cell::UnsafeCell<u32>);

// SAFETY: the test programs are single-core; every access is a single volatile word
// access, exactly as for a memory-mapped register.
unsafe impl Sync for Reg {}

impl Reg {
    /// A register holding 0.
    pub const fn new() -> Self {
        Self(core::cell::UnsafeCell::new(0))
    }

    /// Volatile store.
    #[inline(always)]
    pub fn write(&self, v: u32) {
        // SAFETY: the cell is a valid, aligned, 'static word; see `Sync` above.
        unsafe { self.0.get().write_volatile(v) }
    }

    /// Volatile load.
    #[inline(always)]
    pub fn read(&self) -> u32 {
        // SAFETY: as for `write`.
        unsafe { self.0.get().read_volatile() }
    }
}

/// The PWM compare "register" and the GPIO set/reset "register" of the RAM bridge.
pub static PWM_CCR: Reg = Reg::new();
/// GPIO bit set/reset register of the RAM bridge (like STM32 `BSRR`).
pub static GPIO_BSRR: Reg = Reg::new();

/// A PWM channel whose compare register is a RAM word (`SetDutyCycle`).
pub struct RamPwm {
    ccr: &'static Reg,
    max: u16,
}

impl embedded_hal::pwm::ErrorType for RamPwm {
    type Error = Infallible;
}

impl embedded_hal::pwm::SetDutyCycle for RamPwm {
    fn max_duty_cycle(&self) -> u16 {
        self.max
    }
    #[inline]
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.ccr.write(u32::from(duty));
        Ok(())
    }
}

/// An output pin that writes a BSRR-like RAM word (`OutputPin`), as the STM32 HAL does.
pub struct RamPin {
    bsrr: &'static Reg,
    pin: u8,
}

impl embedded_hal::digital::ErrorType for RamPin {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for RamPin {
    #[inline]
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.bsrr.write(1 << (self.pin + 16));
        Ok(())
    }
    #[inline]
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.bsrr.write(1 << self.pin);
        Ok(())
    }
}

/// The RAM bridge type.
pub type Bridge = HBridge<RamPwm, RamPin>;

/// A bridge on the RAM registers, coasting, with PWM resolution `max_duty` (the
/// firmware's TIM1 at 20 kHz gives [`ema::control::bridge::BOARD_MAX_DUTY`]).
pub fn bridge(max_duty: u16) -> Bridge {
    let pwm = RamPwm {
        ccr: &PWM_CCR,
        max: max_duty,
    };
    let dir = RamPin {
        bsrr: &GPIO_BSRR,
        pin: 8,
    };
    let en = RamPin {
        bsrr: &GPIO_BSRR,
        pin: 9,
    };
    match HBridge::new(pwm, dir, en) {
        Ok(b) => b,
        Err(e) => match e {},
    }
}

/// Minimum, median and maximum of `v` (sorts it).
pub fn min_median_max(v: &mut [u32]) -> (u32, u32, u32) {
    v.sort_unstable();
    match (v.first(), v.get(v.len() / 2), v.last()) {
        (Some(&a), Some(&b), Some(&c)) => (a, b, c),
        _ => (0, 0, 0),
    }
}
