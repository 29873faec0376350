//! Build script.
//!
//! 1. **The actuator the firmware is built for.** `EMA_ACTUATOR=path/to/file.toml cargo fw`
//!    builds the firmware for that actuator file (a hand-written one or the tuned one
//!    `hil-sim tune` writes; a relative path is taken from the workspace root); without
//!    it, for the product's default actuator (`ema::control::actuator::Actuator::PRODUCT`).
//!    The file is read and every setting derived here, with the control core's own code, so
//!    a bad file fails the build with the field and its value named, exactly as `hil-sim`
//!    refuses it. The actuator is then written as a Rust constant to
//!    `$OUT_DIR/actuator.rs`, which the firmware's `board.rs` includes; the firmware
//!    derives its settings from it at start, bit for bit as here (f32 only).
//! 2. **The build's identity.** `EMA_BUILD_ID` (for `ema::device::protocol::Build::THIS`,
//!    which the board reports in its status): the commit the sources are at, `git rev-parse
//!    --short=12 HEAD`; `unknown` outside a repository.
//! 3. **Link scripts.** For the thumb builds, puts `memory.x` on the linker search path
//!    (cortex-m-rt's `link.x` includes it) and links defmt's script into the firmware
//!    binary only. `-Tlink.x` itself is given once, in `.cargo/config.toml`.
//!
//! The control layer (`src/control/`) is included below as one module, under its name in
//! `src/lib.rs`, so that its `crate::control::` paths resolve here too: a build script
//! cannot depend on the package it builds. The control layer depends on nothing else in
//! the crate; the board's application (`src/device/`) is not needed here.
use std::{env, fs, path::PathBuf, process::Command};

#[expect(dead_code, unused_imports, clippy::all)]
#[path = "src/control/mod.rs"]
mod control;

use control::actuator::{Actuator, Board, Coil, Magnetics, Mechanics, Tolerances, Tuning};

fn main() {
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=EMA_ACTUATOR");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo:rustc-env=EMA_BUILD_ID={}", build_id());

    let actuator = match env::var("EMA_ACTUATOR") {
        Ok(path) if !path.is_empty() => {
            let root = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
            let file = root.join(&path);
            println!("cargo:rerun-if-changed={}", file.display());
            let text = fs::read_to_string(&file).unwrap_or_else(|e| {
                fail(&format!(
                    "EMA_ACTUATOR={path}: cannot read {}: {e}",
                    file.display()
                ))
            });
            toml::from_str::<Actuator>(&text)
                .unwrap_or_else(|e| fail(&format!("EMA_ACTUATOR={path}: {e}")))
        }
        _ => Actuator::PRODUCT,
    };
    if let Err(e) = actuator.settings() {
        fail(&format!(
            "the actuator the firmware is built for is refused: {e}"
        ));
    }
    fs::write(out.join("actuator.rs"), literal(&actuator)).expect("OUT_DIR is writable");

    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    fs::copy("memory.x", out.join("memory.x")).expect("memory.x is at the package root");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bin=firmware=-Tdefmt.x");
    // Identical code folding: functions whose machine code is the same (monomorphisations
    // of one generic for types of one layout, identical closures) are kept once.
    println!("cargo:rustc-link-arg-bin=firmware=--icf=all");
}

/// The commit the sources are at (see the module docs); cargo runs the script again when
/// `HEAD` or the branch it names moves.
fn build_id() -> String {
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
    };
    let Some(commit) = git(&["rev-parse", "--short=12", "HEAD"]) else {
        return "unknown".into();
    };
    let branch = git(&["symbolic-ref", "-q", "HEAD"]);
    for watched in ["HEAD", "packed-refs"].into_iter().chain(branch.as_deref()) {
        // Only files that exist: a missing one would run the script at every build.
        if let Some(path) = git(&["rev-parse", "--git-path", watched]) {
            if fs::metadata(&path).is_ok() {
                println!("cargo:rerun-if-changed={path}");
            }
        }
    }
    commit
}

/// Stops the build with `message` (cargo shows it as the script's error).
fn fail(message: &str) -> ! {
    eprintln!("error: {message}");
    std::process::exit(1)
}

/// The actuator as a Rust expression of `ema::control::actuator::Actuator`. `{:?}` writes
/// every `f32` in its shortest form that reads back to the same bits. The destructuring
/// names every field, so a field added to the file format without a place here fails to
/// build.
fn literal(a: &Actuator) -> String {
    let Actuator {
        mechanics:
            Mechanics {
                mass_kg,
                spring_n_per_m,
                preload_n,
                friction_n_s_per_m,
                stroke_m,
                residual_gap_m,
            },
        coil:
            Coil {
                resistance_ohm,
                turns,
                rated_current_a,
                peak_current_a,
                peak_time_s,
            },
        magnetics,
        board:
            Board {
                supply_v,
                rate_hz,
                position_span_m,
                current_full_scale_a,
                vbus_full_scale_v,
            },
        tolerance:
            Tolerances {
                surface,
                mass,
                spring,
                friction,
                resistance,
            },
        tuning,
    } = *a;
    let magnetics = match magnetics {
        Magnetics::Geometry {
            gaps,
            pole_a_m,
            pole_b_m,
            fringing_coefficient,
            fringing_spread,
            iron_reluctance_per_h,
        } => format!(
            "ema::control::actuator::Magnetics::Geometry {{ gaps: {gaps:?}, pole_a_m: {pole_a_m:?}, \
             pole_b_m: {pole_b_m:?}, fringing_coefficient: {fringing_coefficient:?}, \
             fringing_spread: {fringing_spread:?}, iron_reluctance_per_h: \
             {iron_reluctance_per_h:?} }}"
        ),
        Magnetics::Inductance { open_h, closed_h } => format!(
            "ema::control::actuator::Magnetics::Inductance {{ open_h: {open_h:?}, closed_h: {closed_h:?} }}"
        ),
    };
    let tuning = match tuning {
        Some(Tuning {
            alpha_per_s,
            observer_rad_s,
            margin,
            disturbance_follows_force,
        }) => format!(
            "Some(ema::control::actuator::Tuning {{ alpha_per_s: {alpha_per_s:?}, observer_rad_s: \
             {observer_rad_s:?}, margin: {margin:?}, disturbance_follows_force: \
             {disturbance_follows_force} }})"
        ),
        None => "None".into(),
    };
    format!(
        "// Written by build.rs from the actuator file the firmware is built for.\n\
         ema::control::actuator::Actuator {{\n\
         mechanics: ema::control::actuator::Mechanics {{ mass_kg: {mass_kg:?}, spring_n_per_m: \
         {spring_n_per_m:?}, preload_n: {preload_n:?}, friction_n_s_per_m: \
         {friction_n_s_per_m:?}, stroke_m: {stroke_m:?}, residual_gap_m: {residual_gap_m:?} }},\n\
         coil: ema::control::actuator::Coil {{ resistance_ohm: {resistance_ohm:?}, turns: {turns:?}, \
         rated_current_a: {rated_current_a:?}, peak_current_a: {peak_current_a:?}, \
         peak_time_s: {peak_time_s:?} }},\n\
         magnetics: {magnetics},\n\
         board: ema::control::actuator::Board {{ supply_v: {supply_v:?}, rate_hz: {rate_hz:?}, \
         position_span_m: {position_span_m:?}, current_full_scale_a: {current_full_scale_a:?}, \
         vbus_full_scale_v: {vbus_full_scale_v:?} }},\n\
         tolerance: ema::control::actuator::Tolerances {{ surface: {surface:?}, mass: {mass:?}, \
         spring: {spring:?}, friction: {friction:?}, resistance: {resistance:?} }},\n\
         tuning: {tuning},\n\
         }}\n"
    )
}
