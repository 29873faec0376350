//! Fault injection on the product's actuator: each fault is named within 1 ms with its own
//! code, after its injection, the coil current never exceeds the trip level (the
//! actuator's peak current), the bridge coasts from then on, and nothing panics. Every
//! family member's table is pinned as measured, its limits included. On every actuator
//! of the family, healthy runs raise nothing.

use ema::control::supervisor::Fault;
use hil_sim::analysis::faults::{cases, evaluate, Case, Outcome, DEADLINE_S};
use hil_sim::simulation::actuator::{self, FAMILY};
use hil_sim::simulation::scenario::Injected;
use hil_sim::{run, Scenario};

/// The expected fault within [`DEADLINE_S`] of the injection, the coil current at or
/// under the trip level, the bridge coasting after.
fn assert_named_safely(o: &Outcome) {
    assert!(
        o.pass(),
        "{}: expected {} within {} s, got {:?} after {:?} s, peak {} A (trip {} A), coasting {}",
        o.name,
        o.expected,
        DEADLINE_S,
        o.fault,
        o.detected_after_s,
        o.peak_current_a,
        o.trip_a,
        o.coasting
    );
}

fn product_cases() -> Vec<Case> {
    cases(&Scenario::product_sequence(20e3, 24.0).unwrap()).unwrap()
}

fn outcome(name: &str) -> Outcome {
    let all = product_cases();
    evaluate(all.iter().find(|c| c.name == name).unwrap()).unwrap()
}

/// One test per fault-injection case on the product's actuator, by name.
macro_rules! case {
    ($test:ident, $name:literal) => {
        #[test]
        fn $test() {
            assert_named_safely(&outcome($name));
        }
    };
}

case!(position_sensor_open, "position sensor open");
case!(position_sensor_shorted, "position sensor shorted");
case!(position_sensor_stuck, "position sensor stuck");
case!(current_sensor_stuck, "current sensor stuck");
case!(current_sensor_offset, "current sensor offset");
case!(coil_open, "coil open");
case!(coil_short, "coil short");
case!(supply_sag, "supply sag");
case!(supply_over_voltage, "supply over-voltage");
case!(missed_deadlines, "missed deadlines");
case!(tick_stops, "tick stops");

/// What a case does on a family member, as measured (`hil-sim faults MEMBER`).
#[derive(Clone, Copy, Debug)]
enum Pin {
    /// The expected fault, named after the injection, within the bound \[us\] (at most
    /// the 1 ms deadline), the current under the trip level, the bridge coasting.
    Named(f64),
    /// A limit: the expected-or-other fault `.0`, named only after the deadline, between
    /// `.1` and `.2` \[us\] (see [`current_stuck_is_unobservable_within_the_deadline`]).
    Late(&'static str, f64, f64),
    /// A limit: nothing named; the plant is controlled, the current under the trip level.
    Unnamed,
    /// A defect: another fault `.0` named within the bound `.1` \[us\], the bridge
    /// coasting from then on (safe, but the operator is told the wrong cause).
    Misnamed(&'static str, f64),
}

use Pin::{Late, Misnamed, Named, Unnamed};

/// Each member's table, in the order of [`cases`]: position sensor open, shorted, stuck;
/// current sensor stuck, offset; coil open, short; supply sag, over-voltage; missed
/// deadlines; tick stops; plant outside the bounds (timed from power-up). The bounds are
/// the measured latencies rounded up to the next 50 us.
const TABLES: [(&str, [Pin; 12]); 7] = [
    (
        "product",
        [
            Named(50.0),
            Named(50.0),
            Named(600.0),
            Named(800.0),
            Named(100.0),
            Named(200.0),
            Named(150.0),
            Named(100.0),
            Named(100.0),
            Named(200.0),
            Named(250.0),
            Unnamed,
        ],
    ),
    (
        "valve",
        [
            Named(50.0),
            Named(50.0),
            Named(650.0),
            Late("current_stuck", 1000.0, 1750.0),
            Named(100.0),
            Named(200.0),
            Named(200.0),
            Named(100.0),
            Named(100.0),
            Named(200.0),
            Named(250.0),
            Unnamed,
        ],
    ),
    (
        "solenoid-12v",
        [
            Named(100.0),
            Named(100.0),
            Late("current_stuck", 1000.0, 6500.0),
            Late("current_stuck", 1000.0, 4500.0),
            Named(200.0),
            Named(400.0),
            Named(400.0),
            Named(200.0),
            Named(200.0),
            Named(400.0),
            Named(400.0),
            Named(400.0),
        ],
    ),
    (
        "positioner-48v",
        [
            Named(50.0),
            Named(50.0),
            Late("current_stuck", 1000.0, 7250.0),
            Named(350.0),
            Named(50.0),
            Named(100.0),
            Named(100.0),
            Named(50.0),
            Named(50.0),
            Named(100.0),
            Named(200.0),
            Named(100.0),
        ],
    ),
    (
        "plunger-1kg",
        [
            Named(50.0),
            Named(50.0),
            Named(650.0),
            Named(700.0),
            Named(100.0),
            Named(200.0),
            Named(250.0),
            Named(100.0),
            Named(100.0),
            Named(200.0),
            Named(300.0),
            Named(200.0),
        ],
    ),
    (
        "pilot-50khz",
        [
            Named(50.0),
            Named(50.0),
            Named(400.0),
            Named(300.0),
            Named(50.0),
            Named(100.0),
            Misnamed("current_stuck", 300.0),
            Named(50.0),
            Named(50.0),
            Named(100.0),
            Named(200.0),
            Named(100.0),
        ],
    ),
    (
        "micro-valve",
        [
            Named(50.0),
            Named(50.0),
            Named(550.0),
            Late("current_stuck", 1000.0, 2350.0),
            Named(50.0),
            Named(100.0),
            Named(100.0),
            Named(50.0),
            Named(50.0),
            Named(100.0),
            Named(200.0),
            Unnamed,
        ],
    ),
];

/// Every member's fault table as pinned in [`TABLES`]: the named fault and its latency
/// bound per case; the limits named as measured.
#[test]
fn every_member_s_fault_table_is_as_pinned() {
    let pinned: Vec<&str> = TABLES.iter().map(|(m, _)| *m).collect();
    let family: Vec<&str> = FAMILY.iter().map(|e| e.name).collect();
    assert_eq!(pinned, family, "every member of the family has its table");
    for (member, pins) in &TABLES {
        let (name, act) = actuator::load(member).unwrap();
        let all = cases(&actuator::scenario(&name, &act).unwrap()).unwrap();
        assert_eq!(all.len(), pins.len(), "{member}");
        for (c, pin) in all.iter().zip(pins) {
            let o = evaluate(c).unwrap();
            let us = o.detected_after_s.map(|t| t * 1e6);
            let what = format!("{member}, {}: {:?} after {us:?} us", c.name, o.fault);
            assert!(
                o.peak_current_a <= o.trip_a,
                "{what}: peak {}",
                o.peak_current_a
            );
            match *pin {
                Named(bound_us) => {
                    assert!(bound_us <= DEADLINE_S * 1e6, "{what}");
                    assert_named_safely(&o);
                    let t = us.unwrap();
                    assert!(
                        t > 0.0 && t <= bound_us + 1e-3,
                        "{what}: bound {bound_us} us"
                    );
                }
                Late(fault, lo_us, hi_us) => {
                    assert_eq!(o.fault.as_deref(), Some(fault), "{what}");
                    let t = us.unwrap();
                    assert!(
                        t > lo_us && t <= hi_us + 1e-3,
                        "{what}: {lo_us}..{hi_us} us"
                    );
                }
                Unnamed => assert_eq!(o.fault, None, "{what}"),
                Misnamed(fault, bound_us) => {
                    assert_eq!(o.fault.as_deref(), Some(fault), "{what}");
                    assert!(o.coasting, "{what}");
                    let t = us.unwrap();
                    assert!(
                        t > 0.0 && t <= bound_us + 1e-3,
                        "{what}: bound {bound_us} us"
                    );
                }
            }
        }
    }
}

/// Why a current reading frozen "where the current changes fastest" is named late on
/// two members: over the deadline after the injection, the healthy run's true current
/// stays within about one noise allowance of the current detectors
/// ([`ema::control::actuator::NOISE_ALLOWANCE_CODES`] current codes) of its value at the
/// injection (measured: 0.72 allowances on the valve, 0.95 on the 12 V solenoid), so a
/// reading frozen there is, for that millisecond, what an admissible coil could give:
/// nothing observable differs, and the reading is named only once the loop has driven
/// the current away from it. (The product's current moves 5.0 allowances in that
/// millisecond, and it is named within the deadline against the resistance the residual
/// learned while the coil held.)
#[test]
fn current_stuck_is_unobservable_within_the_deadline() {
    for (member, limit) in [("valve", 0.8), ("solenoid-12v", 1.1)] {
        let (name, act) = actuator::load(member).unwrap();
        let base = actuator::scenario(&name, &act).unwrap();
        let all = cases(&base).unwrap();
        let c = all
            .iter()
            .find(|c| c.name == "current sensor stuck")
            .unwrap();
        let healthy = run(&base.clone().with_duration_s(c.at_s + 2.0 * DEADLINE_S)).unwrap();
        let at = healthy
            .samples
            .iter()
            .find(|s| s.t_s >= c.at_s - 1e-9)
            .unwrap()
            .i_a;
        let excursion = healthy
            .samples
            .iter()
            .filter(|s| s.t_s >= c.at_s && s.t_s <= c.at_s + DEADLINE_S)
            .map(|s| (s.i_a - at).abs())
            .fold(0.0, f64::max);
        let allowance = f64::from(ema::control::actuator::NOISE_ALLOWANCE_CODES)
            * f64::from(base.controller.sense.current.scale.abs());
        println!(
            "{member}: {excursion} A within 1 ms, allowance {allowance} A ({} allowances)",
            excursion / allowance
        );
        assert!(excursion < limit * allowance, "{member}: {excursion} A");
    }
}

/// A detection that comes before the injection is not a detection: the table's verdict
/// requires the fault after it.
#[test]
fn a_fault_latched_before_the_injection_fails_the_case() {
    let mut o = outcome("coil open");
    assert!(o.pass());
    o.detected_after_s = Some(-50e-6);
    assert!(!o.pass());
}

/// A current reading frozen while the current holds still carries no information until
/// the loop has wound up against it: it is still named, later.
#[test]
fn a_current_reading_frozen_in_a_steady_phase_is_found_later() {
    let sc = Scenario::product(20e3, 24.0)
        .unwrap()
        .with_duration_s(0.3)
        .with_fault(0.2, Injected::CurrentStuck);
    let r = run(&sc).unwrap();
    let first = r.samples.iter().find(|s| s.fault.is_some()).unwrap();
    assert_eq!(first.fault, Some(Fault::CurrentStuck));
    let after = first.t_s - 0.2;
    println!("current stuck while holding: named after {after} s");
    assert!(after > 1e-3 && after < 50e-3, "{after}");
    assert!(r.metrics.i_peak_a <= f64::from(sc.controller.limits.current_trip_a));
}

/// An interrupt that stops while the start-up ramp drives the coil: the bridge keeps
/// driving (the last duty repeats) until the window watchdog's early wake-up, at most its
/// 292.6 us after the last feed (the last tick, at 0 s), which the simulation checks at
/// the sample instants: the coil coasts from 300 us on, within half a millisecond of the
/// stall, and its current then falls to zero.
#[test]
fn a_tick_that_stops_coasts_the_bridge_within_half_a_millisecond() {
    let stall_s = 50e-6;
    let sc = Scenario::product(20e3, 24.0)
        .unwrap()
        .with_duration_s(0.01)
        .with_fault(stall_s, Injected::MissedDeadlines { ticks: u32::MAX });
    let r = run(&sc).unwrap();
    let first_coast = r
        .samples
        .iter()
        .position(|s| s.t_s >= stall_s && s.mode == ema::control::bridge::Mode::Coast)
        .unwrap();
    let coast_s = r.samples[first_coast].t_s;
    assert!((coast_s - 300e-6).abs() < 1e-9, "{coast_s}");
    assert!(coast_s - stall_s <= 0.5e-3);
    // Driven all through the stall, coasting after, with the overrun latched.
    let stalled = &r.samples[1..first_coast];
    assert!(stalled
        .iter()
        .all(|s| s.mode == ema::control::bridge::Mode::Forward));
    assert!(stalled.iter().all(|s| s.fault.is_none()));
    let after = &r.samples[first_coast..];
    assert!(after
        .iter()
        .all(|s| s.mode == ema::control::bridge::Mode::Coast));
    assert!(after.iter().all(|s| s.fault == Some(Fault::Overrun)));
    assert_eq!(r.samples.last().unwrap().i_a, 0.0);
}

/// Healthy runs of every case's scenario without the injection raise nothing, on every
/// actuator of the family.
#[test]
fn without_the_injection_nothing_is_raised() {
    for e in &FAMILY {
        let (name, act) = actuator::load(e.name).unwrap();
        for mut c in cases(&actuator::scenario(&name, &act).unwrap()).unwrap() {
            if c.name == "plant outside the bounds" || c.name == "tick stops" {
                continue;
            }
            c.scenario.faults.clear();
            let o = evaluate(&c).unwrap();
            assert_eq!(o.fault, None, "{name}: {}", c.name);
        }
    }
}

/// A frozen position reading is observable only once the armature moves: frozen at the
/// fastest point of a move, once the armature has run the noise allowance (measured:
/// 250 us, against a deadline of 1000 us); frozen while holding, with no move before the
/// run ends (20 ms), never. Every other fault is observable at its injection.
#[test]
fn a_frozen_reading_is_observable_once_its_quantity_moves() {
    let all = product_cases();
    let find = |name: &str| all.iter().find(|c| c.name == name).unwrap().clone();
    let moving = find("position sensor stuck");
    let seen = evaluate(&moving).unwrap().observable_after_s.unwrap();
    assert!(seen > 0.0 && seen <= 0.3 * DEADLINE_S, "{seen}");
    let open = find("position sensor open");
    let mut held = moving.clone();
    held.at_s = open.at_s;
    held.scenario = open.scenario.clone();
    held.scenario.faults[0].fault = Injected::PositionStuck;
    assert_eq!(evaluate(&held).unwrap().observable_after_s, None);
    assert_eq!(evaluate(&open).unwrap().observable_after_s, Some(0.0));
}

/// Every fault injected at random instants on drawn plants (the product, 24 instants and
/// plants per case, seed printed): no false alarm before any injection and the bridge
/// coasting after every fault; each fault that changes what the tick reads, the coil or
/// the interrupt's timing (sensor open or shorted, coil open, supply sag and
/// over-voltage, missed deadlines, a tick that stops, a coil short) named as expected
/// within the deadline every time, the current at or under the trip (without the zero
/// volts the tick applies between a jump and its verdict, a short here runs past the
/// trip). The frozen readings and the offset are reported, not required, in
/// `RESULTS.md` (`hil-sim faults NAME --random 200`).
#[test]
fn faults_at_random_instants_are_named_on_drawn_plants() {
    const SEED: u64 = 0xfa17_0000_0000_0015;
    println!("seed {SEED:#x}");
    let at_random = hil_sim::analysis::faults::random(
        &Scenario::product_sequence(20e3, 24.0).unwrap(),
        24,
        SEED,
    )
    .unwrap();
    assert_eq!(at_random.len(), 11);
    for s in &at_random {
        assert_eq!((s.before, s.not_coasting), (0, 0), "{s:?}");
        match s.name.as_str() {
            "position sensor stuck" | "current sensor stuck" | "current sensor offset" => {}
            _ => assert_eq!(
                (
                    s.pass,
                    s.within_deadline,
                    s.observable,
                    s.named_once_observable
                ),
                (s.n, s.n, s.n, s.n),
                "{s:?}"
            ),
        }
    }
}

/// The board's over-current comparator (the break input) switches the bridge off within
/// the substep the current crosses its level, without the tick; the next tick latches
/// `hardware_trip` and the bridge coasts from then on. The paper's law on the product's
/// actuator (`hil-sim compare`'s cell, its current trip brought down to 14 A) drives the
/// coil past the sampled trip between two samples; the comparator holds the peak to its
/// level plus one substep's rise, and without it the same run goes further. At its real
/// level, 1.2 x the peak current, the product's healthy run never reaches it.
#[test]
fn the_board_s_comparator_switches_the_bridge_off_at_its_level() {
    let level = ema::control::actuator::Actuator::PRODUCT.break_current_a();
    let product = Scenario::product(20e3, 24.0).unwrap().with_duration_s(0.1);
    assert_eq!(product.bridge.break_current_a, Some(level));
    let healthy = run(&product).unwrap();
    assert!(healthy.samples.iter().all(|s| s.fault.is_none()));

    let mut without = hil_sim::analysis::compare::scenario("paper", 20e3, 24.0)
        .unwrap()
        .with_duration_s(0.1);
    without.controller.limits.current_trip_a = 14.0;
    let w = run(&without).unwrap();
    let mut with = without.clone();
    with.bridge.break_current_a = Some(level);
    let r = run(&with).unwrap();
    let k = r.samples.iter().position(|s| s.fault.is_some()).unwrap();
    assert_eq!(r.samples[k].fault, Some(Fault::HardwareTrip));
    let peak = r.metrics.i_peak_a;
    assert!(
        peak >= f64::from(level) && peak <= f64::from(level) + 0.4,
        "peak {peak} A against the comparator's {level} A"
    );
    assert!(r.samples[k..]
        .iter()
        .all(|s| s.mode == ema::control::bridge::Mode::Coast));
    assert!(w.metrics.i_peak_a > peak + 1.0, "{} A", w.metrics.i_peak_a);
}
