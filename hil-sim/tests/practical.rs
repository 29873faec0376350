//! The practical law meets the product's targets (issue 4) under the realistic default:
//! 20 kHz ISR (and 10 kHz), 24 V (and 48 V) with 50 mOhm of supply resistance, averaged
//! bridge, 12-bit converters with 1.5 codes of noise and one sample of delay, velocity
//! estimated, the paper's step and the sequence of steps across the stroke; on the
//! nominal plant and on plants drawn from the uncertainty set (surfaces anywhere in the
//! controller's bounds, constant or growing with the gap, frozen or energy-consistent
//! force, R +-20 %, K +-10 %, m +-10 %, lambda +-50 %).

use hil_sim::hal::Adc;
use hil_sim::scenario::{BridgeMode, Sensors, TruePlant, Uncertainty};
use hil_sim::targets::{failing, Targets, Worst};
use hil_sim::{montecarlo::montecarlo_with, run, Scenario};

fn check(sc: &Scenario, supply_v: f64) -> Worst {
    let r = run(sc).unwrap();
    let w = Worst::of([&r.metrics]);
    let misses = w.misses(&Targets::product(supply_v));
    assert!(misses.is_empty(), "{}: misses {misses:?} in {w:?}", sc.name);
    w
}

#[test]
fn nominal_plant_meets_every_target() {
    for (rate, supply) in [(20e3, 24.0), (10e3, 24.0), (20e3, 48.0)] {
        let step = check(&Scenario::product(rate, supply), supply);
        let seq = check(&Scenario::product(rate, supply).with_sequence(), supply);
        // Measured at 20 kHz, 24 V: settling 0.097 s (step) and 0.134 s (sequence),
        // overshoot <= 0.03 %, error <= 0.004 %, ripple <= 0.11 A, peak 7.8 A.
        assert!(
            step.settling_s < 0.15 && seq.settling_s < 0.15,
            "{rate} {supply}"
        );
    }
}

/// Without converter noise (quantisation only), the nominal plant settles within 0.02 %
/// of the reference.
#[test]
fn nominal_plant_without_noise_is_within_two_hundredths_of_a_percent() {
    let quiet = Sensors::Adc(Adc {
        delay_samples: 1,
        ..Adc::default()
    });
    for sc in [
        Scenario::product(20e3, 24.0),
        Scenario::product(20e3, 24.0).with_sequence(),
    ] {
        let r = run(&sc.with_sensors(quiet)).unwrap();
        let w = Worst::of([&r.metrics]);
        assert!(w.steady_error_pct <= 0.02, "{w:?}");
        assert!(w.misses(&Targets::product(24.0)).is_empty(), "{w:?}");
    }
}

/// Switching-level PWM: the coil sees the real pulses, and the samples (taken mid
/// off-time, as the firmware triggers the converter) still meet every target; the ripple
/// inside the PWM period shows in the peak current.
#[test]
fn switching_level_pwm_meets_the_targets_at_the_samples() {
    let sc = Scenario::product(20e3, 24.0)
        .with_sequence()
        .with_bridge_mode(BridgeMode::Switching);
    let w = check(&sc, 24.0);
    // The averaged bridge peaks at 7.80 A on the same sequence; the PWM pulses add about
    // 2.7 A peak to peak inside the period (measured peak 9.17 A).
    assert!(w.current_a > 8.5 && w.current_a < 12.0, "{}", w.current_a);
}

/// A fixed-seed sample of 60 plants from the uncertainty set, every target, at 20 kHz
/// and 24 V on the sequence of steps. The full 1000-plant run is
/// `cargo run -p hil-sim --release -- montecarlo` (result in the README).
#[test]
fn sixty_plants_from_the_uncertainty_set_meet_every_target() {
    let sc = Scenario::product(20e3, 24.0)
        .with_sequence()
        .with_substeps(3)
        .with_plant(TruePlant::Drawn {
            seed: 0,
            uncertainty: Uncertainty::default(),
        });
    let draws = montecarlo_with(&sc, 60, 2026, false).unwrap();
    let bad = failing(&draws, &Targets::product(24.0));
    assert!(
        bad.is_empty(),
        "{} plants fail, first: {:?} {:?}",
        bad.len(),
        bad.first().map(|(d, m)| (m, &d.plant)),
        bad.first().map(|(d, _)| &d.metrics.segments)
    );
    let w = Worst::of_draws(&draws);
    assert_eq!(w.runs, 60);
    // Both force models and both surface models are in the sample.
    let ec = draws
        .iter()
        .filter(|d| d.plant.force == hil_sim::plant::ForceModel::EnergyConsistent)
        .count();
    assert!(ec > 10 && ec < 50, "{ec}");
}
