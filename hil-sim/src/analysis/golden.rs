//! Golden traces for the Cortex-M4F: the simulator records, tick by tick, the converter
//! frames and set points it gave the core and every output the core produced (as bit
//! patterns, `ema::control::trace` format); the emulated target replays the inputs through
//! its own `Config::tick` and must reproduce every output bit (`tests/qemu_golden.rs`).
//!
//! One trace per reference case of `ema::control::trace::CASES` (every law variant), each
//! on the product's realistic conditions: a plant drawn from the uncertainty set (fixed
//! seed), converter noise and one sample of delay, a 24 V supply with its internal
//! resistance, the firmware's PWM resolution (TIM1 at 20 kHz from 168 MHz:
//! [`BOARD_MAX_DUTY`], 4201 counts), the product's sequence of steps, a re-arm at the tick
//! after any latched fault (the paper's law trips its current checks every few ticks at 20
//! kHz), and at the end the current sensor on its rail, so that the trace also covers the
//! fault path. 10 000 ticks (0.5 s): three traces of 270 KB are what the emulated chip's 1
//! MiB of flash holds beside the test program.
//!
//! `cargo run -p hil-sim --release -- golden` writes them to `tests/golden/`; the tests
//! check that the saved files are exactly what this module produces now.

use std::path::Path;

use ema::control::bridge::BOARD_MAX_DUTY;
use ema::control::trace::{Case, Header, CASES, MIN_GOLDEN_TICKS};

use crate::simulation::hal::Adc;
use crate::simulation::scenario::{
    Injected, Reference, Scenario, Sensors, StepAt, TruePlant, Uncertainty,
};
use crate::simulation::sim::{run_with, Recording};
use crate::simulation::Error;

/// Ticks per trace.
pub const TICKS: usize = 10_000;
/// Seed of the drawn plant and of the converter noise.
pub const SEED: u64 = 2026;

/// The scenario a case's trace is recorded on.
///
/// # Errors
/// Settings of the case that the simulator refuses.
#[expect(clippy::cast_precision_loss)]
pub fn scenario(case: &Case) -> Result<Scenario, Error> {
    let settings = (case.settings)()?;
    let rate_hz = f64::from(settings.rate_hz);
    let duration_s = TICKS as f64 / rate_hz;
    let mut sc = Scenario::product(rate_hz, 24.0)?
        .with_reference(Reference::Sequence {
            initial_m: 1e-3,
            steps: vec![
                StepAt {
                    at_s: 0.1,
                    to_m: 3.5e-3,
                },
                StepAt {
                    at_s: 0.22,
                    to_m: 1.5e-3,
                },
                StepAt {
                    at_s: 0.34,
                    to_m: 3.0e-3,
                },
            ],
        })
        .with_duration_s(duration_s)
        .with_plant(TruePlant::Drawn {
            seed: SEED,
            uncertainty: Uncertainty::default(),
        })
        .with_fault(duration_s - 40.0 / rate_hz, Injected::PositionShorted);
    sc.name = format!("golden-{}", case.name);
    sc.controller = settings;
    sc.bridge.max_duty = BOARD_MAX_DUTY;
    // The traces hold what the core computes, under each case's own settings and trip;
    // the product's comparator, sized for the product's trip, is not part of them.
    sc.bridge.break_current_a = None;
    sc.sensors = Sensors::Adc(Adc {
        delay_samples: u32::from(settings.delay_ticks),
        seed: SEED,
        ..Adc::typical()
    });
    Ok(sc)
}

/// The trace of a case: header and records, ready to save.
///
/// # Errors
/// A scenario the simulator refuses.
pub fn generate(case: &Case) -> Result<Vec<u8>, Error> {
    let sc = scenario(case)?;
    let mut rec = Recording {
        rearm_after_fault: true,
        records: Vec::with_capacity(TICKS),
    };
    run_with(&sc, Some(&mut rec))?;
    let cfg = sc.controller.build()?;
    let ticks = u32::try_from(rec.records.len())
        .map_err(|_| Error::param("ticks", f64::NAN, "too many ticks for a trace"))?;
    if ticks < MIN_GOLDEN_TICKS {
        return Err(Error::param(
            "ticks",
            f64::from(ticks),
            format!("a golden trace needs at least {MIN_GOLDEN_TICKS} ticks"),
        ));
    }
    let mut bytes = Header::new(case, &sc.controller, &cfg, BOARD_MAX_DUTY, ticks)
        .encode()
        .to_vec();
    for r in &rec.records {
        bytes.extend_from_slice(&r.encode());
    }
    Ok(bytes)
}

/// Writes every case's trace to `dir/<case>.emat`; the paths written.
///
/// # Errors
/// A scenario the simulator refuses; a file that cannot be written.
pub fn write_all(dir: &Path) -> Result<Vec<std::path::PathBuf>, Error> {
    let mut out = Vec::new();
    for case in CASES {
        let bytes = generate(case)?;
        let path = dir.join(format!("{}.emat", case.name));
        std::fs::write(&path, bytes)
            .map_err(|e| Error::param("out", f64::NAN, format!("{}: {e}", path.display())))?;
        out.push(path);
    }
    Ok(out)
}
