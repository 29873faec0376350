//! The status the interrupt publishes for the main loop's status line (the cycle
//! statistics are the controller's, `ema::device::Cycles`; overruns the guard's,
//! `ema::device::guard`). Plain logic, tested on the host; the main loop only reads
//! [`Published`].

use core::sync::atomic::{fence, AtomicI32, AtomicU32, Ordering};

use ema::device::CycleSummary;

/// What the status line shows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// Ticks since the controller started.
    pub ticks: u32,
    /// Cycle statistics of the last window.
    pub cycles: CycleSummary,
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
                cycles: CycleSummary {
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
    fn the_main_loop_sees_each_snapshot_once() {
        let p = Published::new();
        let mut seen = 0;
        assert_eq!(p.read_new(&mut seen), None);
        let s = Snapshot {
            ticks: 20_000,
            cycles: CycleSummary {
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
