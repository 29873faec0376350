//! Why the last run ended, kept in RAM across a reset, and what the next start makes of
//! it.
//!
//! Every path that stops the firmware on purpose (a refused start, the window watchdog's
//! early wake-up, a panic, a hard fault, a clock failure, an unexpected interrupt) records
//! its cause first, in two words of RAM that start-up does not initialise. After a
//! watchdog reset the next start reads them, logs what really happened and decides:
//!
//! | last run ended by | log | start with |
//! |---|---|---|
//! | a refused start, or the clock set-up hanging | the cause; the watchdog restarted a controller that never drove | nothing latched: the start checks everything again, up to [`START_ATTEMPTS`] times in a row ([`attempt`]) |
//! | the main loop stalling (the tick stopped feeding the watchdogs) | the cause | `Fault::MainLoopStalled` latched |
//! | the tick stopping (early wake-up), a panic, a hard fault, a clock failure, an unexpected interrupt | the cause | `Fault::Overrun` latched |
//! | nothing recorded (the tick stopped with interrupts masked: the reset came without an early wake-up) | "tick stopped, cause not recorded" | `Fault::Overrun` latched |
//!
//! A power-on, the reset pin or a software reset is a person's decision: nothing is
//! latched, and a cause still recorded is only logged.

use ema::control::supervisor::Fault;

/// What stopped the firmware.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Cause {
    /// The clock set-up was running: a crystal that does not start hangs there until the
    /// independent watchdog resets.
    ClockSetup = 1,
    /// Start-up refused to run; the detail is the refusal's code.
    StartRefused = 2,
    /// The window watchdog's early wake-up: the tick stopped, or kept overrunning.
    TickStalled = 3,
    /// A panic (outside the tick, which cannot panic).
    Panic = 4,
    /// A hard fault.
    HardFault = 5,
    /// The clock security system saw the crystal fail.
    ClockFailure = 6,
    /// An interrupt without a handler; the detail is its number.
    UnexpectedInterrupt = 7,
    /// The main loop stopped checking in; the tick stopped feeding the watchdogs.
    MainLoopStalled = 8,
}

/// Refused starts in a row after which the board stays refused instead of letting the
/// watchdog restart it again.
pub const START_ATTEMPTS: u8 = 3;

impl Cause {
    const ALL: [Cause; 8] = [
        Cause::ClockSetup,
        Cause::StartRefused,
        Cause::TickStalled,
        Cause::Panic,
        Cause::HardFault,
        Cause::ClockFailure,
        Cause::UnexpectedInterrupt,
        Cause::MainLoopStalled,
    ];

    /// Whether the controller may have been driving when this stopped it.
    #[must_use]
    pub const fn while_driving(self) -> bool {
        !matches!(self, Cause::ClockSetup | Cause::StartRefused)
    }
}

/// The cause as logged (the texts stay in the log's symbols, not in flash).
#[cfg(target_os = "none")]
impl defmt::Format for Cause {
    fn format(&self, f: defmt::Formatter<'_>) {
        match self {
            Cause::ClockSetup => defmt::write!(f, "clock set-up hung (crystal?)"),
            Cause::StartRefused => defmt::write!(f, "start refused"),
            Cause::TickStalled => defmt::write!(f, "tick stalled (window watchdog early wake-up)"),
            Cause::Panic => defmt::write!(f, "panic"),
            Cause::HardFault => defmt::write!(f, "hard fault"),
            Cause::ClockFailure => defmt::write!(f, "crystal failed (clock security system)"),
            Cause::UnexpectedInterrupt => defmt::write!(f, "unexpected interrupt"),
            Cause::MainLoopStalled => defmt::write!(f, "main loop stalled"),
        }
    }
}

/// A recorded cause and its detail.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Record {
    /// The cause.
    pub cause: Cause,
    /// A detail (refusal code, interrupt number), 0 when none.
    pub detail: u8,
    /// For a refused start: how many in a row (1 to 15); 0 otherwise.
    pub attempt: u8,
}

/// Marks the first word of a valid record (bits 31:20; the second word is its complement).
const MAGIC: u32 = 0xE3A0_0000;
/// The bits of [`MAGIC`].
const MAGIC_MASK: u32 = 0xFFF0_0000;

impl Record {
    /// The two words stored.
    #[must_use]
    pub const fn encode(self) -> [u32; 2] {
        let attempt = if self.attempt > 15 { 15 } else { self.attempt };
        let w = MAGIC | (attempt as u32) << 16 | (self.cause as u32) << 8 | self.detail as u32;
        [w, !w]
    }

    /// The record in two stored words, if they hold one (RAM after a power-on holds
    /// anything).
    #[must_use]
    pub fn decode(words: [u32; 2]) -> Option<Self> {
        let [w, check] = words;
        if check != !w || w & MAGIC_MASK != MAGIC {
            return None;
        }
        let code = (w >> 8) & 0xFF;
        let cause = Cause::ALL.into_iter().find(|c| *c as u32 == code)?;
        Some(Self {
            cause,
            detail: (w & 0xFF) as u8,
            attempt: ((w >> 16) & 0xF) as u8,
        })
    }
}

/// The reset flags that matter here (RCC_CSR).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Flags {
    /// IWDGRSTF: the independent watchdog.
    pub independent_watchdog: bool,
    /// WWDGRSTF: the window watchdog.
    pub window_watchdog: bool,
}

impl Flags {
    /// Either watchdog.
    #[must_use]
    pub const fn watchdog(self) -> bool {
        self.independent_watchdog || self.window_watchdog
    }
}

/// The fault the controller starts with after a reset with `flags`, the last run having
/// recorded `record`.
#[must_use]
pub fn latched_after(flags: Flags, record: Option<Record>) -> Option<Fault> {
    if !flags.watchdog() {
        return None;
    }
    match record {
        Some(r) if !r.cause.while_driving() => None,
        Some(r) if r.cause == Cause::MainLoopStalled => Some(Fault::MainLoopStalled),
        _ => Some(Fault::Overrun),
    }
}

/// Which attempt in a row this start is: one more than a refused start the watchdog
/// ended, else the first (a person's reset or power-on starts counting again).
#[must_use]
pub fn attempt(flags: Flags, record: Option<Record>) -> u8 {
    match record {
        Some(r) if flags.watchdog() && r.cause == Cause::StartRefused => {
            r.attempt.saturating_add(1)
        }
        _ => 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const IWDG: Flags = Flags {
        independent_watchdog: true,
        window_watchdog: false,
    };
    const WWDG: Flags = Flags {
        independent_watchdog: false,
        window_watchdog: true,
    };

    #[test]
    fn records_survive_encoding_and_garbage_is_not_one() {
        for cause in Cause::ALL {
            for attempt in [0, 1, 15] {
                let r = Record {
                    cause,
                    detail: 42,
                    attempt,
                };
                assert_eq!(Record::decode(r.encode()), Some(r));
            }
        }
        assert_eq!(Record::decode([0, 0]), None);
        assert_eq!(Record::decode([0xFFFF_FFFF, 0]), None);
        let [w, c] = Record {
            cause: Cause::Panic,
            detail: 0,
            attempt: 0,
        }
        .encode();
        assert_eq!(Record::decode([w, c ^ 1]), None);
        // A valid frame around an unknown cause.
        let w = MAGIC | 99 << 8;
        assert_eq!(Record::decode([w, !w]), None);
        // The magic's low bits are part of it.
        let w = (MAGIC ^ 1 << 20) | 2 << 8;
        assert_eq!(Record::decode([w, !w]), None);
    }

    #[test]
    fn a_refused_start_is_retried_not_reported_as_an_overrun() {
        let refused = Some(Record {
            cause: Cause::StartRefused,
            detail: 3,
            attempt: 1,
        });
        assert_eq!(latched_after(IWDG, refused), None);
        let hung = Some(Record {
            cause: Cause::ClockSetup,
            detail: 0,
            attempt: 0,
        });
        assert_eq!(latched_after(IWDG, hung), None);
    }

    #[test]
    fn refused_starts_are_counted_in_a_row_and_only_after_the_watchdog() {
        let refused = |attempt| {
            Some(Record {
                cause: Cause::StartRefused,
                detail: 8,
                attempt,
            })
        };
        assert_eq!(attempt(IWDG, None), 1);
        assert_eq!(attempt(IWDG, refused(1)), 2);
        assert_eq!(attempt(IWDG, refused(START_ATTEMPTS)), START_ATTEMPTS + 1);
        // A person's reset starts again from the first.
        assert_eq!(attempt(Flags::default(), refused(2)), 1);
        // Encoded, the count saturates at 15 and still stops the retries.
        let [w, c] = refused(200).unwrap().encode();
        let back = Record::decode([w, c]);
        assert_eq!(back.map(|r| r.attempt), Some(15));
        assert!(attempt(IWDG, back) > START_ATTEMPTS);
    }

    #[test]
    fn a_main_loop_that_stalled_is_named_after_the_reset() {
        let r = Some(Record {
            cause: Cause::MainLoopStalled,
            detail: 0,
            attempt: 0,
        });
        assert_eq!(latched_after(WWDG, r), Some(Fault::MainLoopStalled));
        assert_eq!(latched_after(Flags::default(), r), None);
    }

    #[test]
    fn a_stop_while_driving_latches_overrun() {
        for cause in [
            Cause::TickStalled,
            Cause::Panic,
            Cause::HardFault,
            Cause::ClockFailure,
            Cause::UnexpectedInterrupt,
        ] {
            let r = Some(Record {
                cause,
                detail: 0,
                attempt: 0,
            });
            assert_eq!(latched_after(WWDG, r), Some(Fault::Overrun), "{cause:?}");
            assert_eq!(latched_after(IWDG, r), Some(Fault::Overrun), "{cause:?}");
        }
        // Nothing recorded: the early wake-up could not run (interrupts masked).
        assert_eq!(latched_after(WWDG, None), Some(Fault::Overrun));
        assert_eq!(latched_after(IWDG, None), Some(Fault::Overrun));
    }

    #[test]
    fn a_person_resetting_the_chip_clears_everything() {
        let stalled = Some(Record {
            cause: Cause::TickStalled,
            detail: 0,
            attempt: 0,
        });
        assert_eq!(latched_after(Flags::default(), stalled), None);
        assert_eq!(latched_after(Flags::default(), None), None);
    }
}
