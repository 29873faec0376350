//! The saved golden traces (`tests/golden/*.emat`) against the current core, on the host.
//!
//! A trace is stale when the core no longer computes what it recorded: its settings
//! identity differs from the case's settings now, or a replay through `Config::tick`
//! differs in any output bit. Either fails here, before the slower on-target check
//! (`tests/qemu_golden.rs`) runs. Every reference case must have a trace of at least
//! `ema::control::trace::MIN_GOLDEN_TICKS` ticks, and the on-target check must include it.

use std::path::{Path, PathBuf};

use ema::control::bridge::{HBridge, NullPin, NullPwm};
use ema::control::law;
use ema::control::trace::{self, CASES, MIN_GOLDEN_TICKS};

fn golden(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(format!("{name}.emat"))
}

const REGENERATE: &str = "regenerate with `cargo run -p hil-sim --release -- golden` once the \
                          change is intended";

#[test]
fn every_case_has_a_current_trace_that_replays_bit_for_bit() {
    let mut reverse = 0;
    for case in CASES {
        let path = golden(case.name);
        let bytes = std::fs::read(&path)
            .unwrap_or_else(|e| panic!("{}: {e}; {REGENERATE}", path.display()));
        let (trace, found, cfg) = trace::open(&bytes)
            .unwrap_or_else(|e| panic!("{}: {e:?}; {REGENERATE}", path.display()));
        assert_eq!(found.name, case.name, "{}", path.display());
        let ticks = trace.header().ticks;
        assert!(ticks >= MIN_GOLDEN_TICKS, "{}: {ticks} ticks", case.name);
        let Ok(mut bridge) = HBridge::new(
            NullPwm::new(trace.header().max_duty),
            NullPin(false),
            NullPin(false),
        );
        match trace::replay(&trace, &cfg, &mut bridge) {
            Ok(n) => assert_eq!(n, ticks),
            Err(m) => panic!("{}: stale trace, {m}; {REGENERATE}", case.name),
        }
        // Most ticks run the whole path (the paper's law re-arms often, the others hardly),
        // the bridge drives, and the trace ends in a latched fault.
        let (mut running, mut fwd) = (0, 0);
        for r in trace.records() {
            running += u32::from(r.output.fault == 0);
            fwd += u32::from(r.output.mode == 1);
            reverse += u32::from(r.output.mode == 2);
        }
        assert!(
            running >= ticks / 2 && fwd > 100,
            "{}: {running} running, {fwd} forward",
            case.name
        );
        assert_ne!(trace.records().last().map(|r| r.output.fault), Some(0));
    }
    // Some law reverses the bridge (the practical one never needs to).
    assert!(reverse > 10, "{reverse} reverse ticks in all traces");
}

#[test]
fn the_target_check_includes_every_trace() {
    let src =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/qemu_golden.rs"))
            .unwrap();
    for case in CASES {
        let include = format!("include_bytes!(\"golden/{}.emat\")", case.name);
        assert!(
            src.contains(&include),
            "tests/qemu_golden.rs lacks {include}"
        );
    }
}

/// One reference case per law, in the order of `ema::control::law::NAMES`, each running its
/// law.
#[test]
fn every_law_variant_has_its_case() {
    let names: Vec<&str> = CASES.iter().map(|c| c.name).collect();
    assert_eq!(names, law::NAMES);
    for case in CASES {
        assert_eq!((case.settings)().unwrap().law.name(), case.name);
    }
}
