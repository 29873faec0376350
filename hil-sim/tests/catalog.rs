//! Scenario files: the embedded ones mirror the Rust constructors, and bad files are
//! refused with the field and the value named, before anything runs or is written.

use std::path::PathBuf;

use hil_sim::cli;
use hil_sim::simulation::catalog::{self, LoadError, EMBEDDED};
use hil_sim::Scenario;

/// Each embedded file parses, passes every check and equals the constructor it mirrors
/// (but for the name), so that neither can drift from the other.
#[test]
fn embedded_files_equal_their_constructors() {
    let mirrors = [
        ("paper", Scenario::paper(1e6)),
        (
            "paper-20khz",
            Scenario::paper(20_000.0).with_current_trip_a(100.0),
        ),
        ("product", Scenario::product(20_000.0, 24.0).unwrap()),
        (
            "product-sequence",
            Scenario::product_sequence(20_000.0, 24.0).unwrap(),
        ),
    ];
    assert_eq!(mirrors.len(), EMBEDDED.len());
    for (name, ctor) in mirrors {
        let file = catalog::load(name).unwrap();
        catalog::preflight(&file).unwrap();
        let expected = Scenario {
            name: name.into(),
            ..ctor
        };
        assert_eq!(file, expected, "scenarios/{name}.toml");
    }
}

/// The sections a file may leave out take their documented defaults.
#[test]
fn left_out_sections_take_their_defaults() {
    let full = catalog::embedded("product").unwrap().text;
    let mut lean = String::new();
    let mut skip = false;
    for line in full.lines() {
        if line.starts_with('[') {
            skip = matches!(
                line.split_whitespace().next(),
                Some("[initial]" | "[plant]" | "[bridge]" | "[integration]")
            );
        }
        if !skip {
            lean.push_str(line);
            lean.push('\n');
        }
    }
    let sc = catalog::parse(&lean, "lean").unwrap();
    let product = Scenario::product(20_000.0, 24.0).unwrap();
    assert_eq!(sc.initial, product.initial); // at rest at the step's from_m
    assert_eq!(sc.plant, product.plant); // the controller's nominal plant
                                         // A file without the comparator's level simulates a board without one.
    assert_eq!(
        sc.bridge,
        hil_sim::simulation::scenario::Bridge {
            break_current_a: None,
            ..product.bridge
        }
    );
    assert_eq!(sc.integration.substeps, 10); // none longer than 5 us at 20 kHz
}

fn dir(test: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(test);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes the embedded `base` with `from` replaced by `to` into a file of `test`'s folder.
fn bad_file(test: &str, base: &str, from: &str, to: &str) -> PathBuf {
    let text = catalog::embedded(base).unwrap().text;
    assert!(text.contains(from), "{from}");
    let path = dir(test).join("bad.toml");
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    path
}

fn load_err(path: &std::path::Path) -> LoadError {
    catalog::load(path.to_str().unwrap()).unwrap_err()
}

#[test]
fn an_unknown_field_is_refused_by_name() {
    let p = bad_file(
        "unknown",
        "paper",
        "duration_s = 1.0",
        "duration_ms = 1000.0",
    );
    let e = load_err(&p);
    assert!(matches!(e, LoadError::Toml { .. }), "{e:?}");
    let text = e.to_string();
    assert!(text.contains("unknown field `duration_ms`"), "{text}");
    assert!(text.contains("bad.toml"), "{text}");
}

#[test]
fn a_wrong_type_is_refused_with_the_line_and_the_value() {
    let p = bad_file(
        "wrong-type",
        "paper",
        "mass_kg = 0.1",
        "mass_kg = \"heavy\"",
    );
    let text = load_err(&p).to_string();
    assert!(text.contains("[plant]"), "{text}");
    assert!(
        text.contains("the value is at line 35: mass_kg = \"heavy\""),
        "{text}"
    );
    assert!(text.contains("invalid type: string \"heavy\""), "{text}");
}

#[test]
fn a_negative_mass_is_refused_with_its_value() {
    // The true plant's mass (the first `mass_kg` of the file).
    let p = bad_file("negative-mass", "paper", "mass_kg = 0.1", "mass_kg = -0.1");
    let e = load_err(&p);
    assert_eq!(e.field(), Some("plant.mass_kg"));
    let text = e.to_string();
    assert!(
        text.contains("plant.mass_kg = -0.1: must be finite and positive"),
        "{text}"
    );
}

#[test]
fn gains_that_fail_theorem_1_are_refused() {
    let p = bad_file("theorem1", "paper", "alpha2 = 20000.0", "alpha2 = 10.0");
    let e = load_err(&p);
    assert_eq!(e.field(), Some("alpha2"));
    let text = e.to_string();
    assert!(text.contains("controller: alpha2 = 10"), "{text}");
    assert!(text.contains("Theorem 1"), "{text}");
}

#[test]
fn a_supply_above_the_converter_range_is_refused() {
    // The product's bus channel (the board's) reads up to 72.6 V.
    let p = bad_file("supply", "product", "voltage_v = 24.0", "voltage_v = 80.0");
    let e = load_err(&p);
    assert_eq!(e.field(), Some("supply.voltage_v"));
    let text = e.to_string();
    assert!(text.contains("supply.voltage_v = 80"), "{text}");
    assert!(text.contains("bus channel"), "{text}");
    // Within the channel but above the supervisor's bus window (30 V): refused too.
    let p = bad_file("window", "product", "voltage_v = 24.0", "voltage_v = 33.0");
    let text = load_err(&p).to_string();
    assert!(
        text.contains("supply.voltage_v = 33") && text.contains("bus window"),
        "{text}"
    );
}

/// A refused file makes the command fail before anything is written.
#[test]
fn a_bad_file_writes_nothing() {
    let p = bad_file("writes-nothing", "paper", "mass_kg = 0.1", "mass_kg = -0.1");
    let out = p.parent().unwrap().join("out");
    let args = cli::run::Args {
        scenario: p.to_str().unwrap().into(),
        output: cli::Output {
            out: Some(out.clone()),
        },
        max_rows: 100,
    };
    let mut printed = Vec::new();
    let e = cli::run::run(&args, &mut printed).unwrap_err();
    assert!(e.to_string().contains("plant.mass_kg = -0.1"), "{e}");
    assert!(!out.exists());
    assert!(printed.is_empty());
}

/// The binary exits with 1 and the message, without a panic.
#[test]
fn the_binary_exits_non_zero_with_the_message() {
    let p = bad_file("binary", "paper", "alpha2 = 20000.0", "alpha2 = 10.0");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .args(["run", p.to_str().unwrap(), "--out"])
        .arg(p.parent().unwrap().join("out"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.starts_with("error: scenario "), "{stderr}");
    assert!(stderr.contains("alpha2 = 10"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!p.parent().unwrap().join("out").exists());
}

/// The comparator backs the sampled trip up: a level at or below the trip (13.2 A on the
/// product) is refused by name, with the trip it must exceed.
#[test]
fn a_comparator_below_the_current_trip_is_refused() {
    let p = bad_file(
        "break",
        "product",
        "break_current_a = 15.84",
        "break_current_a = 12.0",
    );
    let e = load_err(&p);
    assert_eq!(e.field(), Some("bridge.break_current_a"));
    let text = e.to_string();
    assert!(
        text.contains("bridge.break_current_a = 12: must be above the current trip, 13.2 A"),
        "{text}"
    );
}
