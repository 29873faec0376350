use ema::control::bridge::HBridge;
use ema::device::commission::{Identification, Plan, Step};
use hil_sim::simulation::board::scenario;
use hil_sim::simulation::hal::{self};
use hil_sim::simulation::scenario::Sensors;
use hil_sim::simulation::sim::Stepper;

fn main() {
    let name = std::env::args().nth(1).unwrap_or("plunger-1kg".into());
    for seed in 1..=6u64 {
        let (_, a) = hil_sim::simulation::actuator::load(&name).unwrap();
        let a = ema::control::actuator::Actuator { tuning: None, ..a };
        let mut sc = scenario(&a, true).unwrap();
        if let Sensors::Adc(adc) = &mut sc.sensors {
            adc.seed = seed;
        }
        let plant = sc.plant.resolve(&sc.controller.plant);
        let mut stepper =
            Stepper::for_scenario(&sc, plant.clone(), sc.integration.substeps).unwrap();
        let mut converter = match &sc.sensors {
            Sensors::Adc(adc) => adc.start(&sc.controller.sense),
            _ => unreachable!(),
        };
        let (pwm, dir, en, lines) = hal::bridge_io(sc.bridge.max_duty);
        let Ok(mut bridge) = HBridge::new(pwm, dir, en);
        let cfg = sc.controller.build().unwrap();
        let plan = Plan::for_actuator(&a, a.board.rate_hz).unwrap();
        let mut id = Identification::new(plan);
        let mut applied = 0.0_f32;
        let mut log: Vec<(f32, f64, f64, f64)> = Vec::new();
        loop {
            let truth = stepper.sample();
            let frame = converter.sample(truth.x_m, truth.i_a, truth.vbus_v);
            let m = cfg.sense().convert(&frame).unwrap();
            log.push((applied, truth.x_m, truth.v_mps, truth.i_a));
            match id.step(&m, applied) {
                Step::Drive(u) => {
                    applied = bridge.apply(u, m.vbus_v).map_or(0.0, |d| d.u_v);
                }
                Step::Done(r) => {
                    let r = r.unwrap();
                    println!(
                        "seed {seed}: L open {:.4e} closed {:.4e} (true {:.4e})",
                        r.inductance.open_h,
                        r.inductance.closed_h,
                        plant.inductance_h(plant.gap_m(0.0))
                    );
                    break;
                }
            }
            stepper.advance(lines.switches(), sc.bridge.mode);
        }
        // find the probe cycle: runs of constant applied voltage of length probe_half_ticks alternating
        let h = plan.probe_half_ticks as usize;
        let mut k = 1;
        let mut changes = vec![];
        while k < log.len() {
            if (log[k].0 - log[k - 1].0).abs() > 0.05 {
                changes.push(k);
            }
            k += 1;
        }
        // print the settled true current at the end of each constant run of length ~h
        for w in changes.windows(2) {
            let len = w[1] - w[0];
            if len > 50 {
                let e = w[0] + h.min(len) - 1;
                let end = log[e];
                let st = log[w[0]];
                let (lo, hi) = log[w[0] + 1..e]
                    .iter()
                    .fold((f32::MAX, f32::MIN), |(l, h), q| (l.min(q.0), h.max(q.0)));
                let flips = log[w[0] + 1..e]
                    .windows(2)
                    .filter(|q| q[0].0 != q[1].0)
                    .count();
                println!("      applied {lo:.5}..{hi:.5} V, {flips} changes");
                println!("   run at {:6} len {:6}: u {:.4} V; at start x {:.3e} v {:.3e}; after h: x {:.3e} v {:.3e} i {:.5} A", w[0], len, end.0, st.1, st.2, end.1, end.2, end.3);
            }
        }
        println!(
            "   probe levels: {:?}, code {:.4} A",
            plan.probe_a,
            a.board.current_full_scale_a / 2048.0
        );
    }
}
