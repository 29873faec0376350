//! The saved golden traces (`tests/golden/*.emat` at the workspace root) are exactly what
//! the simulator records now. The root package's `tests/golden_host.rs` checks that they
//! replay through today's core bit for bit, and `tests/qemu_golden.rs` does the same on
//! the emulated Cortex-M4F; this test catches the other way a trace goes stale: the
//! scenario, the plant model or the converter model changed.

use std::path::Path;

use ema::control::trace::{self, CASES, MIN_GOLDEN_TICKS};

#[test]
fn saved_traces_are_what_the_simulator_records() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/golden");
    for case in CASES {
        let path = dir.join(format!("{}.emat", case.name));
        let saved = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let now = hil_sim::analysis::golden::generate(case).unwrap();
        assert!(
            saved == now,
            "{} is stale: regenerate with `cargo run -p hil-sim --release -- golden`",
            path.display()
        );
        let (t, found, _) = trace::open(&now).unwrap();
        assert_eq!(found.name, case.name);
        assert!(t.header().ticks >= MIN_GOLDEN_TICKS);
    }
}

#[test]
fn a_recorded_run_needs_converter_codes() {
    let case = trace::case("practical").unwrap();
    let sc = hil_sim::analysis::golden::scenario(case)
        .unwrap()
        .with_sensors(hil_sim::simulation::scenario::Sensors::Ideal);
    let mut rec = hil_sim::simulation::sim::Recording::default();
    let e = hil_sim::simulation::sim::run_with(&sc, Some(&mut rec)).unwrap_err();
    assert!(e.to_string().contains("sensors"), "{e}");
}
