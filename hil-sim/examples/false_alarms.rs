//! False alarms of the fault detectors over drawn plants: for each family member, a Monte
//! Carlo of its evaluation scenario (every draw a plant from the member's uncertainty set,
//! its own converter noise), at the member's own interrupt rate and at 20 kHz, counting
//! the draws in which any fault is latched.
//!
//! `cargo run -p hil-sim --release --example false_alarms -- [N] [SEED] [MEMBER...]`
//! (N 1000, seed 1, the whole family by default).

use hil_sim::actuator::{self, FAMILY};
use hil_sim::montecarlo::montecarlo_with;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: usize = args.first().map_or(Ok(1000), |s| s.parse())?;
    let seed: u64 = args.get(1).map_or(Ok(1), |s| s.parse())?;
    let members: Vec<String> = if args.len() > 2 {
        args[2..].to_vec()
    } else {
        FAMILY.iter().map(|e| e.name.to_owned()).collect()
    };
    println!("| member | rate [kHz] | draws | draws with a fault | faults named |");
    println!("|---|---|---|---|---|");
    for member in &members {
        let (name, act) = actuator::load(member)?;
        let own = act.board.rate_hz;
        let rates = if (own - 20e3).abs() < 1.0 {
            vec![own]
        } else {
            vec![own, 20e3]
        };
        for rate in rates {
            let sc = actuator::scenario(&name, &act.with_rate_hz(rate))?;
            let draws = montecarlo_with(&sc, n, seed, false)?;
            let mut named: Vec<String> = Vec::new();
            let mut faulted = 0;
            for d in &draws {
                if let Some(f) = d.metrics.first_fault {
                    faulted += 1;
                    let what = f.fault.map_or("?", ema::supervisor::Fault::name);
                    named.push(format!("draw {} {what} at {:.4} s", d.index, f.t_s));
                }
            }
            println!(
                "| {name} | {} | {n} | {faulted} | {} |",
                rate / 1e3,
                if named.is_empty() {
                    "-".to_owned()
                } else {
                    named.join("; ")
                }
            );
        }
    }
    Ok(())
}
