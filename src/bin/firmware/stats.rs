//! Cycle statistics of the tick and the status the interrupt publishes for the main loop
//! (overruns are the guard's, `ema::guard`). Plain logic, tested on the host; the interrupt owns [`Cycles`], the
//! main loop only reads [`Published`].

use core::sync::atomic::{fence, AtomicI32, AtomicU32, Ordering};

/// Cycle counts of the ticks of the current window, and the maximum since start.
///
/// The window's sum is a `u32`: the ticks of a window cannot take more cycles than the
/// window lasts, and a window of one second is 168 M cycles at 168 MHz, far from 2^32 (25
/// s); past that it saturates. A `u64` sum would bring a software 64-bit division
/// (`__aeabi_uldivmod`, about 900 bytes) into the interrupt.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cycles {
    sum: u32,
    count: u32,
    window_max: u32,
    max: u32,
}

/// One window of cycle counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Summary {
    /// Mean cycles per tick over the window.
    pub mean: u32,
    /// Largest tick of the window \[cycles\].
    pub window_max: u32,
    /// Largest tick since start \[cycles\].
    pub max: u32,
    /// Ticks in the window.
    pub ticks: u32,
}

impl Cycles {
    /// No ticks yet.
    pub const fn new() -> Self {
        Self {
            sum: 0,
            count: 0,
            window_max: 0,
            max: 0,
        }
    }

    /// Adds one tick of `cycles`; every `window` ticks returns the window's summary and
    /// starts the next window.
    pub fn record(&mut self, cycles: u32, window: u32) -> Option<Summary> {
        self.sum = self.sum.saturating_add(cycles);
        self.count = self.count.saturating_add(1);
        self.window_max = self.window_max.max(cycles);
        self.max = self.max.max(cycles);
        if self.count < window.max(1) {
            return None;
        }
        // `count` is at least 1 here (checked against `window.max(1)` above).
        let mean = self.sum / self.count.max(1);
        let summary = Summary {
            mean,
            window_max: self.window_max,
            max: self.max,
            ticks: self.count,
        };
        self.sum = 0;
        self.count = 0;
        self.window_max = 0;
        Some(summary)
    }
}

/// What the status line shows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// Ticks since the controller started.
    pub ticks: u32,
    /// Cycle statistics of the last window.
    pub cycles: Summary,
    /// Overruns since start.
    pub overruns: u32,
    /// Latched fault code (0: none).
    pub fault: u8,
    /// Bridge mode code (0 coast, 1 forward, 2 reverse).
    pub mode: u8,
    /// Position \[um\].
    pub x_um: i32,
    /// Coil current \[mA\].
    pub i_ma: i32,
}

/// A [`Snapshot`] the interrupt writes and the main loop reads, as a sequence lock: the
/// writer (one interrupt, never preempted by the reader) makes the sequence odd, writes,
/// and makes it even again; the reader retries when the sequence was odd or changed. No
/// critical section, so reading the status never delays the tick.
pub struct Published {
    seq: AtomicU32,
    ticks: AtomicU32,
    mean: AtomicU32,
    window_max: AtomicU32,
    max: AtomicU32,
    window_ticks: AtomicU32,
    overruns: AtomicU32,
    fault_mode: AtomicU32,
    x_um: AtomicI32,
    i_ma: AtomicI32,
}

impl Published {
    /// Nothing published yet.
    pub const fn new() -> Self {
        Self {
            seq: AtomicU32::new(0),
            ticks: AtomicU32::new(0),
            mean: AtomicU32::new(0),
            window_max: AtomicU32::new(0),
            max: AtomicU32::new(0),
            window_ticks: AtomicU32::new(0),
            overruns: AtomicU32::new(0),
            fault_mode: AtomicU32::new(0),
            x_um: AtomicI32::new(0),
            i_ma: AtomicI32::new(0),
        }
    }

    /// Publishes `s` (the interrupt's side).
    pub fn publish(&self, s: &Snapshot) {
        let seq = self.seq.load(Ordering::Relaxed);
        self.seq.store(seq.wrapping_add(1), Ordering::Relaxed);
        fence(Ordering::Release);
        self.ticks.store(s.ticks, Ordering::Relaxed);
        self.mean.store(s.cycles.mean, Ordering::Relaxed);
        self.window_max
            .store(s.cycles.window_max, Ordering::Relaxed);
        self.max.store(s.cycles.max, Ordering::Relaxed);
        self.window_ticks.store(s.cycles.ticks, Ordering::Relaxed);
        self.overruns.store(s.overruns, Ordering::Relaxed);
        self.fault_mode.store(
            u32::from(s.fault) << 8 | u32::from(s.mode),
            Ordering::Relaxed,
        );
        self.x_um.store(s.x_um, Ordering::Relaxed);
        self.i_ma.store(s.i_ma, Ordering::Relaxed);
        self.seq.store(seq.wrapping_add(2), Ordering::Release);
    }

    /// The snapshot published since `seen` (the main loop's side), if any; updates `seen`.
    pub fn read_new(&self, seen: &mut u32) -> Option<Snapshot> {
        loop {
            let before = self.seq.load(Ordering::Acquire);
            if before == *seen {
                return None;
            }
            if before % 2 == 1 {
                core::hint::spin_loop();
                continue;
            }
            let fault_mode = self.fault_mode.load(Ordering::Relaxed);
            let s = Snapshot {
                ticks: self.ticks.load(Ordering::Relaxed),
                cycles: Summary {
                    mean: self.mean.load(Ordering::Relaxed),
                    window_max: self.window_max.load(Ordering::Relaxed),
                    max: self.max.load(Ordering::Relaxed),
                    ticks: self.window_ticks.load(Ordering::Relaxed),
                },
                overruns: self.overruns.load(Ordering::Relaxed),
                fault: u8::try_from(fault_mode >> 8).unwrap_or(u8::MAX),
                mode: u8::try_from(fault_mode & 0xff).unwrap_or(u8::MAX),
                x_um: self.x_um.load(Ordering::Relaxed),
                i_ma: self.i_ma.load(Ordering::Relaxed),
            };
            fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == before {
                *seen = before;
                return Some(s);
            }
        }
    }
}

/// `x` scaled by `scale` and rounded to an integer, saturating (NaN gives 0).
pub fn scaled(x: f32, scale: f32) -> i32 {
    let v = x * scale;
    if v.is_nan() {
        0
    } else if v >= 2_147_483_520.0 {
        i32::MAX
    } else if v <= -2_147_483_520.0 {
        i32::MIN
    } else {
        // In range: the cast is exact after rounding.
        (v + if v < 0.0 { -0.5 } else { 0.5 }) as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_give_mean_and_maxima() {
        let mut c = Cycles::new();
        assert_eq!(c.record(100, 3), None);
        assert_eq!(c.record(300, 3), None);
        let s = c.record(200, 3).unwrap();
        assert_eq!((s.mean, s.window_max, s.max, s.ticks), (200, 300, 300, 3));
        c.record(10, 3);
        c.record(20, 3);
        let s = c.record(30, 3).unwrap();
        // The window maximum restarts, the overall one does not.
        assert_eq!((s.mean, s.window_max, s.max), (20, 30, 300));
    }

    #[test]
    fn a_sum_past_the_counter_saturates_instead_of_wrapping() {
        let mut c = Cycles::new();
        assert_eq!(c.record(u32::MAX - 1, 2), None);
        let s = c.record(10, 2).unwrap();
        // Wrapped, the sum would be 8 and the mean 4.
        assert_eq!((s.mean, s.max), (u32::MAX / 2, u32::MAX - 1));
    }

    #[test]
    fn the_main_loop_sees_each_snapshot_once() {
        let p = Published::new();
        let mut seen = 0;
        assert_eq!(p.read_new(&mut seen), None);
        let s = Snapshot {
            ticks: 20_000,
            cycles: Summary {
                mean: 700,
                window_max: 900,
                max: 1200,
                ticks: 20_000,
            },
            overruns: 1,
            fault: 15,
            mode: 2,
            x_um: 2999,
            i_ma: -6123,
        };
        p.publish(&s);
        assert_eq!(p.read_new(&mut seen), Some(s));
        assert_eq!(p.read_new(&mut seen), None);
        p.publish(&Snapshot { ticks: 40_000, ..s });
        assert_eq!(p.read_new(&mut seen).map(|x| x.ticks), Some(40_000));
    }

    #[test]
    fn scaling_saturates() {
        assert_eq!(scaled(3e-3, 1e6), 3000);
        assert_eq!(scaled(-6.1234, 1e3), -6123);
        assert_eq!(scaled(f32::NAN, 1.0), 0);
        assert_eq!(scaled(1e20, 1.0), i32::MAX);
        assert_eq!(scaled(-1e20, 1.0), i32::MIN);
    }
}
