//! The checks around each tick: did it run on time, did the bridge's hardware protection
//! act, and may the tick feed the watchdog.
//!
//! The firmware's control interrupt, the simulator's missed-deadline injection and the
//! on-target test (`tests/qemu_guard.rs`) all run a tick through [`Config::run`], so the
//! policy they rely on is one piece of code:
//!
//! * **Late start.** A tick that starts more than [`Config::max_gap`] (1.5 periods) after
//!   the previous one missed at least one conversion: `Fault::Overrun` latches *before*
//!   the tick, which then only holds the bridge in coast.
//! * **Late end.** A tick whose next tick is already due when it ends, or whose writes
//!   reached the bridge after the period boundary at which they take effect, drove the
//!   coil with stale or split commands: `Fault::Overrun` latches after the tick and the
//!   bridge coasts.
//! * **Hardware trip.** When the bridge's protection switched it off (the PWM timer's break
//!   flag), `Fault::HardwareTrip` latches before the tick.
//! * **Feeding.** Only a tick that started and ended on time may feed the watchdog. A
//!   latched fault does not stop the feeding: the on-time tick is what keeps the bridge
//!   coasting and the fault latched. When ticks keep overrunning, or stop, nothing feeds
//!   and the watchdog coasts the bridge ([`Watchdog`]).
//!
//! Times are readings of a free-running 32-bit counter (the cycle counter in the
//! firmware, an instruction counter under QEMU, simulated nanoseconds in `hil-sim`);
//! differences wrap, so a gap is right as long as it is shorter than the counter's period.
//!
//! ```
//! use ema::control::bridge::{HBridge, Mode, NullPin, NullPwm, BOARD_MAX_DUTY};
//! use ema::control::{Config, Settings, State};
//! use ema::device::guard::{self, End, Start};
//! use ema::control::sense::Measurement;
//! use ema::control::supervisor::Fault;
//!
//! type Bridge = HBridge<NullPwm, NullPin>;
//! /// A tick at counter reading `now`, through the guard.
//! fn tick(g: &mut guard::State, cfg: &Config, st: &mut State, b: &mut Bridge, now: u32) -> guard::Outcome {
//!     let m = Measurement { x_m: 1e-3, i_a: 0.0, vbus_v: 24.0 };
//!     let guard = guard::Config::for_period(8400); // 20 kHz at 168 MHz
//!     let start = Start { now, hardware_trip: false };
//!     guard.run(g, cfg, st, b, start, |s, b| cfg.tick_measured(s, b, &m, 3e-3), End::default)
//! }
//!
//! let cfg = Settings::practical(20_000.0, 24.0).unwrap().build().unwrap();
//! let mut st = cfg.initial_state();
//! let mut b: Bridge = HBridge::new(NullPwm::new(BOARD_MAX_DUTY), NullPin(false), NullPin(false)).unwrap();
//! let mut g = guard::State::default();
//! // On time: fed.
//! assert!(tick(&mut g, &cfg, &mut st, &mut b, 0).feed);
//! assert!(tick(&mut g, &cfg, &mut st, &mut b, 8400).feed);
//! // Two periods later: a conversion went unserved. Overrun, the bridge coasts, not fed.
//! let late = tick(&mut g, &cfg, &mut st, &mut b, 3 * 8400);
//! assert_eq!(late.status.fault, Some(Fault::Overrun));
//! assert!(!late.feed);
//! assert_eq!(b.mode(), Mode::Coast);
//! ```

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

use crate::control::bridge::{Drive, HBridge};
use crate::control::supervisor::Fault;
use crate::control::{self, Status};

/// What the interrupt knows as it starts, before the tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Start {
    /// The free-running counter at the interrupt's entry \[counts\].
    pub now: u32,
    /// The bridge's hardware protection has switched it off (the PWM timer's break flag).
    pub hardware_trip: bool,
}

/// What the interrupt knows after the tick has written the bridge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct End {
    /// The next tick is already due (its interrupt is pending).
    pub next_due: bool,
    /// The period boundary at which this tick's writes take effect passed while it ran,
    /// so some of them act one period late.
    pub boundary_passed: bool,
}

/// The guard's settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    max_gap: u32,
}

/// The guard's memory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct State {
    last_start: Option<u32>,
    overruns: u32,
    fed: u32,
}

impl State {
    /// Ticks that overran (started late or ended late), saturating.
    #[must_use]
    pub const fn overruns(&self) -> u32 {
        self.overruns
    }

    /// Ticks that were allowed to feed the watchdog, saturating.
    #[must_use]
    pub const fn fed(&self) -> u32 {
        self.fed
    }
}

/// What a guarded tick did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Outcome {
    /// The tick's status, with the fault and the coasting bridge of a late end.
    pub status: Status,
    /// The tick ran on time: feed the watchdog.
    pub feed: bool,
}

impl Config {
    /// For ticks every `period` counts: a start more than 1.5 periods after the previous
    /// one is late (the half period is the jitter an on-time interrupt never reaches).
    #[must_use]
    pub const fn for_period(period: u32) -> Self {
        Self {
            max_gap: period.saturating_add(period / 2),
        }
    }

    /// The longest start-to-start gap of on-time ticks \[counts\].
    #[must_use]
    pub const fn max_gap(&self) -> u32 {
        self.max_gap
    }

    /// Runs `tick` between the checks: latches `Fault::HardwareTrip` or `Fault::Overrun`
    /// (late start) before it, calls it, then latches `Fault::Overrun` when `end` says it
    /// ended late. Panic-free when `tick` and `end` are.
    #[inline]
    #[expect(clippy::too_many_arguments)]
    pub fn run<P: SetDutyCycle, O: OutputPin>(
        &self,
        guard: &mut State,
        control: &control::Config,
        state: &mut control::State,
        bridge: &mut HBridge<P, O>,
        start: Start,
        tick: impl FnOnce(&mut control::State, &mut HBridge<P, O>) -> Status,
        end: impl FnOnce() -> End,
    ) -> Outcome {
        let late_start = guard
            .last_start
            .is_some_and(|last| start.now.wrapping_sub(last) > self.max_gap);
        guard.last_start = Some(start.now);
        if start.hardware_trip {
            control.trip(state, bridge, Fault::HardwareTrip);
        }
        if late_start {
            control.trip(state, bridge, Fault::Overrun);
        }
        let mut status = tick(state, bridge);
        let e = end();
        let late_end = e.next_due || e.boundary_passed;
        if late_end {
            status.fault = Some(control.trip(state, bridge, Fault::Overrun));
            status.drive = Drive::default();
        }
        let feed = !(late_start || late_end);
        if feed {
            guard.fed = guard.fed.saturating_add(1);
        } else {
            guard.overruns = guard.overruns.saturating_add(1);
        }
        Outcome { status, feed }
    }
}

/// Feeds of on-time ticks are less than two periods apart (each ends before the next
/// conversion is due, and conversions come once a period); the watchdog must stay quiet
/// for this many periods after a feed, one period of margin.
pub const WATCHDOG_QUIET_PERIODS: u32 = 3;

/// The window watchdog's timing (STM32F4 WWDG, RM0090 section 21.3): a 7-bit counter
/// clocked at APB1 / 4096 (prescaler WDGTB = 0) counts down from the value a feed writes,
/// `0x40 + counts`; at 0x40 it raises its early-wakeup interrupt (which coasts the bridge),
/// one count later (bit 6 clears) it resets the chip.
///
/// The reference manual gives the timeout as `(T[5:0] + 1)` counts from a feed. Whether
/// a feed also restarts the /4096 prescaler is not stated, so the first count is taken to
/// last anywhere from 0 to one count: the early wake-up comes between `counts - 1` and
/// `counts` counts after a feed, the reset one count later.
///
/// ```
/// use ema::device::guard::Watchdog;
/// // 42 MHz APB1, quiet for 3 periods of 20 kHz: 3 counts of 97.5 us.
/// let w = Watchdog::at_least(42_000_000, 150_000);
/// assert_eq!(w.reload(), 0x43);
/// assert_eq!(w.early_wakeup_max_ns(), 292_572);
/// assert!(w.early_wakeup_min_ns() >= 150_000);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Watchdog {
    apb1_hz: u32,
    counts: u8,
}

impl Watchdog {
    /// APB1 cycles per count (4096 x 2^WDGTB, WDGTB = 0).
    pub const CYCLES_PER_COUNT: u64 = 4096;
    /// The counter value at which the early-wakeup interrupt fires.
    pub const EARLY_WAKEUP_AT: u8 = 0x40;
    /// Most counts between a feed and the early wake-up (`T[5:0]` is 6 bits).
    pub const MAX_COUNTS: u8 = 63;

    /// The shortest watchdog on an `apb1_hz` bus whose early wake-up cannot come within
    /// `quiet_ns` of a feed (at most [`Watchdog::MAX_COUNTS`] counts; check
    /// [`Watchdog::early_wakeup_min_ns`] when the bus is slow).
    #[must_use]
    pub const fn at_least(apb1_hz: u32, quiet_ns: u32) -> Self {
        // (counts - 1) whole counts must cover quiet_ns: counts - 1 = ceil(quiet / count).
        let num = (quiet_ns as u64).saturating_mul(apb1_hz as u64);
        let den = Self::CYCLES_PER_COUNT * 1_000_000_000;
        let whole = num.div_ceil(den).saturating_add(1);
        let counts = if whole > Self::MAX_COUNTS as u64 {
            Self::MAX_COUNTS
        } else if whole < 1 {
            1
        } else {
            // In 1..=63: the cast is exact.
            #[expect(clippy::cast_possible_truncation)]
            let c = whole as u8;
            c
        };
        Self { apb1_hz, counts }
    }

    /// Counts from a feed to the early wake-up (`T[5:0]`).
    #[must_use]
    pub const fn counts(&self) -> u8 {
        self.counts
    }

    /// The counter value a feed writes (`T[6:0]`, bit 6 set).
    #[must_use]
    pub const fn reload(&self) -> u8 {
        Self::EARLY_WAKEUP_AT | self.counts
    }

    /// `n` counts \[ns\], rounded up.
    const fn counts_ns(&self, n: u64) -> u32 {
        let num = n
            .saturating_mul(Self::CYCLES_PER_COUNT)
            .saturating_mul(1_000_000_000);
        let ns = if self.apb1_hz == 0 {
            u64::MAX
        } else {
            num.div_ceil(self.apb1_hz as u64)
        };
        if ns > u32::MAX as u64 {
            u32::MAX
        } else {
            // Checked above.
            #[expect(clippy::cast_possible_truncation)]
            let t = ns as u32;
            t
        }
    }

    /// One count \[ns\], rounded up.
    #[must_use]
    pub const fn count_ns(&self) -> u32 {
        self.counts_ns(1)
    }

    /// Earliest early wake-up after a feed \[ns\], rounded up (`counts - 1` counts).
    #[must_use]
    pub const fn early_wakeup_min_ns(&self) -> u32 {
        self.counts_ns((self.counts as u64).saturating_sub(1))
    }

    /// Latest early wake-up after a feed \[ns\], rounded up (`counts` counts): the
    /// interrupt coasts the bridge this long after the last feed at the latest.
    #[must_use]
    pub const fn early_wakeup_max_ns(&self) -> u32 {
        self.counts_ns(self.counts as u64)
    }

    /// Latest reset after a feed \[ns\], rounded up (`counts + 1` counts): when the
    /// early-wakeup interrupt cannot run (interrupts masked), the reset releases the pins
    /// and the board's pull-downs coast the bridge.
    #[must_use]
    pub const fn reset_max_ns(&self) -> u32 {
        self.counts_ns((self.counts as u64).saturating_add(1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::bridge::{Mode, NullPin, NullPwm, BOARD_MAX_DUTY};
    use crate::control::sense::Measurement;
    use crate::control::Settings;

    const PERIOD: u32 = 8400;

    struct Rig {
        guard: Config,
        g: State,
        cfg: control::Config,
        st: control::State,
        b: HBridge<NullPwm, NullPin>,
    }

    impl Rig {
        fn new() -> Self {
            // A fixed measurement: the detectors that need history (a coil that does not
            // answer the voltage is open) stay off, the tick keeps driving.
            let mut settings = Settings::practical(20_000.0, 24.0).unwrap();
            settings.monitors = crate::control::supervisor::Monitors::default();
            let cfg = settings.build().unwrap();
            Self {
                guard: Config::for_period(PERIOD),
                g: State::default(),
                st: cfg.initial_state(),
                cfg,
                b: HBridge::new(NullPwm::new(BOARD_MAX_DUTY), NullPin(false), NullPin(false))
                    .unwrap(),
            }
        }

        fn tick(&mut self, now: u32, hardware_trip: bool, end: End) -> Outcome {
            let cfg = self.cfg;
            let m = Measurement {
                x_m: 1e-3,
                i_a: 0.0,
                vbus_v: 24.0,
            };
            self.guard.run(
                &mut self.g,
                &self.cfg,
                &mut self.st,
                &mut self.b,
                Start { now, hardware_trip },
                |s, b| cfg.tick_measured(s, b, &m, 3e-3),
                || end,
            )
        }
    }

    #[test]
    fn on_time_ticks_drive_and_feed() {
        let mut r = Rig::new();
        for k in 0..100u32 {
            // 1/8 period of jitter either way is on time.
            let jitter = if k % 2 == 0 { PERIOD / 8 } else { 0 };
            let o = r.tick(k * PERIOD + jitter, false, End::default());
            assert!(o.feed);
            assert_eq!(o.status.fault, None);
        }
        assert_eq!(r.b.mode(), Mode::Forward);
        assert_eq!((r.g.fed(), r.g.overruns()), (100, 0));
    }

    #[test]
    fn a_late_start_latches_overrun_before_the_tick_and_does_not_feed() {
        let mut r = Rig::new();
        assert!(r.tick(0, false, End::default()).feed);
        // 1.5 periods is still on time, one count more is late.
        assert!(r.tick(PERIOD + PERIOD / 2, false, End::default()).feed);
        let o = r.tick(2 * PERIOD + 2 * (PERIOD / 2) + 1, false, End::default());
        assert!(!o.feed);
        assert_eq!(o.status.fault, Some(Fault::Overrun));
        // The tick itself saw the fault: it did not drive.
        assert_eq!(o.status.drive, Drive::default());
        assert_eq!(r.b.mode(), Mode::Coast);
        // The next on-time tick feeds again and keeps the bridge coasting.
        let o = r.tick(3 * PERIOD + 2 * (PERIOD / 2) + 1, false, End::default());
        assert!(o.feed);
        assert_eq!(o.status.fault, Some(Fault::Overrun));
        assert_eq!(r.b.mode(), Mode::Coast);
        assert_eq!((r.g.fed(), r.g.overruns()), (3, 1));
    }

    #[test]
    fn the_gap_wraps_with_the_counter() {
        let mut r = Rig::new();
        assert!(r.tick(u32::MAX - PERIOD / 2, false, End::default()).feed);
        assert!(r.tick(PERIOD / 2, false, End::default()).feed);
        assert!(!r.tick(PERIOD / 2 + 2 * PERIOD, false, End::default()).feed);
    }

    #[test]
    fn a_late_end_latches_overrun_and_coasts() {
        for end in [
            End {
                next_due: true,
                boundary_passed: false,
            },
            End {
                next_due: false,
                boundary_passed: true,
            },
        ] {
            let mut r = Rig::new();
            assert!(r.tick(0, false, End::default()).feed);
            assert_eq!(r.b.mode(), Mode::Forward);
            let o = r.tick(PERIOD, false, end);
            assert!(!o.feed, "{end:?}");
            assert_eq!(o.status.fault, Some(Fault::Overrun));
            assert_eq!(o.status.drive, Drive::default());
            assert_eq!(r.b.mode(), Mode::Coast);
            assert_eq!(r.st.supervisor.latched(), Some(Fault::Overrun));
        }
    }

    #[test]
    fn a_hardware_trip_latches_its_own_fault_and_the_ticks_keep_feeding() {
        let mut r = Rig::new();
        assert!(r.tick(0, false, End::default()).feed);
        let o = r.tick(PERIOD, true, End::default());
        assert_eq!(o.status.fault, Some(Fault::HardwareTrip));
        assert_eq!(r.b.mode(), Mode::Coast);
        assert!(o.feed);
        // Latched: the flag clearing does not restart the bridge.
        let o = r.tick(2 * PERIOD, false, End::default());
        assert_eq!(o.status.fault, Some(Fault::HardwareTrip));
        assert!(o.feed);
        assert_eq!(r.b.mode(), Mode::Coast);
        // The physical event is named, even when the tick is also late.
        let mut r = Rig::new();
        r.tick(0, false, End::default());
        let o = r.tick(5 * PERIOD, true, End::default());
        assert_eq!(o.status.fault, Some(Fault::HardwareTrip));
        assert!(!o.feed);
    }

    #[test]
    fn the_reference_watchdog_coasts_within_half_a_millisecond() {
        // 42 MHz APB1, 20 kHz ticks: quiet for 150 us.
        let w = Watchdog::at_least(42_000_000, WATCHDOG_QUIET_PERIODS * 50_000);
        assert_eq!(w.count_ns(), 97_524);
        assert_eq!((w.counts(), w.reload()), (3, 0x43));
        assert_eq!(w.early_wakeup_min_ns(), 195_048);
        assert_eq!(w.early_wakeup_max_ns(), 292_572);
        assert_eq!(w.reset_max_ns(), 390_096);
        assert!(w.early_wakeup_min_ns() >= 150_000);
        assert!(w.reset_max_ns() <= 500_000);
        // One count less would bite on time: the choice is the shortest.
        let shorter = Watchdog { counts: 2, ..w };
        assert!(shorter.early_wakeup_min_ns() < 150_000);
        // 10 kHz: quiet 300 us, 5 counts, early wake-up by 487.6 us.
        let w = Watchdog::at_least(42_000_000, 3 * 100_000);
        assert_eq!(w.counts(), 5);
        assert_eq!(w.early_wakeup_max_ns(), 487_620);
        // Saturates at 63 counts on a slow bus; a zero bus clock never bites.
        assert_eq!(Watchdog::at_least(1_000_000, 300_000_000).counts(), 63);
        assert_eq!(Watchdog::at_least(0, 1).early_wakeup_max_ns(), u32::MAX);
    }
}
