//! Fault injection: each fault is found within 1 ms (20 ticks at 20 kHz) with
//! its own code, the coil current never exceeds the trip level (limit + 10 %, 13.2 A),
//! the bridge coasts from then on, and nothing panics.

use ema::supervisor::Fault;
use hil_sim::faults::{cases, evaluate, table, Outcome, DEADLINE_S};
use hil_sim::scenario::Injected;
use hil_sim::{run, Scenario};

/// The expected fault within [`DEADLINE_S`], the coil current at or under the 13.2 A trip
/// level, the bridge coasting after.
fn assert_named_safely(o: &Outcome) {
    assert!(
        o.pass(),
        "{}: expected {} within {} s, got {:?} after {:?} s, peak {} A, coasting {}",
        o.name,
        o.expected,
        DEADLINE_S,
        o.fault,
        o.detected_after_s,
        o.peak_current_a,
        o.coasting
    );
    assert!(
        o.peak_current_a <= 13.2,
        "{}: {} A",
        o.name,
        o.peak_current_a
    );
}

/// One test per fault-injection case, by name: the expected fault within 1 ms, the current
/// under the trip level, the bridge coasting after.
macro_rules! case {
    ($test:ident, $name:literal) => {
        #[test]
        fn $test() {
            let all = cases(20e3, 24.0);
            let case = all.iter().find(|c| c.name == $name).unwrap();
            assert_named_safely(&evaluate(case).unwrap());
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
case!(plant_outside_the_bounds, "plant outside the bounds");

#[test]
fn every_injected_fault_is_named_within_a_millisecond() {
    let outcomes = table(20e3, 24.0).unwrap();
    assert_eq!(outcomes.len(), 12);
    outcomes.iter().for_each(assert_named_safely);
    // Measured: the rails in one tick (50 us), the bus checks in two, the coil checks in
    // five, the stuck position at the fastest point of the move in 0.80 ms (its 0.7 ms
    // window, the sample delay and where the anchor last moved).
    let slowest = outcomes
        .iter()
        .filter_map(|o| o.detected_after_s)
        .fold(0.0_f64, f64::max);
    assert!(slowest <= 0.85e-3, "{slowest}");
}

/// The same cases at 10 kHz (a tick is 100 us, the deadline is still 1 ms). Two limits of
/// software protection at that rate are pinned here and reported in the README: a coil
/// short is named in 0.3 ms but, reacting one delayed period late while the short adds
/// about 3.6 A per period, the current overshoots the 13.2 A trip (measured 15.5 A; the
/// STM32's comparator on the TIM1 break input is what bounds it in hardware); and the
/// plant outside the bounds, which the law controls, leaves no electrical evidence.
#[test]
fn faults_are_named_at_10_khz_too() {
    for o in table(10e3, 24.0).unwrap() {
        match o.name.as_str() {
            "coil short" => {
                assert_eq!(o.fault.as_deref(), Some("coil_short"));
                assert!(o.detected_after_s.unwrap() <= DEADLINE_S);
                let peak = o.peak_current_a;
                assert!(peak > 13.2 && peak < 16.0, "{peak}");
            }
            "plant outside the bounds" => assert_eq!(o.fault, None),
            _ => assert!(
                o.pass(),
                "{}: {:?} after {:?}",
                o.name,
                o.fault,
                o.detected_after_s
            ),
        }
    }
}

/// A current reading frozen while the current barely changes (in the middle of the move,
/// milliamperes per tick) carries no information until the loop has wound up against it:
/// it is still named, later. Measured: 11.3 ms.
#[test]
fn a_current_reading_frozen_in_a_steady_phase_is_found_later() {
    let sc = Scenario::product(20e3, 24.0)
        .with_duration_s(0.3)
        .with_fault(0.07, Injected::CurrentStuck);
    let r = run(&sc).unwrap();
    let first = r.trace.iter().find(|s| s.fault.is_some()).unwrap();
    assert_eq!(first.fault, Some(Fault::CurrentStuck));
    let after = first.t_s - 0.07;
    assert!(after > 1e-3 && after < 20e-3, "{after}");
    assert!(r.metrics.i_peak_a <= 13.2);
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
        .with_duration_s(0.01)
        .with_fault(stall_s, Injected::MissedDeadlines { ticks: u32::MAX });
    let r = run(&sc).unwrap();
    let first_coast = r
        .trace
        .iter()
        .position(|s| s.t_s >= stall_s && s.mode == ema::bridge::Mode::Coast)
        .unwrap();
    let coast_s = r.trace[first_coast].t_s;
    assert!((coast_s - 300e-6).abs() < 1e-9, "{coast_s}");
    assert!(coast_s - stall_s <= 0.5e-3);
    // Driven all through the stall, coasting after, with the overrun latched.
    let stalled = &r.trace[1..first_coast];
    assert!(stalled.iter().all(|s| s.mode == ema::bridge::Mode::Forward));
    assert!(stalled.iter().all(|s| s.fault.is_none()));
    let after = &r.trace[first_coast..];
    assert!(after.iter().all(|s| s.mode == ema::bridge::Mode::Coast));
    assert!(after.iter().all(|s| s.fault == Some(Fault::Overrun)));
    assert_eq!(r.trace.last().unwrap().i_a, 0.0);
}

/// Healthy runs of every case's scenario without the injection raise nothing.
#[test]
fn without_the_injection_nothing_is_raised() {
    for mut c in cases(20e3, 24.0) {
        if c.name == "plant outside the bounds" {
            continue;
        }
        c.scenario.faults.clear();
        let o = evaluate(&c).unwrap();
        assert_eq!(o.fault, None, "{}", c.name);
    }
}
