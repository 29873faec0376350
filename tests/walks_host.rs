//! Plant-consistent random walks with every detector on: the product's tick closes the
//! loop around the small physical actuator of `tests/common/plant.rs` (the one the QEMU
//! tests drive), so the current answers the drive and the position answers the force, and
//! the residual, stuck, tracking and thermal detectors all run as on a board.
//!
//! Each case is a random sequence of set points (anywhere in the stroke, each held for a
//! random 2-40 ms) on a bus that wanders inside its window, with converter noise. Half the
//! cases also carry hostile frames (a channel on a rail, a non-finite set point) at random
//! ticks, after which an operator re-arms.
//!
//! Promised, on every tick: the duty never exceeds full scale, the applied voltage never
//! exceeds the bus, a hostile frame latches a named fault and coasts the bridge in the same
//! tick. On the clean cases: not one fault (no false alarm from any detector), and every
//! frame reaches the law and the detectors.

#[path = "common/plant.rs"]
mod plant;

use ema::control::bridge::{HBridge, Mode, NullPin, NullPwm, BOARD_MAX_DUTY as MAX_DUTY};
use ema::control::sense::{Frame, ADC_MAX_CODE};
use ema::control::supervisor::Fault;
use ema::control::Settings;
use proptest::prelude::*;
use proptest::test_runner::{FileFailurePersistence, RngSeed, TestRunner};

/// Ticks per case: 0.25 s at 20 kHz.
const TICKS: usize = 5_000;
const CASES: u32 = 48;
const RATE_HZ: f32 = 20_000.0;
/// The seed of every case: a failure replays exactly.
const SEED: u64 = 0x00e3_a5ee_d000_0003;

/// A hostile frame at one tick.
#[derive(Clone, Copy, Debug)]
enum Hostile {
    /// Position code on the lower rail (sensor open).
    PositionRail,
    /// Current code on the upper rail (sensor shorted).
    CurrentRail,
    /// Bus code on the upper rail (divider open).
    VbusRail,
    /// A non-finite set point.
    Setpoint,
}

#[derive(Clone, Debug)]
struct Case {
    /// Set points as fractions of the stroke, each with its hold time in ticks.
    setpoints: Vec<(f32, usize)>,
    /// Bus voltage steps per tick, as fractions of the window's half width.
    bus_drift: f32,
    /// Hostile frames: at which tick, what.
    hostile: Vec<(usize, Hostile)>,
}

fn case(with_hostile: bool) -> impl Strategy<Value = Case> {
    let hostile = prop_oneof![
        Just(Hostile::PositionRail),
        Just(Hostile::CurrentRail),
        Just(Hostile::VbusRail),
        Just(Hostile::Setpoint),
    ];
    let n_hostile = if with_hostile { 1..6 } else { 0..1 };
    (
        proptest::collection::vec((0.0_f32..=1.0, 40_usize..800), 30),
        -1.0_f32..1.0,
        proptest::collection::vec((200_usize..TICKS, hostile), n_hostile),
    )
        .prop_map(|(setpoints, bus_drift, hostile)| Case {
            setpoints,
            bus_drift,
            hostile,
        })
}

#[derive(Clone, Copy, Debug, Default)]
struct Counts {
    frames: u64,
    reached: u64,
    faults: u64,
}

fn run(settings: &Settings, case: &Case) -> Result<Counts, TestCaseError> {
    let cfg = settings.build().unwrap();
    let limits = *cfg.limits();
    let stroke_m = settings.plant.stroke_m;
    let (v_lo, v_hi) = (limits.vbus_min_v, limits.vbus_max_v);
    // The bus wanders inside the inner half of the window.
    let v_mid = 0.5 * (v_lo + v_hi);
    let v_span = 0.25 * (v_hi - v_lo);
    let mut bridge = HBridge::new(NullPwm::new(MAX_DUTY), NullPin(false), NullPin(false)).unwrap();
    let mut state = cfg.initial_state();
    let mut actuator = plant::Plant::new(settings, 0.0, v_mid);
    let mut counts = Counts::default();
    let mut setpoints = case.setpoints.iter().cycle();
    let (mut target, mut left) = (0.0_f32, 0_usize);
    let mut latched_for = 0;
    for k in 0..TICKS {
        if left == 0 {
            let (f, hold) = setpoints.next().copied().unwrap_or((0.5, 400));
            target = f * stroke_m;
            left = hold;
        }
        left -= 1;
        // A slow triangle of the bus inside the window.
        let phase = (k as f32 / TICKS as f32) * 4.0 * case.bus_drift;
        actuator.vbus_v = v_mid + v_span * (phase.sin());
        if state.supervisor.latched().is_some() {
            latched_for += 1;
            if latched_for > 20 {
                cfg.rearm(&mut state);
                latched_for = 0;
            }
        }
        let mut frame: Frame = actuator.frame();
        let mut setpoint_m = target;
        let hostile = case.hostile.iter().find(|(at, _)| *at == k).map(|h| h.1);
        match hostile {
            Some(Hostile::PositionRail) => frame.position = 0,
            Some(Hostile::CurrentRail) => frame.current = ADC_MAX_CODE,
            Some(Hostile::VbusRail) => frame.vbus = ADC_MAX_CODE,
            Some(Hostile::Setpoint) => setpoint_m = f32::NAN,
            None => {}
        }
        let before = state.supervisor.latched();
        let status = cfg.tick(&mut state, &mut bridge, &frame, setpoint_m);
        counts.frames += 1;
        prop_assert!(
            status.drive.duty <= MAX_DUTY,
            "tick {k}: duty {}",
            status.drive.duty
        );
        prop_assert!(
            status.drive.u_v.abs() <= status.measurement.vbus_v.max(0.0) * (1.0 + 1e-6),
            "tick {k}: {} V applied on a {} V bus",
            status.drive.u_v,
            status.measurement.vbus_v
        );
        if hostile.is_some() && before.is_none() {
            prop_assert!(
                status.fault.is_some(),
                "tick {k}: {hostile:?} without a fault"
            );
        }
        if status.fault.is_some() {
            prop_assert_eq!(
                status.drive.mode,
                Mode::Coast,
                "tick {}: fault but driving",
                k
            );
        }
        if before.is_none() {
            if status.fault.is_none_or(Fault::from_detectors) {
                counts.reached += 1;
            }
            if status.fault.is_some() {
                counts.faults += 1;
            }
        }
        actuator.advance(&status.drive);
    }
    Ok(counts)
}

fn property(with_hostile: bool) -> Counts {
    let settings = Settings::practical(RATE_HZ, 24.0).unwrap();
    let config = ProptestConfig {
        cases: CASES,
        rng_seed: RngSeed::Fixed(SEED),
        failure_persistence: Some(Box::new(FileFailurePersistence::WithSource("regressions"))),
        source_file: Some(file!()),
        ..ProptestConfig::default()
    };
    let mut runner = TestRunner::new(config);
    let total = std::cell::Cell::new(Counts::default());
    let result = runner.run(&case(with_hostile), |case| {
        let c = run(&settings, &case)?;
        let mut t = total.get();
        t.frames += c.frames;
        t.reached += c.reached;
        t.faults += c.faults;
        total.set(t);
        if !with_hostile {
            prop_assert_eq!(c.faults, 0, "a fault on a clean walk");
        }
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e} (proptest seed {SEED:#x})");
    }
    total.get()
}

#[test]
fn clean_walks_raise_no_fault_and_every_frame_reaches_the_detectors() {
    let c = property(false);
    eprintln!(
        "proptest seed {SEED:#x}: {} frames, {} reached the law and the detectors, {} faults",
        c.frames, c.reached, c.faults
    );
    assert_eq!(c.frames, u64::from(CASES) * TICKS as u64);
    assert_eq!(c.reached, c.frames);
}

#[test]
fn hostile_frames_on_walks_end_safe_and_the_rest_reach_the_detectors() {
    let c = property(true);
    eprintln!(
        "proptest seed {SEED:#x}: {} frames, {} reached the law and the detectors, {} faults",
        c.frames, c.reached, c.faults
    );
    assert!(c.faults >= u64::from(CASES), "only {} faults", c.faults);
    assert!(2 * c.reached >= c.frames);
}
