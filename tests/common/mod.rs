//! Shared by the on-target test binaries (`tests/qemu_*.rs`): semihosting output and exit,
//! the TIM2 instruction counter, RAM-backed bridge pins, and a small closed-loop plant that
//! gives the tick realistic inputs.
//!
//! These binaries run on QEMU `-machine netduinoplus2 -cpu cortex-m4` (an STM32F405), see
//! the `qemu` alias in `.cargo/config.toml`. QEMU's GPIO, ADC and RCC are not usable, so
//! the bridge writes RAM "registers" with volatile stores instead of the STM32 HAL.
#![allow(dead_code, unused_macros)]

use core::convert::Infallible;
use core::fmt;

use cortex_m_semihosting::debug;
use ema::bridge::HBridge;
use ema::model::Plant;
use ema::sense::{Calibration, Frame, Measurement};
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
/// executed in between (DESIGN section 5). On silicon it would count timer clocks.
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
/// firmware's TIM1 gives 4201).
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

/// PWM resolution of the firmware's TIM1 (ARR + 1).
pub const FIRMWARE_MAX_DUTY: u16 = 4201;

/// A small closed-loop stand-in for the actuator that gives the tick the inputs of a loop
/// that works: the mechanics of DESIGN section 2 (nominal magnetics, explicit Euler, 10
/// sub-steps per tick) driven by a coil current that follows the law's desired current
/// with a first-order lag of [`Loop::CURRENT_LAG_TICKS`] ticks, plus +-2 codes of converter
/// noise on every channel.
///
/// Why not the bridge voltage: the paper's law, sampled at 20 kHz from a 24 V bus, steps
/// the current by about 7 A per tick at 1 mm and drives the current sensor onto its rail
/// within 3 ticks (DESIGN section 3: that is the product's main technical problem). An
/// instruction count of a tick that sits in its latched-fault path measures nothing
/// useful, so the current here is what a working inner loop would give. It is not the
/// simulator (`hil-sim`) and nothing is asserted about the plant.
pub struct Loop {
    plant: Plant,
    cal: Calibration,
    ts_s: f32,
    /// Position \[m\].
    pub x_m: f32,
    /// Velocity \[m/s\].
    pub v_mps: f32,
    /// Coil current \[A\].
    pub i_a: f32,
    /// Bus voltage \[V\].
    pub vbus_v: f32,
    noise: u32,
}

impl Loop {
    /// Time constant of the coil current following the desired current \[ticks\].
    pub const CURRENT_LAG_TICKS: f32 = 4.0;

    /// At rest at `x_m` with no current, on a `vbus_v` bus.
    pub fn new(plant: Plant, cal: Calibration, ts_s: f32, x_m: f32, vbus_v: f32) -> Self {
        Self {
            plant,
            cal,
            ts_s,
            x_m,
            v_mps: 0.0,
            i_a: 0.0,
            vbus_v,
            noise: 0x2545_f491,
        }
    }

    fn jitter(&mut self) -> i32 {
        // xorshift32: +-2 codes of converter noise.
        self.noise ^= self.noise << 13;
        self.noise ^= self.noise >> 17;
        self.noise ^= self.noise << 5;
        (self.noise % 5) as i32 - 2
    }

    /// The converter codes of the present state, with noise.
    pub fn frame(&mut self) -> Frame {
        let ideal = self.cal.frame(&Measurement {
            x_m: self.x_m,
            i_a: self.i_a,
            vbus_v: self.vbus_v,
        });
        let noisy = |c: u16, j: i32| (i32::from(c) + j).clamp(0, 4095) as u16;
        let (a, b, c) = (self.jitter(), self.jitter(), self.jitter());
        Frame {
            position: noisy(ideal.position, a),
            current: noisy(ideal.current, b),
            vbus: noisy(ideal.vbus, c),
        }
    }

    /// Advances one tick with the coil current moving towards `i_target_a`.
    pub fn advance(&mut self, i_target_a: f32) {
        let p = &self.plant;
        let h = self.ts_s / 10.0;
        let target = if i_target_a.is_finite() {
            i_target_a
        } else {
            0.0
        };
        for _ in 0..10 {
            let g = p.gap_m(self.x_m).max(1e-5);
            let mu = p.magnetics.force_coefficient_h_per_m(g);
            let a = (0.5 * self.i_a * self.i_a * mu
                - p.friction_n_s_per_m * self.v_mps
                - p.spring_n_per_m * self.x_m)
                / p.mass_kg;
            self.i_a += (target - self.i_a) / (10.0 * Self::CURRENT_LAG_TICKS);
            self.v_mps += h * a;
            self.x_m += h * self.v_mps;
            // End stops of the stroke.
            if self.x_m < 0.0 {
                self.x_m = 0.0;
                self.v_mps = 0.0;
            } else if self.x_m > p.stroke_m {
                self.x_m = p.stroke_m;
                self.v_mps = 0.0;
            }
        }
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
