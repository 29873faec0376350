//! The board's commissioning routine (`ema::commission`) on every actuator of the family,
//! against its simulated plant: the board's bridge (`ema::bridge` on the mock pins), the
//! converter with its typical noise, quantisation and delay, the plant's RK4 with its end
//! stops, the control interrupt's order (convert, identify, drive). The routine starts
//! from the file; the plant is the file's (the drawn plants are in `tests/commission.rs`,
//! through the host tool and the virtual board).
//!
//! Each member: the resistance within 2 %, the inductance at both stops within 5 % of the
//! plant's, the position readings at both stops within 2 codes of the true positions',
//! the true coil current never above the rating, at most 10 s of actuator time.

use ema::bridge::HBridge;
use ema::commission::{Identification, Plan, Report, Step};
use hil_sim::bench::board::scenario;
use hil_sim::hal::{self, Adc};
use hil_sim::scenario::Sensors;
use hil_sim::sim::Stepper;

/// The family, as `hil-sim actuators` lists it.
const FAMILY: [&str; 6] = [
    "product",
    "valve",
    "solenoid-12v",
    "positioner-48v",
    "plunger-1kg",
    "pilot-50khz",
];

/// What one commissioning gave: its report, its actuator time \[s\] and the largest true
/// coil current \[A\].
fn commission(
    name: &str,
) -> (
    ema::actuator::Actuator,
    Report,
    f64,
    f64,
    hil_sim::plant::Params,
) {
    let (_, a) = hil_sim::actuator::load(name).unwrap();
    let sc = scenario(&a, true).unwrap();
    let plant = sc.plant.resolve(&sc.controller.plant);
    let mut stepper = Stepper::for_scenario(&sc, plant.clone(), sc.integration.substeps).unwrap();
    let mut converter = match &sc.sensors {
        Sensors::Adc(adc) => adc.start(&sc.controller.sense),
        Sensors::Ideal => Adc::default().start(&sc.controller.sense),
    };
    let (pwm, dir, en, lines) = hal::bridge_io(sc.bridge.max_duty);
    let Ok(mut bridge) = HBridge::new(pwm, dir, en);
    let cfg = sc.controller.build().unwrap();
    // As the board's dispatcher plans it (`ema::device`).
    let plan = Plan::for_actuator(&a, a.board.rate_hz).unwrap();
    let mut id = Identification::new(plan);
    let (mut applied, mut peak) = (0.0_f32, 0.0_f64);
    for k in 0..30 * plan.ticks() {
        let truth = stepper.sample();
        peak = peak.max(truth.i_a.abs());
        let frame = converter.sample(truth.x_m, truth.i_a, truth.vbus_v);
        let m = cfg.sense().convert(&frame).unwrap();
        match id.step(&m, applied) {
            Step::Drive(u) => applied = bridge.apply(u, m.vbus_v).unwrap().u_v,
            Step::Done(Ok(report)) => {
                return (
                    a,
                    report,
                    k as f64 / f64::from(a.board.rate_hz),
                    peak,
                    plant,
                )
            }
            Step::Done(Err(e)) => panic!("{name}: commissioning stopped: {}", e.name()),
        }
        stepper.advance(lines.switches(), sc.bridge.mode);
    }
    panic!("{name}: no end after {} ticks", 30 * plan.ticks());
}

#[test]
fn every_member_is_commissioned_within_its_targets() {
    for name in FAMILY {
        let (a, got, took_s, peak, plant) = commission(name);
        let code_m = f64::from(a.time_scales().unwrap().position_code_m);
        let stroke = plant.stroke_m;
        let e_r = f64::from(got.resistance.ohm) / plant.resistance_ohm - 1.0;
        let true_h = [0.0, stroke].map(|x| plant.inductance_h(plant.gap_m(x)));
        let e_l = [
            f64::from(got.inductance.open_h) / true_h[0] - 1.0,
            f64::from(got.inductance.closed_h) / true_h[1] - 1.0,
        ];
        let codes = [
            f64::from(got.ends.open_m).abs() / code_m,
            (f64::from(got.ends.closed_m) - stroke).abs() / code_m,
        ];
        let rated = f64::from(a.coil.rated_current_a);
        eprintln!(
            "{name:15} R {:+.3} %, L open {:+.2} % closed {:+.2} %, stops {:.2} and {:.2} codes, peak {:.1} % of the rating, {took_s:.2} s",
            100.0 * e_r,
            100.0 * e_l[0],
            100.0 * e_l[1],
            codes[0],
            codes[1],
            100.0 * peak / rated
        );
        assert!(e_r.abs() < 0.02, "{name}: {got:?}");
        assert!(
            e_l.iter().all(|e| e.abs() < 0.05),
            "{name}: {got:?} against {true_h:?}"
        );
        assert!(codes.iter().all(|c| *c < 2.0), "{name}: {got:?}");
        assert!(peak <= rated, "{name}: {peak} A");
        assert!(took_s <= 10.0, "{name}: {took_s} s");
    }
}
