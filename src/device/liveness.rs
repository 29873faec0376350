//! Liveness: an armed board never outlives its host, and a hung main loop ends in the safe
//! state.
//!
//! Two clocks run in the control interrupt, both counted in ticks, so that nothing here
//! depends on the main loop being alive to notice that it is not:
//!
//! * **The host.** While the board drives the coil for the link (armed or moving with the
//!   set point from the link, or commissioning), a valid request must arrive at least
//!   every `link.timeout_s`. Any request counts; a host with nothing to ask sends
//!   [`crate::device::protocol::Command::Heartbeat`], the host tool every quarter of the
//!   timeout. On expiry the board does what `link.on_timeout` says ([`OnTimeout`]): it
//!   disarms and latches [`LinkTimeout`] (the default), or it holds the set point it has (a
//!   move in progress ends at its target) and counts the timeout without latching. A
//!   commissioning drives the coil open loop and cannot hold: it always ends with the
//!   fault. With the set point from the analog input the host is not needed to hold it, and
//!   the link's silence is not a fault: the input has its own wire check.
//! * **The main loop.** The main loop checks in on every pass ([`Pulse::main_loop_ran`]).
//!   A check-in older than [`MAIN_LOOP_DEADLINE_S`] latches [`MainLoopStalled`] at once,
//!   whatever the mode (the bridge coasts), and the tick stops feeding the
//!   watchdogs: on the board the window watchdog's early wake-up follows within a few
//!   periods and its reset after it; the next start keeps the fault latched. A hung main
//!   loop is therefore in the safe state [`MAIN_LOOP_DEADLINE_S`] plus one tick after its
//!   last pass.
//!
//! The two halves share one [`Pulse`]: the main loop writes two counters (its passes and
//! the requests it decoded), the interrupt reads them. Each counter has one writer, so a
//! plain load and store suffice (no read-modify-write, which a Cortex-M4 would make with
//! exclusive accesses); the interrupt only compares a counter with the value it saw
//! last, so wrapping is harmless.
//!
//! [`LinkTimeout`]: crate::control::supervisor::Fault::LinkTimeout
//! [`MainLoopStalled`]: crate::control::supervisor::Fault::MainLoopStalled
//!
//! ```
//! use ema::device::liveness::{OnTimeout, Pulse, Settings, Watch};
//!
//! let link = Settings { timeout_s: 0.5, on_timeout: OnTimeout::Disarm };
//! let cfg = link.build(20_000.0).unwrap();
//! let pulse = Pulse::new();
//! let mut watch = Watch::default();
//! // A request, then 0.5 s of silence while driving: the link is lost one tick after
//! // the timeout, counted from the tick that saw the request.
//! pulse.request_received();
//! let mut lost_at = None;
//! for tick in 1..=10_100u32 {
//!     pulse.main_loop_ran();
//!     let seen = watch.check(&cfg, &pulse, tick, true);
//!     assert!(!seen.main_loop_stalled);
//!     if seen.link_lost && lost_at.is_none() {
//!         lost_at = Some(tick);
//!     }
//! }
//! assert_eq!(lost_at, Some(1 + 10_000 + 1));
//! // 0 turns it off, and only 0: anything else below 50 ms is refused by name.
//! assert!(Settings { timeout_s: 0.0, ..link }.build(20_000.0).is_ok());
//! let e = Settings { timeout_s: 0.01, ..link }.build(20_000.0).unwrap_err();
//! assert_eq!(e.param, "link.timeout_s");
//! ```

use core::sync::atomic::{AtomicU32, Ordering};

use serde::{Deserialize, Serialize};

use crate::control::config::{self, Error};
use crate::control::math;

/// The link's timeout unless set otherwise \[s\]: a host's heartbeat every quarter of it
/// (125 ms) survives a desktop operating system's scheduling hiccups of tens of
/// milliseconds, and a host that is gone leaves the coil driven for half a second at
/// most, less than a person takes to reach for the supply.
pub const DEFAULT_TIMEOUT_S: f32 = 0.5;
/// Shortest link timeout other than off \[s\]: the host's heartbeat every quarter of it,
/// 12.5 ms, is as often as a host's scheduler can be trusted to wake a thread; shorter
/// would disarm a healthy board.
pub const MIN_TIMEOUT_S: f32 = 0.05;
/// Longest link timeout \[s\]: beyond a minute the coil outliving its host is the rule, not
/// the exception, and the link would better be turned off openly (0).
pub const MAX_TIMEOUT_S: f32 = 60.0;
/// The main loop checks in at least this often \[s\], or the tick latches
/// `main_loop_stalled` and stops feeding the watchdogs. It is below [`MIN_TIMEOUT_S`], so
/// that a main loop that meets its deadline also serves every request a live host sends
/// within the link's timeout, and far above the main loop's longest pass (a parameter set
/// validated and built, a stored set read: `tests/qemu_device.rs` measures it).
pub const MAIN_LOOP_DEADLINE_S: f32 = 0.02;

/// What the board does when the host falls silent while it drives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub enum OnTimeout {
    /// The bridge coasts and `link_timeout` latches (clear it to arm again).
    #[default]
    Disarm,
    /// The loop stays closed on the set point it has (a move in progress ends at its
    /// target); the timeout is counted as `link_timeout` without latching.
    Hold,
}

impl OnTimeout {
    /// The choices' names, by index (`link.on_timeout`).
    pub const NAMES: [&'static str; 2] = ["disarm", "hold"];

    /// The choice's index.
    #[must_use]
    pub const fn index(self) -> u8 {
        match self {
            OnTimeout::Disarm => 0,
            OnTimeout::Hold => 1,
        }
    }

    /// The choice with index `i`.
    #[must_use]
    pub const fn from_index(i: u8) -> Option<Self> {
        match i {
            0 => Some(OnTimeout::Disarm),
            1 => Some(OnTimeout::Hold),
            _ => None,
        }
    }
}

/// The `link.*` parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Settings {
    /// Longest silence of the host while the board drives for it \[s\]; 0: no timeout.
    pub timeout_s: f32,
    /// What the board does then.
    pub on_timeout: OnTimeout,
}

impl Default for Settings {
    /// [`DEFAULT_TIMEOUT_S`], disarming.
    fn default() -> Self {
        Self {
            timeout_s: DEFAULT_TIMEOUT_S,
            on_timeout: OnTimeout::Disarm,
        }
    }
}

impl Settings {
    /// Validates and builds for a control rate `rate_hz`.
    ///
    /// # Errors
    /// `link.timeout_s` neither 0 nor within [`MIN_TIMEOUT_S`]..=[`MAX_TIMEOUT_S`]; a rate
    /// that is not positive.
    pub fn build(&self, rate_hz: f32) -> Result<Config, Error> {
        config::positive("link.rate_hz", rate_hz)?;
        let timeout_ticks = if self.timeout_s == 0.0 {
            0
        } else {
            math::whole_ticks(
                config::within(
                    "link.timeout_s",
                    self.timeout_s,
                    MIN_TIMEOUT_S,
                    MAX_TIMEOUT_S,
                )? * rate_hz,
            )
        };
        Ok(Config {
            timeout_ticks,
            hold: self.on_timeout == OnTimeout::Hold,
            main_loop_ticks: math::whole_ticks(MAIN_LOOP_DEADLINE_S * rate_hz),
        })
    }
}

/// The validated `link.*` parameters, in ticks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Config {
    /// The link's timeout \[tick\]; 0: off.
    timeout_ticks: u32,
    /// Hold instead of disarming.
    hold: bool,
    /// [`MAIN_LOOP_DEADLINE_S`] \[tick\].
    main_loop_ticks: u32,
}

impl Config {
    /// Holds on a timeout (instead of disarming).
    #[must_use]
    pub const fn holds(&self) -> bool {
        self.hold
    }

    /// The link's timeout in ticks (0: off).
    #[must_use]
    pub const fn timeout_ticks(&self) -> u32 {
        self.timeout_ticks
    }

    /// The main loop's deadline in ticks.
    #[must_use]
    pub const fn main_loop_ticks(&self) -> u32 {
        self.main_loop_ticks
    }
}

/// The main loop's side of the liveness checks: its passes and the requests it decoded.
#[derive(Debug, Default)]
pub struct Pulse {
    passes: AtomicU32,
    requests: AtomicU32,
}

impl Pulse {
    /// Nothing yet.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            passes: AtomicU32::new(0),
            requests: AtomicU32::new(0),
        }
    }

    /// The main loop passed (its only writer).
    #[inline]
    pub fn main_loop_ran(&self) {
        bump(&self.passes);
    }

    /// A valid request arrived (the main loop is its only writer).
    #[inline]
    pub fn request_received(&self) {
        bump(&self.requests);
    }
}

/// `counter + 1` by a load and a store: the caller is the counter's only writer.
#[inline]
fn bump(counter: &AtomicU32) {
    counter.store(
        counter.load(Ordering::Relaxed).wrapping_add(1),
        Ordering::Relaxed,
    );
}

/// The interrupt's side: when each counter last moved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Watch {
    passes: u32,
    passes_at: u32,
    requests: u32,
    requests_at: u32,
    /// The present silence has been reported.
    lost: bool,
}

/// What a tick's check found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Seen {
    /// The main loop has not checked in for longer than its deadline.
    pub main_loop_stalled: bool,
    /// The board drives for the link, and the host's silence has just passed the timeout
    /// (reported once per silence: a request ends it).
    pub link_lost: bool,
}

impl Watch {
    /// Starts both clocks at `now` (the silence counts from here).
    pub fn restart(&mut self, now: u32) {
        self.passes_at = now;
        self.requests_at = now;
        self.lost = false;
    }

    /// At tick `now`: reads the counters, and says whether the main loop is past its
    /// deadline and, when `driving` for the link, whether the host is past its timeout.
    #[inline]
    pub fn check(&mut self, cfg: &Config, pulse: &Pulse, now: u32, driving: bool) -> Seen {
        let passes = pulse.passes.load(Ordering::Relaxed);
        if passes != self.passes {
            self.passes = passes;
            self.passes_at = now;
        }
        let requests = pulse.requests.load(Ordering::Relaxed);
        if requests != self.requests {
            self.requests = requests;
            self.requests_at = now;
            self.lost = false;
        }
        let silent = driving
            && cfg.timeout_ticks != 0
            && now.wrapping_sub(self.requests_at) > cfg.timeout_ticks;
        let link_lost = silent && !self.lost;
        self.lost |= silent;
        Seen {
            main_loop_stalled: now.wrapping_sub(self.passes_at) > cfg.main_loop_ticks,
            link_lost,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(timeout_s: f32, on_timeout: OnTimeout) -> Config {
        Settings {
            timeout_s,
            on_timeout,
        }
        .build(20_000.0)
        .unwrap()
    }

    #[test]
    fn a_silent_main_loop_is_stalled_one_tick_after_its_deadline() {
        let c = cfg(0.5, OnTimeout::Disarm);
        assert_eq!(c.main_loop_ticks(), 400);
        let pulse = Pulse::new();
        let mut w = Watch::default();
        pulse.main_loop_ran();
        assert!(!w.check(&c, &pulse, 1, false).main_loop_stalled);
        for now in 2..=401 {
            assert!(!w.check(&c, &pulse, now, false).main_loop_stalled, "{now}");
        }
        assert!(w.check(&c, &pulse, 402, false).main_loop_stalled);
        // A pass clears it.
        pulse.main_loop_ran();
        assert!(!w.check(&c, &pulse, 403, false).main_loop_stalled);
    }

    #[test]
    fn the_link_counts_only_while_driving_and_not_when_off() {
        let c = cfg(0.05, OnTimeout::Disarm);
        assert_eq!(c.timeout_ticks(), 1000);
        let pulse = Pulse::new();
        let mut w = Watch::default();
        w.restart(0);
        let mut first = None;
        for now in 1..3000 {
            pulse.main_loop_ran();
            let driving = now >= 500;
            let s = w.check(&c, &pulse, now, driving);
            if s.link_lost && first.is_none() {
                first = Some(now);
            }
        }
        // Counted from the last request (here the restart at 0), reported while driving,
        // once.
        assert_eq!(first, Some(1001));
        let mut w = Watch::default();
        let lost = (1..3000)
            .filter(|&now| w.check(&c, &pulse, now, true).link_lost)
            .count();
        assert_eq!(lost, 1);
        // A request ends the silence: the next one is reported again.
        pulse.request_received();
        assert!(!w.check(&c, &pulse, 3000, true).link_lost);
        assert!(w.check(&c, &pulse, 4001, true).link_lost);
        let off = cfg(0.0, OnTimeout::Disarm);
        let mut w = Watch::default();
        assert!((1..100_000).all(|now| !w.check(&off, &pulse, now, true).link_lost));
    }

    #[test]
    fn counters_that_wrap_still_move() {
        let c = cfg(0.05, OnTimeout::Hold);
        assert!(c.holds());
        let pulse = Pulse::new();
        pulse.requests.store(u32::MAX, Ordering::Relaxed);
        let mut w = Watch::default();
        w.check(&c, &pulse, u32::MAX - 10, true);
        pulse.request_received();
        assert_eq!(pulse.requests.load(Ordering::Relaxed), 0);
        // Ten ticks later, across the tick counter's own wrap: fresh.
        assert!(!w.check(&c, &pulse, 5, true).link_lost);
        assert!(!w.check(&c, &pulse, 1005, true).link_lost);
        assert!(w.check(&c, &pulse, 1006, true).link_lost);
    }

    #[test]
    fn timeouts_are_refused_by_name() {
        for bad in [0.049, -1.0, 61.0, f32::NAN] {
            let e = Settings {
                timeout_s: bad,
                on_timeout: OnTimeout::Disarm,
            }
            .build(20_000.0)
            .unwrap_err();
            assert_eq!(e.param, "link.timeout_s", "{bad}");
        }
        assert_eq!(cfg(60.0, OnTimeout::Disarm).timeout_ticks(), 1_200_000);
        assert_eq!(OnTimeout::from_index(2), None);
        for o in [OnTimeout::Disarm, OnTimeout::Hold] {
            assert_eq!(OnTimeout::from_index(o.index()), Some(o));
        }
    }
}
